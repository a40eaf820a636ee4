//! What `showcase-master check` needs of a scene beyond [`super::load_any`],
//! which stops at the first problem: the names a scene declares (to check
//! the cluster's outputs and tracking targets against, even when the scene
//! does not load), every mesh file's problem on its own, and a node's
//! calibration file read as the scene reads one.

use super::error::{Ctx, SceneError};
use super::object::{MeshCache, parts_of};
use super::schema::SceneDef;
use super::{label, read_scene_text};
use showcase_proto::{PinholeDevice, Showcase};
use std::path::Path;

/// The names in each list of a scene, in order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SceneNames {
    /// Objects: a multi-part mesh's objects are `<object>/<part>` in a
    /// loaded scene, only `<object>` in an [`outline`].
    pub objects: Vec<String>,
    /// Lights.
    pub lights: Vec<String>,
    /// Projectors.
    pub projectors: Vec<String>,
    /// Cameras.
    pub cameras: Vec<String>,
    /// CRT faces.
    pub faces: Vec<String>,
    /// Observers.
    pub observers: Vec<String>,
}

impl SceneNames {
    /// The names of a loaded scene.
    pub fn of(scene: &Showcase) -> Self {
        Self {
            objects: names(scene.objects.iter().map(|o| &o.name)),
            lights: names(scene.lights.iter().map(|o| &o.name)),
            projectors: names(scene.projectors.iter().map(|o| &o.name)),
            cameras: names(scene.cameras.iter().map(|o| &o.name)),
            faces: names(scene.faces.iter().map(|o| &o.name)),
            observers: names(scene.observers.iter().map(|o| &o.name)),
        }
    }
}

fn names<'a>(list: impl Iterator<Item = &'a String>) -> Vec<String> {
    list.cloned().collect()
}

/// A TOML scene file read without building it.
#[derive(Debug)]
pub struct SceneOutline {
    /// The names its tables declare.
    pub names: SceneNames,
    /// One error per `[[object]]` whose mesh cannot be used (a missing or
    /// broken file, a bad built-in), in file order.
    pub mesh_errors: Vec<SceneError>,
}

/// Outline the TOML scene file at `path`: its declared names and every
/// mesh problem, each its own error. Fails only when the file cannot be
/// read or is not a scene's TOML.
pub fn outline(path: &Path) -> Result<SceneOutline, SceneError> {
    let (text, file, base_dir) = read_scene_text(path)?;
    let ctx = Ctx { file };
    let def: SceneDef = toml::from_str(&text).map_err(|e| ctx.syntax(&text, &e))?;
    let mut cache = MeshCache::new();
    let mesh_errors = def
        .objects
        .iter()
        .enumerate()
        .filter_map(|(i, o)| {
            parts_of(&ctx, &label("object", i, &o.name), o, &base_dir, &mut cache).err()
        })
        .collect();
    Ok(SceneOutline {
        names: SceneNames {
            objects: names(def.objects.iter().map(|o| &o.name)),
            lights: names(def.lights.iter().map(|o| &o.name)),
            projectors: names(def.projectors.iter().map(|o| &o.name)),
            cameras: names(def.cameras.iter().map(|o| &o.name)),
            faces: names(def.faces.iter().map(|o| &o.name)),
            observers: names(def.observers.iter().map(|o| &o.name)),
        },
        mesh_errors,
    })
}

/// Read a calibration file (the JSON `showcase-master calibrate` writes)
/// as a scene's `calibration = "..."` is read; errors name `file` (the
/// file that refers to it) and `field`. `size` is the device's pixel size
/// where known, which the file must agree with.
pub fn read_calibration(
    path: &Path,
    file: &str,
    field: &str,
    size: Option<(u32, u32)>,
) -> Result<PinholeDevice, SceneError> {
    let ctx = Ctx {
        file: file.to_owned(),
    };
    super::device::calibrated(&ctx, field, (size.map(|s| s.0), size.map(|s| s.1)), path)
}
