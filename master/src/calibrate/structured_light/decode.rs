//! From camera frames to projector coordinates: each captured pattern as a
//! linear signal with its noise, the reference checks (dark, saturated),
//! and the per-pixel decode of the Gray-code pairs with its validity mask.
//!
//! A camera pixel's signal is the sum of its three channels' linear
//! signals (each 0 to 1 of full scale, through the camera's response
//! curve), averaged over the frames taken of one pattern; its variance
//! comes from the camera's noise model (`shot_noise * s + read_noise^2`
//! per channel, plus the quantisation step's `step^2 / 12`).
//!
//! A pixel is valid when
//! - the projector lights it: white minus black exceeds
//!   [`DecodeSettings::min_contrast_sigmas`] standard deviations of that
//!   difference;
//! - every bit is clear: `|pattern - inverse|` exceeds
//!   [`DecodeSettings::min_bit_sigmas`] standard deviations and
//!   [`DecodeSettings::min_bit_fraction`] of the pixel's white-minus-black
//!   contrast (a pixel in the projector's shadow sees only light scattered
//!   from elsewhere, which hardly changes between a fine pattern and its
//!   inverse);
//! - its codes decode to a column and row inside the projector's image.

use super::patterns::{Axis, PatternSet, gray_inverse};
use showcase_light::hardware::CameraFrame;
use showcase_proto::CameraResponse;

/// Thresholds of the decode and the reference checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecodeSettings {
    /// White minus black must exceed this many standard deviations.
    pub min_contrast_sigmas: f64,
    /// Each `|pattern - inverse|` must exceed this many standard deviations.
    pub min_bit_sigmas: f64,
    /// ... and this fraction of the pixel's white-minus-black contrast.
    pub min_bit_fraction: f64,
    /// The white reference is dark when its brightest percent of pixels
    /// stays below this fraction of full scale.
    pub dark_fraction: f64,
    /// The white reference is saturated when more than this fraction of
    /// the lit pixels clip in a channel.
    pub saturated_fraction: f64,
}

impl Default for DecodeSettings {
    fn default() -> Self {
        Self {
            min_contrast_sigmas: 6.0,
            min_bit_sigmas: 4.0,
            min_bit_fraction: 0.25,
            dark_fraction: 0.08,
            saturated_fraction: 0.05,
        }
    }
}

/// One pattern as the camera saw it.
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    /// Camera width.
    pub width: u32,
    /// Camera height.
    pub height: u32,
    /// Linear signal per pixel: the sum of the channels, each 0 to 1.
    pub signal: Vec<f32>,
    /// Its variance.
    pub variance: Vec<f32>,
    /// Largest channel signal per pixel, 0 to 1.
    pub peak: Vec<f32>,
    /// Some channel reached the top code.
    pub clipped: Vec<bool>,
}

/// Code-to-signal tables of a camera response: per channel and code, the
/// linear signal and the quantisation variance.
pub(super) struct ResponseTable {
    signal: [Vec<f32>; 3],
    quantisation: [Vec<f32>; 3],
    read_variance: f64,
    shot: f64,
    max_code: u16,
}

impl ResponseTable {
    pub(super) fn new(response: &CameraResponse) -> Self {
        let bits = response.bits.clamp(1, 16);
        let max = (1u32 << bits) - 1;
        let m = max as f64;
        let table = |f: &dyn Fn(usize, u32) -> f64| -> [Vec<f32>; 3] {
            std::array::from_fn(|c| (0..=max).map(|k| f(c, k) as f32).collect())
        };
        let signal = table(&|c, k| response.decode(c, k as f64 / m));
        let quantisation = table(&|c, k| {
            let lo = response.decode(c, (k as f64 - 0.5).max(0.0) / m);
            let hi = response.decode(c, (k as f64 + 0.5).min(m) / m);
            (hi - lo).powi(2) / 12.0
        });
        let read = f64::from(response.read_noise);
        Self {
            signal,
            quantisation,
            read_variance: if read.is_finite() { read * read } else { 0.0 },
            shot: f64::from(response.shot_noise).max(0.0),
            max_code: max as u16,
        }
    }

    /// The average of `frames` of one pattern.
    pub(super) fn capture(&self, frames: &[CameraFrame]) -> Capture {
        let first = &frames[0].codes;
        let n = first.data.len();
        let k = frames.len() as f64;
        let mut out = Capture {
            width: first.width,
            height: first.height,
            signal: vec![0.0; n],
            variance: vec![0.0; n],
            peak: vec![0.0; n],
            clipped: vec![false; n],
        };
        let mut peak = vec![0.0f64; 3 * n];
        for frame in frames {
            for (i, codes) in frame.codes.data.iter().enumerate() {
                let mut sum = 0.0;
                let mut var = 0.0;
                for (c, &code) in codes.iter().enumerate() {
                    let code = code.min(self.max_code) as usize;
                    let s = f64::from(self.signal[c][code]);
                    sum += s;
                    peak[3 * i + c] += s;
                    var +=
                        self.shot * s + self.read_variance + f64::from(self.quantisation[c][code]);
                    out.clipped[i] |= code == self.max_code as usize;
                }
                out.signal[i] += (sum / k) as f32;
                out.variance[i] += (var / (k * k)) as f32;
            }
        }
        for (i, p) in out.peak.iter_mut().enumerate() {
            *p = ((peak[3 * i] + peak[3 * i + 1] + peak[3 * i + 2]) / k / 3.0)
                .max(peak[3 * i] / k)
                .max(peak[3 * i + 1] / k)
                .max(peak[3 * i + 2] / k) as f32;
        }
        out
    }
}

/// What is wrong with the reference frames.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferenceProblem {
    /// The white reference is too dark: its brightest percent of pixels
    /// reach `peak` of full scale.
    Dark {
        /// The 99th percentile of the white frame's largest channel.
        peak: f64,
    },
    /// Too many pixels clip.
    Saturated {
        /// `"white"` or `"black"`.
        frame: &'static str,
        /// Fraction of the pixels concerned that clip.
        fraction: f64,
    },
}

/// Check the reference frames: the white one neither dark nor clipping
/// on more than `saturated_fraction` of the pixels it lights, the black
/// one clipping nowhere much.
pub(super) fn check_references(
    white: &Capture,
    black: &Capture,
    settings: &DecodeSettings,
) -> Result<(), ReferenceProblem> {
    let n = white.signal.len();
    let black_clipped = black.clipped.iter().filter(|c| **c).count();
    if n > 0 && black_clipped as f64 > 0.01 * n as f64 {
        return Err(ReferenceProblem::Saturated {
            frame: "black",
            fraction: black_clipped as f64 / n as f64,
        });
    }
    let peak = peak99(white);
    if peak < settings.dark_fraction {
        return Err(ReferenceProblem::Dark { peak });
    }
    let lit: Vec<usize> = (0..n)
        .filter(|&i| is_lit(white, black, i, settings))
        .collect();
    let clipped = lit.iter().filter(|&&i| white.clipped[i]).count();
    if !lit.is_empty() && clipped as f64 > settings.saturated_fraction * lit.len() as f64 {
        return Err(ReferenceProblem::Saturated {
            frame: "white",
            fraction: clipped as f64 / lit.len() as f64,
        });
    }
    Ok(())
}

/// How bright a white reference is: the 99th percentile of its pixels'
/// largest channel, and the fraction of its lit pixels that clip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ExposureLevel {
    pub(super) peak: f64,
    pub(super) clipped: f64,
}

pub(super) fn exposure_level(
    white: &Capture,
    black: &Capture,
    settings: &DecodeSettings,
) -> ExposureLevel {
    let n = white.signal.len();
    let lit: Vec<usize> = (0..n)
        .filter(|&i| is_lit(white, black, i, settings))
        .collect();
    let clipped = lit.iter().filter(|&&i| white.clipped[i]).count();
    ExposureLevel {
        peak: peak99(white),
        clipped: if lit.is_empty() {
            0.0
        } else {
            clipped as f64 / lit.len() as f64
        },
    }
}

fn peak99(white: &Capture) -> f64 {
    let n = white.peak.len();
    let mut peaks = white.peak.clone();
    peaks.sort_by(f32::total_cmp);
    peaks
        .get(((n as f64 * 0.99) as usize).min(n.saturating_sub(1)))
        .map_or(0.0, |p| f64::from(*p))
}

fn is_lit(white: &Capture, black: &Capture, i: usize, settings: &DecodeSettings) -> bool {
    let contrast = f64::from(white.signal[i] - black.signal[i]);
    let sd = f64::from(white.variance[i] + black.variance[i]).sqrt();
    contrast > settings.min_contrast_sigmas * sd
}

/// Per camera pixel: the projector pixel it sees, if valid.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    /// Camera width.
    pub width: u32,
    /// Camera height.
    pub height: u32,
    /// Projector `(column, row)` per camera pixel; `None` where invalid.
    pub pixels: Vec<Option<(u32, u32)>>,
    /// Camera pixels the projector lights (the contrast test alone).
    pub lit: usize,
    /// Lit pixels with an unclear bit.
    pub unclear: usize,
    /// Lit pixels whose code falls outside the projector's image.
    pub out_of_range: usize,
}

impl Decoded {
    /// Valid pixels.
    pub fn valid(&self) -> usize {
        self.pixels.iter().filter(|p| p.is_some()).count()
    }
}

/// The streaming decode: the references first, then each pattern with its
/// inverse, so that only two captures are held at a time.
pub(super) struct Decoder {
    set: PatternSet,
    settings: DecodeSettings,
    white: Capture,
    black: Capture,
    /// Gray codes so far, per axis.
    codes: [Vec<u32>; 2],
    clear: Vec<bool>,
}

impl Decoder {
    pub(super) fn new(
        set: PatternSet,
        white: Capture,
        black: Capture,
        settings: DecodeSettings,
    ) -> Self {
        let n = white.signal.len();
        let clear = (0..n)
            .map(|i| is_lit(&white, &black, i, &settings))
            .collect();
        Self {
            set,
            settings,
            white,
            black,
            codes: [vec![0; n], vec![0; n]],
            clear,
        }
    }

    /// Add bit `bit` of `axis` from the capture of its pattern and of its
    /// inverse.
    pub(super) fn add(&mut self, axis: Axis, bit: u32, pattern: &Capture, inverse: &Capture) {
        let codes = &mut self.codes[axis as usize];
        for (i, code) in codes.iter_mut().enumerate() {
            let d = f64::from(pattern.signal[i] - inverse.signal[i]);
            let sd = f64::from(pattern.variance[i] + inverse.variance[i]).sqrt();
            let contrast = f64::from(self.white.signal[i] - self.black.signal[i]);
            if d.abs() <= self.settings.min_bit_sigmas * sd
                || d.abs() < self.settings.min_bit_fraction * contrast
            {
                self.clear[i] = false;
            }
            if d > 0.0 {
                *code |= 1 << bit;
            }
        }
    }

    /// The projector pixel of every camera pixel.
    pub(super) fn finish(self) -> Decoded {
        let n = self.clear.len();
        let lit: Vec<bool> = (0..n)
            .map(|i| is_lit(&self.white, &self.black, i, &self.settings))
            .collect();
        let (mut unclear, mut out_of_range) = (0, 0);
        let pixels = (0..n)
            .map(|i| {
                if !lit[i] {
                    return None;
                }
                if !self.clear[i] {
                    unclear += 1;
                    return None;
                }
                let x = gray_inverse(self.codes[0][i]);
                let y = gray_inverse(self.codes[1][i]);
                if x >= self.set.width || y >= self.set.height {
                    out_of_range += 1;
                    return None;
                }
                Some((x, y))
            })
            .collect();
        Decoded {
            width: self.white.width,
            height: self.white.height,
            pixels,
            lit: lit.iter().filter(|l| **l).count(),
            unclear,
            out_of_range,
        }
    }
}
