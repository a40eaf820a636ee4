//! Writers for radiosity results: PLY meshes with per-vertex radiosity
//! (irradiance maps are PFM images, written with [`crate::pfm`]), and the
//! reader of the PLY files written here (the demo's page draws them).

use glam::DVec3;
use showcase_light::radiosity::VertexMesh;
use std::fmt::Write as _;

/// An ASCII PLY of `mesh`: vertex `x y z nx ny nz` and float
/// `red green blue` (the per-vertex value, B exitance in W/m^2, linear),
/// triangular faces.
pub fn ply_ascii(mesh: &VertexMesh) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "ply\nformat ascii 1.0\ncomment red green blue: radiosity B, exitance in W/m^2, linear RGB\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property float red\nproperty float green\nproperty float blue\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    for ((p, n), v) in mesh.positions.iter().zip(&mesh.normals).zip(&mesh.values) {
        let _ = writeln!(
            s,
            "{} {} {} {} {} {} {} {} {}",
            p.x as f32,
            p.y as f32,
            p.z as f32,
            n.x as f32,
            n.y as f32,
            n.z as f32,
            v.x as f32,
            v.y as f32,
            v.z as f32
        );
    }
    for t in &mesh.triangles {
        let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
    }
    s
}

/// Why a PLY file could not be read back.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// The header is not the one [`ply_ascii`] writes.
    #[error("not a PLY of per-vertex radiosity as `ply_ascii` writes: {0}")]
    Header(String),
    /// A line of the body is short or holds something other than numbers.
    #[error("PLY body line {line}: {what}")]
    Body {
        /// 1-based line number after the header.
        line: usize,
        /// What is wrong.
        what: String,
    },
}

/// The whitespace-separated numbers of body line `i` (0-based).
fn numbers<T: std::str::FromStr>(i: usize, line: &str) -> Result<Vec<T>, PlyError>
where
    T::Err: std::fmt::Display,
{
    line.split_whitespace()
        .map(str::parse::<T>)
        .collect::<Result<_, _>>()
        .map_err(|e| PlyError::Body {
            line: i + 1,
            what: e.to_string(),
        })
}

/// Read a PLY written by [`ply_ascii`] back into a mesh; a face index
/// outside the vertices is an error.
pub fn parse_ply_ascii(text: &str) -> Result<VertexMesh, PlyError> {
    let (header, body) = text
        .split_once("end_header\n")
        .ok_or_else(|| PlyError::Header("no end_header".into()))?;
    if !header.starts_with("ply\nformat ascii 1.0\n") {
        return Err(PlyError::Header("not ASCII PLY 1.0".into()));
    }
    let count = |element: &str| -> Result<usize, PlyError> {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .and_then(|n| n.trim().parse().ok())
            .ok_or_else(|| PlyError::Header(format!("no `element {element}` count")))
    };
    let (vertices, faces) = (count("vertex")?, count("face")?);
    let mut lines = body.lines().enumerate();
    let mut next = |what: &str| {
        lines.next().ok_or_else(|| PlyError::Body {
            line: vertices + faces,
            what: format!("ends before the {what}s do"),
        })
    };
    let mut mesh = VertexMesh {
        positions: Vec::with_capacity(vertices),
        normals: Vec::with_capacity(vertices),
        values: Vec::with_capacity(vertices),
        triangles: Vec::with_capacity(faces),
    };
    for _ in 0..vertices {
        let (i, line) = next("vertex")?;
        let v: Vec<f64> = numbers(i, line)?;
        if v.len() != 9 || v.iter().any(|x| !x.is_finite()) {
            return Err(PlyError::Body {
                line: i + 1,
                what: format!("a vertex needs 9 finite numbers, got {line:?}"),
            });
        }
        mesh.positions.push(DVec3::new(v[0], v[1], v[2]));
        mesh.normals.push(DVec3::new(v[3], v[4], v[5]));
        mesh.values.push(DVec3::new(v[6], v[7], v[8]));
    }
    for _ in 0..faces {
        let (i, line) = next("face")?;
        let f: Vec<u32> = numbers(i, line)?;
        match f[..] {
            [3, a, b, c] if [a, b, c].iter().all(|&k| (k as usize) < vertices) => {
                mesh.triangles.push([a, b, c]);
            }
            _ => {
                return Err(PlyError::Body {
                    line: i + 1,
                    what: format!("not a triangle of known vertices: {line:?}"),
                });
            }
        }
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ply_header_counts_match_the_body() {
        let mesh = VertexMesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            normals: vec![DVec3::Z; 3],
            values: vec![DVec3::new(1.0, 2.0, 3.0); 3],
            triangles: vec![[0, 1, 2]],
        };
        let text = ply_ascii(&mesh);
        let body: Vec<&str> = text.split("end_header\n").nth(1).unwrap().lines().collect();
        assert_eq!(body.len(), 4);
        assert_eq!(body[0], "0 0 0 0 0 1 1 2 3");
        assert_eq!(body[3], "3 0 1 2");
        assert!(text.contains("element vertex 3\n") && text.contains("element face 1\n"));
    }

    #[test]
    fn ply_reads_back_what_it_wrote() {
        let mesh = VertexMesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::new(0.0, 0.5, -0.25)],
            normals: vec![DVec3::Z; 3],
            values: vec![DVec3::new(1.0, 2.0, 3.5); 3],
            triangles: vec![[0, 1, 2], [2, 1, 0]],
        };
        let back = parse_ply_ascii(&ply_ascii(&mesh)).unwrap();
        assert_eq!(back, mesh);
    }

    #[test]
    fn a_bad_ply_is_an_error_naming_the_line() {
        let mesh = VertexMesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            normals: vec![DVec3::Z; 3],
            values: vec![DVec3::ONE; 3],
            triangles: vec![[0, 1, 2]],
        };
        let text = ply_ascii(&mesh);
        let bad_index = text.replace("3 0 1 2", "3 0 1 3");
        let err = parse_ply_ascii(&bad_index).unwrap_err().to_string();
        assert!(err.contains("line 4"), "{err}");
        let short = text.replace("3 0 1 2\n", "");
        assert!(parse_ply_ascii(&short).is_err());
        let nan = text.replacen("0 0 0 0 0 1", "NaN 0 0 0 0 1", 1);
        assert!(parse_ply_ascii(&nan).is_err());
        assert!(parse_ply_ascii("ply\nformat binary_little_endian 1.0\nend_header\n").is_err());
    }
}
