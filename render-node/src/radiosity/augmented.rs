//! Augmented radiosity (paper section 4.2): the passes B0..B3 over real and
//! virtual surfaces, and the projector irradiance maps that make the real
//! surfaces emit B2.
//!
//! - B0: all objects, lit by the scene's emitters and virtual lights.
//! - B1: real surfaces only, each emitting `E = B0`, no virtual light.
//! - B2 = B0 - (B1 - B0), negative values clipped to 0 (counted).
//! - B3: real surfaces only, each emitting `E = B2`: the check `B3 ~ B0`.
//!
//! The irradiance map of a projector (equation 4.6) is rendered from its
//! view: per pixel, the first real surface hit, `B2` interpolated there,
//! `F = cos(theta) / r^2 * h` (h = 1 for the closest front-facing hit, 0
//! otherwise), and the projector drive `(B2 / (rho F) / k - black) / eta`,
//! where `k` is the number of projectors that see the point (they share
//! the work equally) and `eta`, `black` are the projector's intensity at
//! full drive and at zero (W/sr). The paper writes `* eta` for its
//! brightness factor; with our `ProjectorResponse::eta` in W/sr per unit
//! drive the physically consistent form divides by it. The drive is linear
//! (before the device's gamma) and clamped to `[0, 1]`.

use super::mesh::RadiosityMesh;
use super::shooting::{Shooter, SolveError, SolveOptions};
use crate::light::{DeviceError, DeviceRays, Image, RgbImage, SceneGeometry};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use showcase_proto::{Light, Projector};

/// Pixels where `rho * F` is below this floor (per channel) get drive 0.
pub const RHO_F_FLOOR: f64 = 1e-9;

/// The four passes of augmented radiosity, per element of the mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct AugmentedSolution {
    /// All objects, with the virtual lights.
    pub b0: Vec<DVec3>,
    /// Real surfaces emitting B0 (zero on virtual elements).
    pub b1: Vec<DVec3>,
    /// `B0 - (B1 - B0)` clipped at 0 (zero on virtual elements).
    pub b2: Vec<DVec3>,
    /// Real surfaces emitting B2 (zero on virtual elements).
    pub b3: Vec<DVec3>,
    /// Real elements where B2 had a negative channel before clipping.
    pub clipped_elements: usize,
    /// Real elements.
    pub real_elements: usize,
    /// Area-weighted mean `|B1 - B0|` over real surfaces, relative to the
    /// mean B0, per RGB channel.
    pub b1_b0_deviation_rgb: [f64; 3],
    /// Area-weighted mean `|B3 - B0|` over real surfaces, relative to the
    /// mean B0, per RGB channel (the paper's check, near 0 when it works).
    pub b3_b0_deviation_rgb: [f64; 3],
    /// Shots of the three solves.
    pub shots: [usize; 3],
}

/// How the B1 pass propagates B0 among the real surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum B1Pass {
    /// The paper: a converged solve, `B1 = (I - K)^-1 B0` for the real
    /// transport `K`. Then `B3 = B0 - K^2 B0 + ...`: close to B0 only when
    /// the real interreflection is weak.
    Converged,
    /// Beyond the paper: one bounce, `B1 = B0 + K B0`, so that
    /// `B2 = (I - K) B0` and `B3 = (I - K)^-1 B2 = B0` exactly wherever B2
    /// needs no clipping.
    OneBounce,
}

/// Run the passes as the paper does ([`B1Pass::Converged`]). `all` holds
/// every object's geometry and `real` only the real objects'; both from the
/// showcase `mesh` was built from.
pub fn augmented_radiosity(
    mesh: &RadiosityMesh,
    all: &SceneGeometry,
    real: &SceneGeometry,
    lights: &[Light],
    options: &SolveOptions,
) -> Result<AugmentedSolution, SolveError> {
    augmented_radiosity_with(mesh, all, real, lights, options, B1Pass::Converged)
}

/// Run the passes with the B1 propagation `b1_pass`.
pub fn augmented_radiosity_with(
    mesh: &RadiosityMesh,
    all: &SceneGeometry,
    real: &SceneGeometry,
    lights: &[Light],
    options: &SolveOptions,
    b1_pass: B1Pass,
) -> Result<AugmentedSolution, SolveError> {
    let mut s0 = Shooter::new(mesh, all, None, options)?;
    s0.add_surface_emission();
    for l in lights {
        s0.add_light(l, 1.0);
    }
    s0.run();
    let b0 = s0.radiosity().to_vec();
    let mask: Vec<bool> = mesh.elements.iter().map(|e| e.real).collect();
    let real_only = |values: &[DVec3]| -> Vec<DVec3> {
        values
            .iter()
            .zip(&mask)
            .map(|(v, &m)| if m { *v } else { DVec3::ZERO })
            .collect()
    };
    let pass = |emission: &[DVec3], rule: B1Pass| -> Result<(Vec<DVec3>, usize), SolveError> {
        let mut s = Shooter::new(mesh, real, Some(mask.clone()), options)?;
        s.add_emission(emission, 1.0);
        match rule {
            B1Pass::Converged => {
                s.run();
            }
            B1Pass::OneBounce => s.shoot_each_once(),
        }
        Ok((s.radiosity().to_vec(), s.shots()))
    };
    let (b1, shots1) = pass(&real_only(&b0), b1_pass)?;
    let mut clipped_elements = 0;
    let b2: Vec<DVec3> = b0
        .iter()
        .zip(&b1)
        .zip(&mask)
        .map(|((b0, b1), &m)| {
            if !m {
                return DVec3::ZERO;
            }
            let v = 2.0 * *b0 - *b1;
            if v.min_element() < 0.0 {
                clipped_elements += 1;
            }
            v.max(DVec3::ZERO)
        })
        .collect();
    let (b3, shots3) = pass(&b2, B1Pass::Converged)?;
    let deviation = |b: &[DVec3]| -> [f64; 3] {
        let (mut dev, mut sum) = (DVec3::ZERO, DVec3::ZERO);
        for ((e, x), r) in mesh.elements.iter().zip(b).zip(&b0) {
            if e.real {
                dev += (*x - *r).abs() * e.area;
                sum += *r * e.area;
            }
        }
        [0, 1, 2].map(|c| if sum[c] > 0.0 { dev[c] / sum[c] } else { 0.0 })
    };
    Ok(AugmentedSolution {
        b1_b0_deviation_rgb: deviation(&b1),
        b3_b0_deviation_rgb: deviation(&b3),
        real_elements: mask.iter().filter(|m| **m).count(),
        b0,
        b1,
        b2,
        b3,
        clipped_elements,
        shots: [s0.shots(), shots1, shots3],
    })
}

/// A projector's irradiance map: linear drive per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct IrradianceMap {
    /// Linear drive in `[0, 1]` per channel (before the projector's gamma).
    pub drive: RgbImage,
    /// Pixels that land on a real front-facing surface.
    pub mask: Image<bool>,
    /// Masked pixels.
    pub valid: usize,
    /// Masked pixels where a channel had to be clamped (or the floor hit).
    pub clipped: usize,
    /// Which masked pixels were clipped.
    pub clipped_mask: Image<bool>,
}

impl IrradianceMap {
    /// `clipped / valid` (0 when no pixel is valid).
    pub fn clipped_fraction(&self) -> f64 {
        if self.valid > 0 {
            self.clipped as f64 / self.valid as f64
        } else {
            0.0
        }
    }
}

/// Render projector `index` of `projectors`' irradiance map for target
/// exitance `b2_vertices` (per mesh vertex, see
/// [`RadiosityMesh::vertex_values`]) on the real geometry `real`.
pub fn irradiance_map(
    mesh: &RadiosityMesh,
    real: &SceneGeometry,
    b2_vertices: &[DVec3],
    projectors: &[Projector],
    index: usize,
) -> Result<IrradianceMap, DeviceError> {
    let rays: Vec<DeviceRays> = projectors
        .iter()
        .map(|p| DeviceRays::new(&p.device))
        .collect::<Result<_, _>>()?;
    let Some(this) = rays.get(index) else {
        return Err(DeviceError::EmptyImage {
            width: 0,
            height: 0,
        });
    };
    let response = &projectors[index].response;
    let eta = f64::from(response.eta);
    let black = f64::from(response.black_level).max(0.0);
    let (w, h) = (this.device().width, this.device().height);
    let pixels: Vec<Option<(Vec3, bool)>> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let ray = this.pixel_ray(x, y)?;
            let hit = real.closest_hit(&ray, 0.0, f64::INFINITY)?;
            if !hit.front_face {
                return None;
            }
            let prim = mesh.primitive_of(hit.object, hit.triangle)?;
            let (e, _) = mesh.locate(prim, hit.barycentric)?;
            let b2 = mesh.interpolate(prim, hit.barycentric, b2_vertices)?;
            let rho = mesh.elements[e as usize].reflectance;
            let n = hit.geometric_normal;
            let cos = -n.dot(ray.direction);
            let f = cos / (hit.t * hit.t);
            let sharing = rays
                .iter()
                .filter(|r| r.sees(real, hit.point, n))
                .count()
                .max(1) as f64;
            let mut clipped = false;
            let mut drive = DVec3::ZERO;
            for c in 0..3 {
                let denom = rho[c] * f;
                let want = b2[c] / sharing;
                let d = if denom > RHO_F_FLOOR && eta > 0.0 {
                    (want / denom - black) / eta
                } else {
                    if want > 0.0 {
                        clipped = true;
                    }
                    0.0
                };
                let d = if d.is_finite() { d } else { 0.0 };
                if !(0.0..=1.0).contains(&d) {
                    clipped = true;
                }
                drive[c] = d.clamp(0.0, 1.0);
            }
            Some((drive.as_vec3(), clipped))
        })
        .collect();
    let valid = pixels.iter().filter(|p| p.is_some()).count();
    let clipped = pixels.iter().filter(|p| p.is_some_and(|(_, c)| c)).count();
    Ok(IrradianceMap {
        drive: Image {
            width: w,
            height: h,
            data: pixels
                .iter()
                .map(|p| p.map_or(Vec3::ZERO, |(d, _)| d))
                .collect(),
        },
        mask: Image {
            width: w,
            height: h,
            data: pixels.iter().map(Option::is_some).collect(),
        },
        clipped_mask: Image {
            width: w,
            height: h,
            data: pixels.iter().map(|p| p.is_some_and(|(_, c)| c)).collect(),
        },
        valid,
        clipped,
    })
}
