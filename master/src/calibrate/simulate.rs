//! Simulated fiducial marking: fiducial sets inside a showcase, projector
//! shaped devices looking down at them, and noisy marked pixels, so the
//! simulated showcase can calibrate its own devices.

use super::io::model_of_device;
use super::{CalibrationInput, Correspondence};
use glam::DVec3;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use showcase_light::finite::finite_or_zero;
use showcase_light::sampling::GOLDEN_GAMMA;
use showcase_proto::scene::PinholeDevice;

/// Centre of the calibration rig of [`fiducial_rig`] (metres, y up).
pub const RIG_CENTER: DVec3 = DVec3::new(0.0, 0.15, 0.0);
/// Size of the rig box (x, y, z) in metres.
pub const RIG_SIZE: DVec3 = DVec3::new(0.5, 0.3, 0.5);

/// `count` fiducials spread uniformly over the top and the four sides of a
/// 0.5 x 0.3 x 0.5 m box standing on the showcase floor, centred at the
/// origin: a non-coplanar calibration rig.
pub fn fiducial_rig(count: usize, seed: u64) -> Vec<DVec3> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let h = RIG_SIZE * 0.5;
    let areas = [
        RIG_SIZE.x * RIG_SIZE.z, // top
        RIG_SIZE.x * RIG_SIZE.y, // front and back
        RIG_SIZE.x * RIG_SIZE.y,
        RIG_SIZE.z * RIG_SIZE.y, // left and right
        RIG_SIZE.z * RIG_SIZE.y,
    ];
    let total: f64 = areas.iter().sum();
    (0..count)
        .map(|_| {
            let mut pick = rng.random::<f64>() * total;
            let mut face = 0;
            while face < 4 && pick >= areas[face] {
                pick -= areas[face];
                face += 1;
            }
            let (a, b) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let local = match face {
                0 => DVec3::new(a * h.x, h.y, b * h.z),
                1 => DVec3::new(a * h.x, b * h.y, h.z),
                2 => DVec3::new(a * h.x, b * h.y, -h.z),
                3 => DVec3::new(h.x, b * h.y, a * h.z),
                _ => DVec3::new(-h.x, b * h.y, a * h.z),
            };
            RIG_CENTER + local
        })
        .collect()
}

/// `count` fiducials on a 0.6 x 0.6 m plate lying on the showcase floor
/// (y = 0): a coplanar set, usable only with known intrinsics.
pub fn fiducial_plate(count: usize, seed: u64) -> Vec<DVec3> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            DVec3::new(
                rng.random_range(-0.3..0.3),
                0.0,
                rng.random_range(-0.3..0.3),
            )
        })
        .collect()
}

/// A projector-like 1024x768 device inside a showcase: 0.5 to 1.5 m from
/// the rig centre, looking down at 35 to 75 degrees of elevation, a field
/// of view that holds the rig, slightly non-square pixels and some lens
/// shift of the principal point.
pub fn projector_in_showcase(seed: u64) -> PinholeDevice {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ GOLDEN_GAMMA);
    let distance = rng.random_range(0.5..1.5);
    let elevation = rng.random_range(35.0f64..75.0).to_radians();
    let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
    let dir = DVec3::new(
        elevation.cos() * azimuth.cos(),
        elevation.sin(),
        elevation.cos() * azimuth.sin(),
    );
    let eye = RIG_CENTER + distance * dir;
    let fov_x = (2.0 * (0.45 / distance).atan())
        .to_degrees()
        .clamp(30.0, 80.0);
    let mut device = PinholeDevice::look_at(eye, RIG_CENTER, DVec3::Y, fov_x, 1024, 768);
    let f = device.k.x_axis.x;
    device.k.y_axis.y = f * rng.random_range(0.99..1.01);
    device.k.z_axis.x += rng.random_range(-0.03..0.03) * 1024.0;
    device.k.z_axis.y += rng.random_range(-0.05..0.05) * 768.0;
    device
}

/// The correspondences a person marking `fiducials` on `device` would
/// produce: points in front of the device and inside its image only, in
/// their input order, with Gaussian pixel noise of standard deviation
/// `noise_px` per axis (seeded, reproducible). Distortion k1, k2 of the
/// device is applied. A negative or non-finite `noise_px` counts as 0.
pub fn simulate_fiducials(
    device: &PinholeDevice,
    fiducials: &[DVec3],
    noise_px: f64,
    seed: u64,
) -> CalibrationInput {
    let model = model_of_device(device);
    let sigma = finite_or_zero(noise_px).max(0.0);
    let noise = Normal::new(0.0, sigma)
        .unwrap_or_else(|_| Normal::new(0.0, 0.0).expect("zero sigma is valid"));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (w, h) = (device.width as f64, device.height as f64);
    let points = fiducials
        .iter()
        .filter_map(|x| {
            // Draw the noise for every fiducial, so that visibility does not
            // shift the noise of later points.
            let (du, dv) = (noise.sample(&mut rng), noise.sample(&mut rng));
            let world = Vector3::new(x.x, x.y, x.z);
            if !x.is_finite() || model.to_device(&world).z <= device.near {
                return None;
            }
            let p = model.project(&world)?;
            let pixel = [p.x + du, p.y + dv];
            ((0.0..w).contains(&p.x) && (0.0..h).contains(&p.y)).then_some(Correspondence {
                world: x.to_array(),
                pixel,
            })
        })
        .collect();
    CalibrationInput {
        device: "simulated".to_string(),
        width: device.width,
        height: device.height,
        points,
        intrinsics: None,
    }
}
