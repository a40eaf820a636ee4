//! Ground-truth figures of a projector calibration in the simulated
//! showcase, one metric for every method: held-out 3D points where the
//! true projector's light lands on the scene, projected through the fitted
//! and through the true projector, their pixel distance's RMS. And the
//! bench records of `bench calibration` on the showcase's own projectors:
//! structured light beside the simulated hand marking (LM and Powell).

use super::{StructuredLightOptions, calibrate_structured_light};
use crate::calibrate::bench::{BenchRecord, Source, time_per_call};
use crate::calibrate::{
    BENCH_SEEDS, CalibrateOptions, Calibration, HELDOUT_POINTS, Method, calibrate, fiducial_rig,
    heldout_rms, rotation_angle_deg, simulate_fiducials,
};
use glam::{DVec2, DVec3};
use showcase_light::metrics::percentile;
use showcase_light::sampling::{hash64, unit};
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{DeviceRays, ObjectFilter, SceneGeometry};
use showcase_proto::{PinholeDevice, Showcase};
use std::time::Instant;

/// Up to `count` points where the rays of `truth` through jittered pixels
/// of a regular grid over its image first meet `geometry`: the surface the
/// projector lights (seeded, reproducible).
pub fn surface_points(
    truth: &PinholeDevice,
    geometry: &SceneGeometry,
    count: usize,
    seed: u64,
) -> Vec<DVec3> {
    let Ok(rays) = DeviceRays::new(truth) else {
        return Vec::new();
    };
    let (w, h) = (truth.width as f64, truth.height as f64);
    let nx = ((count as f64 * w / h).sqrt().ceil() as usize).max(1);
    let ny = count.div_ceil(nx).max(1);
    let mut out = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let k = (j * nx + i) as u64;
            let jitter = DVec2::new(
                unit(hash64(seed ^ (2 * k))),
                unit(hash64(seed ^ (2 * k + 1))),
            );
            let p = (DVec2::new(i as f64, j as f64) + jitter)
                * DVec2::new(w / nx as f64, h / ny as f64);
            if let Some(hit) = rays
                .ray_through(p)
                .and_then(|r| geometry.closest_hit(&r, 0.0, f64::INFINITY))
            {
                out.push(hit.point);
            }
        }
    }
    out
}

/// RMS pixel distance between `calibration`'s and `truth`'s projections
/// of `points` (a point behind either counts as infinitely far).
pub fn true_rms(calibration: &Calibration, truth: &PinholeDevice, points: &[DVec3]) -> f64 {
    let Ok(rays) = DeviceRays::new(truth) else {
        return f64::INFINITY;
    };
    if points.is_empty() {
        return 0.0;
    }
    let sum: f64 = points
        .iter()
        .map(|&x| match (calibration.project(x), rays.project(x)) {
            (Some(a), Some(b)) => (a - b).length_squared(),
            _ => f64::INFINITY,
        })
        .sum();
    (sum / points.len() as f64).sqrt()
}

/// Held-out surface points per projector in the bench.
pub const SURFACE_POINTS: usize = 2000;
/// Fiducials of the simulated hand marking (the demo's rig).
pub const HAND_FIDUCIALS: usize = 40;
/// Pixel noise of the simulated hand marking (the demo's).
pub const HAND_NOISE_PX: f64 = 0.5;

fn median(v: &[f64]) -> f64 {
    percentile(v, 50.0).unwrap_or(f64::NAN)
}

/// The records of the showcase `scene`'s projectors: per projector the
/// simulated hand marking of the demo (LM and Powell, medians over
/// [`BENCH_SEEDS`] noise seeds) and structured light (one run, its
/// `seconds` the whole job: the sim's light transport, capture, decode
/// and solve), all judged by [`true_rms`] on the same [`SURFACE_POINTS`].
/// `done(k, what)` after each record.
pub fn bench_showcase(
    scene: &Showcase,
    options: &StructuredLightOptions,
    sim_samples: u32,
    done: &dyn Fn(usize, &str),
) -> anyhow::Result<Vec<BenchRecord>> {
    let geometry = SceneGeometry::build(scene, &ObjectFilter::Real)?;
    anyhow::ensure!(
        !scene.cameras.is_empty(),
        "the scene {} has no camera",
        scene.name
    );
    let mut records = Vec::new();
    let rig = fiducial_rig(HAND_FIDUCIALS, 7);
    let heldout_rig = fiducial_rig(HELDOUT_POINTS, 8);
    for (i, p) in scene.projectors.iter().enumerate() {
        let truth = &p.device;
        let points = surface_points(truth, &geometry, SURFACE_POINTS, 1);
        for method in [Method::Lm, Method::Powell] {
            let opts = CalibrateOptions::with_method(method);
            let mut cols: [Vec<f64>; 6] = Default::default();
            let mut n = 0;
            for seed in 0..BENCH_SEEDS {
                let s = 100 + i as u64 + 1000 * seed;
                let input = simulate_fiducials(truth, &rig, HAND_NOISE_PX, s);
                let heldout = simulate_fiducials(truth, &heldout_rig, HAND_NOISE_PX, s + 1);
                n = input.points.len();
                let (result, seconds) = time_per_call(|| calibrate(&input, &opts));
                let Ok(cal) = result else { continue };
                let d = cal.to_device();
                for (c, v) in cols.iter_mut().zip([
                    cal.rms_px,
                    heldout_rms(&cal, &heldout.points),
                    true_rms(&cal, truth, &points),
                    (d.center() - truth.center()).length(),
                    rotation_angle_deg(&d.rotation, &truth.rotation),
                    seconds,
                ]) {
                    c.push(v);
                }
            }
            let [fit, held, held_true, center, rotation, seconds] = cols.map(|v| median(&v));
            records.push(BenchRecord {
                method,
                source: Source::Fiducials,
                device: Some(p.name.clone()),
                points: n,
                noise_px: HAND_NOISE_PX,
                coplanar: false,
                rms_fit_px: fit,
                rms_heldout_px: held,
                rms_heldout_true_px: Some(held_true),
                center_error_m: center,
                rotation_error_deg: rotation,
                seconds,
            });
            done(records.len(), &format!("{} hand marking, {method}", p.name));
        }
        // A fresh sim per run: its light transport is part of the time.
        let sim = SimShowcase::new(
            scene,
            SimConfig {
                samples_per_pixel: sim_samples.max(1),
                ..SimConfig::default()
            },
        )?;
        let t = Instant::now();
        let outcome = calibrate_structured_light(
            &p.name,
            &mut sim.projector(i)?,
            &mut sim.camera(0)?,
            &geometry,
            options,
            &|_, _, _| {},
        )?;
        let seconds = t.elapsed().as_secs_f64();
        let cal = &outcome.calibration;
        let d = cal.to_device();
        // The decoded pixels' own error: their distance from the true
        // projection, per axis.
        let rays = DeviceRays::new(truth)?;
        let decode_error = {
            let heldout = &outcome.heldout;
            let s: f64 = heldout
                .iter()
                .filter_map(|c| {
                    let p = rays.project(DVec3::from_array(c.world))?;
                    Some((p - DVec2::from_array(c.pixel)).length_squared())
                })
                .sum();
            (s / (2.0 * heldout.len().max(1) as f64)).sqrt()
        };
        records.push(BenchRecord {
            method: Method::Lm,
            source: Source::StructuredLight,
            device: Some(p.name.clone()),
            points: outcome.fit_points,
            noise_px: decode_error,
            coplanar: false,
            rms_fit_px: cal.rms_px,
            rms_heldout_px: outcome.heldout_rms_px,
            rms_heldout_true_px: Some(true_rms(cal, truth, &points)),
            center_error_m: (d.center() - truth.center()).length(),
            rotation_error_deg: rotation_angle_deg(&d.rotation, &truth.rotation),
            seconds,
        });
        done(records.len(), &format!("{} structured light", p.name));
    }
    Ok(records)
}
