//! Which objects a light's cube views must hold. A shadow map is only
//! ever asked whether something lies between the light and a receiver (a
//! real surface point), and a texel that holds nothing reads as "lit". So
//! an object that can block no segment from the light to a receiver is
//! left out (a wall of the room seen from a light inside it), and a cube
//! face is drawn only with the objects whose bounds reach into its
//! frustum; a face that holds none is only cleared.
//!
//! Leaving a non-occluder out can only turn a lookup from "shadowed" to
//! "lit" (the stored depth is a minimum over fewer surfaces), and only
//! where the object stood in front of the receiver along the texel's ray
//! but not along the exact ray, which it cannot block: shadow-map
//! aliasing at its own edges. The CPU reference (exact rays) calls those
//! points lit too.

use std::ops::Range;

use glam::{DVec3, Mat4, Vec3, Vec4};

use super::{ShadowView, WorldVertex};

/// Objects with at most this many triangles are tested triangle by
/// triangle; larger ones are kept as occluders (the test is per triangle
/// against every receiver's bounds).
pub const PLANE_TEST_TRIANGLES: usize = 64;

/// A receiver point may lie this far (metres) behind a triangle's plane
/// and still count as in front of it: the lookups' constant bias
/// (`nearest_or_nearer`: 1e-4 m). A surface that dips less than this
/// through a plane touches it (the bench's bunny stands 63 um into its
/// floor); the part below is hidden from a projector on the light's side
/// by the plane's own surface, and the bench test
/// `culled_light_views_change_only_pixels_towards_the_cpu_reference`
/// checks the result against exact rays.
pub const PLANE_TOLERANCE: f64 = 1e-4;

/// One object of a vertex buffer: its vertex range and whether its
/// surface receives light (a real object, in the projector role).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectVertices {
    /// The object's vertices in the buffer (three per triangle).
    pub range: Range<u32>,
    /// True for a receiver.
    pub receiver: bool,
}

fn bounds(vertices: &[WorldVertex]) -> Option<(Vec3, Vec3)> {
    let mut it = vertices.iter().map(|v| Vec3::from_array(v.position));
    let first = it.next()?;
    Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
}

fn corners((lo, hi): (Vec3, Vec3)) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// Every point of every receiver lies in the convex hull of these points:
/// a small receiver's vertices, a large one's bounding box corners.
fn receiver_points(all: &[WorldVertex], objects: &[ObjectVertices]) -> Vec<DVec3> {
    let mut points = Vec::new();
    for o in objects.iter().filter(|o| o.receiver) {
        let Some(v) = all.get(o.range.start as usize..o.range.end as usize) else {
            continue;
        };
        if v.len() <= 3 * PLANE_TEST_TRIANGLES {
            points.extend(v.iter().map(|w| Vec3::from_array(w.position).as_dvec3()));
        } else if let Some(b) = bounds(v) {
            points.extend(corners(b).iter().map(|c| c.as_dvec3()));
        }
    }
    points
}

/// True when no triangle of `vertices` can block a segment from `light`
/// to any point of `receivers`' convex hull: for every triangle, the light
/// lies strictly on one side of its plane and every receiver point on the
/// same side (or within [`PLANE_TOLERANCE`] of the plane). A segment
/// that crosses a plane has its ends on opposite sides.
pub fn cannot_occlude(vertices: &[WorldVertex], light: DVec3, receivers: &[DVec3]) -> bool {
    if vertices.len() > 3 * PLANE_TEST_TRIANGLES || !light.is_finite() {
        return false;
    }
    vertices.chunks_exact(3).all(|t| {
        let p: [DVec3; 3] = std::array::from_fn(|i| Vec3::from_array(t[i].position).as_dvec3());
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        if n == DVec3::ZERO || !n.is_finite() {
            // Degenerate triangles are never drawn.
            return true;
        }
        let side = n.dot(light - p[0]);
        let scale = (light - p[0]).length().max(1.0);
        if side.is_nan() || side.abs() <= PLANE_TOLERANCE * scale {
            return false;
        }
        let n = n * side.signum();
        receivers
            .iter()
            .all(|&q| n.dot(q - p[0]) >= -PLANE_TOLERANCE)
    })
}

/// True when the box `(lo, hi)` may reach into the frustum of `view`
/// (conservative: false only when all eight corners lie outside one
/// clip plane).
pub fn box_in_view(view: &ShadowView, lo: Vec3, hi: Vec3) -> bool {
    let m = Mat4::from_cols_array_2d(&view.clip_from_world);
    let c: Vec<Vec4> = corners((lo, hi))
        .iter()
        .map(|p| m * p.extend(1.0))
        .collect();
    let outside = |f: &dyn Fn(&Vec4) -> bool| c.iter().all(f);
    !(outside(&|v| v.x > v.w)
        || outside(&|v| v.x < -v.w)
        || outside(&|v| v.y > v.w)
        || outside(&|v| v.y < -v.w)
        || outside(&|v| v.z < 0.0)
        || outside(&|v| v.z > v.w))
}

/// For each view of `views` (the cube views of the light at `light`), the
/// vertex ranges of `all` to draw: the objects of `objects` that can
/// occlude a receiver and whose bounds reach into that view, adjacent
/// ranges merged.
pub fn cube_occluder_ranges(
    all: &[WorldVertex],
    objects: &[ObjectVertices],
    light: DVec3,
    views: &[ShadowView],
) -> Vec<Vec<Range<u32>>> {
    let receivers = receiver_points(all, objects);
    let occluders: Vec<(Range<u32>, (Vec3, Vec3))> = objects
        .iter()
        .filter_map(|o| {
            let v = all.get(o.range.start as usize..o.range.end as usize)?;
            let b = bounds(v)?;
            (!cannot_occlude(v, light, &receivers)).then(|| (o.range.clone(), b))
        })
        .collect();
    views
        .iter()
        .map(|view| {
            let mut ranges: Vec<Range<u32>> = Vec::new();
            for (r, (lo, hi)) in &occluders {
                if !box_in_view(view, *lo, *hi) {
                    continue;
                }
                match ranges.last_mut() {
                    Some(last) if last.end == r.start => last.end = r.end,
                    _ => ranges.push(r.clone()),
                }
            }
            ranges
        })
        .collect()
}

/// An identity for a layer drawn with `ranges` of the vertex buffer whose
/// identity is `geometry` (FNV-1a over both), for
/// [`super::LayerDraw::geometry`].
pub fn ranges_identity(geometry: u64, ranges: &[Range<u32>]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |x: u64| {
        for b in x.to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(geometry);
    eat(ranges.len() as u64);
    for r in ranges {
        eat(u64::from(r.start) << 32 | u64::from(r.end));
    }
    h
}

#[cfg(test)]
mod tests {
    use super::super::cube_views;
    use super::*;

    fn quad(corners: [[f32; 3]; 4]) -> Vec<WorldVertex> {
        let v = |i: usize| WorldVertex {
            position: corners[i],
            normal: [0.0; 3],
        };
        vec![v(0), v(1), v(2), v(0), v(2), v(3)]
    }

    /// A floor at y = 0 and a box standing on it.
    fn room() -> (Vec<WorldVertex>, Vec<ObjectVertices>) {
        let mut all = quad([
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
        ]);
        let floor = 0..all.len() as u32;
        // A small tilted quad above the floor (an occluder).
        all.extend(quad([
            [0.4, 0.2, 0.4],
            [0.6, 0.25, 0.4],
            [0.6, 0.25, 0.6],
            [0.4, 0.2, 0.6],
        ]));
        let blocker = floor.end..all.len() as u32;
        (
            all,
            vec![
                ObjectVertices {
                    range: floor,
                    receiver: true,
                },
                ObjectVertices {
                    range: blocker,
                    receiver: true,
                },
            ],
        )
    }

    #[test]
    fn a_floor_under_the_light_cannot_occlude_but_a_blocker_can() {
        let (all, objects) = room();
        let receivers = receiver_points(&all, &objects);
        let light = DVec3::new(0.5, 0.8, 0.5);
        let floor = &all[objects[0].range.start as usize..objects[0].range.end as usize];
        let blocker = &all[objects[1].range.start as usize..objects[1].range.end as usize];
        assert!(cannot_occlude(floor, light, &receivers));
        // The blocker's plane has floor points on the far side.
        assert!(!cannot_occlude(blocker, light, &receivers));
        // A light below the floor: the floor now separates it from the
        // blocker, so it must stay.
        assert!(!cannot_occlude(
            floor,
            DVec3::new(0.5, -0.5, 0.5),
            &receivers
        ));
        // A light in the floor's plane is never trusted.
        assert!(!cannot_occlude(
            floor,
            DVec3::new(0.5, 0.0, 0.5),
            &receivers
        ));
    }

    #[test]
    fn the_verdict_agrees_with_brute_force_segments() {
        use rand::{Rng, SeedableRng};
        let (all, objects) = room();
        let receivers = receiver_points(&all, &objects);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let tri_hit = |a: DVec3, b: DVec3, t: &[WorldVertex]| {
            // Segment a-b against triangle t (Moller-Trumbore, open ends).
            let p = t
                .iter()
                .map(|v| Vec3::from_array(v.position).as_dvec3())
                .collect::<Vec<_>>();
            let (e1, e2, d) = (p[1] - p[0], p[2] - p[0], b - a);
            let h = d.cross(e2);
            let det = e1.dot(h);
            if det.abs() < 1e-15 {
                return false;
            }
            let s = a - p[0];
            let u = s.dot(h) / det;
            let q = s.cross(e1);
            let v = d.dot(q) / det;
            let t = e2.dot(q) / det;
            u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 1e-9 && t < 1.0 - 1e-9
        };
        for _ in 0..50 {
            let light = DVec3::new(
                rng.random_range(-0.5..1.5),
                rng.random_range(-0.5..1.5),
                rng.random_range(-0.5..1.5),
            );
            for o in &objects {
                let v = &all[o.range.start as usize..o.range.end as usize];
                if !cannot_occlude(v, light, &receivers) {
                    continue;
                }
                // Claimed harmless: no segment from the light to a
                // receiver point crosses any of its triangles.
                for r in &objects {
                    let rv = &all[r.range.start as usize..r.range.end as usize];
                    for t in rv.chunks_exact(3) {
                        let (a, b) = (rng.random::<f64>(), rng.random::<f64>());
                        let (a, b) = if a + b > 1.0 {
                            (1.0 - a, 1.0 - b)
                        } else {
                            (a, b)
                        };
                        let p: [DVec3; 3] =
                            std::array::from_fn(|i| Vec3::from_array(t[i].position).as_dvec3());
                        let q = p[0] + a * (p[1] - p[0]) + b * (p[2] - p[0]);
                        for tri in v.chunks_exact(3) {
                            assert!(!tri_hit(light, q, tri), "light {light} to {q}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn faces_hold_only_the_occluders_in_their_frustum() {
        let (all, objects) = room();
        let light = Vec3::new(0.5, 0.8, 0.5);
        let views = cube_views(light, 1e-3, 8.0, 64);
        let ranges = cube_occluder_ranges(&all, &objects, light.as_dvec3(), &views);
        assert_eq!(ranges.len(), 6);
        // Only the -y face (index 3) sees the blocker; the floor is left
        // out everywhere.
        for (face, r) in ranges.iter().enumerate() {
            if face == 3 {
                assert_eq!(r, &vec![objects[1].range.clone()], "face {face}");
            } else {
                assert!(r.is_empty(), "face {face}: {r:?}");
            }
        }
    }

    #[test]
    fn a_box_behind_or_beside_a_view_is_outside_it() {
        let views = cube_views(Vec3::ZERO, 1e-3, 8.0, 64);
        // +x face (0): a box at x = 2 is inside, one at x = -2 is not.
        let (lo, hi) = (Vec3::new(1.9, -0.1, -0.1), Vec3::new(2.1, 0.1, 0.1));
        assert!(box_in_view(&views[0], lo, hi));
        assert!(!box_in_view(&views[1], lo, hi));
        assert!(!box_in_view(&views[2], lo, hi));
        // A box around the origin reaches into every face.
        for v in &views {
            assert!(box_in_view(v, Vec3::splat(-0.1), Vec3::splat(0.1)));
        }
    }

    #[test]
    fn range_identities_differ_with_the_ranges() {
        assert_ne!(
            ranges_identity(1, std::slice::from_ref(&(0..3))),
            ranges_identity(1, std::slice::from_ref(&(0..6)))
        );
        assert_ne!(ranges_identity(1, &[]), ranges_identity(2, &[]));
        assert_eq!(
            ranges_identity(5, &[0..3, 6..9]),
            ranges_identity(5, &[0..3, 6..9])
        );
    }
}
