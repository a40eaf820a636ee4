//! Real cameras behind the hardware seam
//! ([`showcase_light::hardware::CameraDevice`]): frame decoding
//! ([`decode`]), the choice of a pixel format among those a camera offers
//! ([`negotiate`]), the level checks that stop a capture on a saturated or
//! dark frame ([`check_levels`]), a V4L2 backend for Linux (`v4l2`, cargo
//! feature `v4l2`) and a recorded camera that replays a folder of captured
//! frames ([`recorded`]).
//!
//! Exposure and gain are always manual: the capture's radiance maps divide
//! codes by a fixed `gain * exposure`, which auto exposure, auto gain or
//! auto white balance would silently change from frame to frame.

pub mod decode;
pub mod recorded;
#[cfg(all(feature = "v4l2", target_os = "linux"))]
pub mod v4l2;

use decode::{PixelFormat, fourcc_string};
use showcase_light::hardware::CameraFrame;
use std::fmt;

/// One frame with the time the camera stamped it.
#[derive(Clone, Debug, PartialEq)]
pub struct TimedFrame {
    /// The decoded frame.
    pub frame: CameraFrame,
    /// When the frame was taken, in seconds on the camera's clock (V4L2:
    /// `CLOCK_MONOTONIC`, usually the end of the frame's readout; see
    /// [`TimedFrame::start_of_exposure`]).
    pub timestamp_s: f64,
    /// Whether `timestamp_s` is the start of the exposure (V4L2's
    /// `TSTAMP_SRC_SOE`) rather than the end of the frame.
    pub start_of_exposure: bool,
    /// The frame's sequence number (gaps are dropped frames).
    pub sequence: u32,
    /// Exposure time the frame was taken with, in seconds.
    pub exposure_s: f64,
}

/// The frame sizes a camera offers for one pixel format.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameSizes {
    /// A list of sizes (what UVC cameras report).
    Discrete(Vec<(u32, u32)>),
    /// Any size from `min` to `max` in steps (of 1 for V4L2's continuous).
    Stepwise {
        /// Smallest width and height.
        min: (u32, u32),
        /// Largest width and height.
        max: (u32, u32),
        /// Width and height steps.
        step: (u32, u32),
    },
}

impl FrameSizes {
    /// Whether `(width, height)` is one of the sizes.
    pub fn contains(&self, (width, height): (u32, u32)) -> bool {
        match self {
            FrameSizes::Discrete(sizes) => sizes.contains(&(width, height)),
            FrameSizes::Stepwise { min, max, step } => {
                let fits = |v: u32, lo: u32, hi: u32, s: u32| {
                    (lo..=hi).contains(&v) && (v - lo).is_multiple_of(s.max(1))
                };
                fits(width, min.0, max.0, step.0) && fits(height, min.1, max.1, step.1)
            }
        }
    }
}

impl fmt::Display for FrameSizes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameSizes::Discrete(sizes) if sizes.is_empty() => f.write_str("no sizes"),
            FrameSizes::Discrete(sizes) => {
                let list: Vec<String> = sizes.iter().map(|(w, h)| format!("{w}x{h}")).collect();
                f.write_str(&list.join(", "))
            }
            FrameSizes::Stepwise { min, max, step } => write!(
                f,
                "{}x{} to {}x{} in steps of {}x{}",
                min.0, min.1, max.0, max.1, step.0, step.1
            ),
        }
    }
}

/// A pixel format a camera offers, with its sizes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OfferedFormat {
    /// The V4L2 fourcc code (also formats this module cannot decode).
    pub fourcc: u32,
    /// The driver's description.
    pub description: String,
    /// Sizes offered in this format.
    pub sizes: FrameSizes,
}

impl fmt::Display for OfferedFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = fourcc_string(self.fourcc);
        let decodable = if PixelFormat::from_fourcc(self.fourcc).is_some() {
            ""
        } else {
            " (not decoded by Showcase)"
        };
        write!(
            f,
            "{} '{}'{decodable}: {}",
            name.trim_end(),
            self.description,
            self.sizes
        )
    }
}

/// What a capture asks of a camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FormatRequest {
    /// The pixel format, or `None` for the first the camera offers at the
    /// size in the order of [`PixelFormat::ALL`].
    pub format: Option<PixelFormat>,
    /// Width in pixels (the calibrated camera's: never rescaled).
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// The format and size a negotiation settled on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FormatChoice {
    /// Pixel format.
    pub format: PixelFormat,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl fmt::Display for FormatChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}x{}", self.format, self.width, self.height)
    }
}

/// Why no format could be chosen; each says what to change.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum NegotiationError {
    /// The camera offers no format at all.
    #[error(
        "the camera offers no pixel format: is it a capture device (try the next /dev/videoN)?"
    )]
    NothingOffered,
    /// The camera offers only formats this module cannot decode.
    #[error(
        "the camera offers only formats Showcase cannot decode ({offered}); use a camera that \
         sends YUYV, MJPEG, NV12, YU12, UYVY, RGB24, BGR24, GREY or Y16"
    )]
    NothingDecodable {
        /// The offered formats.
        offered: String,
    },
    /// The requested format is not offered.
    #[error(
        "the camera does not offer {format}; it offers:\n{offered}\nask for one of these formats \
         (or none, to let Showcase choose)"
    )]
    FormatNotOffered {
        /// Requested format.
        format: PixelFormat,
        /// The offered formats and sizes, one a line.
        offered: String,
    },
    /// No decodable format is offered at the requested size.
    #[error(
        "the camera does not deliver {what} at {width}x{height}; it offers:\n{offered}\nask for \
         one of these sizes (the camera's calibration must be redone at the new size)"
    )]
    SizeNotOffered {
        /// The format asked for, or "any decodable format".
        what: String,
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// The offered formats and sizes, one a line.
        offered: String,
    },
    /// The driver set another format or size than the one chosen.
    #[error(
        "asked the camera for {asked}, it switched to {got} instead: ask for a format and size \
         that `showcase-camera formats` lists"
    )]
    Refused {
        /// What was asked.
        asked: FormatChoice,
        /// What the driver applied (fourcc as text).
        got: String,
    },
}

fn offered_list(offered: &[OfferedFormat]) -> String {
    offered
        .iter()
        .map(|o| format!("  {o}"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Chooses the format and size to ask the camera for among those it
/// `offered` (a pure function: the V4L2 backend feeds it the driver's
/// enumeration). The size must be offered exactly: a rescaled image would
/// not match the camera's calibration.
pub fn negotiate(
    offered: &[OfferedFormat],
    request: &FormatRequest,
) -> Result<FormatChoice, NegotiationError> {
    if offered.is_empty() {
        return Err(NegotiationError::NothingOffered);
    }
    let size = (request.width, request.height);
    let choice = |format| FormatChoice {
        format,
        width: request.width,
        height: request.height,
    };
    let offers = |format: PixelFormat| offered.iter().filter(move |o| o.fourcc == format.fourcc());
    match request.format {
        Some(format) => {
            if offers(format).next().is_none() {
                return Err(NegotiationError::FormatNotOffered {
                    format,
                    offered: offered_list(offered),
                });
            }
            if offers(format).any(|o| o.sizes.contains(size)) {
                Ok(choice(format))
            } else {
                Err(NegotiationError::SizeNotOffered {
                    what: format.to_string(),
                    width: request.width,
                    height: request.height,
                    offered: offered_list(offered),
                })
            }
        }
        None => {
            if !offered
                .iter()
                .any(|o| PixelFormat::from_fourcc(o.fourcc).is_some())
            {
                let names: Vec<String> = offered
                    .iter()
                    .map(|o| fourcc_string(o.fourcc).trim_end().to_string())
                    .collect();
                return Err(NegotiationError::NothingDecodable {
                    offered: names.join(", "),
                });
            }
            PixelFormat::ALL
                .into_iter()
                .find(|&f| offers(f).any(|o| o.sizes.contains(size)))
                .map(choice)
                .ok_or_else(|| NegotiationError::SizeNotOffered {
                    what: "any decodable format".into(),
                    width: request.width,
                    height: request.height,
                    offered: offered_list(offered),
                })
        }
    }
}

/// Checks that the format the driver applied is the one chosen (drivers
/// silently substitute the nearest format or size they support).
pub fn check_applied(
    asked: &FormatChoice,
    fourcc: u32,
    width: u32,
    height: u32,
) -> Result<(), NegotiationError> {
    if fourcc == asked.format.fourcc() && (width, height) == (asked.width, asked.height) {
        Ok(())
    } else {
        Err(NegotiationError::Refused {
            asked: *asked,
            got: format!("{} {width}x{height}", fourcc_string(fourcc).trim_end()),
        })
    }
}

/// Bounds on a frame's levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelLimits {
    /// Largest fraction of pixels allowed at the top code in any channel.
    pub max_saturated_fraction: f64,
    /// The fraction of pixels that may be brighter than the "peak" (0.001:
    /// the peak is the 99.9th percentile, robust to a few hot pixels).
    pub peak_quantile: f64,
    /// Smallest peak, as a fraction of full scale, of a frame of the
    /// white-lit scene (paper 3.2 sets the gain so the peak is near 90 %).
    pub min_peak_fraction: f64,
}

impl Default for LevelLimits {
    fn default() -> Self {
        Self {
            max_saturated_fraction: 0.001,
            peak_quantile: 0.001,
            min_peak_fraction: 0.5,
        }
    }
}

/// The levels of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Levels {
    /// Fraction of pixels with some channel at the top code.
    pub saturated_fraction: f64,
    /// The peak code (see [`LevelLimits::peak_quantile`]) over channels.
    pub peak: u16,
    /// The top code, `2^bits - 1`.
    pub top: u16,
}

impl Levels {
    /// The levels of `frame`.
    pub fn of(frame: &CameraFrame, peak_quantile: f64) -> Self {
        let top = ((1u32 << frame.bits.clamp(1, 16)) - 1) as u16;
        let n = frame.codes.data.len();
        let mut saturated = 0usize;
        let mut maxima: Vec<u16> = Vec::with_capacity(n);
        for c in &frame.codes.data {
            let m = c[0].max(c[1]).max(c[2]);
            saturated += usize::from(m >= top);
            maxima.push(m.min(top));
        }
        let peak = if n == 0 {
            0
        } else {
            let above = ((n as f64 * peak_quantile.clamp(0.0, 1.0)).floor() as usize).min(n - 1);
            let (_, p, _) = maxima.select_nth_unstable(n - 1 - above);
            *p
        };
        Self {
            saturated_fraction: if n == 0 {
                0.0
            } else {
                saturated as f64 / n as f64
            },
            peak,
            top,
        }
    }
}

/// The camera settings a level message names, so that it can say what to
/// change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Exposure time in seconds.
    pub exposure_s: f64,
    /// The camera's gain control value, when known (a recording does not
    /// know it).
    pub gain: Option<i64>,
}

impl fmt::Display for Settings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "exposure {:.2} ms", self.exposure_s * 1e3)?;
        match self.gain {
            Some(g) => write!(f, ", gain {g}"),
            None => Ok(()),
        }
    }
}

/// A frame too bright or too dark to measure with.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LevelError {
    /// Too many pixels at the top code.
    #[error(
        "saturated frame: {:.2} % of the pixels are at the top code {} (at most {:.2} % allowed) \
         with {settings}; lower the exposure or the gain (or close the aperture) and capture again",
        .levels.saturated_fraction * 100.0, .levels.top, .limit * 100.0
    )]
    Saturated {
        /// The frame's levels.
        levels: Levels,
        /// The largest fraction allowed.
        limit: f64,
        /// The settings in use.
        settings: Settings,
    },
    /// The white-lit scene's peak is too low.
    #[error(
        "dark frame: the brightest pixels reach only code {} of {} ({:.0} %, at least {:.0} % \
         needed) with {settings}; raise the exposure or the gain (or open the aperture, check the \
         lens cap and that the projector shows white) and capture again",
        .levels.peak, .levels.top, .levels.peak as f64 / .levels.top.max(1) as f64 * 100.0,
        .min_fraction * 100.0
    )]
    Dark {
        /// The frame's levels.
        levels: Levels,
        /// The smallest peak allowed, as a fraction of full scale.
        min_fraction: f64,
        /// The settings in use.
        settings: Settings,
    },
}

/// Checks that `frame` is not saturated (every capture).
pub fn check_saturation(
    frame: &CameraFrame,
    limits: &LevelLimits,
    settings: Settings,
) -> Result<Levels, LevelError> {
    let levels = Levels::of(frame, limits.peak_quantile);
    if levels.saturated_fraction > limits.max_saturated_fraction {
        return Err(LevelError::Saturated {
            levels,
            limit: limits.max_saturated_fraction,
            settings,
        });
    }
    Ok(levels)
}

/// Checks a frame of the white-lit scene: neither saturated nor dark (the
/// setup check before a capture).
pub fn check_levels(
    frame: &CameraFrame,
    limits: &LevelLimits,
    settings: Settings,
) -> Result<Levels, LevelError> {
    let levels = check_saturation(frame, limits, settings)?;
    if f64::from(levels.peak) < limits.min_peak_fraction * f64::from(levels.top) {
        return Err(LevelError::Dark {
            levels,
            min_fraction: limits.min_peak_fraction,
            settings,
        });
    }
    Ok(levels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use decode::fourcc;
    use showcase_light::Image;

    fn uvc_offer() -> Vec<OfferedFormat> {
        vec![
            OfferedFormat {
                fourcc: fourcc(b"MJPG"),
                description: "Motion-JPEG".into(),
                sizes: FrameSizes::Discrete(vec![(1920, 1080), (1280, 720), (640, 480)]),
            },
            OfferedFormat {
                fourcc: fourcc(b"YUYV"),
                description: "YUYV 4:2:2".into(),
                sizes: FrameSizes::Discrete(vec![(1280, 720), (640, 480)]),
            },
            OfferedFormat {
                fourcc: fourcc(b"H264"),
                description: "H.264".into(),
                sizes: FrameSizes::Discrete(vec![(1920, 1080)]),
            },
        ]
    }

    fn ask(format: Option<PixelFormat>, width: u32, height: u32) -> FormatRequest {
        FormatRequest {
            format,
            width,
            height,
        }
    }

    #[test]
    fn prefers_uncompressed_then_falls_back_to_mjpeg() {
        let offer = uvc_offer();
        let c = negotiate(&offer, &ask(None, 640, 480)).unwrap();
        assert_eq!(c.format, PixelFormat::Yuyv);
        // Only MJPEG (and undecodable H.264) at full HD.
        let c = negotiate(&offer, &ask(None, 1920, 1080)).unwrap();
        assert_eq!(
            (c.format, c.width, c.height),
            (PixelFormat::Mjpeg, 1920, 1080)
        );
        let c = negotiate(&offer, &ask(Some(PixelFormat::Mjpeg), 640, 480)).unwrap();
        assert_eq!(c.format, PixelFormat::Mjpeg);
    }

    #[test]
    fn errors_say_what_is_offered() {
        let offer = uvc_offer();
        let e = negotiate(&offer, &ask(Some(PixelFormat::Yuyv), 1920, 1080)).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, NegotiationError::SizeNotOffered { .. }));
        assert!(
            text.contains("does not deliver YUYV at 1920x1080"),
            "{text}"
        );
        assert!(
            text.contains("YUYV 'YUYV 4:2:2': 1280x720, 640x480"),
            "{text}"
        );
        assert!(
            text.contains("H264 'H.264' (not decoded by Showcase)"),
            "{text}"
        );
        let e = negotiate(&offer, &ask(Some(PixelFormat::Nv12), 640, 480)).unwrap_err();
        assert!(
            e.to_string().starts_with("the camera does not offer NV12"),
            "{e}"
        );
        let e = negotiate(&offer, &ask(None, 800, 600)).unwrap_err();
        assert!(
            e.to_string().contains("any decodable format at 800x600"),
            "{e}"
        );
        assert_eq!(
            negotiate(&[], &ask(None, 640, 480)),
            Err(NegotiationError::NothingOffered)
        );
        let h264 = vec![offer[2].clone()];
        let e = negotiate(&h264, &ask(None, 1920, 1080)).unwrap_err();
        assert!(
            e.to_string()
                .contains("only formats Showcase cannot decode (H264)"),
            "{e}"
        );
    }

    #[test]
    fn stepwise_sizes_follow_their_steps() {
        let offer = vec![OfferedFormat {
            fourcc: fourcc(b"GREY"),
            description: "Greyscale".into(),
            sizes: FrameSizes::Stepwise {
                min: (16, 16),
                max: (2048, 1536),
                step: (16, 2),
            },
        }];
        assert_eq!(
            negotiate(&offer, &ask(None, 640, 480)).unwrap().format,
            PixelFormat::Grey
        );
        assert!(negotiate(&offer, &ask(None, 650, 480)).is_err());
        assert!(negotiate(&offer, &ask(None, 640, 481)).is_err());
        assert!(negotiate(&offer, &ask(None, 4096, 480)).is_err());
        // A zero step (a broken driver) counts as 1, not a division by 0.
        let zero = FrameSizes::Stepwise {
            min: (1, 1),
            max: (10, 10),
            step: (0, 0),
        };
        assert!(zero.contains((5, 7)));
    }

    #[test]
    fn a_substituted_format_is_refused() {
        let asked = FormatChoice {
            format: PixelFormat::Yuyv,
            width: 1280,
            height: 720,
        };
        assert!(check_applied(&asked, fourcc(b"YUYV"), 1280, 720).is_ok());
        let e = check_applied(&asked, fourcc(b"YUYV"), 640, 480).unwrap_err();
        assert!(e.to_string().contains("switched to YUYV 640x480"), "{e}");
        assert!(check_applied(&asked, fourcc(b"MJPG"), 1280, 720).is_err());
    }

    fn frame(codes: impl Fn(u32) -> u16) -> CameraFrame {
        CameraFrame {
            codes: Image::from_fn(100, 100, |x, y| [codes(y * 100 + x); 3]),
            bits: 8,
        }
    }

    #[test]
    fn level_checks_name_what_to_change() {
        let settings = Settings {
            exposure_s: 0.02,
            gain: Some(64),
        };
        let limits = LevelLimits::default();
        // Peak 230 of 255, nothing saturated.
        let good = frame(|i| (i % 231) as u16);
        let l = check_levels(&good, &limits, settings).unwrap();
        assert_eq!((l.peak, l.top, l.saturated_fraction), (230, 255, 0.0));
        // 1 % of the pixels at 255.
        let hot = frame(|i| if i % 100 == 0 { 255 } else { 100 });
        let e = check_levels(&hot, &limits, settings).unwrap_err();
        let text = e.to_string();
        assert!(
            text.starts_with("saturated frame: 1.00 % of the pixels"),
            "{text}"
        );
        assert!(text.contains("exposure 20.00 ms, gain 64; lower the exposure or the gain"));
        // A few hot pixels (0.05 %) pass and do not count as the peak.
        let few = frame(|i| if i % 2000 == 0 { 255 } else { 40 });
        let e = check_levels(&few, &limits, settings).unwrap_err();
        let text = e.to_string();
        assert!(text.starts_with("dark frame: the brightest pixels reach only code 40 of 255"));
        assert!(text.contains("raise the exposure or the gain"), "{text}");
        // A dark frame is fine for a capture (a projector showing black).
        assert!(check_saturation(&few, &limits, settings).is_ok());
        // An empty frame has no levels to fail.
        let empty = CameraFrame {
            codes: Image::new(0, 0, [0; 3]),
            bits: 8,
        };
        assert!(check_saturation(&empty, &limits, settings).is_ok());
    }
}
