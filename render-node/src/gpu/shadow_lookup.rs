//! What the irradiance-map and face-view shaders share, kept once in
//! `shadow_lookup.part.wgsl` and appended to each shader's source at
//! compile time (WGSL declarations may come in any order): the per-frame
//! records they read (light samples, eyes, shadow views; mirrored here
//! and in [`super::shadow_views::ShadowView`]), the cube-face selection
//! and the shadow-map lookups (`visible_from_light`, `visible_from_eye`,
//! `intensity_towards`).

use bytemuck::{Pod, Zeroable};

/// The WGSL source (`&'static str`) of the file `$file` (relative to the
/// calling module) with `shadow_lookup.part.wgsl` appended.
macro_rules! with_shadow_lookup {
    ($file:literal) => {
        concat!(
            include_str!($file),
            "\n",
            include_str!("../shadow_lookup.part.wgsl")
        )
    };
}
pub(crate) use with_shadow_lookup;

/// Mirrors WGSL `struct LightSample` in `shadow_lookup.part.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LightSampleGpu {
    /// xyz position.
    pub position: [f32; 4],
    /// rgb peak intensity.
    pub intensity: [f32; 4],
    /// xyz axis or normal, w kind (0 isotropic, 1 spot, 2 cosine).
    pub axis: [f32; 4],
    /// cos inner, cos outer.
    pub cone: [f32; 4],
    /// first view, view count.
    pub views: [u32; 4],
}

/// Mirrors WGSL `struct Eye` in `shadow_lookup.part.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct EyeGpu {
    /// xyz position.
    pub position: [f32; 4],
    /// first view, view count.
    pub views: [u32; 4],
}
