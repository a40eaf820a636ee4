//! Cube-map reflections (paper section 5.3), CPU reference: for each
//! reflective virtual object, six 90-degree faces of the *real*
//! environment seen from the centre of the object's bounding box. A texel
//! holds the radiance `rho / pi * E` of the first real surface along its
//! centre's direction, `rho` the surface's albedo (its procedural texture
//! where it has one) and `E` the virtual lights' irradiance with shadow
//! types 4 and 5 (phantoms and virtual objects occlude the lights) plus
//! the ambient term: the same direct-light model as the face view's
//! shading ([`super::projector::target_irradiance`]). Virtual objects are
//! not in the map (the paper reflects the real environment); a direction
//! that meets no real surface is 0.
//!
//! Faces follow [`crate::gpu::shadow_views::cube_views`] (+x, -x, +y, -y,
//! +z, -z, each `look_to_rh`), rows from the top, so the GPU pass draws
//! them with those views. A reflective surface of albedo `rho_m` seen
//! along `d` with normal `n` shows `rho_m * C(reflect(d, n))` (a mirror
//! tinted by its albedo, no diffuse term), where `C` is the map sampled
//! bilinearly between texel centres, clamped at the face's edges (no
//! filtering across faces) by [`CubeMap::sample`]; the GPU does the same.

use super::RenderSetupError;
use super::frame::FrameScene;
use super::projector::{Occluders, PixelState, target_irradiance};
use crate::light::{Image, Ray, RgbImage, world_matrix};
use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;
use showcase_proto::ObjectKind;

/// Default texels per side of a cube-map face.
pub const DEFAULT_CUBE_RES: u32 = 128;

/// Faces of a cube map.
pub const CUBE_FACES: usize = 6;

/// The world direction (not normalised) of the point `(right, up,
/// forward)` in `face`'s view: the inverse of
/// [`crate::gpu::shadow_views::cube_coords`].
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

/// [`crate::gpu::shadow_views::cube_coords`] in f64: the face holding
/// direction `d` and `d`'s `(right, up, forward)` in that face's view.
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
    /// What each texel sees: `object` and `primitive` of the real surface
    /// (`masked` where there is none), `lit` the light samples reaching
    /// it. Neighbours that differ mark silhouette and shadow edges.
    pub state: Vec<Image<PixelState>>,
}

impl CubeMap {
    /// Radiance along direction `d` from the centre: bilinear between the
    /// four nearest texel centres of `d`'s face, clamped at the face's
    /// edges (0 for a zero or non-finite `d`).
    pub fn sample(&self, d: DVec3) -> Vec3 {
        if !d.is_finite() || d == DVec3::ZERO {
            return Vec3::ZERO;
        }
        let (face, c) = world_to_face(d);
        let ndc = DVec2::new(c.x, c.y) / c.z;
        let res = f64::from(self.res);
        let fx = (ndc.x * 0.5 + 0.5) * res - 0.5;
        let fy = (0.5 - ndc.y * 0.5) * res - 0.5;
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = ((fx - x0) as f32, (fy - y0) as f32);
        let max = res - 1.0;
        let at = |x: f64, y: f64| {
            let (x, y) = (x.clamp(0.0, max) as u32, y.clamp(0.0, max) as u32);
            self.faces[face].get(x, y).copied().unwrap_or(Vec3::ZERO)
        };
        // `a + (b - a) t` is exactly `a` when the texels are equal (glam's
        // `lerp`, `a (1 - t) + b t`, can round past both).
        let mix = |a: Vec3, b: Vec3, t: f32| a + (b - a) * t;
        let top = mix(at(x0, y0), at(x0 + 1.0, y0), tx);
        let bottom = mix(at(x0, y0 + 1.0), at(x0 + 1.0, y0 + 1.0), tx);
        let v = mix(top, bottom, ty);
        if v.is_finite() { v } else { Vec3::ZERO }
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
    let mut state = Vec::with_capacity(CUBE_FACES);
    for face in 0..CUBE_FACES {
        let texels: Vec<(Vec3, PixelState)> = (0..res)
            .into_par_iter()
            .flat_map_iter(|y| {
                (0..res).map(move |x| {
                    environment(frame, occluders, centre, texel_direction(face, x, y, res))
                })
            })
            .collect();
        let (radiance, st): (Vec<Vec3>, Vec<PixelState>) = texels.into_iter().unzip();
        faces.push(Image {
            width: res,
            height: res,
            data: radiance,
        });
        state.push(Image {
            width: res,
            height: res,
            data: st,
        });
    }
    Ok(CubeMap {
        object,
        centre,
        res,
        faces,
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
    let masked = PixelState {
        masked: true,
        ..PixelState::default()
    };
    let Some(hit) = occluders
        .real_only
        .closest_hit(&Ray::new(from, dir), 0.0, f64::INFINITY)
    else {
        return (Vec3::ZERO, masked);
    };
    let Some(o) = frame.showcase.objects.get(hit.object as usize) else {
        return (Vec3::ZERO, masked);
    };
    let object = Some(hit.object);
    if hit.geometric_normal == DVec3::ZERO {
        return (Vec3::ZERO, PixelState { object, ..masked });
    }
    let facing = if hit.geometric_normal.dot(dir) <= 0.0 {
        hit.geometric_normal
    } else {
        -hit.geometric_normal
    };
    let (e, lit) = target_irradiance(frame, occluders, hit.point, facing);
    let rho = o
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    let l = rho / std::f64::consts::PI * e;
    (
        if l.is_finite() {
            l.as_vec3()
        } else {
            Vec3::ZERO
        },
        PixelState {
            object,
            primitive: Some(hit.primitive),
            lit,
            ..PixelState::default()
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_coordinates_round_trip() {
        for face in 0..CUBE_FACES {
            for (x, y) in [(0, 0), (3, 7), (7, 0), (5, 5)] {
                let d = texel_direction(face, x, y, 8);
                let (f, c) = world_to_face(d);
                assert_eq!(f, face, "{face} {x} {y} -> {d}");
                let ndc = DVec2::new(c.x, c.y) / c.z;
                let tx = ((ndc.x * 0.5 + 0.5) * 8.0).floor() as u32;
                let ty = ((0.5 - ndc.y * 0.5) * 8.0).floor() as u32;
                assert_eq!((tx, ty), (x, y), "face {face}");
            }
        }
    }

    #[test]
    fn faces_match_the_shadow_cube_views() {
        // The texel's direction projects into the same texel through the
        // GPU pass's view matrices.
        let views = crate::gpu::shadow_views::cube_views(glam::Vec3::ZERO, 0.01, 10.0, 8);
        for (face, v) in views.iter().enumerate() {
            let m = glam::Mat4::from_cols_array_2d(&v.clip_from_world);
            let d = texel_direction(face, 2, 5, 8).as_vec3();
            let c = m * d.extend(1.0);
            let ndc = glam::Vec2::new(c.x, c.y) / c.w;
            let tx = ((ndc.x * 0.5 + 0.5) * 8.0).floor() as u32;
            let ty = ((0.5 - ndc.y * 0.5) * 8.0).floor() as u32;
            assert!(c.w > 0.0 && (tx, ty) == (2, 5), "face {face}: {ndc}");
        }
    }

    #[test]
    fn sampling_interpolates_between_texel_centres_and_clamps() {
        let mut faces = vec![Image::new(2, 2, Vec3::ZERO); CUBE_FACES];
        faces[4].data = vec![Vec3::ZERO, Vec3::ONE, Vec3::ZERO, Vec3::ONE];
        let map = CubeMap {
            object: 0,
            centre: DVec3::ZERO,
            res: 2,
            faces,
            state: vec![Image::new(2, 2, PixelState::default()); CUBE_FACES],
        };
        // +z face: right is -x. Straight ahead lies between the columns.
        assert!((map.sample(DVec3::Z).x - 0.5).abs() < 1e-6);
        // Beyond the outer texel centres the value is clamped.
        assert_eq!(map.sample(DVec3::new(0.9, 0.0, 1.0)).x, 0.0);
        assert_eq!(map.sample(DVec3::new(-0.9, 0.0, 1.0)).x, 1.0);
        assert_eq!(map.sample(DVec3::ZERO), Vec3::ZERO);
        assert_eq!(map.sample(DVec3::NAN), Vec3::ZERO);
    }

    proptest::proptest! {
        #[test]
        fn sampling_any_direction_is_finite(
            x in proptest::num::f64::ANY,
            y in proptest::num::f64::ANY,
            z in proptest::num::f64::ANY,
        ) {
            let map = CubeMap {
                object: 0,
                centre: DVec3::ZERO,
                res: 3,
                faces: (0..CUBE_FACES).map(|f| Image::new(3, 3, Vec3::splat(f as f32))).collect(),
                state: vec![Image::new(3, 3, PixelState::default()); CUBE_FACES],
            };
            let v = map.sample(DVec3::new(x, y, z));
            proptest::prop_assert!(v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 5.0);
        }
    }

    #[test]
    fn reflection_mirrors_the_normal_component() {
        let r = reflect(DVec3::new(1.0, -1.0, 0.0), DVec3::Y);
        assert_eq!(r, DVec3::new(1.0, 1.0, 0.0));
    }
}
