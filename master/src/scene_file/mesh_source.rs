//! Mesh files as lists of named parts: OBJ+MTL through tobj (one part per
//! `o` object, `Kd` as albedo and `Ke` as emitted radiance) and glTF 2.0
//! through the gltf crate (one part per node with a mesh, node transforms
//! baked in, `baseColorFactor` as albedo and `emissiveFactor` as emission).

use glam::{Mat3, Mat4, Vec2, Vec3};
use showcase_proto::{Mesh, Validate};
use std::path::Path;

/// Largest mesh file read, in bytes.
pub(crate) const MAX_MESH_FILE_BYTES: u64 = 512 << 20;

/// One selectable piece of a mesh file.
#[derive(Clone, Debug)]
pub(crate) struct Part {
    /// Unique name within its file.
    pub(crate) name: String,
    /// Other names that select this part (a glTF mesh name, an OBJ object
    /// name shared by several material groups).
    pub(crate) aliases: Vec<String>,
    /// The geometry, in file units and axes.
    pub(crate) mesh: Mesh,
    /// Diffuse albedo from the file, if it gives one.
    pub(crate) albedo: Option<Vec3>,
    /// Emitted radiance from the file, if it gives one.
    pub(crate) emission: Option<Vec3>,
}

impl Part {
    /// Whether `name` selects this part.
    pub(crate) fn answers_to(&self, name: &str) -> bool {
        self.name == name || self.aliases.iter().any(|a| a == name)
    }
}

/// A failure in a mesh file: what and, where known, on which line.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MeshFileError {
    pub(crate) line: Option<usize>,
    pub(crate) problem: String,
}

impl MeshFileError {
    fn new(problem: impl Into<String>) -> Self {
        Self {
            line: None,
            problem: problem.into(),
        }
    }
}

/// Read a mesh file (by extension) into its parts.
pub(crate) fn load(path: &Path) -> Result<Vec<Part>, MeshFileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let bytes = read_limited(path)?;
    let parts = match ext.as_str() {
        "obj" => load_obj(path, &bytes)?,
        "gltf" | "glb" => load_gltf(path, &bytes)?,
        _ => {
            return Err(MeshFileError::new(format!(
                "unknown mesh format {ext:?} (expected .obj, .gltf or .glb)"
            )));
        }
    };
    if parts.is_empty() {
        return Err(MeshFileError::new("the file holds no triangles"));
    }
    for p in &parts {
        p.mesh.validate().map_err(|e| {
            MeshFileError::new(format!("part {:?}: {}: {}", p.name, e.field, e.problem))
        })?;
    }
    Ok(parts)
}

fn read_limited(path: &Path) -> Result<Vec<u8>, MeshFileError> {
    if let Some(built_in) = super::embedded::read(path) {
        return built_in
            .map(<[u8]>::to_vec)
            .map_err(|e| MeshFileError::new(format!("cannot read: {e}")));
    }
    let meta =
        std::fs::metadata(path).map_err(|e| MeshFileError::new(format!("cannot read: {e}")))?;
    if !meta.is_file() {
        return Err(MeshFileError::new("not a regular file"));
    }
    if meta.len() > MAX_MESH_FILE_BYTES {
        return Err(MeshFileError::new(format!(
            "{} bytes is over the limit of {MAX_MESH_FILE_BYTES}",
            meta.len()
        )));
    }
    std::fs::read(path).map_err(|e| MeshFileError::new(format!("cannot read: {e}")))
}

/// Run a third-party parser, turning a panic into an error: bad input must
/// never bring the loader down.
fn guarded<T>(
    what: &str,
    f: impl FnOnce() -> Result<T, MeshFileError>,
) -> Result<T, MeshFileError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|_| {
        Err(MeshFileError::new(format!(
            "the {what} parser failed on this file"
        )))
    })
}

fn load_obj(path: &Path, bytes: &[u8]) -> Result<Vec<Part>, MeshFileError> {
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mtl_errors = std::cell::RefCell::new(Vec::new());
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, materials) = guarded("OBJ", || {
        let mut reader = std::io::BufReader::new(bytes);
        tobj::load_obj_buf(&mut reader, &options, |mtl_path| {
            let full = dir.join(mtl_path);
            let result = super::embedded::read(&full)
                .map(|b| b.map(<[u8]>::to_vec))
                .unwrap_or_else(|| std::fs::read(&full))
                .map_err(|e| format!("cannot read material library {}: {e}", full.display()))
                .and_then(|mtl| {
                    tobj::load_mtl_buf(&mut std::io::BufReader::new(mtl.as_slice()))
                        .map_err(|e| format!("material library {}: {e}", full.display()))
                });
            result.map_err(|msg| {
                mtl_errors.borrow_mut().push(msg);
                tobj::LoadError::ReadError
            })
        })
        .map_err(|e| MeshFileError {
            line: obj_error_line(bytes, &e),
            problem: e.to_string(),
        })
    })?;
    if let Some(msg) = mtl_errors.into_inner().into_iter().next() {
        return Err(MeshFileError::new(msg));
    }
    let materials = materials.map_err(|e| MeshFileError::new(format!("material library: {e}")))?;
    if let Some((line, name)) = unknown_material(bytes, &materials) {
        return Err(MeshFileError {
            line: Some(line),
            problem: format!("usemtl {name}: the material library defines no such material"),
        });
    }

    let mut parts: Vec<Part> = Vec::new();
    for model in models {
        let m = &model.mesh;
        if m.indices.is_empty() {
            continue;
        }
        let mesh = obj_mesh(m)?;
        let material = m.material_id.and_then(|i| materials.get(i));
        let albedo = material.and_then(|mt| mt.diffuse).map(Vec3::from_array);
        let emission = material.and_then(|mt| mt.emissive).map(Vec3::from_array);
        let base = model.name.clone();
        // tobj splits an object at each `usemtl`: the pieces share a name.
        match parts.iter_mut().find(|p| p.name == base) {
            Some(p) if p.albedo == albedo && p.emission == emission => append(&mut p.mesh, &mesh),
            Some(_) => {
                let suffix = material.map_or("default", |mt| mt.name.as_str());
                let mut name = format!("{base}.{suffix}");
                let mut k = 1;
                while parts.iter().any(|p| p.name == name) {
                    k += 1;
                    name = format!("{base}.{suffix}.{k}");
                }
                parts.push(Part {
                    name,
                    aliases: vec![base],
                    mesh,
                    albedo,
                    emission,
                });
            }
            None => parts.push(Part {
                name: base,
                aliases: Vec::new(),
                mesh,
                albedo,
                emission,
            }),
        }
    }
    Ok(parts)
}

/// The first `usemtl` (line, name) that names no material of
/// `materials`: tobj leaves the faces after it without a material (grey,
/// and dark where the material would emit) and says nothing. The name is
/// read as tobj reads it: the line after its first space, trimmed.
fn unknown_material(bytes: &[u8], materials: &[tobj::Material]) -> Option<(usize, String)> {
    let text = String::from_utf8_lossy(bytes);
    text.lines().enumerate().find_map(|(i, line)| {
        if line.split_whitespace().next() != Some("usemtl") {
            return None;
        }
        let name = line.split_once(' ').map_or("", |(_, rest)| rest.trim());
        (!materials.iter().any(|m| m.name == name)).then(|| (i + 1, name.to_owned()))
    })
}

fn obj_mesh(m: &tobj::Mesh) -> Result<Mesh, MeshFileError> {
    let n = m.positions.len() / 3;
    let positions: Vec<Vec3> = m
        .positions
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    let normals = if m.normals.len() == 3 * n {
        m.normals
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    } else {
        Vec::new()
    };
    let uvs = if m.texcoords.len() == 2 * n {
        m.texcoords
            .chunks_exact(2)
            .map(|c| Vec2::new(c[0], c[1]))
            .collect()
    } else {
        Vec::new()
    };
    let mut triangles = Vec::with_capacity(m.indices.len() / 3);
    for t in m.indices.chunks_exact(3) {
        if let Some(&bad) = t.iter().find(|&&i| i as usize >= n) {
            return Err(MeshFileError::new(format!(
                "vertex index {bad} is out of range for {n} vertices"
            )));
        }
        triangles.push([t[0], t[1], t[2]]);
    }
    Ok(Mesh {
        positions,
        normals,
        uvs,
        triangles,
    })
}

/// The line tobj stumbled on: tobj reports only the kind of error, so scan
/// for the first line of that kind that does not parse.
fn obj_error_line(bytes: &[u8], e: &tobj::LoadError) -> Option<usize> {
    use tobj::LoadError as E;
    let (keyword, arity) = match e {
        E::PositionParseError => ("v", 3),
        E::NormalParseError => ("vn", 3),
        E::TexcoordParseError => ("vt", 1),
        E::FaceParseError | E::InvalidPolygon => ("f", 3),
        E::InvalidObjectName => ("o", 1),
        E::FaceVertexOutOfBounds => return index_out_of_range(bytes, "v", 0),
        E::FaceTexCoordOutOfBounds => return index_out_of_range(bytes, "vt", 1),
        E::FaceNormalOutOfBounds => return index_out_of_range(bytes, "vn", 2),
        _ => return None,
    };
    let text = String::from_utf8_lossy(bytes);
    text.lines().enumerate().find_map(|(i, line)| {
        let mut words = line.split_whitespace();
        if words.next() != Some(keyword) {
            return None;
        }
        let args: Vec<&str> = words.collect();
        let ok = match keyword {
            "f" => {
                args.len() >= arity
                    && args.iter().all(|w| {
                        w.split('/').enumerate().all(|(k, s)| {
                            (k > 0 && s.is_empty()) || s.parse::<i64>().is_ok_and(|v| v != 0)
                        })
                    })
            }
            "o" => !args.is_empty(),
            _ => args.len() >= arity && args.iter().all(|w| w.parse::<f64>().is_ok()),
        };
        (!ok).then_some(i + 1)
    })
}

/// The first face line with an index of kind `keyword` (slot `slot` of
/// `v/vt/vn`) that refers to no such element: a positive index past the
/// file's count (tobj checks against the whole file), or a negative one
/// reaching before the first element defined so far.
fn index_out_of_range(bytes: &[u8], keyword: &str, slot: usize) -> Option<usize> {
    let text = String::from_utf8_lossy(bytes);
    let count = |line: &str| line.split_whitespace().next() == Some(keyword);
    let total = text.lines().filter(|l| count(l)).count() as i64;
    let mut so_far = 0_i64;
    text.lines().enumerate().find_map(|(i, line)| {
        if count(line) {
            so_far += 1;
        }
        let mut words = line.split_whitespace();
        if words.next() != Some("f") {
            return None;
        }
        let bad = words.any(|w| {
            let index = w.split('/').nth(slot).and_then(|s| s.parse::<i64>().ok());
            index.is_some_and(|k| (k > 0 && k > total) || (k < 0 && so_far + k < 0))
        });
        bad.then_some(i + 1)
    })
}

fn append(into: &mut Mesh, more: &Mesh) {
    let base = into.positions.len() as u32;
    let keep_normals =
        into.normals.len() == into.positions.len() && more.normals.len() == more.positions.len();
    let keep_uvs = into.uvs.len() == into.positions.len() && more.uvs.len() == more.positions.len();
    into.positions.extend_from_slice(&more.positions);
    if keep_normals {
        into.normals.extend_from_slice(&more.normals);
    } else {
        into.normals.clear();
    }
    if keep_uvs {
        into.uvs.extend_from_slice(&more.uvs);
    } else {
        into.uvs.clear();
    }
    into.triangles
        .extend(more.triangles.iter().map(|t| t.map(|i| i + base)));
}

fn load_gltf(path: &Path, bytes: &[u8]) -> Result<Vec<Part>, MeshFileError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    guarded("glTF", || {
        let gltf =
            gltf::Gltf::from_slice(bytes).map_err(|e| MeshFileError::new(format!("glTF: {e}")))?;
        let gltf::Gltf { document, blob } = gltf;
        let buffers = gltf::import_buffers(&document, Some(dir), blob)
            .map_err(|e| MeshFileError::new(format!("glTF buffers: {e}")))?;
        let scene = document
            .default_scene()
            .or_else(|| document.scenes().next())
            .ok_or_else(|| MeshFileError::new("glTF file has no scene"))?;
        let mut parts = Vec::new();
        let mut stack: Vec<(gltf::Node, Mat4, usize)> =
            scene.nodes().map(|n| (n, Mat4::IDENTITY, 0)).collect();
        while let Some((node, parent, depth)) = stack.pop() {
            if depth > 64 {
                return Err(MeshFileError::new("glTF node hierarchy is deeper than 64"));
            }
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * local;
            if let Some(mesh) = node.mesh() {
                parts.push(gltf_part(&node, &mesh, world, &buffers)?);
            }
            stack.extend(node.children().map(|c| (c, world, depth + 1)));
        }
        parts.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(parts)
    })
}

fn gltf_part(
    node: &gltf::Node,
    mesh: &gltf::Mesh,
    world: Mat4,
    buffers: &[gltf::buffer::Data],
) -> Result<Part, MeshFileError> {
    let name = node
        .name()
        .or(mesh.name())
        .map_or_else(|| format!("node{}", node.index()), str::to_owned);
    let aliases = mesh
        .name()
        .filter(|m| *m != name)
        .map(|m| vec![m.to_owned()])
        .unwrap_or_default();
    let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
    let mut out = Mesh::default();
    let mut albedo = None;
    let mut emission = None;
    for (k, prim) in mesh.primitives().enumerate() {
        if prim.mode() != gltf::mesh::Mode::Triangles {
            return Err(MeshFileError::new(format!(
                "mesh {name:?} primitive {k}: mode {:?} is not triangles",
                prim.mode()
            )));
        }
        for acc in prim.attributes().map(|(_, a)| a).chain(prim.indices()) {
            check_accessor(&acc, buffers)?;
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| {
                MeshFileError::new(format!("mesh {name:?} primitive {k} has no positions"))
            })?
            .map(|p| world.transform_point3(Vec3::from_array(p)))
            .collect();
        let n = positions.len();
        let normals: Vec<Vec3> = reader
            .read_normals()
            .map(|it| {
                it.map(|v| (normal_matrix * Vec3::from_array(v)).normalize_or_zero())
                    .collect()
            })
            .unwrap_or_default();
        let uvs: Vec<Vec2> = reader
            .read_tex_coords(0)
            .map(|it| it.into_f32().map(Vec2::from_array).collect())
            .unwrap_or_default();
        let indices: Vec<u32> = match reader.read_indices() {
            Some(it) => it.into_u32().collect(),
            None => (0..n as u32).collect(),
        };
        let mut triangles = Vec::with_capacity(indices.len() / 3);
        for t in indices.chunks_exact(3) {
            if let Some(&bad) = t.iter().find(|&&i| i as usize >= n) {
                return Err(MeshFileError::new(format!(
                    "mesh {name:?} primitive {k}: index {bad} is out of range for {n} vertices"
                )));
            }
            // A mirroring node transform flips the winding.
            if world.determinant() < 0.0 {
                triangles.push([t[0], t[2], t[1]]);
            } else {
                triangles.push([t[0], t[1], t[2]]);
            }
        }
        let piece = Mesh {
            normals: if normals.len() == n {
                normals
            } else {
                Vec::new()
            },
            uvs: if uvs.len() == n { uvs } else { Vec::new() },
            positions,
            triangles,
        };
        if k == 0 {
            let m = prim.material();
            let c = m.pbr_metallic_roughness().base_color_factor();
            albedo = Some(Vec3::new(c[0], c[1], c[2]));
            emission = Some(Vec3::from_array(m.emissive_factor()));
            out = piece;
        } else {
            append(&mut out, &piece);
        }
    }
    Ok(Part {
        name,
        aliases,
        mesh: out,
        albedo,
        emission,
    })
}

/// Check that an accessor lies within its buffer view and the view within
/// its buffer, so that reading it cannot run off the end.
fn check_accessor(
    acc: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
) -> Result<(), MeshFileError> {
    let Some(view) = acc.view() else {
        return Err(MeshFileError::new(format!(
            "accessor {} has no buffer view (sparse accessors are not supported)",
            acc.index()
        )));
    };
    let data = buffers.get(view.buffer().index()).ok_or_else(|| {
        MeshFileError::new(format!("buffer {} is missing", view.buffer().index()))
    })?;
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|e| e > data.0.len()) {
        return Err(MeshFileError::new(format!(
            "buffer view {} runs past the end of buffer {}",
            view.index(),
            view.buffer().index()
        )));
    }
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem).max(elem);
    let needed = match acc.count() {
        0 => Some(0),
        c => (c - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(elem))
            .and_then(|x| x.checked_add(acc.offset())),
    };
    if needed.is_none_or(|n| n > view.length()) {
        return Err(MeshFileError::new(format!(
            "accessor {} runs past the end of buffer view {}",
            acc.index(),
            view.index()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_error_line_finds_the_bad_line_of_each_kind() {
        let text = b"v 0 0 0\nv 1 0 0\nv 1 x 0\nf 1 2 3\n";
        assert_eq!(
            obj_error_line(text, &tobj::LoadError::PositionParseError),
            Some(3)
        );
        let text = b"v 0 0 0\nf 1 2 3\nf 1 2 q\n";
        assert_eq!(
            obj_error_line(text, &tobj::LoadError::FaceParseError),
            Some(3)
        );
        let text = b"v 0 0 0\nf 1/1/1 2//2 3\nf 1 2\n";
        assert_eq!(
            obj_error_line(text, &tobj::LoadError::FaceParseError),
            Some(3)
        );
        assert_eq!(obj_error_line(text, &tobj::LoadError::ReadError), None);
        // Indices past the file's count, or before its first element.
        use tobj::LoadError as E;
        for (text, kind, line) in [
            (
                &b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n"[..],
                E::FaceVertexOutOfBounds,
                5,
            ),
            (
                b"v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n",
                E::FaceVertexOutOfBounds,
                3,
            ),
            (
                b"v 0 0 0\nvt 0 0\nf 1/1 1/2 1/1\n",
                E::FaceTexCoordOutOfBounds,
                3,
            ),
            (
                b"v 0 0 0\nvn 0 0 1\nf 1//1 1//1 1//2\n",
                E::FaceNormalOutOfBounds,
                3,
            ),
        ] {
            assert_eq!(obj_error_line(text, &kind), Some(line), "{kind:?}");
        }
    }

    #[test]
    fn append_offsets_indices_and_drops_partial_attributes() {
        let tri = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z; 3],
            uvs: Vec::new(),
            triangles: vec![[0, 1, 2]],
        };
        let mut m = tri.clone();
        append(&mut m, &tri);
        assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(m.normals.len(), 6);
        assert!(m.uvs.is_empty());
    }
}
