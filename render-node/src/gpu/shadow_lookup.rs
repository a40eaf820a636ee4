//! The shadow-map lookups (`visible_from_light`, `visible_from_eye`,
//! `intensity_towards`) that the irradiance-map and face-view shaders
//! share, kept once in `shadow_lookup.part.wgsl` and appended to each shader's
//! source at compile time (WGSL declarations may come in any order).

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
