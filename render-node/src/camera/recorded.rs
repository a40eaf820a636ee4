//! A recorded camera: replays a folder of captured frames through
//! [`CameraDevice`], for tests and for re-running a capture offline.
//!
//! # The folder
//! - `camera.json`: `{"format": "showcase-recorded-camera/1", "device":
//!   PinholeDevice, "response": CameraResponse, "bits": 8, "frames": [{"file":
//!   "frame-00000.png", "timestamp_s": 12.5, "exposure_s": 0.02, "sequence":
//!   0}, ...]}`; `device` and `response` are the scene format's (`PinholeDevice`,
//!   `CameraResponse`), `timestamp_s` the camera's clock (V4L2:
//!   `CLOCK_MONOTONIC`), `file` a name inside the folder.
//! - One RGB PNG per frame whose values are the codes themselves: 8-bit
//!   for `bits <= 8`, 16-bit otherwise (greyscale PNGs are read as three
//!   equal channels).
//!
//! [`Recorder`] writes such a folder; `showcase-camera record` fills one
//! from a real camera.

use super::TimedFrame;
use serde::{Deserialize, Serialize};
use showcase_light::Image;
use showcase_light::hardware::{CameraDevice, CameraFrame};
use showcase_proto::{CameraResponse, PinholeDevice};
use std::path::{Path, PathBuf};

/// The `format` tag of `camera.json`.
pub const FORMAT: &str = "showcase-recorded-camera/1";
/// The index file's name.
pub const INDEX: &str = "camera.json";

/// `camera.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordingIndex {
    /// [`FORMAT`].
    pub format: String,
    /// The camera's geometry.
    pub device: PinholeDevice,
    /// The camera's photometric calibration.
    pub response: CameraResponse,
    /// Bits per channel of every frame.
    pub bits: u32,
    /// The frames in capture order.
    pub frames: Vec<RecordedFrame>,
}

/// One frame of `camera.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedFrame {
    /// The PNG's name inside the folder.
    pub file: String,
    /// The camera's timestamp, in seconds.
    pub timestamp_s: f64,
    /// Exposure time, in seconds.
    pub exposure_s: f64,
    /// The camera's sequence number.
    #[serde(default)]
    pub sequence: u32,
}

/// What is wrong with a recording; each names the folder or file.
#[derive(Debug, thiserror::Error)]
pub enum RecordedError {
    /// The folder or a file could not be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The error.
        error: std::io::Error,
    },
    /// `camera.json` is not a recording index.
    #[error("{path}: not a recorded camera's index: {reason}")]
    Index {
        /// Path of `camera.json`.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A frame's PNG is unreadable or does not fit the index.
    #[error("{path}: {reason}")]
    Frame {
        /// The PNG's path.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Every frame was replayed.
    #[error(
        "{dir}: the recording holds {frames} frames and the capture asked for one more: record \
         the capture again with at least as many frames"
    )]
    Exhausted {
        /// The folder.
        dir: PathBuf,
        /// Frames in the recording.
        frames: usize,
    },
    /// The capture asks for another exposure than the frame was taken with.
    #[error(
        "{dir}: frame {index} was recorded with a {recorded_ms:.3} ms exposure, the capture asks \
         {asked_ms:.3} ms: replay it with the recording's exposure"
    )]
    Exposure {
        /// The folder.
        dir: PathBuf,
        /// Index of the frame.
        index: usize,
        /// Recorded exposure, ms.
        recorded_ms: f64,
        /// Asked exposure, ms.
        asked_ms: f64,
    },
    /// The capture asks for another gain than the recording's.
    #[error(
        "{dir}: the recording's camera has gain {recorded}, the capture asks {asked}: a \
         recording cannot change its gain; capture with the recording's camera calibration, or \
         record again at the new gain"
    )]
    Gain {
        /// The folder.
        dir: PathBuf,
        /// The recording's gain.
        recorded: f64,
        /// The asked gain.
        asked: f64,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> RecordedError + '_ {
    move |error| RecordedError::Io {
        path: path.to_path_buf(),
        error,
    }
}

/// Replays a recorded folder.
#[derive(Debug)]
pub struct RecordedCamera {
    dir: PathBuf,
    index: RecordingIndex,
    next: usize,
}

impl RecordedCamera {
    /// Opens the recording in `dir`, checking its index and that every
    /// frame file exists (frames are read as they are replayed).
    pub fn open(dir: impl AsRef<Path>) -> Result<Self, RecordedError> {
        let dir = dir.as_ref().to_path_buf();
        let path = dir.join(INDEX);
        if !path.is_file() && dir.is_dir() {
            return Err(RecordedError::Index {
                path,
                reason: "missing: this folder is no recording (`showcase-camera record` makes one)"
                    .into(),
            });
        }
        let text = std::fs::read_to_string(&path).map_err(io(&path))?;
        let bad = |reason: String| RecordedError::Index {
            path: path.clone(),
            reason,
        };
        let index: RecordingIndex = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if index.format != FORMAT {
            return Err(bad(format!(
                "format is {:?}, this build reads {FORMAT:?}",
                index.format
            )));
        }
        if !(1..=16).contains(&index.bits) {
            return Err(bad(format!("bits is {}, must be 1 to 16", index.bits)));
        }
        if index.response.bits != index.bits {
            return Err(bad(format!(
                "the frames have {} bits, the response {} bits",
                index.bits, index.response.bits
            )));
        }
        if index.device.width == 0 || index.device.height == 0 {
            return Err(bad(format!(
                "the device is {}x{} pixels",
                index.device.width, index.device.height
            )));
        }
        if index.frames.is_empty() {
            return Err(bad("no frames".into()));
        }
        for (i, f) in index.frames.iter().enumerate() {
            let name = Path::new(&f.file);
            if f.file.is_empty()
                || name.is_absolute()
                || name.components().count() != 1
                || f.file == ".."
            {
                return Err(bad(format!(
                    "frame {i}: file {:?} must be a plain file name inside the folder",
                    f.file
                )));
            }
            if !(f.timestamp_s.is_finite() && f.exposure_s.is_finite() && f.exposure_s >= 0.0) {
                return Err(bad(format!(
                    "frame {i}: timestamp {} s / exposure {} s must be finite and the exposure \
                     not negative",
                    f.timestamp_s, f.exposure_s
                )));
            }
            let file = dir.join(&f.file);
            if !file.is_file() {
                return Err(RecordedError::Frame {
                    path: file,
                    reason: format!("frame {i} of {INDEX} is missing"),
                });
            }
        }
        Ok(Self {
            dir,
            index,
            next: 0,
        })
    }

    /// The recording's folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The recording's index.
    pub fn index(&self) -> &RecordingIndex {
        &self.index
    }

    /// Frames not yet replayed.
    pub fn remaining(&self) -> usize {
        self.index.frames.len() - self.next
    }

    /// Starts the replay over.
    pub fn rewind(&mut self) {
        self.next = 0;
    }

    /// `Err` when the next frame was recorded with another exposure than
    /// `exposure_s` (more than 1 % off): a recording cannot change its
    /// exposure. `Ok` when no frame is left ([`Self::next_frame`] says so).
    pub fn check_exposure(&self, exposure_s: f64) -> Result<(), RecordedError> {
        if let Some(entry) = self.index.frames.get(self.next) {
            let recorded = entry.exposure_s;
            let off = (exposure_s - recorded).abs();
            if off.is_nan() || off > 0.01 * recorded.max(1e-9) {
                return Err(RecordedError::Exposure {
                    dir: self.dir.clone(),
                    index: self.next,
                    recorded_ms: recorded * 1e3,
                    asked_ms: exposure_s * 1e3,
                });
            }
        }
        Ok(())
    }

    /// `Err` when `gain` (signal per unit radiance and second) is not the
    /// recording's calibrated gain (more than 0.1 % off): a recording cannot
    /// change its gain.
    pub fn check_gain(&self, gain: f64) -> Result<(), RecordedError> {
        let recorded = f64::from(self.index.response.gain);
        let off = (gain - recorded).abs();
        if off.is_nan() || off > 1e-3 * recorded.abs().max(1e-9) {
            return Err(RecordedError::Gain {
                dir: self.dir.clone(),
                recorded,
                asked: gain,
            });
        }
        Ok(())
    }

    /// The next frame, whatever its exposure.
    pub fn next_frame(&mut self) -> Result<TimedFrame, RecordedError> {
        let Some(entry) = self.index.frames.get(self.next) else {
            return Err(RecordedError::Exhausted {
                dir: self.dir.clone(),
                frames: self.index.frames.len(),
            });
        };
        let path = self.dir.join(&entry.file);
        let codes = read_codes(&path, self.index.bits)?;
        let (w, h) = (self.index.device.width, self.index.device.height);
        if (codes.width, codes.height) != (w, h) {
            return Err(RecordedError::Frame {
                path,
                reason: format!(
                    "{}x{} pixels, the recorded camera is {w}x{h}",
                    codes.width, codes.height
                ),
            });
        }
        self.next += 1;
        Ok(TimedFrame {
            frame: CameraFrame {
                codes,
                bits: self.index.bits,
            },
            timestamp_s: entry.timestamp_s,
            start_of_exposure: false,
            sequence: entry.sequence,
            exposure_s: entry.exposure_s,
        })
    }
}

impl CameraDevice for RecordedCamera {
    type Error = RecordedError;

    fn device(&self) -> &PinholeDevice {
        &self.index.device
    }

    fn response(&self) -> &CameraResponse {
        &self.index.response
    }

    /// The next recorded frame; `start_s` is not replayed (the recording's
    /// timestamps are), the exposure must match the recorded one within
    /// 1 %.
    fn capture(&mut self, _start_s: f64, exposure_s: f64) -> Result<CameraFrame, RecordedError> {
        self.check_exposure(exposure_s)?;
        self.next_frame().map(|f| f.frame)
    }
}

/// Reads a frame PNG's codes, checking they fit `bits`.
fn read_codes(path: &Path, bits: u32) -> Result<Image<[u16; 3]>, RecordedError> {
    let bad = |reason: String| RecordedError::Frame {
        path: path.to_path_buf(),
        reason,
    };
    let file = std::fs::File::open(path).map_err(io(path))?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder
        .read_info()
        .map_err(|e| bad(format!("not a readable PNG ({e})")))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| bad(format!("not a readable PNG ({e})")))?;
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Grayscale => 1,
        other => return Err(bad(format!("{other:?} PNG, RGB or greyscale expected"))),
    };
    let wide = match info.bit_depth {
        png::BitDepth::Eight => false,
        png::BitDepth::Sixteen => true,
        other => return Err(bad(format!("{other:?}-bit PNG, 8 or 16 expected"))),
    };
    if wide != (bits > 8) {
        return Err(bad(format!(
            "{}-bit PNG, the recording has {bits}-bit codes (8-bit PNGs up to 8 bits, 16-bit above)",
            if wide { 16 } else { 8 }
        )));
    }
    let sample = |i: usize| -> u16 {
        if wide {
            u16::from_be_bytes([buf[2 * i], buf[2 * i + 1]])
        } else {
            u16::from(buf[i])
        }
    };
    let (w, h) = (info.width, info.height);
    let n = w as usize * h as usize;
    let needed = n * channels * if wide { 2 } else { 1 };
    if info.buffer_size() < needed || buf.len() < needed {
        return Err(bad("truncated PNG".into()));
    }
    let stride = info.line_size / if wide { 2 } else { 1 };
    let top = (1u32 << bits) - 1;
    let mut data = Vec::with_capacity(n);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let i = y * stride + x * channels;
            let px = if channels == 3 {
                [sample(i), sample(i + 1), sample(i + 2)]
            } else {
                [sample(i); 3]
            };
            if px.iter().any(|&c| u32::from(c) > top) {
                return Err(bad(format!(
                    "pixel ({x}, {y}) has code {}, above the top code {top} of {bits} bits",
                    px.iter().max().copied().unwrap_or(0)
                )));
            }
            data.push(px);
        }
    }
    Ok(Image {
        width: w,
        height: h,
        data,
    })
}

/// Writes a frame's codes as an RGB PNG (8-bit up to 8 bits, else 16).
fn write_codes(path: &Path, frame: &CameraFrame) -> Result<(), RecordedError> {
    let file = std::fs::File::create(path).map_err(io(path))?;
    let codes = &frame.codes;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), codes.width, codes.height);
    enc.set_color(png::ColorType::Rgb);
    let wide = frame.bits > 8;
    enc.set_depth(if wide {
        png::BitDepth::Sixteen
    } else {
        png::BitDepth::Eight
    });
    let bytes: Vec<u8> = if wide {
        codes
            .data
            .iter()
            .flat_map(|p| p.iter().flat_map(|c| c.to_be_bytes()))
            .collect()
    } else {
        codes
            .data
            .iter()
            .flat_map(|p| p.map(|c| c.min(255) as u8))
            .collect()
    };
    let png_error = |e: png::EncodingError| RecordedError::Frame {
        path: path.to_path_buf(),
        reason: format!("cannot write the PNG ({e})"),
    };
    enc.write_header()
        .and_then(|mut w| w.write_image_data(&bytes).and_then(|()| w.finish()))
        .map_err(png_error)
}

/// Writes a recording folder frame by frame; [`Recorder::finish`] writes
/// its index.
#[derive(Debug)]
pub struct Recorder {
    dir: PathBuf,
    index: RecordingIndex,
}

impl Recorder {
    /// Starts a recording in `dir` (created if missing; an existing
    /// recording there is replaced when [`Recorder::finish`] runs).
    pub fn create(
        dir: impl AsRef<Path>,
        device: PinholeDevice,
        response: CameraResponse,
    ) -> Result<Self, RecordedError> {
        let dir = dir.as_ref().to_path_buf();
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        Ok(Self {
            dir,
            index: RecordingIndex {
                format: FORMAT.into(),
                bits: response.bits,
                device,
                response,
                frames: Vec::new(),
            },
        })
    }

    /// Adds one frame.
    pub fn push(&mut self, frame: &TimedFrame) -> Result<(), RecordedError> {
        let file = format!("frame-{:05}.png", self.index.frames.len());
        let path = self.dir.join(&file);
        let codes = &frame.frame.codes;
        let (w, h) = (self.index.device.width, self.index.device.height);
        if frame.frame.bits != self.index.bits || (codes.width, codes.height) != (w, h) {
            return Err(RecordedError::Frame {
                path,
                reason: format!(
                    "a {}x{} frame of {} bits, the recording is {w}x{h} of {} bits",
                    codes.width, codes.height, frame.frame.bits, self.index.bits
                ),
            });
        }
        write_codes(&path, &frame.frame)?;
        self.index.frames.push(RecordedFrame {
            file,
            timestamp_s: frame.timestamp_s,
            exposure_s: frame.exposure_s,
            sequence: frame.sequence,
        });
        Ok(())
    }

    /// Writes `camera.json` and returns the folder.
    pub fn finish(self) -> Result<PathBuf, RecordedError> {
        let path = self.dir.join(INDEX);
        let text = serde_json::to_string_pretty(&self.index).map_err(|e| RecordedError::Index {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        std::fs::write(&path, text).map_err(io(&path))?;
        Ok(self.dir)
    }
}
