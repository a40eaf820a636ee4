//! Built-in procedural meshes (`mesh = "builtin:plate"` etc.): a subdivided
//! textured plate, a single quad and a UV sphere, with normals and texture
//! coordinates.

use glam::{Vec2, Vec3};
use showcase_proto::Mesh;
use std::f32::consts::{PI, TAU};

/// Most subdivisions of a plate per side, and most segments of a sphere.
pub(crate) const MAX_SUBDIVISIONS: u32 = 1024;

/// A plate in the xz-plane at y = 0, centred on the origin, `width` along x
/// and `depth` along z, facing +y, split into `n x n` cells of two
/// triangles. Texture coordinates run from `(0, 0)` at `(-w/2, -d/2)` to
/// `(1, 1)` at `(+w/2, +d/2)`.
pub(crate) fn plate(width: f32, depth: f32, n: u32) -> Mesh {
    let n = n.clamp(1, MAX_SUBDIVISIONS);
    let mut mesh = Mesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let uv = Vec2::new(i as f32 / n as f32, j as f32 / n as f32);
            mesh.positions
                .push(Vec3::new((uv.x - 0.5) * width, 0.0, (uv.y - 0.5) * depth));
            mesh.normals.push(Vec3::Y);
            mesh.uvs.push(uv);
        }
    }
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            // Counter-clockwise seen from +y: x right, z towards the viewer
            // looking down means (a, c, b) turns left.
            mesh.triangles.push([a, c, b]);
            mesh.triangles.push([b, c, d]);
        }
    }
    mesh
}

/// A UV sphere of `radius` centred on the origin with `segments` slices
/// around y and `segments / 2` stacks, outward normals, and no degenerate
/// triangles at the poles.
pub(crate) fn sphere(radius: f32, segments: u32) -> Mesh {
    let slices = segments.clamp(3, MAX_SUBDIVISIONS);
    let stacks = (slices / 2).max(2);
    let mut mesh = Mesh::default();
    for j in 0..=stacks {
        let theta = PI * j as f32 / stacks as f32;
        for i in 0..=slices {
            let phi = TAU * i as f32 / slices as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            );
            mesh.positions.push(radius * n);
            mesh.normals.push(n);
            mesh.uvs.push(Vec2::new(
                i as f32 / slices as f32,
                j as f32 / stacks as f32,
            ));
        }
    }
    let row = slices + 1;
    for j in 0..stacks {
        for i in 0..slices {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            // Stack j runs from the north pole down; phi turns
            // counter-clockwise seen from +y.
            if j != 0 {
                mesh.triangles.push([a, c, b]);
            }
            if j != stacks - 1 {
                mesh.triangles.push([b, c, d]);
            }
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face_normal(m: &Mesh, t: [u32; 3]) -> Vec3 {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        (b - a).cross(c - a)
    }

    #[test]
    fn plate_faces_up_with_the_requested_area_and_uv_corners() {
        let m = plate(0.4, 0.3, 8);
        assert_eq!(m.triangles.len(), 2 * 8 * 8);
        assert_eq!(m.positions.len(), 9 * 9);
        assert!((m.area() - 0.12).abs() < 1e-6);
        for t in &m.triangles {
            let n = face_normal(&m, *t);
            assert!(n.y > 0.0 && n.x.abs() < 1e-9 && n.z.abs() < 1e-9, "{n}");
        }
        let (lo, hi) = m.bounds().unwrap();
        assert_eq!(
            (lo, hi),
            (Vec3::new(-0.2, 0.0, -0.15), Vec3::new(0.2, 0.0, 0.15))
        );
        assert_eq!(m.uvs[0], Vec2::ZERO);
        assert_eq!(*m.uvs.last().unwrap(), Vec2::ONE);
    }

    #[test]
    fn sphere_is_round_outward_and_close_to_its_analytic_area() {
        let r = 0.05;
        let m = sphere(r, 48);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((p.length() - r).abs() < 1e-6);
            assert!((n.length() - 1.0).abs() < 1e-5);
        }
        for t in &m.triangles {
            let n = face_normal(&m, *t);
            assert!(n.length() > 1e-9, "degenerate triangle {t:?}");
            let centroid = t.iter().map(|&i| m.positions[i as usize]).sum::<Vec3>() / 3.0;
            assert!(n.dot(centroid) > 0.0, "inward triangle {t:?}");
        }
        // A polyhedron inscribed in the sphere: a little less than 4 pi r^2.
        let exact = 4.0 * std::f64::consts::PI * (r as f64).powi(2);
        let rel = (m.area() - exact) / exact;
        assert!((-0.01..0.0).contains(&rel), "relative area error {rel}");
    }

    #[test]
    fn subdivisions_are_clamped() {
        assert_eq!(plate(1.0, 1.0, 0).triangles.len(), 2);
        assert_eq!(sphere(1.0, 0).triangles.len(), 3 * 2);
    }
}
