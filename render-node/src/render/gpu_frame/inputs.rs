//! What both roles' shadow stage and shaders read of a frame, computed
//! on the CPU: the light samples with their cube views, the eyes whose
//! occlusion shadows are looked up with the views fitted around the
//! virtual objects' bounds, and the shadow views' far plane.

use std::ops::Range;

use glam::{DVec3, Vec3};
use showcase_proto::ObjectKind;

use super::scene_buffers::SceneBuffers;
use crate::gpu::shadow_lookup::{EyeGpu, LightSampleGpu};
use crate::gpu::shadow_views::{SHADOW_NEAR, ShadowView, WorldVertex, cube_views, fitted_views};
use crate::render::passes::{Pass, PassList, bounding_sphere};
use showcase_light::render::frame::{FrameScene, Lobe};

/// One frame's shadow views, light samples and eyes, as they are uploaded:
/// the light samples' cube views from layer 0, then each eye's views.
#[derive(Debug)]
pub struct FrameInputs {
    /// Far plane of every shadow view ([`stable_far`] of [`shadow_far`]).
    pub far: f32,
    /// Whether the light samples' views are drawn and looked up
    /// ([`Pass::LightShadowViews`]).
    pub shadows: bool,
    /// Whether the eyes' views are drawn and looked up
    /// ([`Pass::EyeShadowViews`]).
    pub occlusion: bool,
    /// The shadow views, one per layer of the shadow maps.
    pub views: Vec<ShadowView>,
    /// The light samples, each naming its cube views.
    pub lights: Vec<LightSampleGpu>,
    /// The eyes, in the order given, each naming its views.
    pub eyes: Vec<EyeGpu>,
    /// The layers of the light samples' cube views.
    pub light_layers: Range<u32>,
    /// The layers of the eyes' views.
    pub eye_layers: Range<u32>,
}

impl FrameInputs {
    /// The inputs of `frame` for `passes`, with the scene's vertices as
    /// `scene` last uploaded them: `from` is the far plane's reference
    /// point (any point will do; the projector's centre, the face's first
    /// eye) and `eyes` the eyes whose occlusion shadows the role looks up.
    pub fn new(
        frame: &FrameScene,
        scene: &SceneBuffers,
        from: DVec3,
        eyes: impl IntoIterator<Item = DVec3>,
        passes: &PassList,
        shadow_res: u32,
    ) -> Self {
        let far = stable_far(shadow_far(frame, scene.all(), from));
        let shadows = passes.runs(Pass::LightShadowViews);
        let occlusion = passes.runs(Pass::EyeShadowViews);
        let (mut views, lights) = light_inputs(frame, shadows, SHADOW_NEAR, far, shadow_res);
        let light_layers = 0..views.len() as u32;
        let bounds = if occlusion {
            virtual_bounds(frame, scene)
        } else {
            None
        };
        let eyes = eye_inputs(eyes, bounds, far, shadow_res, &mut views);
        let eye_layers = light_layers.end..views.len() as u32;
        Self {
            far,
            shadows,
            occlusion,
            views,
            lights,
            eyes,
            light_layers,
            eye_layers,
        }
    }
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

/// A far plane at least `far`, rounded up to a power of two, so that a
/// moving light or eye changes the shadow views' projection (and forces
/// layers to be redrawn) only when the scene's extent really changes.
pub fn stable_far(far: f32) -> f32 {
    if !(far.is_finite() && far > 0.0) {
        return far;
    }
    let rounded = 2f32.powi(far.log2().ceil() as i32);
    if rounded >= far {
        rounded
    } else {
        2.0 * rounded
    }
}

/// The bounding sphere (centre, radius) of the virtual objects' vertices
/// in `scene`; `None` without any.
pub fn virtual_bounds(frame: &FrameScene, scene: &SceneBuffers) -> Option<(DVec3, f64)> {
    let all = scene.all();
    bounding_sphere(
        scene
            .ranges()
            .iter()
            .filter(|(oi, _)| frame.showcase.objects[*oi].kind == ObjectKind::Virtual)
            .flat_map(|(_, r)| all[r.start as usize..r.end as usize].iter())
            .map(|v| Vec3::from_array(v.position).as_dvec3()),
    )
}

/// Each of `eyes` as the shaders read it, its views fitted around the
/// virtual objects' `bounds` appended to `views` (none without bounds:
/// nothing virtual casts an occlusion shadow).
pub fn eye_inputs(
    eyes: impl IntoIterator<Item = DVec3>,
    bounds: Option<(DVec3, f64)>,
    far: f32,
    shadow_res: u32,
    views: &mut Vec<ShadowView>,
) -> Vec<EyeGpu> {
    eyes.into_iter()
        .map(|e| {
            let first = views.len() as u32;
            if let Some((c, r)) = bounds {
                views.extend(fitted_views(
                    e.as_vec3(),
                    c.as_vec3(),
                    (r * 1.001 + 1e-6) as f32,
                    SHADOW_NEAR,
                    far,
                    shadow_res,
                ));
            }
            EyeGpu {
                position: e.as_vec3().extend(0.0).to_array(),
                views: [first, views.len() as u32 - first, 0, 0],
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::stable_far;

    #[test]
    fn stable_far_rounds_up_to_a_power_of_two() {
        for (far, expected) in [(1.0, 1.0), (3.2, 4.0), (4.0, 4.0), (4.01, 8.0), (0.3, 0.5)] {
            assert_eq!(stable_far(far), expected, "{far}");
        }
        assert!(stable_far(f32::NAN).is_nan());
    }
}
