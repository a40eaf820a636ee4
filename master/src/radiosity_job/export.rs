//! Writers for radiosity results: PLY meshes with per-vertex radiosity
//! (irradiance maps are PFM images, written with [`crate::pfm`]).

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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

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
}
