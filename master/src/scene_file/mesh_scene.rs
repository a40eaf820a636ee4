//! A mesh file given as the whole scene: one real object per part of an
//! OBJ or glTF file, read as a scene file's mesh is.

use super::SceneError;
use super::mesh_source;
use glam::Vec3;
use showcase_proto::{Material, Object, ObjectKind, Showcase, Transform, Validate};
use std::path::Path;

/// Load the mesh file at `path` as a showcase named after its stem: one
/// real object per part (per OBJ object, or per material group where an
/// object has several; per glTF node with a mesh), with identity
/// transforms, the file's albedo (0.5 grey without a material) and its
/// emitted radiance. A material library that cannot be read, a `usemtl`
/// it does not define, a bad index or a parser failure is an error naming
/// the file and, where known, the line.
pub(super) fn load_mesh_scene(path: &Path) -> Result<Showcase, SceneError> {
    let file = path.display().to_string();
    let parts = mesh_source::load(path).map_err(|e| SceneError::Mesh {
        file: file.clone(),
        line: e.line,
        problem: e.problem,
    })?;
    let mut s = Showcase {
        name: path
            .file_stem()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        ..Showcase::default()
    };
    for part in parts {
        let mut material = Material::diffuse(part.albedo.unwrap_or(Vec3::splat(0.5)));
        if let Some(ke) = part.emission {
            material.emission = ke;
        }
        let id = s.add_mesh(part.mesh);
        s.objects.push(Object {
            name: part.name,
            mesh: id,
            material,
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
    }
    s.validate().map_err(|e| SceneError::Invalid {
        file,
        field: e.field,
        problem: e.problem,
    })?;
    Ok(s)
}
