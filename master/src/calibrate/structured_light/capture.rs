//! The capture stage: every pattern shown and captured, the automatic
//! exposure, the reference checks and the decode.

use super::decode::{Decoder, ReferenceProblem, ResponseTable, check_references};
use super::{Decoded, Pattern, PatternSet, StructuredLightError, StructuredLightOptions};
use showcase_light::hardware::{CameraDevice, ProjectorDevice};

/// The longest exposure the automatic exposure chooses (seconds).
pub const MAX_EXPOSURE_S: f64 = 0.5;

/// The capture stage's result.
#[derive(Clone, Debug, PartialEq)]
pub struct Captured {
    /// The decode.
    pub decoded: Decoded,
    /// Patterns shown (without the automatic exposure's repeats).
    pub patterns: usize,
    /// Camera frames taken.
    pub frames: usize,
    /// Exposure used (seconds).
    pub exposure_s: f64,
}

/// Show every pattern of `projector` (named `name` in errors), capture
/// and decode it with `camera`. `progress(done, total, what)` after each
/// pattern, `total` being the patterns plus one (the solve that follows).
pub fn capture_and_decode<P: ProjectorDevice, C: CameraDevice>(
    name: &str,
    projector: &mut P,
    camera: &mut C,
    options: &StructuredLightOptions,
    progress: &dyn Fn(usize, usize, &str),
) -> Result<Captured, StructuredLightError> {
    let device = || name.to_string();
    let boxed = |what: &'static str| {
        move |e: Box<dyn std::error::Error + Send + Sync>| StructuredLightError::Device {
            device: device(),
            what,
            source: e,
        }
    };
    let (pw, ph) = (projector.device().width, projector.device().height);
    let set = PatternSet::new(pw, ph);
    let patterns = set.patterns();
    let total = patterns.len() + 1;
    let mut taken = 0;
    let table = ResponseTable::new(camera.response());
    let period = projector.wheel_period_s();
    let whole_turns = |e: f64| {
        if period > 0.0 && e.is_finite() {
            (e / period).round().max(1.0) * period
        } else {
            e
        }
    };
    let given = options.exposure_s.map(whole_turns);
    let mut exposure =
        given.unwrap_or_else(|| whole_turns(f64::from(camera.response().exposure_s)));
    let frames = options.frames.max(1);
    let mut shoot = |projector: &mut P, camera: &mut C, p: Pattern, exposure: f64| {
        projector
            .show_pattern(&set.seam_pattern(p, options.level))
            .map_err(|e| boxed("projector")(Box::new(e)))?;
        // One request for the pattern's frames (one round trip to a camera
        // node), their starts spread over the wheel's turn.
        let shots = camera
            .capture_series(exposure, period, frames)
            .map_err(|e| boxed("camera")(Box::new(e)))?;
        if shots.is_empty() {
            return Err(boxed("camera")("no frame came back".into()));
        }
        taken += shots.len();
        Ok::<_, StructuredLightError>(table.capture(&shots))
    };
    let mut white = shoot(projector, camera, Pattern::White, exposure)?;
    let mut black = shoot(projector, camera, Pattern::Black, exposure)?;
    if given.is_none() {
        // Auto-exposure: halve while the white reference clips on more
        // than half the tolerated fraction of its lit pixels, lengthen
        // while its brightest pixels stay below half of full scale.
        for _ in 0..8 {
            let level = super::decode::exposure_level(&white, &black, &options.decode);
            let next = if level.clipped > 0.5 * options.decode.saturated_fraction {
                whole_turns(0.5 * exposure)
            } else if level.peak < 0.5 && level.clipped == 0.0 {
                whole_turns(exposure * (0.75 / level.peak.max(0.05)).min(8.0)).min(MAX_EXPOSURE_S)
            } else {
                break;
            };
            if (next - exposure).abs() <= 1e-9 * exposure {
                break;
            }
            exposure = next;
            white = shoot(projector, camera, Pattern::White, exposure)?;
            black = shoot(projector, camera, Pattern::Black, exposure)?;
        }
    }
    progress(1, total, "white reference");
    progress(2, total, "black reference");
    check_references(&white, &black, &options.decode).map_err(|p| match p {
        ReferenceProblem::Dark { peak } => StructuredLightError::Dark {
            device: device(),
            peak,
            needed: options.decode.dark_fraction,
            exposure_s: exposure,
            level: options.level,
        },
        ReferenceProblem::Saturated { frame, fraction } => StructuredLightError::Saturated {
            device: device(),
            frame,
            fraction,
            exposure_s: exposure,
            level: options.level,
        },
    })?;
    let mut decoder = Decoder::new(set, white, black, options.decode);
    let mut shown = 2;
    for pair in patterns[2..].chunks(2) {
        let [
            Pattern::Bit {
                axis,
                bit,
                inverted: false,
            },
            inverse,
        ] = *pair
        else {
            unreachable!("PatternSet::patterns pairs each bit with its inverse");
        };
        let a = shoot(projector, camera, pair[0], exposure)?;
        let b = shoot(projector, camera, inverse, exposure)?;
        decoder.add(axis, bit, &a, &b);
        shown += 2;
        progress(shown, total, &format!("{axis:?} bit {bit}").to_lowercase());
    }
    // Leave the projector dark.
    projector
        .show_pattern(&set.seam_pattern(Pattern::Black, 0.0))
        .map_err(|e| boxed("projector")(Box::new(e)))?;
    Ok(Captured {
        decoded: decoder.finish(),
        patterns: patterns.len(),
        frames: taken,
        exposure_s: exposure,
    })
}
