//! What the projector and face passes draw and look up, from a frame: the
//! scene's world-space vertices by object, the light samples with their
//! cube views, and the shadow views' far plane.

use glam::{DVec3, Vec3};
use showcase_proto::{ObjectKind, Showcase};

use crate::gpu::shadow_lookup::LightSampleGpu;
use crate::gpu::shadow_views::{ShadowView, WorldVertex, cube_views};
use crate::render::RenderError;
use showcase_light::render::frame::{FrameScene, Lobe};
use showcase_light::world_matrix;

/// World-space vertices (three per triangle, flat normals) of the objects
/// of `kind` (`None`: all); degenerate triangles are left out.
pub fn world_vertices(
    showcase: &Showcase,
    kind: Option<ObjectKind>,
) -> Result<Vec<WorldVertex>, RenderError> {
    Ok(world_vertices_by_object(showcase, kind)?.0)
}

/// An object index and its vertex range in a vertex buffer.
pub type ObjectRange = (usize, std::ops::Range<u32>);

/// [`world_vertices`] with the vertex range of each object drawn, as
/// `(object index, range)` in object order.
pub fn world_vertices_by_object(
    showcase: &Showcase,
    kind: Option<ObjectKind>,
) -> Result<(Vec<WorldVertex>, Vec<ObjectRange>), RenderError> {
    let mut out = Vec::new();
    let mut ranges = Vec::new();
    for (oi, o) in showcase.objects.iter().enumerate() {
        if kind.is_some_and(|k| k != o.kind) {
            continue;
        }
        let start = out.len() as u32;
        let name = || o.name.clone();
        let mesh =
            showcase
                .mesh(&o.mesh)
                .ok_or_else(|| showcase_light::GeometryError::MissingMesh {
                    object: oi,
                    name: name(),
                })?;
        let m = world_matrix(&o.transform).ok_or_else(|| {
            showcase_light::GeometryError::BadTransform {
                object: oi,
                name: name(),
            }
        })?;
        for (ti, tri) in mesh.triangles.iter().enumerate() {
            let mut v = [DVec3::ZERO; 3];
            for (k, &i) in tri.iter().enumerate() {
                let p = mesh.positions.get(i as usize).ok_or_else(|| {
                    showcase_light::GeometryError::IndexOutOfRange {
                        object: oi,
                        name: name(),
                        triangle: ti,
                        index: i,
                    }
                })?;
                v[k] = m.transform_point3(p.as_dvec3());
            }
            let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
            if n == DVec3::ZERO || !n.is_finite() {
                continue;
            }
            let normal = n.as_vec3().to_array();
            out.extend(v.iter().map(|p| WorldVertex {
                position: p.as_vec3().to_array(),
                normal,
            }));
        }
        ranges.push((oi, start..out.len() as u32));
    }
    Ok((out, ranges))
}

/// The light samples as the shaders read them and, with `shadows`, the
/// six cube views of each (in sample order, from layer 0).
pub fn light_inputs(
    frame: &FrameScene,
    shadows: bool,
    near: f32,
    far: f32,
    shadow_res: u32,
) -> (Vec<ShadowView>, Vec<LightSampleGpu>) {
    let mut views: Vec<ShadowView> = Vec::new();
    let mut lights = Vec::with_capacity(frame.samples.len());
    for s in &frame.samples {
        let first = views.len() as u32;
        if shadows {
            views.extend(cube_views(s.position.as_vec3(), near, far, shadow_res));
        }
        let (axis, kind, cone) = match s.lobe {
            Lobe::Isotropic => (DVec3::ZERO, 0.0, [0.0, 0.0]),
            Lobe::Spot {
                axis,
                cos_inner,
                cos_outer,
            } => (axis, 1.0, [cos_inner as f32, cos_outer as f32]),
            Lobe::Cosine { normal } => (normal, 2.0, [0.0, 0.0]),
        };
        let a = axis.as_vec3();
        lights.push(LightSampleGpu {
            position: s.position.as_vec3().extend(0.0).to_array(),
            intensity: s.intensity.as_vec3().extend(0.0).to_array(),
            axis: [a.x, a.y, a.z, kind],
            cone: [cone[0], cone[1], 0.0, 0.0],
            views: [first, views.len() as u32 - first, 0, 0],
        });
    }
    (views, lights)
}

/// Far plane for shadow views: every light, eye and surface point lies
/// within it from every origin (`from` is any reference point).
pub fn shadow_far(frame: &FrameScene, points: &[WorldVertex], from: DVec3) -> f32 {
    let mut far_base = 0.0f64;
    for p in points
        .iter()
        .map(|w| Vec3::from_array(w.position).as_dvec3())
        .chain(frame.eyes.iter().copied())
        .chain(frame.samples.iter().map(|s| s.position))
    {
        far_base = far_base.max((p - from).length());
    }
    // Every origin is within 2 far_base of every point.
    (4.0 * far_base + 1.0) as f32
}
