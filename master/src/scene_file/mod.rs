//! Scene files: TOML scenes placing OBJ/glTF meshes, lights and devices, loaded into a validated `Showcase`.
//!
//! [`load_any`] reads any scene by its extension: a mesh file (OBJ or
//! glTF) as a scene of real objects, anything else as a TOML scene file.
//! [`load_scene`] reads a TOML scene file, [`load_scene_str`] reads text
//! (tests). The result always passes [`showcase_proto::Validate`]. Every
//! error names the scene file and the line (TOML errors) or field
//! (everything else), and bad input never panics.
//!
//! A path `builtin:NAME` names a scene built into the binary
//! (`builtin:showcase`, the demo cabinet; `builtin:figure3`;
//! `builtin:cornell`; see `embedded.rs`), so an installed binary needs no
//! source tree.
//!
//! # Conventions
//! Metres, a right-handed world with y up, linear RGB. Paths (meshes,
//! calibration files) are relative to the scene file's folder. Every table
//! rejects unknown keys, and every number must be finite (TOML's `nan` and
//! `inf` are errors) with magnitude at most 1e9. Names must be unique
//! within their list.
//!
//! # Schema, by example
//! ```toml
//! name = "demo"                 # required
//! ambient = [0.0, 0.0, 0.0]     # W/m^2 per channel; default 0
//! illumination = "global"       # "direct" (default: direct light only) or
//!                               # "global" (the master solves radiosity, the
//!                               # projectors add its indirect light)
//! patch_area = 0.0025           # m^2, the largest radiosity patch in global
//!                               # mode; default 0.01. Finer is more accurate
//!                               # and slower to solve and update
//!
//! [[object]]
//! name = "room"                 # one scene object per part: "room/floor", ...
//! mesh = "../../../shared/data/cornell-box.obj"   # .obj (+ its .mtl), .gltf or .glb
//! kind = "real"                 # "real" (a phantom of a physical object) or "virtual"
//! parts = ["floor", "back"]     # optional: OBJ `o` names or glTF node/mesh names
//! exclude_parts = ["light"]     # optional; an unknown name is an error listing the parts
//! translation = [0.0, 0.0, 0.0] # metres; default 0
//! rotation_deg = [0.0, 90.0, 0.0] # XYZ Euler: R = Rx * Ry * Rz (z applied first)
//! # rotation_quat = [0, 0, 0, 1]  # or a quaternion [x, y, z, w] (normalised)
//! scale = 1.0                   # or [sx, sy, sz]; positive
//! # normalize_height = 0.3      # instead of `scale`: uniform scale to this height (y extent)
//! anchor = "origin"             # "origin" | "center" | "bottom": the point of the
//!                               # selected parts' bounds put at `translation`
//! albedo = [0.8, 0.8, 0.8]      # overrides the file's Kd / baseColorFactor
//! emission = [0.0, 0.0, 0.0]    # radiance; overrides Ke / emissiveFactor
//! texture = { type = "wood", light = [0.75, 0.55, 0.35], dark = [0.35, 0.2, 0.1], rings = 7.0 }
//! # texture = { type = "checker", cells = 8, a = [0.9, 0.9, 0.9], b = [0.1, 0.1, 0.1] }
//! reflectance_map = "plate"     # a captured reflectance map, by name
//! specular = false
//! reflective = false
//!
//! [[object]]
//! name = "plate"
//! mesh = "builtin:plate"        # subdivided quad in xz at y = 0, facing +y, with UVs
//! size = [0.3, 0.2]             # width (x), depth (z); default [0.2, 0.2]
//! subdivisions = 16             # cells per side; default 16
//! kind = "real"
//! # Other built-ins: "builtin:quad" (size), "builtin:sphere" (radius = 0.05, segments = 32).
//!
//! [[light]]
//! name = "lamp"
//! type = "point"                # "point": position, intensity (W/sr)
//! position = [0.0, 0.4, 0.0]
//! intensity = [0.3, 0.3, 0.3]
//! # type = "spot": position, direction, intensity, inner_deg, outer_deg
//! # type = "area": corner, edge_u, edge_v, radiance, samples (default 16);
//! #                emits along edge_u x edge_v
//!
//! [[projector]]
//! name = "projector-0"
//! width = 1024
//! height = 768
//! look_at = { eye = [0.3, 0.7, 0.3], target = [0.0, 0.1, 0.0], up = [0.0, 1.0, 0.0], fov_deg = 50.0 }
//! # or: camera_matrix = [[fx, s, cx], [0, fy, cy], [0, 0, 1]], rotation = [[..], [..], [..]]
//! #     (rows, world to device, x_cam = R X + t), translation = [tx, ty, tz],
//! #     dist_coeffs = [k1, k2, p1, p2, k3] (optional)
//! # or: calibration = "projector-0.json"  (the output of `showcase-master calibrate`;
//! #     width/height may then be left out)
//! near = 0.01                   # default 0.01
//! far = 100.0                   # default 100
//! gamma = 2.2                   # projector response defaults: gamma 2.2, eta 1, black_level 0,
//! eta = 1.0                     # wheel_segments [] (no DLP slicing), wheel_period_s 1/120
//! wheel_segments = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
//!
//! [[camera]]
//! name = "camera-0"
//! width = 640
//! height = 480
//! look_at = { eye = [0.278, 0.273, -0.8], target = [0.278, 0.273, 0.0], fov_deg = 39.3077 }
//! # camera response defaults: gamma 1 (or gamma_rgb = [r, g, b]), knee 1 and
//! # shoulder 1 (no knee: above `knee` the curve's slope is `shoulder` times
//! # its own), gain 1, exposure_s 1/30, read_noise 0, shot_noise 0, bits 8
//!
//! [[face]]
//! name = "face-0"
//! width = 1280
//! height = 1024
//! screen = { origin = [-0.3, 0.8, 0.4], right = [0.6, 0.0, 0.0], down = [0.0, -0.3, 0.5] }
//! mirror = { point = [0.0, 0.0, 0.6], normal = [0.0, 0.5, 0.866] }  # normal is normalised
//! gamma = 2.2                   # a nominal CRT behind an ideal combiner; default 2.2
//! # or state the device per channel (the simulated showcase's truth; a real
//! # cabinet's is measured by `calibrate --photometric`):
//! # crt = { gamma = [2.4, 2.5, 2.3], peak = [2.0, 1.8, 2.2], black_level = [0.004, 0.004, 0.004] }
//! # beam_splitter = { transmission = [0.62, 0.6, 0.57], reflection = [0.33, 0.35, 0.37] }
//! # or the profile `calibrate --photometric` measured (relative to this file):
//! # photometric_profile = "calibration/face-0-photometric.json"
//!
//! [[observer]]
//! name = "alice"
//! position = [0.0, 0.45, 1.4]   # head centre, between the eyes
//! look_at = [0.0, 0.15, 0.0]    # or orientation_quat = [x, y, z, w]; neither: identity
//! up = [0.0, 1.0, 0.0]          # with look_at only; default +y
//! ipd = 0.064                   # metres; default 0.064
//! ```
//!
//! # Meshes
//! An OBJ file with several `o` objects gives one scene object per part,
//! named `<object name>/<part>`; a file with one part gives one object
//! named `<object name>`. An OBJ object split by `usemtl` into groups with
//! different materials gives parts `<o>.<material>`, all selected by `<o>`.
//! `Kd` becomes the albedo and `Ke` the emitted radiance (exitance
//! `pi * Ke`). A glTF file gives one part per node with a mesh (named by
//! the node, else the mesh, else `node<i>`), with node transforms baked in
//! and the first primitive's `baseColorFactor` and `emissiveFactor` as
//! albedo and emission. Parts without a material get albedo 0.8.
//!
//! Objects keep the mesh data exactly as the file has it: `scale`,
//! `normalize_height` and `anchor` go into the object's transform, so the
//! real and the virtual bunny share one mesh.
//!
//! # Devices
//! A rotation whose `R^T R` is within 1e-3 of the identity is projected onto
//! the nearest rotation (rounded decimals are fine); a larger deviation or
//! a reflection is an error. A camera matrix must be upper triangular with
//! last row `[0, 0, 1]` and positive focal lengths. A calibration file's
//! `projection`, when present, must agree with `K [R | t]`.

mod builtin;
mod device;
mod embedded;
mod error;
mod mesh_scene;
mod mesh_source;
mod object;
mod outline;
mod schema;

pub use embedded::{SCENES as BUILTIN_SCENES, is_builtin, shared_data};
pub use error::SceneError;
pub use outline::{SceneNames, SceneOutline, outline, read_calibration};

use error::Ctx;
use schema::SceneDef;
use showcase_proto::{Showcase, Validate, ValidationError};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest scene file read, in bytes.
pub const MAX_SCENE_FILE_BYTES: u64 = 16 << 20;

/// Load the scene at `path` by its extension: `.obj`, `.gltf` or `.glb`
/// (any case) as a mesh file given whole, one real object per part with
/// the file's albedo (0.5 grey without a material) and emission and
/// identity transforms, named after the file's stem; anything else as a
/// TOML scene file ([`load_scene`]). Errors name `path` as it is written
/// and, where known, the line.
pub fn load_any(path: &Path) -> Result<Showcase, SceneError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("obj" | "gltf" | "glb") => mesh_scene::load_mesh_scene(path),
        _ => load_scene(path),
    }
}

/// A scene path `scene` as written in a file in folder `base`: joined to
/// `base`, unless it is a built-in name (`builtin:showcase`), which stays
/// as it is.
pub fn resolve(base: &Path, scene: &Path) -> PathBuf {
    if is_builtin(scene) {
        scene.to_path_buf()
    } else {
        base.join(scene)
    }
}

/// `scene` as a config in another folder must name it: a built-in name as
/// it is, a file by its absolute path.
pub fn absolute(scene: &Path) -> std::io::Result<PathBuf> {
    if is_builtin(scene) {
        Ok(scene.to_path_buf())
    } else {
        std::fs::canonicalize(scene)
    }
}

/// Load and validate the scene file at `path`. Relative paths inside it are
/// resolved against its folder; errors name it as `path` is written.
pub fn load_scene(path: &Path) -> Result<Showcase, SceneError> {
    let (text, file, base_dir) = read_scene_text(path)?;
    load_scene_str(&text, &base_dir, &file)
}

/// The text of the TOML scene file at `path` (at most
/// [`MAX_SCENE_FILE_BYTES`]), its label for errors, and the folder its
/// relative paths start from (a built-in scene's, under the embedded root).
fn read_scene_text(path: &Path) -> Result<(String, String, PathBuf), SceneError> {
    let file = path.display().to_string();
    let read_err = |error| SceneError::Read {
        file: file.clone(),
        error,
    };
    if let Some(resolved) = embedded::scene_file(path) {
        let resolved = resolved.map_err(|problem| SceneError::Invalid {
            file: file.clone(),
            field: "scene".into(),
            problem,
        })?;
        let text = embedded::read(&resolved)
            .unwrap_or_else(|| Err(std::io::ErrorKind::NotFound.into()))
            .and_then(|b| std::str::from_utf8(b).map_err(std::io::Error::other))
            .map_err(read_err)?;
        let base_dir = resolved.parent().unwrap_or(Path::new("")).to_path_buf();
        return Ok((text.to_owned(), file, base_dir));
    }
    let meta = std::fs::metadata(path).map_err(read_err)?;
    if meta.len() > MAX_SCENE_FILE_BYTES {
        return Err(SceneError::Invalid {
            file,
            field: "file".into(),
            problem: format!(
                "{} bytes is over the limit of {MAX_SCENE_FILE_BYTES}",
                meta.len()
            ),
        });
    }
    let text = std::fs::read_to_string(path).map_err(read_err)?;
    let base_dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    Ok((text, file, base_dir))
}

/// Load and validate a scene from `text`, resolving relative paths against
/// `base_dir` and naming the scene `file_label` in errors.
pub fn load_scene_str(
    text: &str,
    base_dir: &Path,
    file_label: &str,
) -> Result<Showcase, SceneError> {
    let ctx = Ctx {
        file: file_label.to_owned(),
    };
    let def: SceneDef = toml::from_str(text).map_err(|e| ctx.syntax(text, &e))?;
    build(&ctx, &def, base_dir)
}

fn build(ctx: &Ctx, def: &SceneDef, base_dir: &Path) -> Result<Showcase, SceneError> {
    unique(ctx, "object", def.objects.iter().map(|o| o.name.as_str()))?;
    unique(ctx, "light", def.lights.iter().map(|o| o.name.as_str()))?;
    unique(
        ctx,
        "projector",
        def.projectors.iter().map(|o| o.name.as_str()),
    )?;
    unique(ctx, "camera", def.cameras.iter().map(|o| o.name.as_str()))?;
    unique(ctx, "face", def.faces.iter().map(|o| o.name.as_str()))?;
    unique(
        ctx,
        "observer",
        def.observers.iter().map(|o| o.name.as_str()),
    )?;

    let mut showcase = Showcase {
        name: def.name.clone(),
        ambient: def.ambient.map_or(glam::Vec3::ZERO, device::v3),
        illumination: def.illumination,
        patch_area: def.patch_area.map(|a| a.0),
        ..Showcase::default()
    };
    let mut labels = Labels::default();
    let mut cache = object::MeshCache::new();
    for (i, o) in def.objects.iter().enumerate() {
        let label = label("object", i, &o.name);
        labels.objects.extend(object::add_object(
            ctx,
            &label,
            o,
            base_dir,
            &mut cache,
            &mut showcase,
        )?);
    }
    for (i, l) in def.lights.iter().enumerate() {
        let label = label("light", i, &l.name);
        showcase.lights.push(device::light(ctx, &label, l)?);
        labels.lights.push(label);
    }
    for (i, p) in def.projectors.iter().enumerate() {
        let label = label("projector", i, &p.name);
        showcase
            .projectors
            .push(device::projector(ctx, &label, p, base_dir)?);
        labels.projectors.push(label);
    }
    for (i, c) in def.cameras.iter().enumerate() {
        let label = label("camera", i, &c.name);
        showcase
            .cameras
            .push(device::camera(ctx, &label, c, base_dir)?);
        labels.cameras.push(label);
    }
    for (i, f) in def.faces.iter().enumerate() {
        let label = label("face", i, &f.name);
        showcase.faces.push(device::face(ctx, &label, f, base_dir)?);
        labels.faces.push(label);
    }
    for (i, o) in def.observers.iter().enumerate() {
        let label = label("observer", i, &o.name);
        showcase.observers.push(device::observer(ctx, &label, o)?);
        labels.observers.push(label);
    }
    showcase
        .validate()
        .map_err(|e| ctx.invalid(labels.field(&e), e.problem))?;
    Ok(showcase)
}

/// How the scene file's `i`-th table of `kind` is named in errors.
pub(crate) fn label(kind: &str, i: usize, name: &str) -> String {
    format!("{kind}[{i}] '{}'", name.escape_debug())
}

fn unique<'a>(
    ctx: &Ctx,
    list: &str,
    names: impl Iterator<Item = &'a str>,
) -> Result<(), SceneError> {
    let mut seen = HashMap::new();
    for (i, n) in names.enumerate() {
        if let Some(first) = seen.insert(n, i) {
            return Err(ctx.invalid(
                format!("{}.name", label(list, i, n)),
                format!("duplicate name {n:?}, also used by {list}[{first}]"),
            ));
        }
    }
    Ok(())
}

/// Scene-file labels of the proto lists, to translate a validation path
/// such as `objects[3].material.albedo` back into the file's terms.
#[derive(Default)]
struct Labels {
    objects: Vec<String>,
    lights: Vec<String>,
    projectors: Vec<String>,
    cameras: Vec<String>,
    faces: Vec<String>,
    observers: Vec<String>,
}

impl Labels {
    fn field(&self, e: &ValidationError) -> String {
        let path = e.field.as_str();
        let lists: [(&str, &[String]); 6] = [
            ("objects", &self.objects),
            ("lights", &self.lights),
            ("projectors", &self.projectors),
            ("cameras", &self.cameras),
            ("faces", &self.faces),
            ("observers", &self.observers),
        ];
        for (list, labels) in lists {
            let Some(rest) = path.strip_prefix(list).and_then(|r| r.strip_prefix('[')) else {
                continue;
            };
            let Some((index, rest)) = rest.split_once(']') else {
                continue;
            };
            if let Some(label) = index.parse::<usize>().ok().and_then(|i| labels.get(i)) {
                return format!("{label}{rest}");
            }
        }
        path.to_owned()
    }
}

#[cfg(test)]
mod tests;
