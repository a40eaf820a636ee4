//! Camera response recovery from an exposure bracket (Debevec & Malik 1997).
//!
//! # The model
//!
//! A pixel site `i` with irradiance `E_i`, exposed for `dt_j`, receives the
//! exposure `X = E_i dt_j` and reports the code `Z_ij = f(X)`, where the
//! response `f` is monotonic and otherwise unknown. With `g = ln f^-1`:
//!
//! ```text
//! g(Z_ij) = ln E_i + ln dt_j
//! ```
//!
//! The unknowns are `g(z)` for each of the `n` codes and `ln E_i` for each
//! of the `N` sampled sites, solved per channel by least squares over
//!
//! ```text
//!   sum_ij [w(Z_ij) (g(Z_ij) - ln E_i - ln dt_j)]^2          (data)
//! + sum_z  [lambda w(z) (g(z-1) - 2 g(z) + g(z+1))]^2        (smoothness)
//! + [g(n/2)]^2                                               (scale)
//! ```
//!
//! with the hat weight `w(z) = min(z, n-1-z) / ((n-1)/2)`, which trusts the
//! middle codes most and ignores the clipped codes 0 and `n-1`. The data
//! and smoothness terms do not change when `g` and every `ln E_i` shift by
//! one constant; the scale term picks the shift with `g(n/2) = 0`, so the
//! middle code maps to the relative exposure 1. Each channel keeps its own
//! unknown scale.
//!
//! # The solve
//!
//! The normal equations have the block form
//!
//! ```text
//! [ A   B ] [ g ]   [ a ]
//! [ B^T D ] [ e ] = [ d ]
//! ```
//!
//! where `D` is diagonal: each `ln E_i` meets only the rows of its own
//! site, `D_ii = sum_j w(Z_ij)^2`. Eliminating `e` leaves the `n x n` Schur
//! complement system `(A - B D^-1 B^T) g = a - B D^-1 d`, to which each site
//! adds the outer product of its (at most one per exposure) codes. With the
//! scale term it is symmetric positive definite, and its dense Cholesky
//! costs `n^3 / 3` flops (6 Mflop for 8-bit codes) whatever the number of
//! sites. Then `ln E_i` is the weighted mean of `g(Z_ij) - ln dt_j`.
//!
//! # Checks
//!
//! A site is usable when its codes lie inside the range (more than 2 % of
//! it from either end) in at least two exposures; with too few usable sites
//! the bracket is saturated or under-exposed. After the solve the curve
//! must rise over its trusted range (the codes with samples at and beyond
//! them on both sides), and the data must fit it: a falling curve or a
//! large residual means the frames are not of one static scene at the
//! stated exposure times.

use nalgebra::{DMatrix, DVector};
use showcase_light::sampling::hash64;

/// Fewest code values accepted.
pub const MIN_LEVELS: u32 = 16;
/// Most code values accepted: the solve is a dense `levels x levels`
/// Cholesky, so deeper codes are binned first.
pub const MAX_LEVELS: u32 = 1024;
/// Fewest usable sites (codes inside the range in at least two exposures)
/// per channel; also the fewest [`ResponseOptions::samples`].
pub const MIN_USABLE_SITES: usize = 16;
/// Fraction of the code range at either end that counts as clipped.
pub const CLIP_MARGIN: f64 = 0.02;

const CHANNELS: usize = 3;
/// Observations that must lie at or beyond each end of the trusted range.
const TRUST_TAIL: usize = 3;
/// Bound on `g`, so that `exp(g)` is finite and positive.
const LOG_EXPOSURE_BOUND: f64 = 700.0;
/// Relative difference under which two exposure times count as one.
const DUPLICATE_EXPOSURE_RATIO: f64 = 1e-9;

/// One camera's frames of a static scene at several exposure times.
#[derive(Clone, Copy, Debug)]
pub struct ExposureBracket<'a> {
    /// Exposure time of each frame in seconds, in any order; distinct,
    /// finite and greater than 0.
    pub exposures_s: &'a [f64],
    /// One frame per exposure time, all the same size: a code per channel
    /// (RGB) for each pixel, each code in `0..levels`.
    pub frames: &'a [Vec<[u16; 3]>],
    /// Number of code values (256 for 8 bits).
    pub levels: u32,
}

/// How [`recover_response`] samples and solves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResponseOptions {
    /// Pixel sites sampled per channel, chosen deterministically to spread
    /// over the range of codes and over the frame; at least
    /// [`MIN_USABLE_SITES`].
    ///
    /// The default, 1000, is more than Debevec and Malik's 50 to 200: with
    /// the Schur complement solve a site costs only the outer product of
    /// its codes, so 1000 sites solve as fast as 200 (milliseconds), and
    /// the upper codes, which each cover a narrow slice of log exposure and
    /// so collect few samples, need them. On a synthetic 8-bit camera with
    /// 0.5-code read noise and a knee, the worst error over ten noise seeds
    /// falls from about 2.5 % with 200 sites to 1.6 % with 1000.
    pub samples: usize,
    /// Weight `lambda` of the smoothness term, in Debevec and Malik's units
    /// (relative to hat-weighted data rows); finite and greater than 0.
    pub smoothness: f64,
    /// Largest accepted hat-weighted rms residual of the data equations, in
    /// ln exposure; `f64::INFINITY` turns the check off.
    pub max_residual: f64,
    /// The camera's noise floor: codes at or below it are what the camera
    /// reads of no light (read noise clipped at black, averaged), not a
    /// response to exposure, and are left out like clipped codes (0: no
    /// floor beyond the clip margin).
    pub noise_floor: u32,
}

impl Default for ResponseOptions {
    fn default() -> Self {
        Self {
            samples: 1000,
            smoothness: 10.0,
            max_residual: 0.1,
            noise_floor: 0,
        }
    }
}

/// The recovered inverse response of each channel: the relative linear
/// exposure of each code, up to one unknown scale per channel, normalised
/// so that the middle code (`levels / 2`) maps to 1.
#[derive(Clone, Debug, PartialEq)]
pub struct RecoveredResponse {
    levels: u32,
    /// `g = ln exposure` per channel and code.
    log_exposure: [Vec<f64>; CHANNELS],
    trusted: [(u32, u32); CHANNELS],
    residual_rms: [f64; CHANNELS],
}

impl RecoveredResponse {
    /// Number of code values.
    pub fn levels(&self) -> u32 {
        self.levels
    }

    /// Natural log of [`Self::exposure`]: linear in `code` between
    /// integer codes. Codes outside `0..levels` are clamped and a NaN code
    /// reads as 0.
    ///
    /// # Panics
    ///
    /// If `channel` is not 0, 1 or 2.
    pub fn log_exposure(&self, channel: usize, code: f64) -> f64 {
        let g = &self.log_exposure[channel];
        let top = g.len() - 1;
        let x = if code.is_nan() {
            0.0
        } else {
            code.clamp(0.0, top as f64)
        };
        let below = (x.floor() as usize).min(top);
        let above = (below + 1).min(top);
        let t = x - below as f64;
        g[below] + (g[above] - g[below]) * t
    }

    /// Relative linear exposure of `code` in `channel`, interpolated,
    /// finite and greater than 0. Codes outside `0..levels` are clamped
    /// and a NaN code reads as 0.
    ///
    /// # Panics
    ///
    /// If `channel` is not 0, 1 or 2.
    pub fn exposure(&self, channel: usize, code: f64) -> f64 {
        self.log_exposure(channel, code).exp()
    }

    /// The codes, inclusive, over which the curve of `channel` is trusted:
    /// enough sampled codes fell at and beyond each end, and neither end is
    /// within [`CLIP_MARGIN`] of the code range's ends.
    ///
    /// # Panics
    ///
    /// If `channel` is not 0, 1 or 2.
    pub fn trusted_range(&self, channel: usize) -> (u32, u32) {
        self.trusted[channel]
    }

    /// Linear radiance-proportional value (relative units) of a pixel of
    /// `code` in `channel` exposed for `exposure_s` seconds:
    /// `exposure(code) / exposure_s`. Finite and not negative: 0 when
    /// `exposure_s` is not finite and greater than 0.
    ///
    /// # Panics
    ///
    /// If `channel` is not 0, 1 or 2.
    pub fn radiance(&self, channel: usize, code: f64, exposure_s: f64) -> f64 {
        if !(exposure_s.is_finite() && exposure_s > 0.0) {
            return 0.0;
        }
        (self.exposure(channel, code) / exposure_s).min(f64::MAX)
    }

    /// Hat-weighted rms residual of the data equations of `channel`, in ln
    /// exposure: how far the samples sit from the recovered curve.
    ///
    /// # Panics
    ///
    /// If `channel` is not 0, 1 or 2.
    pub fn residual_rms(&self, channel: usize) -> f64 {
        self.residual_rms[channel]
    }
}

/// Why a response could not be recovered.
#[derive(Debug, thiserror::Error)]
pub enum ResponseError {
    /// Fewer than two exposure times.
    #[error(
        "the bracket has {found} exposure time(s), at least 2 are needed: capture the scene at two or more exposure times"
    )]
    TooFewExposures {
        /// Exposure times given.
        found: usize,
    },
    /// Not one frame per exposure time.
    #[error(
        "the bracket has {frames} frames for {exposures} exposure times: give exactly one frame per exposure time"
    )]
    FrameCountMismatch {
        /// Frames given.
        frames: usize,
        /// Exposure times given.
        exposures: usize,
    },
    /// A frame without pixels.
    #[error("frame {index} is empty: every frame needs the pixels of the scene")]
    EmptyFrame {
        /// Index of the frame.
        index: usize,
    },
    /// Frames of different sizes.
    #[error(
        "frame {index} has {len} pixels but frame 0 has {expected}: all frames must be the same size, from one camera that did not move"
    )]
    FrameSizeMismatch {
        /// Index of the frame.
        index: usize,
        /// Its pixel count.
        len: usize,
        /// Pixel count of frame 0.
        expected: usize,
    },
    /// An exposure time that is not finite and greater than 0.
    #[error("exposure time {index} is {value} s: exposure times must be finite and greater than 0")]
    InvalidExposure {
        /// Index of the exposure time.
        index: usize,
        /// Its value in seconds.
        value: f64,
    },
    /// Two frames with the same exposure time.
    #[error(
        "exposure times {first} and {second} are both {value} s: each frame needs its own exposure time"
    )]
    DuplicateExposure {
        /// Index of the first.
        first: usize,
        /// Index of the second.
        second: usize,
        /// The shared value in seconds.
        value: f64,
    },
    /// A code count outside the supported range.
    #[error(
        "levels is {levels}, supported are {MIN_LEVELS} to {MAX_LEVELS} code values: bin deeper codes first (e.g. shift 16-bit codes right by 8 for 256 levels)"
    )]
    InvalidLevels {
        /// The code count given.
        levels: u32,
    },
    /// A code not below `levels`.
    #[error(
        "frame {frame}, pixel {pixel}, channel {channel} has code {code}, outside 0..{levels}: check levels against the bit depth of the frames"
    )]
    CodeOutOfRange {
        /// Index of the frame.
        frame: usize,
        /// Index of the pixel in the frame.
        pixel: usize,
        /// Channel, 0 to 2.
        channel: usize,
        /// The code.
        code: u16,
        /// The code count given.
        levels: u32,
    },
    /// Options out of range.
    #[error("invalid response options: {reason}")]
    InvalidOptions {
        /// What is wrong with them.
        reason: String,
    },
    /// Too few usable sites, most codes at the top of the range.
    #[error(
        "channel {channel} is saturated: only {usable} pixel sites have codes inside {low}..={high} in at least two exposures, {needed} are needed, and {clipped_percent:.0}% of its codes are above {high}: add shorter exposures"
    )]
    Saturated {
        /// Channel, 0 to 2.
        channel: usize,
        /// Usable sites found.
        usable: usize,
        /// Usable sites needed.
        needed: usize,
        /// Lowest inside code.
        low: u32,
        /// Highest inside code.
        high: u32,
        /// Percentage of all codes of the channel above `high`.
        clipped_percent: f64,
    },
    /// Too few usable sites, most codes at the bottom of the range.
    #[error(
        "channel {channel} is under-exposed: only {usable} pixel sites have codes inside {low}..={high} in at least two exposures, {needed} are needed, and {clipped_percent:.0}% of its codes are below {low}: add longer exposures"
    )]
    Underexposed {
        /// Channel, 0 to 2.
        channel: usize,
        /// Usable sites found.
        usable: usize,
        /// Usable sites needed.
        needed: usize,
        /// Lowest inside code.
        low: u32,
        /// Highest inside code.
        high: u32,
        /// Percentage of all codes of the channel below `low`.
        clipped_percent: f64,
    },
    /// The recovered curve falls somewhere in its trusted range.
    #[error(
        "the recovered response of channel {channel} is not monotonic: it falls from code {from} to code {to} inside its trusted range {low}..={high}; the scene moved or changed between frames, or the frames are not in the order of exposures_s: recapture a static scene with a locked camera"
    )]
    NotMonotonic {
        /// Channel, 0 to 2.
        channel: usize,
        /// Code where the fall starts.
        from: u32,
        /// Code where it ends.
        to: u32,
        /// Lowest trusted code.
        low: u32,
        /// Highest trusted code.
        high: u32,
    },
    /// The samples do not fit one response curve.
    #[error(
        "the frames of channel {channel} do not fit one response curve: the weighted rms residual is {rms:.3} in ln exposure, above {limit}; the scene or its lighting changed between frames, or exposures_s does not match the frames"
    )]
    InconsistentFrames {
        /// Channel, 0 to 2.
        channel: usize,
        /// The residual.
        rms: f64,
        /// [`ResponseOptions::max_residual`].
        limit: f64,
    },
    /// The linear solve gave no finite curve.
    #[error(
        "the least-squares solve for channel {channel} gave no finite curve: try a larger smoothness or more samples"
    )]
    SolveFailed {
        /// Channel, 0 to 2.
        channel: usize,
    },
}

/// Recover the inverse response of each channel from `bracket`.
///
/// Errors, never a wrong curve, for malformed brackets, saturated or
/// under-exposed brackets, and frames that do not fit one static scene.
pub fn recover_response(
    bracket: &ExposureBracket,
    options: &ResponseOptions,
) -> Result<RecoveredResponse, ResponseError> {
    validate_options(options)?;
    validate_bracket(bracket)?;
    let (low, high) = inside_codes(bracket.levels, options.noise_floor);
    if low + 16 > high {
        return Err(ResponseError::InvalidOptions {
            reason: format!(
                "noise_floor is {}, which leaves codes {low}..={high} of {}: fewer than 16 \
                 to recover the curve from; lower the camera's gain or its noise",
                options.noise_floor, bracket.levels
            ),
        });
    }
    let levels = bracket.levels;
    // Centred log exposure times: the mean goes into the ln E_i.
    let ln_dt: Vec<f64> = bracket.exposures_s.iter().map(|t| t.ln()).collect();
    let mean = ln_dt.iter().sum::<f64>() / ln_dt.len() as f64;
    let ln_dt: Vec<f64> = ln_dt.iter().map(|t| t - mean).collect();
    let floor = options.noise_floor;
    let weights: Vec<f64> = (0..levels)
        .map(|z| {
            if z <= floor {
                0.0
            } else {
                hat_weight(z, levels)
            }
        })
        .collect();

    let mut log_exposure: [Vec<f64>; CHANNELS] = Default::default();
    let mut trusted = [(0, 0); CHANNELS];
    let mut residual = [0.0; CHANNELS];
    for channel in 0..CHANNELS {
        let usable = usable_sites(bracket, channel, floor);
        if usable.len() < MIN_USABLE_SITES {
            return Err(exposure_error(bracket, channel, usable.len(), floor));
        }
        let sites = select_sites(bracket, channel, &usable, options.samples);
        let observations: Vec<Vec<u16>> = sites
            .iter()
            .map(|&p| bracket.frames.iter().map(|f| f[p][channel]).collect())
            .collect();
        let g = solve_channel(&observations, &ln_dt, &weights, options.smoothness)
            .ok_or(ResponseError::SolveFailed { channel })?;
        let (low, high) = trusted_range(&observations, levels, floor);
        check_monotonic(channel, &g, low, high)?;
        let rms = residual_rms(&observations, &ln_dt, &weights, &g);
        if rms > options.max_residual {
            return Err(ResponseError::InconsistentFrames {
                channel,
                rms,
                limit: options.max_residual,
            });
        }
        log_exposure[channel] = g;
        trusted[channel] = (low, high);
        residual[channel] = rms;
    }
    Ok(RecoveredResponse {
        levels,
        log_exposure,
        trusted,
        residual_rms: residual,
    })
}

fn validate_options(options: &ResponseOptions) -> Result<(), ResponseError> {
    let invalid = |reason: String| Err(ResponseError::InvalidOptions { reason });
    if options.samples < MIN_USABLE_SITES {
        return invalid(format!(
            "samples is {}, at least {MIN_USABLE_SITES} are needed",
            options.samples
        ));
    }
    if !(options.smoothness.is_finite() && options.smoothness > 0.0) {
        return invalid(format!(
            "smoothness is {}, it must be finite and greater than 0 (10 is a good start)",
            options.smoothness
        ));
    }
    if options.max_residual.is_nan() || options.max_residual <= 0.0 {
        return invalid(format!(
            "max_residual is {}, it must be greater than 0 (infinity turns the check off)",
            options.max_residual
        ));
    }
    Ok(())
}

fn validate_bracket(bracket: &ExposureBracket) -> Result<(), ResponseError> {
    let exposures = bracket.exposures_s;
    if exposures.len() < 2 {
        return Err(ResponseError::TooFewExposures {
            found: exposures.len(),
        });
    }
    if bracket.frames.len() != exposures.len() {
        return Err(ResponseError::FrameCountMismatch {
            frames: bracket.frames.len(),
            exposures: exposures.len(),
        });
    }
    if let Some((index, &value)) = exposures
        .iter()
        .enumerate()
        .find(|(_, t)| !(t.is_finite() && **t > 0.0))
    {
        return Err(ResponseError::InvalidExposure { index, value });
    }
    let mut order: Vec<usize> = (0..exposures.len()).collect();
    order.sort_by(|&a, &b| exposures[a].total_cmp(&exposures[b]));
    for pair in order.windows(2) {
        let (a, b) = (exposures[pair[0]], exposures[pair[1]]);
        if b - a <= DUPLICATE_EXPOSURE_RATIO * b {
            return Err(ResponseError::DuplicateExposure {
                first: pair[0].min(pair[1]),
                second: pair[0].max(pair[1]),
                value: a,
            });
        }
    }
    if !(MIN_LEVELS..=MAX_LEVELS).contains(&bracket.levels) {
        return Err(ResponseError::InvalidLevels {
            levels: bracket.levels,
        });
    }
    let expected = bracket.frames[0].len();
    for (index, frame) in bracket.frames.iter().enumerate() {
        if frame.is_empty() {
            return Err(ResponseError::EmptyFrame { index });
        }
        if frame.len() != expected {
            return Err(ResponseError::FrameSizeMismatch {
                index,
                len: frame.len(),
                expected,
            });
        }
    }
    for (frame, pixels) in bracket.frames.iter().enumerate() {
        for (pixel, codes) in pixels.iter().enumerate() {
            if let Some(channel) = codes.iter().position(|&c| u32::from(c) >= bracket.levels) {
                return Err(ResponseError::CodeOutOfRange {
                    frame,
                    pixel,
                    channel,
                    code: codes[channel],
                    levels: bracket.levels,
                });
            }
        }
    }
    Ok(())
}

/// The codes, inclusive, more than [`CLIP_MARGIN`] of the range from
/// either end and above the noise floor `floor`.
fn inside_codes(levels: u32, floor: u32) -> (u32, u32) {
    let margin = (CLIP_MARGIN * f64::from(levels - 1)).floor() as u32;
    (
        (margin + 1).max(floor.saturating_add(1)),
        levels - 2 - margin,
    )
}

/// The hat weight: 0 at the ends of the code range, about 1 in its middle.
fn hat_weight(code: u32, levels: u32) -> f64 {
    let top = f64::from(levels - 1);
    let z = f64::from(code);
    z.min(top - z) / (0.5 * top)
}

/// Pixels whose codes in `channel` lie inside the range in at least two
/// exposures.
fn usable_sites(bracket: &ExposureBracket, channel: usize, floor: u32) -> Vec<usize> {
    let (low, high) = inside_codes(bracket.levels, floor);
    (0..bracket.frames[0].len())
        .filter(|&p| {
            bracket
                .frames
                .iter()
                .filter(|f| (low..=high).contains(&u32::from(f[p][channel])))
                .count()
                >= 2
        })
        .collect()
}

/// The saturated or under-exposed error of `channel`, whichever end holds
/// more of its codes.
fn exposure_error(
    bracket: &ExposureBracket,
    channel: usize,
    usable: usize,
    floor: u32,
) -> ResponseError {
    let (low, high) = inside_codes(bracket.levels, floor);
    let (mut above, mut below, mut total) = (0usize, 0usize, 0usize);
    for code in bracket
        .frames
        .iter()
        .flatten()
        .map(|c| u32::from(c[channel]))
    {
        total += 1;
        above += usize::from(code > high);
        below += usize::from(code < low);
    }
    let percent = |n: usize| 100.0 * n as f64 / total.max(1) as f64;
    if above >= below {
        ResponseError::Saturated {
            channel,
            usable,
            needed: MIN_USABLE_SITES,
            low,
            high,
            clipped_percent: percent(above),
        }
    } else {
        ResponseError::Underexposed {
            channel,
            usable,
            needed: MIN_USABLE_SITES,
            low,
            high,
            clipped_percent: percent(below),
        }
    }
}

/// Up to `count` of the `usable` pixels, spread evenly over the range of
/// their summed codes (a monotonic function of the site's irradiance) and,
/// among equal sums, scattered over the frame by a fixed hash of the pixel
/// index.
fn select_sites(
    bracket: &ExposureBracket,
    channel: usize,
    usable: &[usize],
    count: usize,
) -> Vec<usize> {
    if usable.len() <= count {
        return usable.to_vec();
    }
    let mut ranked: Vec<(u64, u64, usize)> = usable
        .iter()
        .map(|&p| {
            let key = bracket
                .frames
                .iter()
                .map(|f| u64::from(f[p][channel]))
                .sum();
            (key, hash64(p as u64), p)
        })
        .collect();
    ranked.sort_unstable();
    let first = ranked[0].0 as f64;
    let span = ranked[ranked.len() - 1].0 as f64 - first;
    let mut used = vec![false; ranked.len()];
    let mut picked = Vec::with_capacity(count);
    for k in 0..count {
        let target = first + (k as f64 + 0.5) / count as f64 * span;
        let pos = ranked.partition_point(|r| (r.0 as f64) < target);
        // The nearest unused entry by key, looking both ways from `pos`.
        let mut left = pos;
        while left > 0 && used[left - 1] {
            left -= 1;
        }
        let mut right = pos;
        while right < ranked.len() && used[right] {
            right += 1;
        }
        let distance = |i: usize| (ranked[i].0 as f64 - target).abs();
        let choice = match (left > 0, right < ranked.len()) {
            (true, true) if distance(left - 1) < distance(right) => left - 1,
            (_, true) => right,
            (true, false) => left - 1,
            // `count < ranked.len()`, so some entry is unused.
            (false, false) => break,
        };
        used[choice] = true;
        picked.push(ranked[choice].2);
    }
    picked
}

/// `g` for each code from the sampled codes (one row per site, one code per
/// exposure), by the Schur complement solve of the module doc; `None` when
/// it gives no finite curve.
fn solve_channel(
    observations: &[Vec<u16>],
    ln_dt: &[f64],
    weights: &[f64],
    smoothness: f64,
) -> Option<Vec<f64>> {
    let n = weights.len();
    let mut system = DMatrix::<f64>::zeros(n, n);
    let mut rhs = DVector::<f64>::zeros(n);
    // The site's column of B: (code, -w^2) per exposure with weight.
    let mut column: Vec<(usize, f64)> = Vec::with_capacity(ln_dt.len());
    for codes in observations {
        column.clear();
        let (mut d, mut r) = (0.0, 0.0);
        for (&code, &t) in codes.iter().zip(ln_dt) {
            let z = usize::from(code);
            let w2 = weights[z] * weights[z];
            if w2 == 0.0 {
                continue;
            }
            system[(z, z)] += w2;
            rhs[z] += w2 * t;
            d += w2;
            r -= w2 * t;
            column.push((z, -w2));
        }
        if d == 0.0 {
            continue;
        }
        for &(za, ba) in &column {
            rhs[za] -= ba * r / d;
            for &(zb, bb) in &column {
                system[(za, zb)] -= ba * bb / d;
            }
        }
    }
    let second_difference = [1.0, -2.0, 1.0];
    for z in 1..n - 1 {
        let c = (smoothness * weights[z]).powi(2);
        for (a, ca) in second_difference.iter().enumerate() {
            for (b, cb) in second_difference.iter().enumerate() {
                system[(z - 1 + a, z - 1 + b)] += c * ca * cb;
            }
        }
    }
    // The scale row; any positive weight gives g(mid) = 0, one of the size
    // of the diagonal keeps the system well conditioned.
    let mid = n / 2;
    system[(mid, mid)] += system.diagonal().mean().max(1.0);
    if !system.iter().chain(rhs.iter()).all(|v| v.is_finite()) {
        return None;
    }
    let g = match system.clone().cholesky() {
        Some(cholesky) => cholesky.solve(&rhs),
        None => system
            .try_svd(true, true, f64::EPSILON, 10_000)?
            .solve(&rhs, 1e-12)
            .ok()?,
    };
    if !g.iter().all(|v| v.is_finite()) {
        return None;
    }
    let shift = g[mid];
    Some(
        g.iter()
            .map(|v| (v - shift).clamp(-LOG_EXPOSURE_BOUND, LOG_EXPOSURE_BOUND))
            .collect(),
    )
}

/// The trusted codes: at least [`TRUST_TAIL`] sampled inside codes lie at
/// or below the first and at or above the last.
fn trusted_range(observations: &[Vec<u16>], levels: u32, floor: u32) -> (u32, u32) {
    let (low, high) = inside_codes(levels, floor);
    let mut histogram = vec![0usize; levels as usize];
    for &code in observations.iter().flatten() {
        if (low..=high).contains(&u32::from(code)) {
            histogram[usize::from(code)] += 1;
        }
    }
    let reach = |codes: &mut dyn Iterator<Item = u32>, fallback: u32| {
        let mut seen = 0;
        for z in codes {
            seen += histogram[z as usize];
            if seen >= TRUST_TAIL {
                return z;
            }
        }
        fallback
    };
    let first = reach(&mut (low..=high), high);
    let last = reach(&mut (low..=high).rev(), low);
    (first.min(last), first.max(last))
}

fn check_monotonic(channel: usize, g: &[f64], low: u32, high: u32) -> Result<(), ResponseError> {
    let g_at = |z: u32| g[z as usize];
    if let Some(from) = (low..high).find(|&z| g_at(z + 1) <= g_at(z)) {
        let mut to = from + 1;
        while to < high && g_at(to + 1) <= g_at(to) {
            to += 1;
        }
        return Err(ResponseError::NotMonotonic {
            channel,
            from,
            to,
            low,
            high,
        });
    }
    Ok(())
}

/// Hat-weighted rms of `g(Z_ij) - ln E_i - ln dt_j`, with each `ln E_i` at
/// its least-squares value.
fn residual_rms(observations: &[Vec<u16>], ln_dt: &[f64], weights: &[f64], g: &[f64]) -> f64 {
    let (mut sum, mut total) = (0.0, 0.0);
    for codes in observations {
        let rows = || {
            codes.iter().zip(ln_dt).map(|(&code, &t)| {
                let z = usize::from(code);
                (weights[z] * weights[z], g[z] - t)
            })
        };
        let d: f64 = rows().map(|(w2, _)| w2).sum();
        if d == 0.0 {
            continue;
        }
        let ln_e = rows().map(|(w2, x)| w2 * x).sum::<f64>() / d;
        sum += rows().map(|(w2, x)| w2 * (x - ln_e).powi(2)).sum::<f64>();
        total += d;
    }
    if total > 0.0 {
        (sum / total).sqrt()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests;
