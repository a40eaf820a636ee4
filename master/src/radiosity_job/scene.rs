//! Scenes for the radiosity job: an OBJ file read with tobj (`Kd` albedo,
//! `Ke` emitted radiance, every object real), or a TOML scene through the
//! scene-file loader.

use showcase_proto::Showcase;
use std::path::Path;

/// Load `path` by extension: `.obj` as real objects, anything else through
/// [`crate::scene_file::load_scene`] (the capture job's loader).
pub fn load_any_scene(path: &Path) -> anyhow::Result<Showcase> {
    crate::capture::load_any_scene(path)
}

/// Read an OBJ (with its MTL) as a showcase of real objects, one per OBJ
/// object, with identity transforms; `Kd` is the albedo and `Ke` the
/// emitted radiance.
pub fn load_obj_scene(path: &Path) -> anyhow::Result<Showcase> {
    crate::capture::scenes::load_obj_showcase(path)
}
