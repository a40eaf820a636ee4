//! The page's pictures of result files a browser cannot show: the
//! radiosity solution (PLY, B per vertex) drawn by ray casting from a
//! fixed view, and PFM maps (reflectance, irradiance) as PNGs.

use crate::demo::views::write_radiance;
use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use showcase_light::bvh::Bvh;
use showcase_light::radiosity::VertexMesh;
use showcase_light::{Ray, RgbImage};
use std::path::Path;

/// Size of a drawn radiosity solution.
const SOLUTION_SIZE: (u32, u32) = (320, 240);
/// Vertical field of view of that drawing.
const SOLUTION_FOV_DEG: f64 = 40.0;

/// The direction from the mesh's centre to the eye: towards the mesh's
/// open side, raised a little so floors show. The area-weighted normals of
/// a closed surface sum to zero, so their sum points out of the opening of
/// an open box whose walls face inwards (the Cornell box), and closed
/// objects inside it do not change it; a mesh with no opening (or one
/// open upwards or downwards only) is seen from -z.
fn view_direction(mesh: &VertexMesh) -> DVec3 {
    let (open, area) = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            // The area times the unit normal.
            0.5 * (b - a).cross(c - a)
        })
        .fold((DVec3::ZERO, 0.0), |(sum, area), n| {
            (sum + n, area + n.length())
        });
    let horizontal = DVec3::new(open.x, 0.0, open.z);
    let side = if horizontal.length() > 1e-3 * area {
        horizontal.normalize()
    } else {
        DVec3::NEG_Z
    };
    (side + 0.3 * DVec3::Y).normalize()
}

/// `mesh` drawn from [`view_direction`], far enough that its bounding
/// sphere fits the frame: B interpolated across each triangle (linear
/// W/m^2); `None` for pixels that see nothing.
pub(super) fn draw_solution(mesh: &VertexMesh, width: u32, height: u32) -> Image {
    let triangles: Vec<[DVec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| mesh.positions[i as usize]))
        .collect();
    let bvh = Bvh::build(triangles);
    let bounds = bvh.bounds();
    let (lo, hi) = (bounds.min, bounds.max);
    let centre = 0.5 * (lo + hi);
    let radius = (0.5 * (hi - lo).length()).max(1e-9);
    let tan = (0.5 * SOLUTION_FOV_DEG.to_radians()).tan();
    let back = view_direction(mesh);
    let eye = centre + back * radius / (0.5 * SOLUTION_FOV_DEG.to_radians()).sin();
    let forward = -back;
    let right = forward.cross(DVec3::Y).normalize();
    let up = right.cross(forward);
    let aspect = width as f64 / height as f64;
    Image::from_fn(width, height, |x, y| {
        let sx = (2.0 * (x as f64 + 0.5) / width as f64 - 1.0) * tan * aspect;
        let sy = (1.0 - 2.0 * (y as f64 + 0.5) / height as f64) * tan;
        let ray = Ray::new(eye, forward + sx * right + sy * up);
        let hit = bvh.closest_hit(&ray, 0.0, f64::INFINITY)?;
        let [a, b, c] = mesh.triangles[hit.triangle as usize].map(|i| mesh.values[i as usize]);
        let (u, v) = (hit.hit.u, hit.hit.v);
        Some((1.0 - u - v) * a + u * b + v * c)
    })
}

/// A drawn solution: B per pixel, `None` where nothing was hit.
pub(super) type Image = showcase_light::Image<Option<DVec3>>;

/// Exposure that maps the 99th percentile of the drawn values' largest
/// channel to 0.9 (1 when nothing positive was drawn).
fn exposure(values: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = values.filter(|v| *v > 0.0).collect();
    showcase_light::metrics::percentile(&v, 99.0).map_or(1.0, |p| 0.9 / p)
}

/// Draw the radiosity solution `ply` into the PNG `png`, exposed to its
/// brightest percent; background dark grey.
pub(super) fn write_solution_png(ply: &Path, png: &Path) -> Result<()> {
    let text =
        std::fs::read_to_string(ply).with_context(|| format!("cannot read {}", ply.display()))?;
    let mesh = crate::radiosity_job::export::parse_ply_ascii(&text)
        .with_context(|| ply.display().to_string())?;
    let drawn = draw_solution(&mesh, SOLUTION_SIZE.0, SOLUTION_SIZE.1);
    let pixels = || drawn.data.iter().flatten();
    let k = exposure(pixels().map(|c| c.max_element()));
    let background = Vec3::splat(0.02 / k as f32);
    let image = RgbImage::from_fn(drawn.width, drawn.height, |x, y| {
        drawn
            .get(x, y)
            .copied()
            .flatten()
            .map_or(background, |c| c.as_vec3())
    });
    write_radiance(png, &image, k)
}

/// A PFM map (linear, 0 to 1: reflectance or projector drive) as an
/// sRGB PNG.
pub(super) fn write_pfm_png(pfm: &Path, png: &Path) -> Result<()> {
    let image = crate::pfm::read_pfm(pfm).with_context(|| pfm.display().to_string())?;
    write_radiance(png, &image, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square in the plane z = 0, facing +z, B = 1 at every vertex
    /// but the last (B = 3).
    fn square() -> VertexMesh {
        VertexMesh {
            positions: vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            normals: vec![DVec3::Z; 4],
            values: vec![DVec3::ONE, DVec3::ONE, DVec3::ONE, DVec3::splat(3.0)],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn the_solution_is_seen_from_the_side_its_faces_turn_to() {
        let mesh = square();
        let d = view_direction(&mesh);
        assert!(d.z > 0.9 && d.y > 0.0, "{d}");
        let drawn = draw_solution(&mesh, 64, 48);
        let hits: Vec<DVec3> = drawn.data.iter().flatten().copied().collect();
        // The square is in view but does not fill it.
        assert!(!hits.is_empty() && hits.len() < drawn.data.len());
        // Interpolated B stays between the vertices' values, and both ends
        // of that range are approached.
        let (lo, hi) = hits.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), c| {
            (lo.min(c.x), hi.max(c.x))
        });
        assert!(lo >= 1.0 - 1e-9 && hi <= 3.0 + 1e-9, "{lo} {hi}");
        assert!(lo < 1.2 && hi > 2.5, "{lo} {hi}");
        // The B = 3 corner (top left as seen from +z) is brighter than the
        // opposite one.
        let row = |y: u32| {
            (0..64)
                .filter_map(|x| drawn.get(x, y).copied().flatten())
                .map(|c| c.x)
                .collect::<Vec<_>>()
        };
        let top = (0..48).find(|&y| !row(y).is_empty()).unwrap();
        let bottom = (0..48).rev().find(|&y| !row(y).is_empty()).unwrap();
        assert!(row(top)[0] > row(bottom)[row(bottom).len() - 1]);
    }

    #[test]
    fn an_open_box_is_seen_through_its_opening() {
        // Five inward-facing walls of a unit box, open towards +x.
        let quad = |o: DVec3, u: DVec3, v: DVec3| [o, o + u, o + u + v, o + v];
        let walls = [
            quad(DVec3::ZERO, DVec3::Y, DVec3::Z), // x = 0, normal +x
            quad(DVec3::ZERO, DVec3::Z, DVec3::X), // floor, normal +y
            quad(DVec3::Y, DVec3::X, DVec3::Z),    // ceiling, normal -y
            quad(DVec3::ZERO, DVec3::X, DVec3::Y), // z = 0, normal +z
            quad(DVec3::Z, DVec3::Y, DVec3::X),    // z = 1, normal -z
        ];
        let mut mesh = VertexMesh::default();
        for w in walls {
            let k = mesh.positions.len() as u32;
            mesh.positions.extend(w);
            mesh.normals.extend([DVec3::ZERO; 4]);
            mesh.values.extend([DVec3::ONE; 4]);
            mesh.triangles
                .extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
        }
        let d = view_direction(&mesh);
        assert!(d.x > 0.9 && d.y > 0.0 && d.z.abs() < 1e-9, "{d}");
        // Closed (the sixth wall added): seen from -z.
        let k = mesh.positions.len() as u32;
        mesh.positions.extend(quad(DVec3::X, DVec3::Z, DVec3::Y)); // x = 1, normal -x
        mesh.normals.extend([DVec3::ZERO; 4]);
        mesh.values.extend([DVec3::ONE; 4]);
        mesh.triangles
            .extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
        let d = view_direction(&mesh);
        assert!(d.z < -0.9, "{d}");
    }

    #[test]
    fn exposure_maps_the_brightest_percent_below_white() {
        assert_eq!(exposure(std::iter::empty()), 1.0);
        assert_eq!(exposure([0.0, -1.0].into_iter()), 1.0);
        let k = exposure((1..=100).map(f64::from));
        assert!((k * 99.0 - 0.9).abs() < 1e-12, "{k}");
    }
}
