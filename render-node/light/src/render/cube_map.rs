//! Cube-map reflections (paper section 5.3), CPU reference: for each
//! reflective virtual object, six 90-degree faces of the *real*
//! environment seen from the centre of the object's bounding box. A texel
//! holds the radiance `rho / pi * E` of the first real surface along its
//! centre's direction, and that surface's distance from the centre
//! ([`NO_SURFACE_DISTANCE`] where there is none), `rho` the surface's albedo (its procedural texture
//! where it has one) and `E` the virtual lights' irradiance with shadow
//! types 4 and 5 (phantoms and virtual objects occlude the lights) plus
//! the ambient term: the same direct-light model as the face view's
//! shading ([`super::projector::target_irradiance`]), and in global mode
//! ([`super::FrameScene::indirect`]) all the surface's indirect light
//! (`add + cabinet`: in the target a real surface shows both). Virtual objects are
//! not in the map (the paper reflects the real environment); a direction
//! that meets no real surface is 0.
//!
//! Faces follow `showcase_render::gpu::shadow_views::cube_views` (+x, -x, +y, -y,
//! +z, -z, each `look_to_rh`), rows from the top, so the GPU pass draws
//! them with those views. A reflective surface of albedo `rho_m` seen
//! along `d` with normal `n` at point `p` shows `rho_m * C(p, reflect(d,
//! n))` (a mirror tinted by its albedo, no diffuse term). `C` is the
//! *distance-corrected* lookup of distance impostors (Szirmay-Kalos et al.
//! 2005, "Approximate ray-tracing on the GPU with distance impostors";
//! beyond the paper, whose lookup along `r` is exact at the centre only):
//! [`CubeMap::reflection_direction`] finds the point `x = p + t r` whose
//! distance from the centre equals the stored distance along `x - c`,
//! with [`PARALLAX_LINEAR_STEPS`] steps of a linear search and
//! [`PARALLAX_SECANT_STEPS`] secant steps (fixed counts, as on the GPU),
//! and the radiance is read along `x - c` (0 where the search ends on a
//! silhouette seen from the centre). For a planar surface the ratio
//! `|x - c| / D(x - c)` is linear in `t`, so one secant step lands on it
//! up to the distances' interpolation error. Radiance and distance are
//! sampled bilinearly between texel centres, clamped at the face's edges
//! (no filtering across faces) by [`CubeMap::sample`] and
//! [`CubeMap::distance_along`]; the GPU (`face_view.wgsl`) does the same.

use super::RenderSetupError;
use super::frame::FrameScene;
use super::projector::{Occluders, PixelState, target_irradiance};
use crate::finite::{finite_or, finite_or_zero};
use crate::{Image, Ray, RgbImage, world_matrix};
use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;
use showcase_proto::ObjectKind;

/// Default texels per side of a cube-map face.
pub const DEFAULT_CUBE_RES: u32 = 128;

/// Faces of a cube map.
pub const CUBE_FACES: usize = 6;

/// Distance (metres) a texel holds where its direction meets no real
/// surface: far beyond any showcase, so that the lookup treats it as the
/// environment at infinity (the GPU pass clears to it).
pub const NO_SURFACE_DISTANCE: f32 = 1.0e6;

/// Linear-search steps of the distance-corrected lookup (module docs);
/// `face_view.wgsl` has the same constant.
pub const PARALLAX_LINEAR_STEPS: u32 = 8;

/// Relative mismatch `|x - c| / D(x - c) - 1` above which the lookup's end
/// point is not on a stored surface but on a jump of the stored distance
/// (a silhouette seen from the centre); `face_view.wgsl` has the same
/// constant.
pub const PARALLAX_SURFACE_TOLERANCE: f64 = 0.05;

/// Secant steps of the distance-corrected lookup after the linear search;
/// `face_view.wgsl` has the same constant.
pub const PARALLAX_SECANT_STEPS: u32 = 4;

/// The world direction (not normalised) of the point `(right, up,
/// forward)` in `face`'s view: the inverse of [`world_to_face`].
pub fn face_to_world(face: usize, c: DVec3) -> DVec3 {
    match face {
        0 => DVec3::new(c.z, c.y, c.x),
        1 => DVec3::new(-c.z, c.y, -c.x),
        2 => DVec3::new(c.x, c.z, c.y),
        3 => DVec3::new(-c.x, -c.z, c.y),
        4 => DVec3::new(-c.x, c.y, c.z),
        _ => DVec3::new(c.x, c.y, -c.z),
    }
}

/// Cube-face selection, its one home in Rust: the face (0 to 5: +x, -x,
/// +y, -y, +z, -z, the order of the GPU's cube views) holding direction
/// `d`, and `d`'s `(right, up, forward)` components in that face's view.
/// The major axis picks the face and the view's axes are a signed
/// permutation of `d`, so f32 callers lose nothing by converting. Mirrors
/// WGSL `cube_face` in `shadow_lookup.part.wgsl`.
pub fn world_to_face(d: DVec3) -> (usize, DVec3) {
    let a = d.abs();
    if a.x >= a.y && a.x >= a.z {
        if d.x > 0.0 {
            (0, DVec3::new(d.z, d.y, d.x))
        } else {
            (1, DVec3::new(-d.z, d.y, -d.x))
        }
    } else if a.y >= a.z {
        if d.y > 0.0 {
            (2, DVec3::new(d.x, d.z, d.y))
        } else {
            (3, DVec3::new(-d.x, d.z, -d.y))
        }
    } else if d.z > 0.0 {
        (4, DVec3::new(-d.x, d.y, d.z))
    } else {
        (5, DVec3::new(d.x, d.y, -d.z))
    }
}

/// Unit direction through the centre of texel `(x, y)` of `face` at
/// `res` texels per side (row 0 at the top, as the GPU draws it).
pub fn texel_direction(face: usize, x: u32, y: u32, res: u32) -> DVec3 {
    let res = f64::from(res.max(1));
    let ndc = DVec2::new(
        (f64::from(x) + 0.5) / res * 2.0 - 1.0,
        1.0 - (f64::from(y) + 0.5) / res * 2.0,
    );
    face_to_world(face, ndc.extend(1.0)).normalize()
}

/// Mirror direction `d` about unit normal `n`.
pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// One object's cube map.
#[derive(Clone, Debug)]
pub struct CubeMap {
    /// The reflective object (index into `Showcase::objects`).
    pub object: usize,
    /// Centre of the object's world bounding box: the maps' origin.
    pub centre: DVec3,
    /// Texels per side.
    pub res: u32,
    /// Radiance per face ([`CUBE_FACES`] of them, module docs' order).
    pub faces: Vec<RgbImage>,
    /// Distance (metres) from `centre` to the first real surface along
    /// each texel's direction, per face ([`NO_SURFACE_DISTANCE`] where
    /// there is none).
    pub distance: Vec<Image<f32>>,
    /// What each texel sees: `object` and `primitive` of the real surface
    /// (`masked` where there is none), `lit` the light samples reaching
    /// it. Neighbours that differ mark silhouette and shadow edges.
    pub state: Vec<Image<PixelState>>,
}

/// Where a bilinear lookup along a direction reads: the face, the four
/// texels (`x0, y0, x1, y1`, clamped to the face) and the weights.
#[derive(Clone, Copy, Debug)]
struct Bilinear {
    face: usize,
    x: [u32; 2],
    y: [u32; 2],
    t: DVec2,
}

impl Bilinear {
    /// The texels around direction `d` at `res` texels per side; `None`
    /// for a zero or non-finite `d`.
    fn new(d: DVec3, res: u32) -> Option<Self> {
        if !d.is_finite() || d == DVec3::ZERO {
            return None;
        }
        let (face, c) = world_to_face(d);
        if !(c.z > 0.0) {
            return None;
        }
        let ndc = DVec2::new(c.x, c.y) / c.z;
        let res = f64::from(res.max(1));
        let f = DVec2::new(
            (ndc.x * 0.5 + 0.5) * res - 0.5,
            (0.5 - ndc.y * 0.5) * res - 0.5,
        );
        let f0 = f.floor();
        let max = res - 1.0;
        let at = |v: f64| v.clamp(0.0, max) as u32;
        Some(Self {
            face,
            x: [at(f0.x), at(f0.x + 1.0)],
            y: [at(f0.y), at(f0.y + 1.0)],
            t: f - f0,
        })
    }
}

impl CubeMap {
    /// Radiance along direction `d` from the centre: bilinear between the
    /// four nearest texel centres of `d`'s face, clamped at the face's
    /// edges (0 for a zero or non-finite `d`).
    pub fn sample(&self, d: DVec3) -> Vec3 {
        let Some(b) = Bilinear::new(d, self.res) else {
            return Vec3::ZERO;
        };
        let at = |i: usize, j: usize| {
            self.faces
                .get(b.face)
                .and_then(|f| f.get(b.x[i], b.y[j]))
                .copied()
                .unwrap_or(Vec3::ZERO)
        };
        // `a + (b - a) t` is exactly `a` when the texels are equal (glam's
        // `lerp`, `a (1 - t) + b t`, can round past both).
        let mix = |a: Vec3, b: Vec3, t: f64| a + (b - a) * t as f32;
        let top = mix(at(0, 0), at(1, 0), b.t.x);
        let bottom = mix(at(0, 1), at(1, 1), b.t.x);
        let v = mix(top, bottom, b.t.y);
        finite_or_zero(v)
    }

    /// Distance from the centre to the real surface along direction `d`,
    /// bilinear like [`Self::sample`]; [`NO_SURFACE_DISTANCE`] for a zero
    /// or non-finite `d`.
    pub fn distance_along(&self, d: DVec3) -> f64 {
        let none = f64::from(NO_SURFACE_DISTANCE);
        let Some(b) = Bilinear::new(d, self.res) else {
            return none;
        };
        let at = |i: usize, j: usize| {
            self.distance
                .get(b.face)
                .and_then(|f| f.get(b.x[i], b.y[j]))
                .map_or(none, |v| f64::from(*v))
        };
        let mix = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let top = mix(at(0, 0), at(1, 0), b.t.x);
        let bottom = mix(at(0, 1), at(1, 1), b.t.x);
        let v = mix(top, bottom, b.t.y);
        if v.is_finite() && v > 0.0 { v } else { none }
    }

    /// The direction from the centre along which a mirror at `p`
    /// reflecting along unit `r` sees the stored environment (module docs):
    /// `x - c` for the point `x = p + t r` at the stored distance, found by
    /// [`PARALLAX_LINEAR_STEPS`] linear-search steps over `t = s a / (1 -
    /// a)`, `a = i / (steps + 1)` (`s` the stored distance along `r`, so
    /// that the search is centred on the single-centre estimate, or along
    /// the bisector of `p - c` and `r` where that is nearer), then
    /// [`PARALLAX_SECANT_STEPS`] secant steps on `q(t) = |x - c| / D(x -
    /// c) - 1`. Where nothing real is stored, [`NO_SURFACE_DISTANCE`]
    /// acts as a sphere at infinity and the direction is `r` up to `|p -
    /// c| / NO_SURFACE_DISTANCE`; `r` itself where the search finds no
    /// surface (or for a zero or non-finite input). Zero (radiance 0)
    /// where the search ends on a jump of the stored distance rather than
    /// on a surface (`|x - c| / D(x - c)` off 1 by more than
    /// [`PARALLAX_SURFACE_TOLERANCE`]): the ray passes a silhouette seen
    /// from the centre, such as an open room's edge, behind which the map
    /// knows nothing; it is taken to escape.
    pub fn reflection_direction(&self, p: DVec3, r: DVec3) -> DVec3 {
        let o = p - self.centre;
        if !o.is_finite() || !r.is_finite() || r == DVec3::ZERO {
            return r;
        }
        // q + 1 at parameter t: the point's distance over the stored one.
        let ratio = |t: f64| {
            let x = o + t * r;
            x.length() / self.distance_along(x)
        };
        // The search's scale: the stored distance along r, or along the
        // bisector of o and r where that is nearer (r from the centre may
        // pass an edge that the ray from p meets).
        let scale = self
            .distance_along(r)
            .min(self.distance_along(o.normalize_or_zero() + r));
        let (mut t_under, mut q_under) = (0.0, ratio(0.0));
        let (mut t_over, mut q_over) = (0.0, 0.0);
        let mut found = false;
        let steps = f64::from(PARALLAX_LINEAR_STEPS + 1);
        for i in 1..=PARALLAX_LINEAR_STEPS {
            let a = f64::from(i) / steps;
            let t = scale * a / (1.0 - a);
            let q = ratio(t);
            let over = !found && q >= 1.0;
            if over {
                (t_over, q_over) = (t, q);
            } else if !found {
                (t_under, q_under) = (t, q);
            }
            found = found || over;
        }
        if !found {
            return r;
        }
        let secant = |t_under: f64, q_under: f64, t_over: f64, q_over: f64| {
            let w = (1.0 - q_under) / (q_over - q_under);
            let w = finite_or_zero(w).clamp(0.0, 1.0);
            t_under + (t_over - t_under) * w
        };
        for _ in 0..PARALLAX_SECANT_STEPS {
            let t = secant(t_under, q_under, t_over, q_over);
            let q = ratio(t);
            if q < 1.0 {
                (t_under, q_under) = (t, q);
            } else {
                (t_over, q_over) = (t, q);
            }
        }
        let x = o + secant(t_under, q_under, t_over, q_over) * r;
        if !(x.is_finite() && x != DVec3::ZERO) {
            return r;
        }
        // The search ends on a jump of the stored distance instead of a
        // surface: the ray passes a silhouette seen from the centre
        // (behind it the map knows nothing): nothing real is seen.
        let q = x.length() / self.distance_along(x);
        if (q - 1.0).abs() > PARALLAX_SURFACE_TOLERANCE {
            return DVec3::ZERO;
        }
        x
    }

    /// Radiance a mirror at `p` reflecting along unit `r` shows: the map
    /// along [`Self::reflection_direction`].
    pub fn reflection(&self, p: DVec3, r: DVec3) -> Vec3 {
        self.sample(self.reflection_direction(p, r))
    }
}

/// The reflective virtual objects of `frame` with at least one triangle,
/// and the centres of their world bounding boxes, in object order.
pub fn reflective_centres(frame: &FrameScene) -> Vec<(usize, DVec3)> {
    let s = &frame.showcase;
    s.objects
        .iter()
        .enumerate()
        .filter(|(_, o)| o.kind == ObjectKind::Virtual && o.material.reflective)
        .filter_map(|(i, o)| {
            let mesh = s.mesh(&o.mesh)?;
            let m = world_matrix(&o.transform)?;
            if mesh.triangles.is_empty() {
                return None;
            }
            let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
            for t in &mesh.triangles {
                for &v in t {
                    let p = m.transform_point3(mesh.positions.get(v as usize)?.as_dvec3());
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
            let c = 0.5 * (lo + hi);
            c.is_finite().then_some((i, c))
        })
        .collect()
}

/// Render the cube map of `object` around `centre` at `res` texels per
/// side on the CPU (module docs).
pub fn cube_map_cpu(
    frame: &FrameScene,
    occluders: &Occluders,
    object: usize,
    centre: DVec3,
    res: u32,
) -> Result<CubeMap, RenderSetupError> {
    if !centre.is_finite() {
        return Err(RenderSetupError::NonFinite);
    }
    let res = res.max(1);
    let mut faces = Vec::with_capacity(CUBE_FACES);
    let mut distance = Vec::with_capacity(CUBE_FACES);
    let mut state = Vec::with_capacity(CUBE_FACES);
    fn image<T>(res: u32, data: Vec<T>) -> Image<T> {
        Image {
            width: res,
            height: res,
            data,
        }
    }
    for face in 0..CUBE_FACES {
        let texels: Vec<EnvironmentHit> = (0..res)
            .into_par_iter()
            .flat_map_iter(|y| {
                (0..res).map(move |x| {
                    environment_hit(frame, occluders, centre, texel_direction(face, x, y, res))
                })
            })
            .collect();
        faces.push(image(res, texels.iter().map(|t| t.radiance).collect()));
        distance.push(image(res, texels.iter().map(|t| t.distance).collect()));
        state.push(image(res, texels.into_iter().map(|t| t.state).collect()));
    }
    Ok(CubeMap {
        object,
        centre,
        res,
        faces,
        distance,
        state,
    })
}

/// The cube maps of every reflective virtual object of `frame`.
pub fn cube_maps_cpu(
    frame: &FrameScene,
    occluders: &Occluders,
    res: u32,
) -> Result<Vec<CubeMap>, RenderSetupError> {
    reflective_centres(frame)
        .into_iter()
        .map(|(object, centre)| cube_map_cpu(frame, occluders, object, centre, res))
        .collect()
}

/// Radiance of the first real surface from `from` along unit `dir` (the
/// model a texel holds), and that surface's state.
pub fn environment(
    frame: &FrameScene,
    occluders: &Occluders,
    from: DVec3,
    dir: DVec3,
) -> (Vec3, PixelState) {
    let hit = environment_hit(frame, occluders, from, dir);
    (hit.radiance, hit.state)
}

/// What a texel holds: [`environment`]'s radiance and state, and the
/// surface's distance along the ray.
struct EnvironmentHit {
    radiance: Vec3,
    distance: f32,
    state: PixelState,
}

fn environment_hit(
    frame: &FrameScene,
    occluders: &Occluders,
    from: DVec3,
    dir: DVec3,
) -> EnvironmentHit {
    let none = |state| EnvironmentHit {
        radiance: Vec3::ZERO,
        distance: NO_SURFACE_DISTANCE,
        state,
    };
    let masked = PixelState {
        masked: true,
        ..PixelState::default()
    };
    let Some(hit) = occluders
        .real_only
        .closest_hit(&Ray::new(from, dir), 0.0, f64::INFINITY)
    else {
        return none(masked);
    };
    let Some(o) = frame.showcase.objects.get(hit.object as usize) else {
        return none(masked);
    };
    let object = Some(hit.object);
    let distance = (hit.point - from).length() as f32;
    if hit.geometric_normal == DVec3::ZERO {
        return EnvironmentHit {
            distance,
            ..none(PixelState { object, ..masked })
        };
    }
    let facing = hit.facing_normal(dir);
    let (mut e, lit) = target_irradiance(frame, occluders, hit.point, facing);
    if let Some(field) = &frame.indirect {
        // Global mode: all the real surface's indirect light, what the
        // projectors add and what the real surfaces bring each other.
        let f = field.at(&hit);
        e += f.add + f.cabinet;
    }
    let rho = o
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    let l = rho / std::f64::consts::PI * e;
    EnvironmentHit {
        radiance: finite_or_zero(l).as_vec3(),
        distance: finite_or(distance, NO_SURFACE_DISTANCE),
        state: PixelState {
            object,
            primitive: Some(hit.primitive),
            lit,
            ..PixelState::default()
        },
    }
}

#[cfg(test)]
mod tests;
