//! Scenes for the radiosity job: an OBJ file read with tobj (`Kd` albedo,
//! `Ke` emitted radiance, every object real), or a TOML scene through the
//! scene-file loader.

use anyhow::Context;
use glam::Vec3;
use showcase_proto::{Material, Mesh, Object, ObjectKind, Showcase, Transform};
use std::path::Path;

/// Load `path` by extension: `.obj` here, anything else through
/// [`crate::scene_file::load_scene`].
pub fn load_any_scene(path: &Path) -> anyhow::Result<Showcase> {
    let is_obj = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if is_obj {
        load_obj_scene(path)
    } else {
        crate::scene_file::load_scene(path)
    }
}

/// Read an OBJ (with its MTL) as a showcase of real objects, one per OBJ
/// object (or per material within it), with identity transforms. `Kd` is
/// the albedo and `Ke` the emitted radiance; missing values are 0.
pub fn load_obj_scene(path: &Path) -> anyhow::Result<Showcase> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..tobj::LoadOptions::default()
    };
    let (models, materials) =
        tobj::load_obj(path, &options).with_context(|| format!("reading {}", path.display()))?;
    let materials =
        materials.with_context(|| format!("reading materials of {}", path.display()))?;
    let mut showcase = Showcase {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        ..Showcase::default()
    };
    for (i, model) in models.iter().enumerate() {
        let m = &model.mesh;
        let positions: Vec<Vec3> = m
            .positions
            .chunks_exact(3)
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        if positions.iter().any(|p| !p.is_finite()) {
            anyhow::bail!(
                "{}: object {} has a non-finite vertex",
                path.display(),
                model.name
            );
        }
        let normals: Vec<Vec3> = if m.normals.len() == m.positions.len() {
            m.normals
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect()
        } else {
            Vec::new()
        };
        let triangles: Vec<[u32; 3]> = m
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        if let Some(bad) = m.indices.iter().find(|&&k| k as usize >= positions.len()) {
            anyhow::bail!(
                "{}: object {} has vertex index {bad} out of range",
                path.display(),
                model.name
            );
        }
        let mtl = m.material_id.and_then(|id| materials.get(id));
        let rgb = |c: Option<[f32; 3]>| c.map_or(Vec3::ZERO, Vec3::from_array);
        let mut material = Material::diffuse(rgb(mtl.and_then(|m| m.diffuse)));
        material.emission = rgb(mtl.and_then(|m| m.emissive));
        if !(material.albedo.is_finite() && material.emission.is_finite()) {
            anyhow::bail!(
                "{}: object {} has a non-finite material",
                path.display(),
                model.name
            );
        }
        let id = showcase.add_mesh(Mesh {
            positions,
            normals,
            uvs: Vec::new(),
            triangles,
        });
        let name = if model.name.is_empty() {
            format!("object{i}")
        } else {
            model.name.clone()
        };
        showcase.objects.push(Object {
            name,
            mesh: id,
            material,
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
    }
    Ok(showcase)
}
