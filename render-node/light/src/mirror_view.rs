//! Per-eye views of a CRT face seen through the beam splitter: the
//! generalised (off-axis) perspective projection onto the mirror image of
//! the screen. Pure math.
//!
//! An observer sees the CRT reflected in the half-silvered mirror, so the
//! screen appears at its mirror image. For a world point `X` and eye `E`,
//! the CRT must light the pixel whose *reflected* position lies on the line
//! of sight `E -> X`. [`FaceView::clip_from_world`] is that map, written as
//! one projective matrix straight onto the CRT's pixel grid (`u` along
//! `screen.right`, `v` along `screen.down`), so it holds for any mirror,
//! including the handedness flip of the reflection (see
//! [`FaceView::flips_winding`]).
#![forbid(unsafe_code)]

use glam::{DMat4, DVec2, DVec3, DVec4};
use showcase_proto::{CrtFace, Observer, Pose};

/// The view of one eye through one face.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceView {
    /// The eye position.
    pub eye: DVec3,
    /// World to clip space for the face's framebuffer: `x, y` in NDC map to
    /// CRT pixels with `y` down as in wgpu framebuffers, depth `0..1`
    /// between `near` and `far` measured along the screen normal.
    pub clip_from_world: DMat4,
    /// True when the image is mirrored relative to the world, so triangle
    /// winding flips (set the pipeline's front face accordingly).
    pub flips_winding: bool,
}

/// Reflected screen corner and edges.
fn reflected_screen(face: &CrtFace) -> (DVec3, DVec3, DVec3) {
    let n = face.mirror.normal.as_dvec3();
    let d = face.mirror.offset as f64;
    let point = |p: DVec3| p - 2.0 * (n.dot(p) - d) * n;
    let vector = |v: DVec3| v - 2.0 * n.dot(v) * n;
    let s = face.screen;
    (
        point(s.origin.as_dvec3()),
        vector(s.right.as_dvec3()),
        vector(s.down.as_dvec3()),
    )
}

impl FaceView {
    /// The view of the eye at `eye` through `face`, with clip planes at
    /// `near` and `far` metres from the eye along the screen normal.
    /// `None` when the eye lies in the plane of the reflected screen.
    pub fn new(face: &CrtFace, eye: DVec3, near: f64, far: f64) -> Option<Self> {
        let (o, u, v) = reflected_screen(face);
        let mut n = u.cross(v).normalize_or_zero();
        let mut dist = n.dot(o - eye);
        if dist.abs() < 1e-9 || n == DVec3::ZERO {
            return None;
        }
        if dist < 0.0 {
            n = -n;
            dist = -dist;
        }
        // Dual basis of (u, v) in the screen plane: s = (H - o) . us.
        let (uu, uv, vv) = (u.dot(u), u.dot(v), v.dot(v));
        let det = uu * vv - uv * uv;
        let us = (vv * u - uv * v) / det;
        let vs = (uu * v - uv * u) / det;
        // For D = X - E, w = n.D, the hit H = E + dist D / w, and
        // s = ((E - o).us w + dist D.us) / w: linear in D over w.
        let a = (eye - o).dot(us) * n + dist * us;
        let b = (eye - o).dot(vs) * n + dist * vs;
        let rx = 2.0 * a - n; // x_ndc = 2s - 1
        let ry = n - 2.0 * b; // y_ndc = 1 - 2t
        let zs = far / (far - near);
        let rz = zs * n;
        let rows = [rx, ry, rz, n];
        let offsets = [
            -rx.dot(eye),
            -ry.dot(eye),
            -rz.dot(eye) - far * near / (far - near),
            -n.dot(eye),
        ];
        let row = |i: usize| DVec4::new(rows[i].x, rows[i].y, rows[i].z, offsets[i]);
        let clip_from_world = DMat4::from_cols(row(0), row(1), row(2), row(3)).transpose();
        let mut view = Self {
            eye,
            clip_from_world,
            flips_winding: false,
        };
        view.flips_winding = view.mirrored(o + 0.5 * (u + v));
        Some(view)
    }

    /// Whether a small triangle facing the eye, counter-clockwise as seen
    /// from it, comes out clockwise-as-seen on the CRT. In an ordinary
    /// camera image with `v` down such a triangle has negative signed area.
    fn mirrored(&self, toward: DVec3) -> bool {
        let dir = (toward - self.eye).normalize();
        let a = dir.any_orthonormal_vector();
        let b = dir.cross(a);
        let (a, b) = if a.cross(b).dot(-dir) > 0.0 {
            (a, b)
        } else {
            (b, a)
        };
        let p0 = self.eye + 0.5 * dir;
        let px = |x: DVec3| {
            let c = self.clip_from_world * x.extend(1.0);
            DVec2::new(c.x / c.w, -c.y / c.w) // NDC with y down, like pixels
        };
        let (q0, q1, q2) = (px(p0), px(p0 + 0.01 * a), px(p0 + 0.01 * b));
        (q1 - q0).perp_dot(q2 - q0) > 0.0
    }

    /// Both eyes of a head pose: `[left, right]`.
    pub fn stereo(face: &CrtFace, head: &Pose, ipd: f32, near: f64, far: f64) -> Option<[Self; 2]> {
        let [l, r] = Observer::eyes(head, ipd);
        Some([
            Self::new(face, l.as_dvec3(), near, far)?,
            Self::new(face, r.as_dvec3(), near, far)?,
        ])
    }

    /// The CRT pixel coordinates (`u` right, `v` down, in pixels of a
    /// `width x height` face) where `world` must be drawn; `None` behind
    /// the eye.
    pub fn pixel(&self, world: DVec3, width: u32, height: u32) -> Option<DVec2> {
        let c = self.clip_from_world * world.extend(1.0);
        if c.w <= 0.0 {
            return None;
        }
        Some(DVec2::new(
            (c.x / c.w + 1.0) * 0.5 * width as f64,
            (1.0 - c.y / c.w) * 0.5 * height as f64,
        ))
    }
}

/// The physical CRT point of pixel `(u, v)` of a face.
pub fn screen_point(face: &CrtFace, pixel: DVec2) -> DVec3 {
    let s = face.screen;
    s.origin.as_dvec3()
        + pixel.x / face.width as f64 * s.right.as_dvec3()
        + pixel.y / face.height as f64 * s.down.as_dvec3()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use proptest::prelude::*;
    use showcase_proto::{Plane, Rect3};

    /// A CRT lying face-up under a 45-degree beam splitter that leans
    /// towards the observer (plane y - z = 0.4). The CRT and the observer
    /// are on the same side of the mirror; the observer looks along -z and
    /// sees the screen's reflection standing upright at z = -0.4, upside
    /// down relative to the CRT's own pixel layout (a mirrored image).
    fn face() -> CrtFace {
        CrtFace {
            name: "face-0".into(),
            screen: Rect3 {
                origin: Vec3::new(-0.2, 0.0, -0.35),
                right: Vec3::new(0.4, 0.0, 0.0),
                down: Vec3::new(0.0, 0.0, 0.3),
            },
            mirror: Plane::from_point_normal(Vec3::new(0.0, 0.2, -0.2), Vec3::new(0.0, 1.0, -1.0)),
            width: 1024,
            height: 768,
            photometry: showcase_proto::CrtPhotometry::nominal(2.2),
        }
    }

    /// The criterion of a correct face view: a point drawn on the screen lies on the eye's
    /// line of sight through its reflected position.
    fn assert_on_line_of_sight(face: &CrtFace, view: &FaceView, x: DVec3) {
        let px = view.pixel(x, face.width, face.height).unwrap();
        let p = screen_point(face, px);
        let n = face.mirror.normal.as_dvec3();
        let reflected = p - 2.0 * (n.dot(p) - face.mirror.offset as f64) * n;
        let sight = (x - view.eye).normalize();
        let to_reflection = reflected - view.eye;
        let off_line = (to_reflection - to_reflection.dot(sight) * sight).length();
        assert!(
            off_line < 1e-7,
            "{x}: reflected pixel is {off_line} m off the line of sight"
        );
        // The reflection is in front of the eye (not behind it).
        assert!(to_reflection.dot(sight) > 0.0);
    }

    #[test]
    fn points_lie_on_the_line_of_sight_through_their_reflection() {
        let f = face();
        let head = Pose {
            position: Vec3::new(0.05, 0.25, 0.6),
            orientation: Quat::IDENTITY,
        };
        for view in FaceView::stereo(&f, &head, 0.064, 0.05, 10.0).unwrap() {
            for x in [
                DVec3::new(0.0, 0.2, -0.3),
                DVec3::new(0.1, 0.1, -0.5),
                DVec3::new(-0.15, 0.3, -0.2),
            ] {
                assert_on_line_of_sight(&f, &view, x);
            }
        }
    }

    #[test]
    fn the_reflected_screen_corners_map_to_the_crt_corners() {
        let f = face();
        let view = FaceView::new(&f, DVec3::new(0.0, 0.25, 0.6), 0.05, 10.0).unwrap();
        let (o, u, v) = reflected_screen(&f);
        for (corner, px) in [
            (o, DVec2::ZERO),
            (o + u, DVec2::new(1024.0, 0.0)),
            (o + v, DVec2::new(0.0, 768.0)),
            (o + u + v, DVec2::new(1024.0, 768.0)),
        ] {
            let got = view.pixel(corner, f.width, f.height).unwrap();
            assert!((got - px).length() < 1e-6, "{got} vs {px}");
        }
    }

    #[test]
    fn depth_runs_from_near_to_far() {
        let f = face();
        let eye = DVec3::new(0.0, 0.25, 0.6);
        let view = FaceView::new(&f, eye, 0.05, 10.0).unwrap();
        // Depth is measured along the reflected screen's normal (here -z).
        let (o, u, v) = reflected_screen(&f);
        assert!(
            (u.cross(v).normalize().abs() - DVec3::Z).length() < 1e-6,
            "{u} {v}"
        );
        assert!((o.z + 0.4).abs() < 1e-6 && (o.y - 0.05).abs() < 1e-6, "{o}");
        let depth = |d: f64| {
            let c = view.clip_from_world * (eye + DVec3::new(0.0, 0.0, -d)).extend(1.0);
            c.z / c.w
        };
        assert!(depth(0.05).abs() < 1e-9);
        assert!((depth(10.0) - 1.0).abs() < 1e-9);
        assert!(depth(0.5) < depth(0.6));
    }

    #[test]
    fn a_reflection_flips_winding_and_a_plain_window_does_not() {
        let f = face();
        let eye = DVec3::new(0.0, 0.25, 0.6);
        assert!(FaceView::new(&f, eye, 0.05, 10.0).unwrap().flips_winding);
        // An upright screen (right = +x, down = -y) in a mirror plane that
        // contains it is reflected onto itself: an ordinary window, which
        // must not flip.
        let mut g = f.clone();
        g.screen = Rect3 {
            origin: Vec3::new(-0.2, 0.35, -0.4),
            right: Vec3::new(0.4, 0.0, 0.0),
            down: Vec3::new(0.0, -0.3, 0.0),
        };
        g.mirror = Plane::from_point_normal(g.screen.origin, Vec3::Z);
        let plain = FaceView::new(&g, eye, 0.05, 10.0).unwrap();
        assert!(!plain.flips_winding);
        // Winding check by projection: a counter-clockwise triangle as seen
        // from the eye stays counter-clockwise in the plain view.
        let tri = [
            DVec3::new(-0.05, 0.2, -0.4),
            DVec3::new(0.05, 0.2, -0.4),
            DVec3::new(0.0, 0.3, -0.4),
        ];
        let signed_area = |view: &FaceView, face: &CrtFace| {
            let p: Vec<DVec2> = tri
                .iter()
                .map(|x| view.pixel(*x, face.width, face.height).unwrap())
                .collect();
            (p[1] - p[0]).perp_dot(p[2] - p[0])
        };
        let mirrored = FaceView::new(&f, eye, 0.05, 10.0).unwrap();
        assert!(signed_area(&plain, &g) * signed_area(&mirrored, &f) < 0.0);
    }

    #[test]
    fn an_eye_in_the_screen_plane_has_no_view() {
        let f = face();
        let (o, u, _) = reflected_screen(&f);
        assert!(FaceView::new(&f, o + 0.5 * u, 0.05, 10.0).is_none());
    }

    proptest! {
        #[test]
        fn line_of_sight_holds_for_random_eyes_and_points(
            ex in -0.3f64..0.3, ey in 0.1f64..0.5, ez in 0.3f64..1.2,
            x in -0.2f64..0.2, y in 0.0f64..0.4, z in -0.6f64..-0.1,
        ) {
            let f = face();
            let view = FaceView::new(&f, DVec3::new(ex, ey, ez), 0.05, 10.0).unwrap();
            assert_on_line_of_sight(&f, &view, DVec3::new(x, y, z));
        }
    }
}
