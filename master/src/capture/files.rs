//! The reflectance-map file format: for a map named `NAME` in a folder,
//! - `NAME.pfm`: `I_ref`, linear RGB float (PFM, little-endian);
//! - `NAME.weight.pfm`: blend weight in `[0, 1]` (grey PFM);
//! - `NAME.depth.pfm`: device depth of the surface each pixel saw, metres,
//!   0 for none (grey PFM);
//! - `NAME.object.pfm`: object index each pixel saw, -1 for none (grey PFM);
//! - `NAME.json`: `{"format": "showcase-reflectance-map/1", "camera":
//!   PinholeDevice (K, R, t in the OpenCV convention), "object_transforms":
//!   [O_c per object index as 16 f64, column-major]}`.

use crate::pfm::{decode_pfm, encode_pfm, encode_pfm_grey};
use anyhow::Context;
use glam::DMat4;
use serde::{Deserialize, Serialize};
use showcase_light::Image;
use showcase_light::reflectance::ReflectanceMap;
use showcase_proto::PinholeDevice;
use std::path::Path;

/// Format tag of the JSON sidecar.
pub const FORMAT: &str = "showcase-reflectance-map/1";

#[derive(Serialize, Deserialize)]
struct Sidecar {
    format: String,
    camera: PinholeDevice,
    object_transforms: Vec<[f64; 16]>,
}

/// Write `map` as `NAME.*` into `dir`; returns the file names written.
pub fn write_reflectance_map(
    dir: &Path,
    name: &str,
    map: &ReflectanceMap,
) -> anyhow::Result<Vec<String>> {
    let files = [
        (format!("{name}.pfm"), encode_pfm(&map.reflectance)),
        (format!("{name}.weight.pfm"), encode_pfm_grey(&map.weight)),
        (format!("{name}.depth.pfm"), encode_pfm_grey(&map.depth)),
        (
            format!("{name}.object.pfm"),
            encode_pfm_grey(&map.object.map(|o| o.map_or(-1.0, |o| o as f32))),
        ),
        (
            format!("{name}.json"),
            serde_json::to_vec_pretty(&Sidecar {
                format: FORMAT.into(),
                camera: map.camera.clone(),
                object_transforms: map
                    .object_transforms
                    .iter()
                    .map(|m| m.to_cols_array())
                    .collect(),
            })?,
        ),
    ];
    let mut names = Vec::new();
    for (file, bytes) in files {
        let path = dir.join(&file);
        std::fs::write(&path, bytes)
            .with_context(|| format!("{}: cannot write", path.display()))?;
        names.push(file);
    }
    Ok(names)
}

/// Every map in `dir`, by name: each `NAME.json` whose format is
/// [`FORMAT`] with its images (`summary.json` and other JSON files are not
/// maps and are skipped). A folder with no map is an error that says how
/// maps are made.
pub fn read_reflectance_maps(dir: &Path) -> anyhow::Result<Vec<(String, ReflectanceMap)>> {
    let entries =
        std::fs::read_dir(dir).with_context(|| format!("{}: cannot list", dir.display()))?;
    let mut names = Vec::new();
    for entry in entries {
        let path = entry
            .with_context(|| format!("{}: cannot list", dir.display()))?
            .path();
        let (Some(name), Some("json")) = (
            path.file_stem().and_then(|s| s.to_str()),
            path.extension().and_then(|s| s.to_str()),
        ) else {
            continue;
        };
        #[derive(Deserialize)]
        struct Format {
            format: Option<String>,
        }
        let is_map = std::fs::read(&path)
            .ok()
            .and_then(|b| serde_json::from_slice::<Format>(&b).ok())
            .is_some_and(|f| f.format.as_deref() == Some(FORMAT));
        if is_map {
            names.push(name.to_owned());
        }
    }
    names.sort();
    anyhow::ensure!(
        !names.is_empty(),
        "{}: no reflectance map here (a map is NAME.json of format {FORMAT:?} beside its NAME*.pfm images); `showcase-master capture --config CLUSTER.toml --out DIR` writes them",
        dir.display()
    );
    names
        .into_iter()
        .map(|name| Ok((name.clone(), read_reflectance_map(dir, &name)?)))
        .collect()
}

/// Read the map `NAME.*` from `dir`.
pub fn read_reflectance_map(dir: &Path, name: &str) -> anyhow::Result<ReflectanceMap> {
    let read = |suffix: &str| -> anyhow::Result<showcase_light::RgbImage> {
        let path = dir.join(format!("{name}{suffix}"));
        let bytes =
            std::fs::read(&path).with_context(|| format!("{}: cannot read", path.display()))?;
        decode_pfm(&bytes).with_context(|| path.display().to_string())
    };
    let reflectance = read(".pfm")?;
    let grey = |img: showcase_light::RgbImage| img.map(|v| v.x);
    let weight = grey(read(".weight.pfm")?);
    let depth = grey(read(".depth.pfm")?);
    let object: Image<Option<u32>> = grey(read(".object.pfm")?)
        .map(|v| (*v >= 0.0 && *v < u32::MAX as f32).then_some(*v as u32));
    let path = dir.join(format!("{name}.json"));
    let sidecar: Sidecar = serde_json::from_slice(
        &std::fs::read(&path).with_context(|| format!("{}: cannot read", path.display()))?,
    )
    .with_context(|| path.display().to_string())?;
    anyhow::ensure!(
        sidecar.format == FORMAT,
        "{}: format {:?}, expected {FORMAT:?}",
        path.display(),
        sidecar.format
    );
    let (w, h) = (sidecar.camera.width, sidecar.camera.height);
    for (what, img) in [
        ("reflectance", (reflectance.width, reflectance.height)),
        ("weight", (weight.width, weight.height)),
        ("depth", (depth.width, depth.height)),
        ("object", (object.width, object.height)),
    ] {
        anyhow::ensure!(
            img == (w, h),
            "{name}: {what} is {img:?}, the camera has {:?}",
            (w, h)
        );
    }
    let object_transforms: Vec<DMat4> = sidecar
        .object_transforms
        .iter()
        .map(DMat4::from_cols_array)
        .collect();
    anyhow::ensure!(
        object_transforms.iter().all(|m| m.is_finite()),
        "{}: object transform is not finite",
        path.display()
    );
    Ok(ReflectanceMap {
        reflectance,
        weight,
        depth,
        object,
        camera: sidecar.camera,
        object_transforms,
    })
}
