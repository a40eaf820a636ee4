//! The pass list (DESIGN section 7): a node builds it from the scene and
//! the frame state and runs only the passes that can change its output.
//!
//! Projector role rules, each of which leaves the output bit-identical:
//! - light shadow views run only when an occluder can be lit: some light
//!   sample emits, and the occluding geometry is not a single plane (a
//!   plane cannot shadow itself, so every visibility test would pass);
//! - eye (occlusion shadow) views run only when there is an eye and a
//!   virtual object to cast the shadow;
//! - the whole frame is reused when its [`FrameKey`] (everything visible
//!   to this output: scene version, lights, object transforms, and the
//!   heads only when occlusion shadows are drawn) equals the last one.
//!
//! The face role ([`PassList::for_face`]) also runs the cube maps only
//! when a reflective virtual object exists; between drawn frames the
//! face pipeline keeps its cube maps while the lights, the geometry and
//! the albedos stay put (`crate::gpu::cube_map::CubeMapFrames`).

use glam::DVec3;
use showcase_light::digest::Fnv64;
use showcase_light::render::frame::FrameScene;
use showcase_proto::{FrameState, ObjectKind, Showcase};

/// A GPU pass of the projector role.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pass {
    /// Distance maps around every light sample (shadow types 4 and 5).
    LightShadowViews,
    /// Distance maps of the virtual objects from every eye (occlusion shadows).
    EyeShadowViews,
    /// The irradiance map with device compensation.
    IrradianceMap,
    /// Cube maps of the real environment around each reflective virtual
    /// object (face role, paper section 5.3).
    CubeMaps,
    /// A face role eye view (phantom depth, shaded virtual objects).
    FaceView,
}

impl Pass {
    /// A short stable name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Pass::LightShadowViews => "light_shadow_views",
            Pass::EyeShadowViews => "eye_shadow_views",
            Pass::IrradianceMap => "irradiance_map",
            Pass::CubeMaps => "cube_maps",
            Pass::FaceView => "face_view",
        }
    }
}

/// The passes one projector frame runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PassList {
    /// In execution order.
    pub passes: Vec<Pass>,
}

impl PassList {
    /// True when `pass` is in the list.
    pub fn runs(&self, pass: Pass) -> bool {
        self.passes.contains(&pass)
    }

    /// Every projector pass (the full pipeline, for comparisons).
    pub fn full() -> Self {
        Self {
            passes: vec![
                Pass::LightShadowViews,
                Pass::EyeShadowViews,
                Pass::IrradianceMap,
            ],
        }
    }

    /// Every face pass.
    pub fn full_face() -> Self {
        Self {
            passes: vec![
                Pass::LightShadowViews,
                Pass::EyeShadowViews,
                Pass::CubeMaps,
                Pass::FaceView,
            ],
        }
    }

    /// The passes a face frame needs: light shadow views only when an
    /// occluder can be lit and a virtual object is there (to be shaded, or
    /// to cast the occlusion shadows that phantoms are filled in for); the
    /// eye views of the other tracked eyes (occluding occlusion shadows)
    /// only when a drawn eye sees another eye's shadows (`other_eyes > 0`:
    /// another observer's eyes, or the observer's own other eye in stereo)
    /// and a virtual object exists; the cube
    /// maps only when a reflective virtual object with geometry exists
    /// (without one the pass draws nothing any fragment reads).
    pub fn for_face(frame: &FrameScene, other_eyes: usize) -> Self {
        let has_virtual = frame
            .showcase
            .objects
            .iter()
            .any(|o| o.kind == ObjectKind::Virtual);
        let mut passes = Vec::new();
        if has_virtual && some_light_emits(frame) && !coplanar(&frame.showcase) {
            passes.push(Pass::LightShadowViews);
        }
        if has_virtual && other_eyes > 0 {
            passes.push(Pass::EyeShadowViews);
        }
        if !showcase_light::render::cube_map::reflective_centres(frame).is_empty() {
            passes.push(Pass::CubeMaps);
        }
        passes.push(Pass::FaceView);
        Self { passes }
    }

    /// The passes `frame` needs (module docs).
    pub fn for_projector(frame: &FrameScene) -> Self {
        let mut passes = Vec::new();
        if some_light_emits(frame) && !coplanar(&frame.showcase) {
            passes.push(Pass::LightShadowViews);
        }
        let has_virtual = frame
            .showcase
            .objects
            .iter()
            .any(|o| o.kind == ObjectKind::Virtual);
        if !frame.eyes.is_empty() && has_virtual {
            passes.push(Pass::EyeShadowViews);
        }
        passes.push(Pass::IrradianceMap);
        Self { passes }
    }
}

fn some_light_emits(frame: &FrameScene) -> bool {
    frame
        .samples
        .iter()
        .any(|s| s.intensity.max_element() > 0.0)
}

/// True when every vertex of every object lies in one plane (within
/// 1e-9 of the scene's size), or there is no geometry.
pub fn coplanar(showcase: &Showcase) -> bool {
    let mut points = Vec::new();
    for o in &showcase.objects {
        let (Some(mesh), Some(m)) = (
            showcase.mesh(&o.mesh),
            showcase_light::world_matrix(&o.transform),
        ) else {
            return false;
        };
        points.extend(
            mesh.positions
                .iter()
                .map(|p| m.transform_point3(p.as_dvec3())),
        );
    }
    let Some(&a) = points.first() else {
        return true;
    };
    let scale = points.iter().map(|p| (*p - a).length()).fold(0.0, f64::max);
    let Some(normal) = points.iter().find_map(|&b| {
        points.iter().find_map(|&c| {
            let n = (b - a).cross(c - a);
            (n.length() > 1e-6 * scale * scale).then(|| n.normalize())
        })
    }) else {
        return true;
    };
    points
        .iter()
        .all(|p| (*p - a).dot(normal).abs() <= 1e-9 * scale.max(1.0))
}

/// A digest of everything visible to a projector output in a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameKey(pub u64);

impl FrameKey {
    /// The key of `frame` for a projector: heads count only when
    /// occlusion shadows are drawn (`passes` runs the eye views).
    pub fn projector(projector: usize, frame: &FrameState, passes: &PassList) -> Self {
        Self::digest(
            b"projector",
            projector,
            frame,
            passes.runs(Pass::EyeShadowViews),
        )
    }

    /// The key of `frame` for a face output (`face`, `observer`): every
    /// head counts (the observer's eyes, and the others' occlusion shadows).
    pub fn face(face: usize, observer: usize, frame: &FrameState) -> Self {
        Self::digest(b"face", face << 8 | observer.min(255), frame, true)
    }

    fn digest(role: &[u8], output: usize, frame: &FrameState, heads: bool) -> Self {
        let mut h = Fnv64::default();
        let f = |h: &mut Fnv64, v: f32| h.write(&v.to_bits().to_le_bytes());
        h.write(role);
        h.write(&(output as u64).to_le_bytes());
        h.write(&frame.scene_version.to_le_bytes());
        for l in &frame.lights {
            h.write(l.name.as_bytes());
            h.write(format!("{:?}", l.light).as_bytes());
        }
        for t in &frame.object_transforms {
            h.write(&t.object.to_le_bytes());
            for c in t.transform.matrix().to_cols_array() {
                f(&mut h, c);
            }
        }
        if heads {
            for p in &frame.heads {
                for c in p
                    .position
                    .to_array()
                    .into_iter()
                    .chain(p.orientation.to_array())
                {
                    f(&mut h, c);
                }
            }
        }
        Self(h.finish())
    }
}

/// Centre and radius of a sphere around `points` (None when empty).
pub fn bounding_sphere(points: impl Iterator<Item = DVec3>) -> Option<(DVec3, f64)> {
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    let mut any = false;
    for p in points.filter(|p| p.is_finite()) {
        lo = lo.min(p);
        hi = hi.max(p);
        any = true;
    }
    any.then(|| (0.5 * (lo + hi), 0.5 * (hi - lo).length()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use showcase_proto::{Material, Mesh, Object, Transform};

    fn scene(points: Vec<Vec3>) -> Showcase {
        let mut s = Showcase::default();
        let n = points.len() as u32;
        let id = s.add_mesh(Mesh {
            positions: points,
            triangles: (1..n - 1).map(|i| [0, i, i + 1]).collect(),
            ..Mesh::default()
        });
        s.objects.push(Object {
            name: "o".into(),
            mesh: id,
            material: Material::diffuse(Vec3::ONE),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
        s
    }

    #[test]
    fn coplanar_detects_a_plate_and_rejects_a_fold() {
        let plate = scene(vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z]);
        assert!(coplanar(&plate));
        let fold = scene(vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 0.3, 1.0),
        ]);
        assert!(!coplanar(&fold));
        assert!(coplanar(&Showcase::default()));
    }

    #[test]
    fn sphere_bounds_points() {
        let (c, r) = bounding_sphere([DVec3::ZERO, DVec3::new(2.0, 0.0, 0.0)].into_iter()).unwrap();
        assert_eq!(c, DVec3::X);
        assert_eq!(r, 1.0);
        assert!(bounding_sphere(std::iter::empty()).is_none());
    }
}
