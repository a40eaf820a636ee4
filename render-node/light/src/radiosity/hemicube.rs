//! The CPU hemi-cube (Cohen and Greenberg 1985): five faces of a unit cube
//! around a shooter's centre, each pixel weighted by its analytic delta
//! form factor, and an *item buffer* saying which element every pixel sees.
//!
//! The item buffer is the only step a GPU rasteriser replaces: it is built
//! here by casting one ray per pixel centre into the shared BVH
//! ([`HemiCube::item_buffer`]); [`HemiCube::accumulate`] then turns any item
//! buffer (CPU or GPU) into per-element form factors with f64 sums.
//!
//! A rasteriser (the GPU hemi-cube in `showcase_render::gpu::hemicube`) plugs in
//! through [`ItemBufferRasteriser`]: it gets the element triangles once
//! ([`ItemTriangle`]) and then renders batches of [`HemiCubeShot`]s into
//! item buffers laid out exactly as [`HemiCube::new`] orders its pixels:
//! the top face row by row (`y` rows, `x` columns of the local frame), then
//! the side faces `+x`, `-x`, `+y`, `-y`, each `resolution / 2` rows from
//! the surface (`z` near 0) up, `resolution` columns along the other axis.

use crate::{Hit, Ray, SceneGeometry};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Item-buffer entry for a pixel that sees no element.
pub const NO_ITEM: u32 = u32::MAX;

/// Why a hemi-cube cannot be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum HemiCubeError {
    /// The resolution is odd, below 2 or above 4096.
    #[error("hemi-cube resolution {0} must be even and in 2..=4096")]
    BadResolution(u32),
}

/// Where a hemi-cube sits for one shot: a shooter's centre, its unit
/// normal, and the rotation about the normal (radians) against aliasing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HemiCubeShot {
    /// Eye point (the shooting patch's centre).
    pub origin: DVec3,
    /// Unit surface normal (the top face's axis).
    pub normal: DVec3,
    /// Turn of the tangent frame about the normal (radians).
    pub rotation: f64,
}

impl HemiCubeShot {
    /// The local frame `(x, y, z)` of the hemi-cube in world space: the
    /// tangents of [`HemiCube::world_directions`] and the normal.
    pub fn frame(&self) -> [DVec3; 3] {
        let (t1, t2) = frame(self.normal, self.rotation);
        [t1, t2, self.normal]
    }
}

/// One element triangle handed to a rasteriser.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ItemTriangle {
    /// The id its pixels get in the item buffer (below [`NO_ITEM`]).
    pub item: u32,
    /// World corners.
    pub vertices: [DVec3; 3],
    /// Unit front normal: pixels that see the other side get [`NO_ITEM`]
    /// (the triangle still occludes).
    pub normal: DVec3,
}

/// Why a rasterised item buffer could not be made.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum ItemBufferError {
    /// The rasteriser (e.g. the GPU device) failed; the message says how.
    #[error("item-buffer rasteriser failed: {0}")]
    Raster(String),
}

/// Something that rasterises hemi-cube item buffers (the GPU hemi-cube):
/// the step of [`HemiCube::item_buffer`] that a rasteriser replaces.
pub trait ItemBufferRasteriser: Send + Sync {
    /// One line naming the rasteriser (e.g. the GPU adapter).
    fn describe(&self) -> String;

    /// Upload `triangles` (the receivers and occluders of a solve) for
    /// hemi-cubes of top-face `resolution`.
    fn upload(
        &self,
        resolution: u32,
        triangles: &[ItemTriangle],
    ) -> Result<Box<dyn ItemBufferScene>, ItemBufferError>;
}

/// Triangles uploaded by an [`ItemBufferRasteriser`].
pub trait ItemBufferScene: Send + Sync {
    /// How many shots one [`Self::render`] call handles best (at least 1).
    fn batch_size(&self) -> usize;

    /// One item buffer per shot, in [`HemiCube`] pixel order, holding the
    /// [`ItemTriangle::item`] seen front-on at each pixel centre or
    /// [`NO_ITEM`].
    fn render(&self, shots: &[HemiCubeShot]) -> Result<Vec<Vec<u32>>, ItemBufferError>;
}

/// A hemi-cube of `resolution x resolution` top-face pixels.
#[derive(Clone, Debug)]
pub struct HemiCube {
    resolution: u32,
    /// Pixel-centre directions in the local frame (z = surface normal),
    /// not normalised.
    directions: Vec<DVec3>,
    /// Delta form factor of each pixel.
    delta: Vec<f64>,
}

impl HemiCube {
    /// The pixels and delta form factors of a hemi-cube of `resolution`
    /// (top face `resolution^2`, four side faces `resolution x resolution/2`).
    pub fn new(resolution: u32) -> Result<Self, HemiCubeError> {
        if resolution < 2 || !resolution.is_multiple_of(2) || resolution > 4096 {
            return Err(HemiCubeError::BadResolution(resolution));
        }
        let n = resolution as usize;
        let h = 2.0 / n as f64;
        let da = h * h;
        let mut directions = Vec::with_capacity(3 * n * n);
        let mut delta = Vec::with_capacity(3 * n * n);
        let coord = |i: usize| -1.0 + (i as f64 + 0.5) * h;
        // Top face, z = 1.
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (coord(i), coord(j));
                let r2 = x * x + y * y + 1.0;
                directions.push(DVec3::new(x, y, 1.0));
                delta.push(da / (PI * r2 * r2));
            }
        }
        // Side faces at x = +-1 and y = +-1, z in (0, 1).
        for side in 0..4 {
            for k in 0..n / 2 {
                let z = (k as f64 + 0.5) * h;
                for i in 0..n {
                    let s = coord(i);
                    let d = match side {
                        0 => DVec3::new(1.0, s, z),
                        1 => DVec3::new(-1.0, s, z),
                        2 => DVec3::new(s, 1.0, z),
                        _ => DVec3::new(s, -1.0, z),
                    };
                    let r2 = 1.0 + s * s + z * z;
                    directions.push(d);
                    delta.push(z * da / (PI * r2 * r2));
                }
            }
        }
        Ok(Self {
            resolution,
            directions,
            delta,
        })
    }

    /// Top-face resolution.
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// Number of pixels over all five faces (`3 * resolution^2`).
    pub fn pixel_count(&self) -> usize {
        self.delta.len()
    }

    /// Delta form factor of every pixel, in item-buffer order.
    pub fn delta_form_factors(&self) -> &[f64] {
        &self.delta
    }

    /// Sum of all delta form factors in f64 (analytically 1).
    pub fn total(&self) -> f64 {
        self.delta.iter().sum()
    }

    /// World directions of the pixels for a hemi-cube on a surface with unit
    /// normal `normal`, turned by `rotation` radians about it.
    pub fn world_directions(&self, normal: DVec3, rotation: f64) -> Vec<DVec3> {
        let (t1, t2) = frame(normal, rotation);
        self.directions
            .iter()
            .map(|d| (d.x * t1 + d.y * t2 + d.z * normal).normalize())
            .collect()
    }

    /// The CPU item buffer: for each pixel, the id `resolve` gives the first
    /// surface seen from `origin` (on a surface with unit `normal`), or
    /// [`NO_ITEM`]. Back faces are hit (they occlude) and `resolve` decides
    /// whether they count.
    pub fn item_buffer(
        &self,
        geometry: &SceneGeometry,
        origin: DVec3,
        normal: DVec3,
        rotation: f64,
        resolve: impl Fn(&Hit) -> Option<u32> + Sync,
    ) -> Vec<u32> {
        let start = geometry.offset_point(origin, normal, origin + normal);
        self.world_directions(normal, rotation)
            .par_iter()
            .map(|d| {
                geometry
                    .closest_hit(&Ray::new(start, *d), 0.0, f64::INFINITY)
                    .and_then(|h| resolve(&h))
                    .unwrap_or(NO_ITEM)
            })
            .collect()
    }

    /// Add each pixel's delta form factor to `form_factors[item]`; returns
    /// the items touched (once each, in first-seen order). Items out of
    /// range are ignored.
    pub fn accumulate(&self, item_buffer: &[u32], form_factors: &mut [f64]) -> Vec<u32> {
        let mut touched = Vec::new();
        for (&item, &df) in item_buffer.iter().zip(&self.delta) {
            if let Some(f) = form_factors.get_mut(item as usize) {
                if *f == 0.0 {
                    touched.push(item);
                }
                *f += df;
            }
        }
        touched
    }
}

/// An orthonormal tangent frame about unit `n`, turned by `rotation`.
fn frame(n: DVec3, rotation: f64) -> (DVec3, DVec3) {
    let a = n.any_orthonormal_vector();
    let b = n.cross(a);
    let (s, c) = rotation.sin_cos();
    (c * a + s * b, c * b - s * a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ObjectFilter, form_factor_point_polygon};
    use glam::Vec3;
    use showcase_proto::{Material, Mesh, Object, ObjectKind, Showcase, Transform};

    #[test]
    fn delta_form_factors_sum_to_one() {
        for n in [128, 256, 512] {
            let h = HemiCube::new(n).unwrap();
            assert_eq!(h.pixel_count(), 3 * (n * n) as usize);
            assert!((h.total() - 1.0).abs() < 1e-3, "{n}: {}", h.total());
        }
        // The sum converges (midpoint rule, second order).
        let coarse = (HemiCube::new(8).unwrap().total() - 1.0).abs();
        let fine = (HemiCube::new(64).unwrap().total() - 1.0).abs();
        assert!(fine < coarse / 10.0, "{coarse} {fine}");
        for bad in [0, 1, 3, 4097, 8192] {
            assert_eq!(
                HemiCube::new(bad).unwrap_err(),
                HemiCubeError::BadResolution(bad)
            );
        }
    }

    #[test]
    fn directions_cover_the_upper_hemisphere_for_any_rotation() {
        let h = HemiCube::new(16).unwrap();
        let n = DVec3::new(0.3, -0.5, 0.8).normalize();
        for rot in [0.0, 0.7, 3.0] {
            let d = h.world_directions(n, rot);
            assert!(
                d.iter()
                    .all(|d| d.dot(n) > 0.0 && (d.length() - 1.0).abs() < 1e-12)
            );
        }
    }

    #[test]
    fn item_buffer_form_factor_matches_the_closed_form() {
        // A unit square 1 m above the origin facing down, seen from a point
        // on the floor facing up.
        let mut s = Showcase::default();
        let id = s.add_mesh(Mesh {
            positions: vec![
                Vec3::new(-0.5, 1.0, -0.5),
                Vec3::new(0.5, 1.0, -0.5),
                Vec3::new(0.5, 1.0, 0.5),
                Vec3::new(-0.5, 1.0, 0.5),
            ],
            normals: vec![],
            uvs: vec![],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        });
        s.objects.push(Object {
            name: "square".into(),
            mesh: id,
            material: Material::diffuse(Vec3::splat(0.5)),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
        let g = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
        let square: Vec<DVec3> = g.triangles().flat_map(|t| t.vertices).collect();
        let polygon = [square[0], square[1], square[2], square[5]];
        let exact = form_factor_point_polygon(DVec3::ZERO, DVec3::Y, &polygon).unwrap();
        assert!(exact > 0.1);
        for rot in [0.0, 0.4] {
            let h = HemiCube::new(128).unwrap();
            let items = h.item_buffer(&g, DVec3::ZERO, DVec3::Y, rot, |hit| {
                hit.front_face.then_some(hit.primitive)
            });
            let mut ff = vec![0.0; 2];
            h.accumulate(&items, &mut ff);
            let total = ff[0] + ff[1];
            assert!((total - exact).abs() < 0.01 * exact, "{total} vs {exact}");
        }
    }
}
