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
//! view: at each sub-pixel point, the first real surface hit, `B2`
//! interpolated there, `F = cos(theta) / r^2 * h` (h = 1 for the closest
//! front-facing hit, 0 otherwise) and `k`, the number of projectors that
//! see the point (they share the work equally). The paper's per-pixel
//! `L = B2 / (rho F) / k` holds at one point only, but a pixel sends one
//! intensity through its whole solid angle and `F` and `B2` change across
//! its footprint (fast at grazing incidence, and across an edge between
//! surfaces, where the pixel-centre value overshoots the other surface
//! tenfold). So the pixel's intensity is the least-squares fit
//! `L = sum(rho F B2 / k) / sum((rho F)^2)` over [`MAP_SUBSAMPLES`]^2
//! points, which is the paper's `L` on a uniform footprint. The projector
//! drive is `(L - black) / eta`, where `eta`, `black` are the projector's
//! intensity at full drive and at zero (W/sr). The paper writes `* eta`
//! for its brightness factor; with our `ProjectorResponse::eta` in W/sr
//! per unit drive the physically consistent form divides by it. The drive
//! is linear
//! (before the device's gamma) and clamped to `[0, 1]`.

use super::gather::{GatherOptions, gather_vertices};
use super::hierarchy::{Hierarchy, HierarchyError, HierarchyOptions};
use super::mesh::RadiosityMesh;
use super::shooting::{Shooter, SolveError, SolveOptions};
use crate::finite::finite_or_zero;
use crate::{DeviceError, DeviceRays, Image, RgbImage, SceneGeometry};
use glam::{DVec2, DVec3, Vec3};
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
    /// Shots of the three solves (gathers, for the hierarchical solver).
    pub shots: [usize; 3],
    /// How far from converged B0 stopped: the unshot fraction
    /// (progressive) or the last gather's relative change (hierarchical).
    pub b0_residual: f64,
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
    /// Beyond the paper: one bounce that also accounts for clipping. Where
    /// the real interreflection alone exceeds B0 (`(K B)_i > B0_i`, e.g.
    /// on a real floor in a virtual object's shadow), no projector can take
    /// light away: B2 is 0 there and the real surface settles at
    /// `B_i = (K B)_i > B0_i`, and that surplus is interreflected onto the
    /// other real surfaces. This pass finds the radiosity the real room
    /// will actually reach, the fixed point `B* = max(B0, K B*)` (per
    /// channel; monotone from `B0` and a contraction, so a few iterations
    /// of one bounce each), and sets `B1 = B0 + K B*`: then
    /// `B2 = max(2 B0 - B1, 0) = max(B0 - K B*, 0)` and the real room's
    /// `(I - K)^-1 B2 = B*`, equal to B0 wherever B2 is not clipped.
    ClipCompensated,
}

/// Fixed-point iterations of [`B1Pass::ClipCompensated`] at most.
pub const CLIP_ITERATIONS: usize = 8;

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
    let pass = |emission: &[DVec3], rule: B1Pass| -> Result<(Vec<DVec3>, usize), SolveError> {
        let mut s = Shooter::new(mesh, real, Some(mask.clone()), options)?;
        s.add_emission(emission, 1.0);
        match rule {
            B1Pass::Converged => {
                s.run();
            }
            B1Pass::OneBounce => s.shoot_each_once(),
            B1Pass::ClipCompensated => return Ok(clip_compensated(&mut s, emission)),
        }
        Ok((s.radiosity().to_vec(), s.shots()))
    };
    let shots0 = s0.shots();
    let residual = s0.unshot_fraction();
    passes_from_b0(mesh, b0, (shots0, residual), |emission, first| {
        pass(emission, if first { b1_pass } else { B1Pass::Converged })
    })
}

/// B1, B2 and B3 from `b0`: `pass(emission, true)` is the B1 pass and
/// `pass(emission, false)` the converged B3 pass over the real surfaces,
/// each returning B and its work (shots or gathers).
fn passes_from_b0<E>(
    mesh: &RadiosityMesh,
    b0: Vec<DVec3>,
    (work0, b0_residual): (usize, f64),
    mut pass: impl FnMut(&[DVec3], bool) -> Result<(Vec<DVec3>, usize), E>,
) -> Result<AugmentedSolution, E> {
    let mask: Vec<bool> = mesh.elements.iter().map(|e| e.real).collect();
    let real_only = |values: &[DVec3]| -> Vec<DVec3> {
        values
            .iter()
            .zip(&mask)
            .map(|(v, &m)| if m { *v } else { DVec3::ZERO })
            .collect()
    };
    let (b1, shots1) = pass(&real_only(&b0), true)?;
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
    let (b3, shots3) = pass(&b2, false)?;
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
        shots: [work0, shots1, shots3],
        b0_residual,
    })
}

/// [`augmented_radiosity_with`] on the hierarchical solver: B0 over all
/// objects, then B1 (by `b1_pass`) and B3 over the real ones, each a
/// [`Hierarchy`] of its own (the real passes share one: the links made for
/// B0's exitance serve B2's). `shots` holds gathers, not shots.
pub fn augmented_radiosity_hierarchical(
    mesh: &RadiosityMesh,
    all: &SceneGeometry,
    real: &SceneGeometry,
    lights: &[Light],
    options: &HierarchyOptions,
    b1_pass: B1Pass,
) -> Result<AugmentedSolution, HierarchyError> {
    let mut h0 = Hierarchy::new(mesh, all, None, options)?;
    let emission: Vec<DVec3> = mesh.elements.iter().map(|e| e.emission).collect();
    let direct = h0.direct(lights);
    let s0 = h0.solve(&emission, &direct)?;
    drop(h0);
    let mask: Vec<bool> = mesh.elements.iter().map(|e| e.real).collect();
    let mut h = Hierarchy::new(mesh, real, Some(&mask), options)?;
    passes_from_b0(
        mesh,
        s0.radiosity,
        (s0.iterations as usize, s0.residual),
        |emission, first| {
            if !first || b1_pass == B1Pass::Converged {
                let s = h.solve(emission, &[])?;
                return Ok((s.radiosity, s.iterations as usize));
            }
            if h.links() == 0 {
                h.link(emission)?;
            }
            if b1_pass == B1Pass::OneBounce {
                return Ok((h.gather_step(emission, emission), 1));
            }
            Ok(clip_fixed_point(emission, |b| (h.reflect(b), 1)))
        },
    )
}

/// The global-illumination light at one place (W/m^2 per channel).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IndirectLight {
    /// What the displays add to the direct light: on a virtual surface its
    /// indirect irradiance, on a real one what the target's indirect light
    /// has beyond the cabinet's own interreflection
    /// ([`indirect_correction`]).
    pub add: DVec3,
    /// What the real surfaces' own interreflection brings a real surface
    /// (0 on virtual ones): where the projectors leave it dark (an
    /// occlusion shadow), the irradiance it still reflects, seen through
    /// the virtual objects in front of it.
    pub cabinet: DVec3,
}

impl IndirectLight {
    /// Whether both parts are finite.
    pub fn is_finite(&self) -> bool {
        self.add.is_finite() && self.cabinet.is_finite()
    }
}

/// Per element, the global-illumination light ([`IndirectLight`], W/m^2
/// per channel): `add`, the irradiance that the displays must add to the
/// virtual lights' direct irradiance so that every surface shows the
/// target's global illumination, and `cabinet`, `E_real` below: what the
/// real surfaces' own interreflection brings a real element, the light a
/// dark one still reflects (through the virtual objects in front of it,
/// which the faces compensate). On a virtual element
/// (drawn by the CRT faces) it is the whole indirect irradiance
/// `E_indirect(B0)`. On a real element (lit by the projectors, or drawn
/// by a face in an occluding occlusion shadow) it is what the target's
/// indirect light lacks in a real cabinet, where light bounces between
/// the real surfaces alone:
///
/// `dE = E_indirect(B0) - E_real(B0_real)`
///
/// with `B0` the hierarchical solution of every object under `lights`,
/// `E_indirect(B0)` the irradiance its bounce brings (`K B0 / rho` over
/// every object: colour bleeding, the virtual objects' light and shadows)
/// and `E_real(B0_real)` what the real surfaces at their target exitance
/// bring each other over the real geometry alone (`K_real B0 / rho`,
/// which the cabinet adds by itself). A projector delivering
/// `E_direct + dE` makes `B = rho (E_direct + dE + E_real(B))`, whose
/// solution is `B0`: the exact one-bounce compensation `B2 = (I - K) B0`
/// with the direct part left to the per-pixel pass. Negative where the
/// virtual objects block light that passes in the cabinet.
///
/// A real element the projectors leave dark (`lit`, per element, false;
/// `None`: every element is lit) cannot show B0: one no projector reaches
/// ([`projector_reach`]) or one in an observer's occlusion shadow. In the
/// cabinet it only reflects what the others send it, `rho E_real` (one
/// bounce), and that is what it brings the others in `E_real`.
pub fn indirect_correction(
    mesh: &RadiosityMesh,
    all: &SceneGeometry,
    real: &SceneGeometry,
    lights: &[Light],
    lit: Option<&[bool]>,
    options: &HierarchyOptions,
) -> Result<Vec<IndirectLight>, HierarchyError> {
    let emission: Vec<DVec3> = mesh.elements.iter().map(|e| e.emission).collect();
    let mut h0 = Hierarchy::new(mesh, all, None, options)?;
    let direct = h0.direct(lights);
    let b0 = h0.solve(&emission, &direct)?.radiosity;
    let bounce_all = h0.reflect(&b0);
    drop(h0);
    let mask: Vec<bool> = mesh.elements.iter().map(|e| e.real).collect();
    let real_b0 = real_part(mesh, &b0);
    let mut h = Hierarchy::new(mesh, real, Some(&mask), options)?;
    h.link(&real_b0)?;
    Ok(correction(mesh, &h, &real_b0, &bounce_all, lit))
}

/// `b` on the real elements, zero on the virtual ones.
pub(super) fn real_part(mesh: &RadiosityMesh, b: &[DVec3]) -> Vec<DVec3> {
    mesh.elements
        .iter()
        .zip(b)
        .map(|(e, b)| if e.real { *b } else { DVec3::ZERO })
        .collect()
}

/// [`indirect_correction`] from B0's real part `real_b0`, one bounce of
/// all of B0 over every object (`bounce_all`) and `h`, the real elements'
/// links: the light the real surfaces bring each other (the dark ones
/// only reflecting), and what the displays add beyond it.
pub(super) fn correction(
    mesh: &RadiosityMesh,
    h: &Hierarchy<'_>,
    real_b0: &[DVec3],
    bounce_all: &[DVec3],
    lit: Option<&[bool]>,
) -> Vec<IndirectLight> {
    let reached: Vec<bool> = (0..mesh.elements.len())
        .map(|e| lit.is_none_or(|l| l.get(e).copied().unwrap_or(false)))
        .collect();
    let mut cabinet: Vec<DVec3> = real_b0
        .iter()
        .zip(&reached)
        .map(|(b, r)| if *r { *b } else { DVec3::ZERO })
        .collect();
    if reached.iter().any(|r| !r) {
        let bounce = h.reflect(&cabinet);
        for ((c, b), r) in cabinet.iter_mut().zip(&bounce).zip(&reached) {
            if !r {
                *c = *b;
            }
        }
    }
    let bounce_real = h.reflect(&cabinet);
    mesh.elements
        .iter()
        .zip(bounce_all.iter().zip(&bounce_real))
        .map(|(e, (all, real))| {
            let rho = e.reflectance;
            // Irradiance from reflected exitance `b`.
            let irradiance = |b: DVec3| {
                let per = |c: usize| {
                    if rho[c] > RHO_F_FLOOR {
                        b[c] / rho[c]
                    } else {
                        0.0
                    }
                };
                finite_or_zero(DVec3::new(per(0), per(1), per(2)))
            };
            // On a virtual element `real` is zero (the real-only links
            // leave it inactive): `add` is its whole indirect irradiance.
            IndirectLight {
                add: irradiance(*all - *real),
                cabinet: irradiance(*real),
            }
        })
        .collect()
}

/// Per element of `mesh`: whether some projector of `projectors` reaches
/// its centre on its front side over the real geometry `real` (false for
/// virtual elements).
pub fn projector_reach(
    mesh: &RadiosityMesh,
    real: &SceneGeometry,
    projectors: &[DeviceRays],
) -> Vec<bool> {
    mesh.elements
        .par_iter()
        .map(|e| e.real && projectors.iter().any(|p| p.sees(real, e.center, e.normal)))
        .collect()
}

/// One bounce of the real transport: `K x` for exitance `x` per element,
/// with the form-factor rows `shooter` has cached (its energy is reset).
fn one_bounce(shooter: &mut Shooter<'_>, x: &[DVec3]) -> Vec<DVec3> {
    shooter.restart();
    shooter.add_emission(x, 1.0);
    shooter.shoot_each_once();
    shooter
        .radiosity()
        .iter()
        .zip(x)
        .map(|(b, x)| (*b - *x).max(DVec3::ZERO))
        .collect()
}

/// [`B1Pass::ClipCompensated`]: `B1 = B0 + K B*` with `B* = max(B0, K B*)`,
/// iterated from `B* = B0` until no element changes by more than 1e-6 of
/// the largest B0 or [`CLIP_ITERATIONS`]. `shooter` holds only the real
/// elements and already has `b0` added (non-real elements are zero in
/// `b0`). Returns B1 and the shots taken.
fn clip_compensated(shooter: &mut Shooter<'_>, b0: &[DVec3]) -> (Vec<DVec3>, usize) {
    clip_fixed_point(b0, |b| {
        let kb = one_bounce(shooter, b);
        (kb, shooter.shots())
    })
}

/// The fixed point of [`B1Pass::ClipCompensated`] for either solver:
/// `bounce(x)` returns `K x` and its work (shots or gathers); returns
/// `B1 = B0 + K B*` and the total work.
fn clip_fixed_point(
    b0: &[DVec3],
    mut bounce: impl FnMut(&[DVec3]) -> (Vec<DVec3>, usize),
) -> (Vec<DVec3>, usize) {
    let scale = b0.iter().map(|b| b.max_element()).fold(0.0, f64::max);
    let mut b = b0.to_vec();
    let (mut kb, mut work) = bounce(&b);
    for _ in 0..CLIP_ITERATIONS {
        let next: Vec<DVec3> = b0.iter().zip(&kb).map(|(b0, kb)| b0.max(*kb)).collect();
        let change = next
            .iter()
            .zip(&b)
            .map(|(n, b)| (*n - *b).abs().max_element())
            .fold(0.0, f64::max);
        b = next;
        let (k, w) = bounce(&b);
        kb = k;
        work += w;
        if !(change > 1e-6 * scale) {
            break;
        }
    }
    let b1 = b0.iter().zip(&kb).map(|(b0, kb)| *b0 + *kb).collect();
    (b1, work)
}

/// B2 per vertex of `mesh` with the real interreflection evaluated *at*
/// the vertices: `max(B0_v - rho E_v, 0)` on real vertices (0 elsewhere),
/// where `B0_v` is B0 averaged to the vertices
/// ([`RadiosityMesh::vertex_values`], the interpolated B0 the display
/// promises) and `E_v` is the irradiance that the real surfaces' B0 sends
/// to the vertex, gathered from the patches over the real geometry `real`
/// ([`gather_vertices`]: closed-form point-to-polygon form factors with
/// visibility rays).
///
/// Why: the real room adds its interreflection point by point, `K B(x)`,
/// but `B0 - B2 = K B0` of the element passes is an element average, and
/// averaged to a vertex it lies half an element inside at every edge and
/// corner, where the real interreflection changes fastest (a wall next
/// to a wall sees it at a form factor up to 1/2). Interpolated B2 then
/// misses the real interreflection there by a first-order amount; gathered
/// at the vertices it is right to second order in the element size. This
/// is the one-bounce rule of [`B1Pass::OneBounce`] (`B2 = (I - K) B0`)
/// evaluated at the vertices, so use it with that pass's `solution`.
pub fn gathered_b2_vertices(
    mesh: &RadiosityMesh,
    real: &SceneGeometry,
    solution: &AugmentedSolution,
    options: &GatherOptions,
) -> Vec<DVec3> {
    let is_real: Vec<DVec3> = mesh
        .elements
        .iter()
        .map(|e| if e.real { DVec3::ONE } else { DVec3::ZERO })
        .collect();
    let real_b0: Vec<DVec3> = solution
        .b0
        .iter()
        .zip(&is_real)
        .map(|(b, r)| *b * *r)
        .collect();
    let real_vertex = mesh.vertex_values(&is_real);
    let b0 = mesh.vertex_values(&solution.b0);
    // The gather returns emission + rho E at each vertex; only rho E is
    // the real room's interreflection.
    let emission =
        mesh.vertex_values(&mesh.elements.iter().map(|e| e.emission).collect::<Vec<_>>());
    let reflected: Vec<DVec3> = gather_vertices(mesh, &real_b0, mesh, real, &[], options)
        .iter()
        .zip(&emission)
        .map(|(g, e)| (*g - *e).max(DVec3::ZERO))
        .collect();
    b0.iter()
        .zip(&reflected)
        .zip(&real_vertex)
        .map(|((b0, kb), r)| {
            let v = (*b0 - *kb).max(DVec3::ZERO);
            if r.min_element() > 1.0 - 1e-9 && v.is_finite() {
                v
            } else {
                DVec3::ZERO
            }
        })
        .collect()
}

/// Sub-pixel points per side at which [`irradiance_map`] fits a pixel's
/// intensity (`MAP_SUBSAMPLES^2` rays per pixel).
pub const MAP_SUBSAMPLES: u32 = 4;

/// One sub-pixel point of an irradiance map: `(rho F, B2 / k)` per channel
/// at the first real front-facing surface through continuous pixel
/// coordinate `pixel` of `this`, or `None` where there is none.
fn map_sample(
    mesh: &RadiosityMesh,
    real: &SceneGeometry,
    all_projectors: &[DeviceRays],
    this: &DeviceRays,
    pixel: DVec2,
    b2_vertices: &[DVec3],
) -> Option<(DVec3, DVec3)> {
    let ray = this.ray_through(pixel)?;
    let hit = real.closest_hit(&ray, 0.0, f64::INFINITY)?;
    if !hit.front_face {
        return None;
    }
    let prim = mesh.primitive_of(hit.object, hit.triangle)?;
    let (e, _) = mesh.locate(prim, hit.barycentric)?;
    let b2 = mesh.interpolate(prim, hit.barycentric, b2_vertices)?;
    let rho = mesh.elements.get(e as usize)?.reflectance;
    let n = hit.geometric_normal;
    let cos = -n.dot(ray.direction);
    let f = cos / (hit.t * hit.t);
    let sharing = all_projectors
        .iter()
        .filter(|r| r.sees(real, hit.point, n))
        .count()
        .max(1) as f64;
    let rho_f = rho * f;
    (rho_f.is_finite() && b2.is_finite()).then_some((rho_f.max(DVec3::ZERO), b2 / sharing))
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
    let n = MAP_SUBSAMPLES.max(1);
    let pixels: Vec<Option<(Vec3, bool)>> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            // Least squares over the pixel's footprint: the projector pixel
            // sends one intensity I through its whole solid angle, which
            // makes exitance rho F I at each point it lights; pick the I
            // that minimises sum (rho F I - B2 / k)^2 over n x n
            // sub-pixel points (per channel).
            let (mut num, mut den) = (DVec3::ZERO, DVec3::ZERO);
            let mut hits = 0;
            for sub in 0..n * n {
                let offset = DVec2::new(
                    (f64::from(sub % n) + 0.5) / f64::from(n),
                    (f64::from(sub / n) + 0.5) / f64::from(n),
                );
                let Some(sample) = map_sample(
                    mesh,
                    real,
                    &rays,
                    this,
                    DVec2::new(f64::from(x), f64::from(y)) + offset,
                    b2_vertices,
                ) else {
                    continue;
                };
                hits += 1;
                let (rho_f, want) = sample;
                num += rho_f * want;
                den += rho_f * rho_f;
            }
            if hits == 0 {
                return None;
            }
            let mut clipped = false;
            let mut drive = DVec3::ZERO;
            for c in 0..3 {
                let d = if den[c] > RHO_F_FLOOR * RHO_F_FLOOR && eta > 0.0 {
                    (num[c] / den[c] - black) / eta
                } else {
                    if num[c] > 0.0 {
                        clipped = true;
                    }
                    0.0
                };
                let d = finite_or_zero(d);
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
