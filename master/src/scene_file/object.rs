//! `[[object]]` tables: mesh lookup (file or built-in), part selection,
//! transform (with `normalize_height` and `anchor`), and the material of
//! each resulting scene object.

use super::builtin;
use super::device::{dv3, quat, v3};
use super::error::{Ctx, SceneError};
use super::mesh_source::{self, Part};
use super::schema::{AnchorDef, KindDef, ObjectDef, ScaleDef, TextureDef};
use glam::{EulerRot, Quat, Vec3};
use showcase_proto::{AlbedoTexture, Material, Object, ObjectKind, Showcase, Transform};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Albedo of a part whose file gives none and whose table sets none.
pub(crate) const DEFAULT_ALBEDO: f32 = 0.8;

/// Parsed mesh files, by resolved path, so that a file used by several
/// objects is read once.
pub(crate) type MeshCache = HashMap<PathBuf, Rc<Vec<Part>>>;

/// Add the scene objects of one `[[object]]` table to `showcase`; returns
/// a label per added object, for error messages.
pub(crate) fn add_object(
    ctx: &Ctx,
    label: &str,
    d: &ObjectDef,
    base_dir: &Path,
    cache: &mut MeshCache,
    showcase: &mut Showcase,
) -> Result<Vec<String>, SceneError> {
    let all = parts_of(ctx, label, d, base_dir, cache)?;
    let selected = select(ctx, label, d, &all)?;
    let transform = transform(ctx, label, d, &selected)?;
    let mut labels = Vec::new();
    for part in selected {
        if d.texture.is_some() && part.mesh.uvs.is_empty() {
            return Err(ctx.invalid(
                format!("{label}.texture"),
                format!(
                    "a texture needs texture coordinates, and part {:?} has none",
                    part.name
                ),
            ));
        }
        let name = if all.len() > 1 {
            format!("{}/{}", d.name, part.name)
        } else {
            d.name.clone()
        };
        let material = Material {
            albedo: d
                .albedo
                .map(v3)
                .or(part.albedo)
                .unwrap_or(Vec3::splat(DEFAULT_ALBEDO)),
            texture: d.texture.as_ref().map(texture),
            reflectance_map: d.reflectance_map.clone(),
            emission: d.emission.map(v3).or(part.emission).unwrap_or(Vec3::ZERO),
            specular: d.specular,
            reflective: d.reflective,
        };
        let mesh = showcase.add_mesh(part.mesh.clone());
        labels.push(if all.len() > 1 {
            format!("{label} part {:?}", part.name)
        } else {
            label.to_owned()
        });
        showcase.objects.push(Object {
            name,
            mesh,
            material,
            kind: match d.kind {
                KindDef::Real => ObjectKind::Real,
                KindDef::Virtual => ObjectKind::Virtual,
            },
            transform,
        });
    }
    Ok(labels)
}

fn texture(t: &TextureDef) -> AlbedoTexture {
    match t {
        TextureDef::Checker { cells, a, b } => AlbedoTexture::Checker {
            cells: *cells,
            a: v3(*a),
            b: v3(*b),
        },
        TextureDef::Wood { light, dark, rings } => AlbedoTexture::Wood {
            light: v3(*light),
            dark: v3(*dark),
            rings: rings.0 as f32,
        },
    }
}

/// The parts of the object's mesh: a file's parts, or one built-in part.
pub(crate) fn parts_of(
    ctx: &Ctx,
    label: &str,
    d: &ObjectDef,
    base_dir: &Path,
    cache: &mut MeshCache,
) -> Result<Rc<Vec<Part>>, SceneError> {
    let params = [
        ("size", d.size.is_some()),
        ("subdivisions", d.subdivisions.is_some()),
        ("radius", d.radius.is_some()),
        ("segments", d.segments.is_some()),
    ];
    let allowed: &[&str] = match d.mesh.as_str() {
        "builtin:plate" => &["size", "subdivisions"],
        "builtin:quad" => &["size"],
        "builtin:sphere" => &["radius", "segments"],
        m if m.starts_with("builtin:") => {
            return Err(ctx.invalid(
                format!("{label}.mesh"),
                format!("unknown built-in mesh {m:?} (expected builtin:plate, builtin:quad or builtin:sphere)"),
            ));
        }
        _ => &[],
    };
    if let Some((key, _)) = params
        .iter()
        .find(|(k, present)| *present && !allowed.contains(k))
    {
        return Err(ctx.invalid(
            format!("{label}.{key}"),
            format!("`{key}` does not apply to mesh {:?}", d.mesh),
        ));
    }
    let positive = |key: &str, x: f64| {
        if x > 0.0 {
            Ok(x as f32)
        } else {
            Err(ctx.invalid(format!("{label}.{key}"), format!("{x} must be positive")))
        }
    };
    let built = match d.mesh.as_str() {
        "builtin:plate" | "builtin:quad" => {
            let [w, dp] = d.size.map_or([0.2, 0.2], |s| [s[0].0, s[1].0]);
            let (w, dp) = (positive("size", w)?, positive("size", dp)?);
            let n = if d.mesh == "builtin:quad" {
                1
            } else {
                d.subdivisions.unwrap_or(16)
            };
            if !(1..=builtin::MAX_SUBDIVISIONS).contains(&n) {
                return Err(ctx.invalid(
                    format!("{label}.subdivisions"),
                    format!("{n} is outside 1..={}", builtin::MAX_SUBDIVISIONS),
                ));
            }
            Some(("plate", builtin::plate(w, dp, n)))
        }
        "builtin:sphere" => {
            let r = positive("radius", d.radius.map_or(0.05, |r| r.0))?;
            let n = d.segments.unwrap_or(32);
            if !(3..=builtin::MAX_SUBDIVISIONS).contains(&n) {
                return Err(ctx.invalid(
                    format!("{label}.segments"),
                    format!("{n} is outside 3..={}", builtin::MAX_SUBDIVISIONS),
                ));
            }
            Some(("sphere", builtin::sphere(r, n)))
        }
        _ => None,
    };
    if let Some((name, mesh)) = built {
        return Ok(Rc::new(vec![Part {
            name: name.to_owned(),
            aliases: Vec::new(),
            mesh,
            albedo: None,
            emission: None,
        }]));
    }
    let path = base_dir.join(&d.mesh);
    if let Some(parts) = cache.get(&path) {
        return Ok(parts.clone());
    }
    let parts = mesh_source::load(&path)
        .map_err(|e| ctx.referenced(format!("{label}.mesh"), &path, e.line, e.problem))?;
    let parts = Rc::new(parts);
    cache.insert(path, parts.clone());
    Ok(parts)
}

/// Apply `parts` and `exclude_parts`; every name given must exist.
fn select<'a>(
    ctx: &Ctx,
    label: &str,
    d: &ObjectDef,
    all: &'a [Part],
) -> Result<Vec<&'a Part>, SceneError> {
    let available = || {
        all.iter()
            .map(|p| format!("{:?}", p.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for (key, names) in [("parts", &d.parts), ("exclude_parts", &d.exclude_parts)] {
        for n in names.iter().flatten() {
            if !all.iter().any(|p| p.answers_to(n)) {
                return Err(ctx.invalid(
                    format!("{label}.{key}"),
                    format!(
                        "no part named {n:?} in {:?}; available: {}",
                        d.mesh,
                        available()
                    ),
                ));
            }
        }
    }
    let picked: Vec<&Part> = all
        .iter()
        .filter(|p| {
            d.parts
                .as_ref()
                .is_none_or(|names| names.iter().any(|n| p.answers_to(n)))
        })
        .filter(|p| !d.exclude_parts.iter().flatten().any(|n| p.answers_to(n)))
        .collect();
    if picked.is_empty() {
        return Err(ctx.invalid(format!("{label}.parts"), "the selection leaves no parts"));
    }
    Ok(picked)
}

/// The object-to-world transform: `T * R * S` with `normalize_height`
/// folded into `S` and the anchor folded into `T`, so that the mesh data
/// stay as in the file (and objects sharing a file share meshes).
fn transform(
    ctx: &Ctx,
    label: &str,
    d: &ObjectDef,
    parts: &[&Part],
) -> Result<Transform, SceneError> {
    let rotation = match (d.rotation_deg, d.rotation_quat) {
        (Some(_), Some(_)) => {
            return Err(ctx.invalid(
                format!("{label}.rotation_quat"),
                "give `rotation_deg` or `rotation_quat`, not both",
            ));
        }
        (Some(e), None) => {
            let [x, y, z] = dv3(e).to_array().map(f64::to_radians);
            glam::DQuat::from_euler(EulerRot::XYZ, x, y, z)
                .normalize()
                .as_quat()
        }
        (None, Some(q)) => quat(q)
            .ok_or_else(|| ctx.invalid(format!("{label}.rotation_quat"), "quaternion is zero"))?,
        (None, None) => Quat::IDENTITY,
    };
    let mut scale = match d.scale {
        None => Vec3::ONE,
        Some(ScaleDef::Uniform(s)) => Vec3::splat(s.0 as f32),
        Some(ScaleDef::PerAxis(s)) => v3(s),
    };
    if scale.min_element() <= 0.0 {
        return Err(ctx.invalid(
            format!("{label}.scale"),
            format!("scale {scale} must be positive on every axis"),
        ));
    }
    let (lo, hi) = parts
        .iter()
        .filter_map(|p| p.mesh.bounds())
        .reduce(|(a, b), (c, e)| (a.min(c), b.max(e)))
        .ok_or_else(|| {
            ctx.invalid(
                format!("{label}.mesh"),
                "the selected parts have no vertices",
            )
        })?;
    if let Some(h) = d.normalize_height {
        if d.scale.is_some() {
            return Err(ctx.invalid(
                format!("{label}.normalize_height"),
                "give `scale` or `normalize_height`, not both",
            ));
        }
        let height = f64::from(hi.y) - f64::from(lo.y);
        if h.0 <= 0.0 {
            return Err(ctx.invalid(
                format!("{label}.normalize_height"),
                format!("{} must be positive", h.0),
            ));
        }
        if height < 1e-9 {
            return Err(ctx.invalid(
                format!("{label}.normalize_height"),
                "the selected parts are flat in y, so they have no height to normalise",
            ));
        }
        scale = Vec3::splat((h.0 / height) as f32);
    }
    let anchor = match d.anchor {
        AnchorDef::Origin => Vec3::ZERO,
        AnchorDef::Center => 0.5 * (lo + hi),
        AnchorDef::Bottom => Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z)),
    };
    let translation = d.translation.map_or(Vec3::ZERO, v3) - rotation * (scale * anchor);
    Ok(Transform {
        translation,
        rotation,
        scale,
    })
}
