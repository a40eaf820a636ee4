//! End-to-end consistency on the simulated showcase:
//! every projector shows its irradiance map through the sim's projector
//! model onto the *real* geometry only, the sim path-traces the light
//! (with its own interreflection between the real surfaces, independent of
//! our radiosity solver), and a camera compares the radiance it sees with
//! the radiance B0 / pi that augmented radiosity promised there.
//!
//! `consistency_rel_rmse` is the relative RMSE (rmse / mean of B0, all
//! channels) over the camera pixels that see a real front face lit by at
//! least one projector through an unclipped pixel of its map, on an
//! element whose B2 was not clipped (where B2 = 2 B0 - B1 fell below zero
//! the real interreflection alone exceeds B0 and no projector can take
//! light away), and not across an edge from the projector pixel's centre
//! (a mixed pixel carries the other surface's drive).

use anyhow::Context;
use glam::{DVec3, Vec3};
use showcase_light::finite::finite_or_zero;
use showcase_light::metrics::relative_rmse_values;
use showcase_light::radiosity::{IrradianceMap, RadiosityMesh};
use showcase_light::sim::devices::projector_intensity;
use showcase_light::sim::{ProjectorLight, SimWorld};
use showcase_light::{DeviceRays, Image, ObjectFilter, SceneGeometry};
use showcase_proto::{PinholeDevice, Showcase};

/// The consistency figure and what it was taken over.
#[derive(Clone, Debug, PartialEq)]
pub struct Consistency {
    /// rmse / mean(B0) over the compared pixels.
    pub rel_rmse: f64,
    /// Camera pixels compared.
    pub pixels: usize,
    /// Camera pixels that see a real front face.
    pub real_pixels: usize,
    /// The same over the projectors' direct light alone against B2: how
    /// well the maps reproduce their target before interreflection.
    pub direct_rel_rmse: f64,
    /// Sum of the sim's B over the sum of B0 (all channels, compared
    /// pixels): the overall level.
    pub level: f64,
    /// The sim's interreflected light alone (two or more bounces) against
    /// what augmented radiosity left to the real room, `B0 - B2`, as
    /// rmse / mean(B0): the indirect share of `rel_rmse`.
    pub indirect_rel_rmse: f64,
    /// The same figures per real object (surface), each as rmse over that
    /// object's pixels / the mean B0 of all compared pixels, so that the
    /// pixel-weighted squares add up to the overall figures'.
    pub per_object: Vec<SurfaceConsistency>,
}

/// [`Consistency`] on one real object.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceConsistency {
    /// Index into `Showcase::objects`.
    pub object: u32,
    /// Camera pixels compared on it.
    pub pixels: usize,
    /// rmse there / mean B0 overall.
    pub rel_rmse: f64,
    /// Direct light against B2: rmse there / mean B0 overall.
    pub direct_rel_rmse: f64,
    /// Interreflection against `B0 - B2`: rmse there / mean B0 overall.
    pub indirect_rel_rmse: f64,
    /// Sum of the sim's B over the sum of B0 there.
    pub level: f64,
}

/// What augmented radiosity promised, on the mesh the maps were made from.
#[derive(Clone, Copy, Debug)]
pub struct Promise<'a> {
    /// The solution mesh.
    pub mesh: &'a RadiosityMesh,
    /// Geometry of the real objects.
    pub real: &'a SceneGeometry,
    /// B0 per vertex of `mesh`: what the camera should see (times pi).
    pub b0_vertices: &'a [DVec3],
    /// B2 per vertex: the maps' target for the projectors' direct light.
    pub b2_vertices: &'a [DVec3],
    /// Per element of `mesh`: B2 was not clipped there.
    pub unclipped: &'a [bool],
}

/// Show `maps` (one per projector of `scene`) in the sim, look with
/// `camera` (`samples` paths per pixel) and compare with the promise's B0;
/// the direct light alone is compared with its B2. Only unclipped
/// elements count.
pub fn consistency(
    scene: &Showcase,
    promise: &Promise<'_>,
    maps: &[IrradianceMap],
    camera: &PinholeDevice,
    samples: u32,
) -> anyhow::Result<Consistency> {
    consistency_seeded(scene, promise, maps, camera, samples, 17)
}

/// [`consistency`] with the sim's random seed `seed` (two seeds measure
/// the path tracer's noise).
pub fn consistency_seeded(
    scene: &Showcase,
    promise: &Promise<'_>,
    maps: &[IrradianceMap],
    camera: &PinholeDevice,
    samples: u32,
    seed: u64,
) -> anyhow::Result<Consistency> {
    anyhow::ensure!(
        maps.len() == scene.projectors.len(),
        "{} maps for {} projectors",
        maps.len(),
        scene.projectors.len()
    );
    let Promise {
        mesh,
        real,
        b0_vertices,
        b2_vertices,
        unclipped,
    } = *promise;
    let world = SimWorld::new(scene, &ObjectFilter::Real, false).context("sim world")?;
    let camera_rays = DeviceRays::new(camera)?;
    let (w, h) = (camera.width, camera.height);
    let mut radiance = vec![DVec3::ZERO; (w * h) as usize];
    let mut direct = vec![DVec3::ZERO; (w * h) as usize];
    let mut projector_rays = Vec::new();
    for (p, map) in scene.projectors.iter().zip(maps) {
        let rays = DeviceRays::new(&p.device)?;
        // The map is linear drive; the device applies its gamma, so send
        // drive^(1/gamma) to get eta * drive + black out.
        let gamma = if p.response.gamma.is_finite() && p.response.gamma > 0.0 {
            p.response.gamma
        } else {
            1.0
        };
        let intensity = Image {
            width: map.drive.width,
            height: map.drive.height,
            data: map
                .drive
                .data
                .iter()
                .map(|d| projector_intensity(&p.response, d.max(Vec3::ZERO).powf(1.0 / gamma)))
                .collect(),
        };
        let light = ProjectorLight::new(rays.clone(), intensity).context("sim projector")?;
        let image = world.render(
            &camera_rays,
            &showcase_light::sim::SimLights::projectors([&light]),
            samples,
            seed,
        );
        for (r, v) in radiance.iter_mut().zip(&image.total().data) {
            *r += v.as_dvec3();
        }
        for (r, v) in direct.iter_mut().zip(&image.direct.data) {
            *r += v.as_dvec3();
        }
        projector_rays.push(rays);
    }
    let (mut test, mut reference) = (Vec::new(), Vec::new());
    let (mut direct_test, mut direct_reference) = (Vec::new(), Vec::new());
    let (mut indirect_test, mut indirect_reference) = (Vec::new(), Vec::new());
    let mut objects = Vec::new();
    let mut real_pixels = 0;
    for i in 0..w * h {
        let Some(ray) = camera_rays.pixel_ray(i % w, i / w) else {
            continue;
        };
        let Some(hit) = real.closest_hit(&ray, 0.0, f64::INFINITY) else {
            continue;
        };
        if !hit.front_face {
            continue;
        }
        let Some(prim) = mesh.primitive_of(hit.object, hit.triangle) else {
            continue;
        };
        let (Some(b0), Some(b2)) = (
            mesh.interpolate(prim, hit.barycentric, b0_vertices),
            mesh.interpolate(prim, hit.barycentric, b2_vertices),
        ) else {
            continue;
        };
        real_pixels += 1;
        let element_ok = mesh
            .locate(prim, hit.barycentric)
            .is_some_and(|(e, _)| unclipped.get(e as usize).copied().unwrap_or(false));
        if !element_ok {
            continue;
        }
        let n = hit.geometric_normal;
        let mut lit = false;
        let mut clipped = false;
        for (rays, map) in projector_rays.iter().zip(maps) {
            if !rays.sees(real, hit.point, n) {
                continue;
            }
            let Some((x, y)) = rays.pixel_of(hit.point) else {
                continue;
            };
            // A projector pixel whose centre lands on another surface
            // (across an edge) carries that surface's drive: such mixed
            // pixels are skipped like clipped ones.
            let same_surface = rays
                .pixel_ray(x, y)
                .and_then(|r| real.closest_hit(&r, 0.0, f64::INFINITY))
                .is_some_and(|h| h.object == hit.object && h.geometric_normal.dot(n) > 0.999);
            clipped |= !same_surface;
            lit |= map.mask.get(x, y).copied().unwrap_or(false);
            clipped |= map.clipped_mask.get(x, y).copied().unwrap_or(true);
        }
        if !lit || clipped {
            continue;
        }
        let sim = radiance[i as usize] * std::f64::consts::PI;
        let sim_direct = direct[i as usize] * std::f64::consts::PI;
        objects.push(hit.object);
        for c in 0..3 {
            test.push(sim[c]);
            reference.push(b0[c]);
            direct_test.push(sim_direct[c]);
            direct_reference.push(b2[c]);
            indirect_test.push(sim[c] - sim_direct[c]);
            indirect_reference.push(b0[c] - b2[c]);
        }
    }
    let rel_rmse = relative_rmse_values(&test, &reference, None)?;
    let direct_rel_rmse = relative_rmse_values(&direct_test, &direct_reference, None)?;
    let mean_b0 = reference.iter().sum::<f64>() / reference.len().max(1) as f64;
    let indirect_sq: f64 = indirect_test
        .iter()
        .zip(&indirect_reference)
        .map(|(t, r)| (t - r) * (t - r))
        .sum();
    let indirect_rel_rmse = (indirect_sq / indirect_test.len().max(1) as f64).sqrt() / mean_b0;
    let mut ids = objects.clone();
    ids.sort_unstable();
    ids.dedup();
    let rms_over = |t: &[f64], r: &[f64], object: u32| -> f64 {
        let (mut sq, mut n) = (0.0, 0usize);
        for (k, o) in objects.iter().enumerate() {
            if *o == object {
                for c in 0..3 {
                    let d = t[3 * k + c] - r[3 * k + c];
                    sq += d * d;
                    n += 1;
                }
            }
        }
        let v = (sq / n.max(1) as f64).sqrt() / mean_b0;
        finite_or_zero(v)
    };
    let per_object = ids
        .iter()
        .map(|&object| {
            let (mut st, mut sr) = (0.0, 0.0);
            for (k, o) in objects.iter().enumerate() {
                if *o == object {
                    st += test[3 * k..3 * k + 3].iter().sum::<f64>();
                    sr += reference[3 * k..3 * k + 3].iter().sum::<f64>();
                }
            }
            let level = st / sr;
            SurfaceConsistency {
                object,
                pixels: objects.iter().filter(|o| **o == object).count(),
                rel_rmse: rms_over(&test, &reference, object),
                direct_rel_rmse: rms_over(&direct_test, &direct_reference, object),
                indirect_rel_rmse: rms_over(&indirect_test, &indirect_reference, object),
                level: finite_or_zero(level),
            }
        })
        .collect();
    let level = test.iter().sum::<f64>() / reference.iter().sum::<f64>();
    Ok(Consistency {
        rel_rmse,
        pixels: test.len() / 3,
        real_pixels,
        direct_rel_rmse,
        level: finite_or_zero(level),
        indirect_rel_rmse: finite_or_zero(indirect_rel_rmse),
        per_object,
    })
}

/// The observer's camera of the figure-3 scene: beside the projector in
/// front of the open side, looking in.
pub fn figure3_camera() -> PinholeDevice {
    PinholeDevice::look_at(
        DVec3::new(0.25, 0.3, -0.85),
        DVec3::new(0.278, 0.274, 0.28),
        DVec3::Y,
        42.0,
        96,
        72,
    )
}
