//! Photometric calibration of a projector, per channel, with the camera
//! whose response a face's calibration recovered ([`super::face`]):
//!
//! 1. The projector shows one device value over its whole frame, every
//!    other projector black, the CRT off; the camera merges a bracket of
//!    it through the recovered response. Its lamp switched off (or its
//!    lens capped) gives the rest of the room's light, which every level
//!    less it leaves out.
//! 2. Light is linear in the projector's intensity, and a uniform frame
//!    sends the same light along every path at every level, so per camera
//!    pixel the level's light over full white's is `I(d) / I(1)`, per
//!    channel: the camera's scale, the splitter's transmission, the
//!    surfaces' reflectance, the geometry and the room's interreflection
//!    all cancel. The median over the pixels the projector lights well is
//!    the measurement.
//! 3. The level is put in the product's units with the product's own full
//!    white, the model's `eta + black_level`: what the capture's eta fit
//!    measures against a target of known reflectance (a camera of unknown
//!    scale per channel cannot tell a projector's white from the
//!    reflectance captured under it, so that white is the anchor), and
//!    `black + peak * d^gamma` is fitted per channel (`fit_power`).
//! 4. Held-out levels between the fitted ones judge the new profile
//!    against the one in place (the model where there is none); the new
//!    one is kept only if it is no worse.
//!
//! Checks that stop it with what to do: the projector's white saturated at
//! every exposure or too dim at every one, a camera that moved (full white
//! shown first and last), light that falls as the value rises.

use super::face::{
    CHANNELS, Level, Merge, PhotometricOptions, check_rising, check_still_of, fit_power,
    median_codes, region_median,
};
use super::response::RecoveredResponse;
use super::rig::{Lamp, MirrorCamera};
use anyhow::{Context, Result, bail};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use showcase_light::metrics;
use showcase_proto::{CrtResponse, Projector};

/// A projector's photometric calibration.
#[derive(Clone, Debug, Serialize)]
pub struct ProjectorCalibration {
    /// The projector.
    pub projector: String,
    /// The profile to use: the new one, or the one in place when the new
    /// one is worse on the held-out levels.
    pub profile: CrtResponse,
    /// The profile fitted from this run.
    pub fitted: CrtResponse,
    /// The new profile was worse than the one in place, so that is kept.
    pub kept_previous: bool,
    /// Largest relative error of the fitted profile on the held-out levels.
    pub held_out_error: f64,
    /// The same of the profile in place.
    pub held_out_error_before: f64,
    /// Every level measured (`seen`: the light in W/sr).
    pub levels: Vec<Level>,
    /// Camera pixels compared: those the projector's white lights well.
    pub pixels: usize,
    /// Frames captured.
    pub frames: usize,
}

/// Calibrate `projector` (the product's: its model and the profile in
/// place) with `rig`, whose camera's response is `response` (recovered
/// from its bracket of a face's ramp, the same exposures).
pub fn calibrate_projector(
    rig: &mut dyn MirrorCamera,
    index: usize,
    projector: &Projector,
    response: &RecoveredResponse,
    options: &PhotometricOptions,
) -> Result<ProjectorCalibration> {
    let base = rig.base_exposure_s();
    anyhow::ensure!(
        base.is_finite() && base > 0.0,
        "the camera's exposure time {base} s is not a positive time"
    );
    let exposures: Vec<f64> = options.stops.iter().map(|s| base * 2f64.powi(*s)).collect();
    let k = options.frames_per_exposure.max(1) as usize;
    let repeated: Vec<f64> = exposures
        .iter()
        .flat_map(|t| std::iter::repeat_n(*t, k))
        .collect();
    let (w, h) = rig.size();
    let merge = Merge {
        response,
        exposures: &exposures,
    };
    let mut frames = 0;
    let mut shoot = |rig: &mut dyn MirrorCamera, lamp: Lamp| -> Result<Vec<[f64; 3]>> {
        frames += repeated.len();
        let shot = rig.capture_projector(index, lamp, &repeated)?;
        anyhow::ensure!(
            shot.len() == repeated.len() && shot.iter().all(|f| f.len() == (w * h) as usize),
            "the camera returned {} frames for {} exposures, or frames of another size than \
             {w}x{h}",
            shot.len(),
            repeated.len()
        );
        let codes: Vec<Vec<[u16; 3]>> = shot.chunks(k).map(median_codes).collect();
        Ok(merge.image(&codes))
    };

    let off = shoot(rig, Lamp::Off)?;
    let white = shoot(rig, Lamp::Uniform(1.0))?;
    let region = lit_region(&white, &off, &projector.name)?;

    let mut drives: Vec<(f64, bool)> = vec![(0.0, false)];
    drives.extend((1..=options.levels).map(|k| (f64::from(k) / f64::from(options.levels), false)));
    drives.extend(
        options
            .held_out
            .iter()
            .filter(|k| **k < options.levels)
            .map(|k| ((f64::from(*k) + 0.5) / f64::from(options.levels), true)),
    );
    // The product's full white: the anchor of the units (module docs).
    let anchor = projector.response.model(Vec3::ONE);
    let mut levels = Vec::new();
    for &(d, held_out) in &drives {
        let img = if d == 1.0 {
            white.clone()
        } else {
            shoot(rig, Lamp::Uniform(d as f32))?
        };
        for (c, channel) in CHANNELS.iter().enumerate() {
            let what = format!("{} at value {d:.3} in channel {channel}", projector.name);
            // Per pixel, the level's light over white's.
            let ratios: Vec<[f64; 3]> = img
                .iter()
                .zip(&off)
                .zip(&white)
                .map(|((l, o), w)| std::array::from_fn(|k| (l[k] - o[k]) / (w[k] - o[k])))
                .collect();
            let zero = vec![[0.0; 3]; ratios.len()];
            let ratio = region_median(&ratios, &zero, &region, c, &what)?;
            levels.push(Level {
                channel: c,
                drive: d,
                seen: ratio * f64::from(anchor[c]),
                held_out,
            });
        }
    }
    let after = shoot(rig, Lamp::Uniform(1.0))?;
    let still = |img: &[[f64; 3]]| -> Vec<[f64; 3]> {
        img.iter()
            .zip(&off)
            .map(|(l, o)| std::array::from_fn(|c| l[c] - o[c]))
            .collect()
    };
    check_still_of(
        &still(&white),
        &still(&after),
        &region,
        &format!("{}'s full white", projector.name),
    )?;

    let mut fitted = CrtResponse::nominal(1.0);
    for (c, channel) in CHANNELS.iter().enumerate() {
        let mut points: Vec<(f64, f64)> = levels
            .iter()
            .filter(|l| l.channel == c && !l.held_out)
            .map(|l| (l.drive, l.seen))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        check_rising(
            &points,
            c,
            &format!("{}'s", projector.name),
            "check that the projector's picture processing (dynamic iris, brilliant colour, \
             eco mode) is off and that nothing changed the light during the calibration",
        )?;
        let (gamma, peak, black) = fit_power(&points)
            .with_context(|| format!("fitting {}'s curve in channel {channel}", projector.name))?;
        fitted.gamma[c] = gamma as f32;
        fitted.peak[c] = peak as f32;
        fitted.black_level[c] = black as f32;
    }
    let previous = projector
        .response
        .photometry
        .unwrap_or_else(|| projector.response.model_curve());
    let held_out_error_before = held_out_error(&previous, &levels);
    let held_out_error = held_out_error(&fitted, &levels);
    let kept_previous = held_out_error > held_out_error_before;
    Ok(ProjectorCalibration {
        projector: projector.name.clone(),
        profile: if kept_previous { previous } else { fitted },
        fitted,
        kept_previous,
        held_out_error,
        held_out_error_before,
        levels,
        pixels: region.len(),
        frames,
    })
}

/// The camera pixels the projector's white lights well: in every channel
/// a finite light above the lamp-off frame's, at least a quarter of the
/// brightest tenth's; an error saying what to do when they are too few.
fn lit_region(white: &[[f64; 3]], off: &[[f64; 3]], name: &str) -> Result<Vec<usize>> {
    let added: Vec<[f64; 3]> = white
        .iter()
        .zip(off)
        .map(|(w, o)| std::array::from_fn(|c| w[c] - o[c]))
        .collect();
    let saturated = added
        .iter()
        .filter(|a| a.iter().any(|x| x.is_nan()))
        .count();
    let tops: [f64; 3] = std::array::from_fn(|c| {
        let v: Vec<f64> = added
            .iter()
            .map(|a| a[c])
            .filter(|x| x.is_finite())
            .collect();
        metrics::percentile(&v, 90.0).unwrap_or(0.0)
    });
    let region: Vec<usize> = added
        .iter()
        .enumerate()
        .filter(|(_, a)| (0..3).all(|c| a[c].is_finite() && a[c] > 0.25 * tops[c] && tops[c] > 0.0))
        .map(|(i, _)| i)
        .collect();
    if region.len() >= 16 {
        return Ok(region);
    }
    if saturated * 4 > added.len() {
        bail!(
            "{name}'s full white is saturated at every exposure of the bracket on {saturated} of \
             {} camera pixels: add shorter exposures (`stops`) or lower the camera's base \
             exposure",
            added.len()
        );
    }
    bail!(
        "the camera sees only {} pixels that {name}'s full white lights above the room \
         (under-exposed at the longest exposure, or the projector lights nothing the camera \
         sees): add longer exposures (`stops`), or aim the camera at a surface the projector \
         lights",
        region.len()
    )
}

/// The largest relative error of `curve` on the held-out levels.
fn held_out_error(curve: &CrtResponse, levels: &[Level]) -> f64 {
    levels
        .iter()
        .filter(|l| l.held_out && l.seen > 0.0)
        .map(|l| {
            let got = f64::from(curve.emit(Vec3::splat(l.drive as f32))[l.channel]);
            ((got - l.seen) / l.seen).abs()
        })
        .fold(0.0, f64::max)
}

/// What `calibrate --photometric` writes per projector, and a scene's
/// projector `photometric_profile` reads: the profile its node encodes
/// with, and how it was measured.
#[derive(Clone, Debug, Deserialize, Serialize)]
pub struct ProjectorProfileFile {
    /// The projector it belongs to.
    pub projector: String,
    /// Its light per device value and channel (W/sr).
    pub photometry: CrtResponse,
    /// Largest relative error on the held-out levels.
    #[serde(default)]
    pub held_out_error: Option<f64>,
}

impl From<&ProjectorCalibration> for ProjectorProfileFile {
    fn from(c: &ProjectorCalibration) -> Self {
        Self {
            projector: c.projector.clone(),
            photometry: c.profile,
            held_out_error: Some(if c.kept_previous {
                c.held_out_error_before
            } else {
                c.held_out_error
            }),
        }
    }
}
