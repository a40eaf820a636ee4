//! Capture through the cluster (paper section 3): the master asks a
//! projector node to show a [`Pattern`] and a camera node to capture frames
//! ([`CaptureFrames`]) with fixed exposure and gain; the frames come back as
//! [`FrameChunk`]s, size-limited and validated, and are put together by a
//! [`FrameAssembler`] that refuses anything out of order, oversized or
//! mismatched. Captured reflectance maps travel in the scene snapshot
//! ([`CapturedMap`]). Pure: no IO, no clock.

use crate::scene::PinholeDevice;
use crate::validate::{MAX_RESOLUTION, Validate, ValidationError};
use serde::{Deserialize, Serialize};

/// Largest payload of one [`FrameChunk`] (bytes).
pub const MAX_CHUNK_BYTES: usize = 1 << 20;
/// Most frames one [`CaptureFrames`] may ask for.
pub const MAX_CAPTURE_FRAMES: u32 = 256;
/// Most runs of a [`Pattern::Mask`].
pub const MAX_PATTERN_RUNS: usize = 1 << 22;
/// Longest exposure a capture may ask for (s).
pub const MAX_EXPOSURE_S: f64 = 60.0;
/// Longest reason of a [`CaptureFailed`] (bytes).
pub const MAX_REASON_LEN: usize = 4096;
/// Most reflectance maps a snapshot carries.
pub const MAX_MAPS: usize = 64;
/// Bytes per pixel of a frame on the wire: three little-endian `u16` codes.
pub const BYTES_PER_PIXEL: usize = 6;

/// What a projector shows, described rather than shipped as an image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Pattern {
    /// Every pixel at one level (linear pixel values per channel, `[0, 1]`).
    Full {
        /// The level.
        level: [f32; 3],
    },
    /// A binary mask of the projector's image (one piece of a piecewise
    /// capture): `level` where set, black elsewhere. `runs` are run
    /// lengths in row-major order, alternating unset and set, starting
    /// with unset (so a mask that starts set begins with a 0 run); they
    /// sum to `width * height`.
    Mask {
        /// Image width (the projector's).
        width: u32,
        /// Image height.
        height: u32,
        /// Run lengths.
        runs: Vec<u32>,
        /// Level of set pixels.
        level: [f32; 3],
    },
    /// Structured light: bit `bit` of the Gray code of each pixel's column
    /// (`columns`) or row, `level` where the bit is 1 (0 if `inverted`),
    /// black elsewhere.
    GrayCode {
        /// Code the column (else the row).
        columns: bool,
        /// The bit (0: least significant).
        bit: u32,
        /// Swap set and unset.
        inverted: bool,
        /// Level of set pixels.
        level: [f32; 3],
    },
}

impl Pattern {
    /// A mask pattern from one flag per pixel (row-major).
    pub fn mask(
        width: u32,
        height: u32,
        set: impl IntoIterator<Item = bool>,
        level: [f32; 3],
    ) -> Self {
        let mut runs = Vec::new();
        let mut current = false;
        let mut run = 0u32;
        for s in set {
            if s != current {
                runs.push(run);
                run = 0;
                current = s;
            }
            run += 1;
        }
        runs.push(run);
        Pattern::Mask {
            width,
            height,
            runs,
            level,
        }
    }

    /// The level of pixel `(x, y)` of a `width x height` projector image.
    /// For a mask, use [`Pattern::pixels`] (runs are sequential).
    pub fn pixels(&self, width: u32, height: u32) -> Vec<[f32; 3]> {
        let n = width as usize * height as usize;
        match self {
            Pattern::Full { level } => vec![*level; n],
            Pattern::Mask { runs, level, .. } => {
                let mut out = Vec::with_capacity(n);
                let mut set = false;
                for r in runs {
                    let v = if set { *level } else { [0.0; 3] };
                    out.extend(std::iter::repeat_n(v, *r as usize));
                    set = !set;
                }
                out.resize(n, [0.0; 3]);
                out
            }
            Pattern::GrayCode {
                columns,
                bit,
                inverted,
                level,
            } => (0..height)
                .flat_map(|y| (0..width).map(move |x| (x, y)))
                .map(|(x, y)| {
                    let c = if *columns { x } else { y };
                    let gray = c ^ (c >> 1);
                    let on = (gray.checked_shr(*bit).unwrap_or(0) & 1 == 1) != *inverted;
                    if on { *level } else { [0.0; 3] }
                })
                .collect(),
        }
    }

    /// Whether it fits a `width x height` projector.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        match self {
            Pattern::Mask {
                width: w,
                height: h,
                ..
            } => (*w, *h) == (width, height),
            _ => true,
        }
    }

    /// A short description for logs and errors.
    pub fn describe(&self) -> String {
        match self {
            Pattern::Full { level } => format!("full field at {level:?}"),
            Pattern::Mask { runs, .. } => format!("a mask of {} runs", runs.len()),
            Pattern::GrayCode { columns, bit, .. } => format!(
                "Gray-code bit {bit} of the {}",
                if *columns { "columns" } else { "rows" }
            ),
        }
    }
}

/// Master to projector node: show `pattern` until the next one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShowPattern {
    /// Request id (answered by [`PatternShown`] or [`CaptureFailed`]).
    pub id: u64,
    /// What to show.
    pub pattern: Pattern,
}

/// Projector node to master: the pattern of request `id` is showing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PatternShown {
    /// The request.
    pub id: u64,
}

/// Master to camera node: capture `count` frames, each exposed for
/// `exposure_s` at gain `gain` (fixed: no auto exposure, no white
/// balance), their starts spread over the projectors' display period
/// `period_s` as the DLP averaging of paper 3.2 wants: frame `k` starts at
/// `k * (4 + 1/count) * period_s` (at `k / 30` s when `period_s` is 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaptureFrames {
    /// Request id (answered by [`FrameChunk`]s or [`CaptureFailed`]).
    pub id: u64,
    /// Exposure of each frame (s).
    pub exposure_s: f64,
    /// Camera gain (signal per unit radiance and second).
    pub gain: f64,
    /// The colour wheel's period (s), 0 without time slicing.
    pub period_s: f64,
    /// Frames.
    pub count: u32,
}

impl CaptureFrames {
    /// The start time of frame `k` (s), see the type's docs.
    pub fn start_s(&self, k: u32) -> f64 {
        frame_start_s(k, self.count, self.period_s)
    }
}

/// The start (s) of frame `k` of `count` spread over the display period
/// `period_s` (see [`CaptureFrames`]).
pub fn frame_start_s(k: u32, count: u32, period_s: f64) -> f64 {
    if period_s > 0.0 {
        k as f64 * (4.0 + 1.0 / count.max(1) as f64) * period_s
    } else {
        k as f64 / 30.0
    }
}

/// Camera node to master: one piece of one frame of capture `id`. A
/// frame's codes are `width * height` pixels of three little-endian `u16`
/// each, row-major, split into `chunks` pieces of at most
/// [`MAX_CHUNK_BYTES`], sent in order, frame after frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameChunk {
    /// The request.
    pub id: u64,
    /// The frame (`0..frames`).
    pub frame: u32,
    /// Frames of the capture.
    pub frames: u32,
    /// The chunk (`0..chunks`).
    pub chunk: u32,
    /// Chunks of this frame.
    pub chunks: u32,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Bits per code.
    pub bits: u32,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// Node to master: request `id` failed on the node.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CaptureFailed {
    /// The request.
    pub id: u64,
    /// Why, in words that say what to change.
    pub reason: String,
}

/// One frame's codes, as the wire carries them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameCodes {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Bits per code.
    pub bits: u32,
    /// Codes per pixel, row-major.
    pub codes: Vec<[u16; 3]>,
}

/// Split frame `frame` of `frames` of capture `id` into chunks of at most
/// `chunk_bytes` (clamped to `1..=MAX_CHUNK_BYTES`).
pub fn split_frame(
    id: u64,
    frame: u32,
    frames: u32,
    codes: &FrameCodes,
    chunk_bytes: usize,
) -> Vec<FrameChunk> {
    let size = chunk_bytes.clamp(1, MAX_CHUNK_BYTES);
    let mut bytes = Vec::with_capacity(codes.codes.len() * BYTES_PER_PIXEL);
    for c in &codes.codes {
        for v in c {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    let pieces: Vec<&[u8]> = if bytes.is_empty() {
        vec![&[]]
    } else {
        bytes.chunks(size).collect()
    };
    let chunks = pieces.len() as u32;
    pieces
        .into_iter()
        .enumerate()
        .map(|(i, b)| FrameChunk {
            id,
            frame,
            frames,
            chunk: i as u32,
            chunks,
            width: codes.width,
            height: codes.height,
            bits: codes.bits,
            bytes: b.to_vec(),
        })
        .collect()
}

/// Why a chunk was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ChunkError {
    /// The chunk belongs to another request.
    #[error("a frame chunk of capture {got} arrived during capture {expected}")]
    WrongCapture {
        /// The request being assembled.
        expected: u64,
        /// The chunk's.
        got: u64,
    },
    /// A chunk came out of order.
    #[error(
        "frame chunk out of order: got frame {frame} chunk {chunk}, expected frame {want_frame} chunk {want_chunk}"
    )]
    OutOfOrder {
        /// Got.
        frame: u32,
        /// Got.
        chunk: u32,
        /// Expected.
        want_frame: u32,
        /// Expected.
        want_chunk: u32,
    },
    /// The chunk's frame description differs from what was asked or from
    /// the capture's first chunk.
    #[error("frame chunk mismatch: {0}")]
    Mismatch(String),
    /// The chunk carries more bytes than its frame can hold.
    #[error(
        "frame chunk oversized: frame {frame} would hold {got} bytes, a {width}x{height} frame has {limit}"
    )]
    Oversized {
        /// The frame.
        frame: u32,
        /// Bytes so far with this chunk.
        got: usize,
        /// The frame's bytes.
        limit: usize,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// A frame's last chunk came and the frame is short.
    #[error("frame {frame} ended after {got} of its {want} bytes")]
    Short {
        /// The frame.
        frame: u32,
        /// Bytes received.
        got: usize,
        /// Bytes expected.
        want: usize,
    },
    /// Every frame was already received.
    #[error("a frame chunk arrived after all {frames} frames of capture {id}")]
    Extra {
        /// The request.
        id: u64,
        /// Its frames.
        frames: u32,
    },
}

/// Puts the chunks of one capture back together, refusing chunks that are
/// out of order, oversized or do not match the request.
#[derive(Clone, Debug)]
pub struct FrameAssembler {
    id: u64,
    frames: u32,
    size: Option<(u32, u32)>,
    /// `(width, height, bits, chunks)` of the frame being received.
    current: Option<(u32, u32, u32, u32)>,
    next_frame: u32,
    next_chunk: u32,
    buf: Vec<u8>,
    done: Vec<FrameCodes>,
}

impl FrameAssembler {
    /// For request `id` of `frames` frames; `size`, when given, is the
    /// `(width, height)` every frame must have (the camera as the master
    /// knows it).
    pub fn new(id: u64, frames: u32, size: Option<(u32, u32)>) -> Self {
        Self {
            id,
            frames,
            size,
            current: None,
            next_frame: 0,
            next_chunk: 0,
            buf: Vec::new(),
            done: Vec::new(),
        }
    }

    /// Whether every frame has arrived.
    pub fn is_complete(&self) -> bool {
        self.next_frame >= self.frames
    }

    /// Frames complete so far.
    pub fn frames_done(&self) -> usize {
        self.done.len()
    }

    /// Take the complete frames (all of them once [`Self::is_complete`]).
    pub fn take(&mut self) -> Vec<FrameCodes> {
        std::mem::take(&mut self.done)
    }

    /// Add the next chunk; validates it first.
    pub fn push(&mut self, c: &FrameChunk) -> Result<(), ChunkError> {
        c.validate()
            .map_err(|e| ChunkError::Mismatch(e.to_string()))?;
        if c.id != self.id {
            return Err(ChunkError::WrongCapture {
                expected: self.id,
                got: c.id,
            });
        }
        if self.is_complete() {
            return Err(ChunkError::Extra {
                id: self.id,
                frames: self.frames,
            });
        }
        if c.frames != self.frames {
            return Err(ChunkError::Mismatch(format!(
                "the chunk says {} frames, {} were asked for",
                c.frames, self.frames
            )));
        }
        if (c.frame, c.chunk) != (self.next_frame, self.next_chunk) {
            return Err(ChunkError::OutOfOrder {
                frame: c.frame,
                chunk: c.chunk,
                want_frame: self.next_frame,
                want_chunk: self.next_chunk,
            });
        }
        if let Some((w, h)) = self.size
            && (c.width, c.height) != (w, h)
        {
            return Err(ChunkError::Mismatch(format!(
                "frame {} is {}x{}, the camera is {w}x{h}",
                c.frame, c.width, c.height
            )));
        }
        let desc = (c.width, c.height, c.bits, c.chunks);
        match self.current {
            None => {
                self.current = Some(desc);
                self.size.get_or_insert((c.width, c.height));
            }
            Some(d) if d != desc => {
                return Err(ChunkError::Mismatch(format!(
                    "chunk {} of frame {} says {}x{} at {} bits in {} chunks, its first chunk said {}x{} at {} bits in {} chunks",
                    c.chunk, c.frame, c.width, c.height, c.bits, c.chunks, d.0, d.1, d.2, d.3
                )));
            }
            Some(_) => {}
        }
        let want = c.width as usize * c.height as usize * BYTES_PER_PIXEL;
        let got = self.buf.len() + c.bytes.len();
        if got > want {
            return Err(ChunkError::Oversized {
                frame: c.frame,
                got,
                limit: want,
                width: c.width,
                height: c.height,
            });
        }
        self.buf.extend_from_slice(&c.bytes);
        self.next_chunk += 1;
        if self.next_chunk == c.chunks {
            if self.buf.len() != want {
                return Err(ChunkError::Short {
                    frame: c.frame,
                    got: self.buf.len(),
                    want,
                });
            }
            let codes = self
                .buf
                .chunks_exact(BYTES_PER_PIXEL)
                .map(|p| std::array::from_fn(|k| u16::from_le_bytes([p[2 * k], p[2 * k + 1]])))
                .collect();
            self.done.push(FrameCodes {
                width: c.width,
                height: c.height,
                bits: c.bits,
                codes,
            });
            self.buf.clear();
            self.current = None;
            self.next_chunk = 0;
            self.next_frame += 1;
        }
        Ok(())
    }
}

/// A captured reflectance map as the scene snapshot carries it (paper
/// 3.6): per camera pixel the reflectance, its blend weight, the depth and
/// object it saw, and the camera and object poses of the capture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CapturedMap {
    /// Its name (objects' `reflectance_map` refer to it).
    pub name: String,
    /// The capturing camera.
    pub camera: PinholeDevice,
    /// `I_ref` per pixel, linear RGB.
    pub reflectance: Vec<[f32; 3]>,
    /// Blend weight per pixel in `[0, 1]`.
    pub weight: Vec<f32>,
    /// Device depth per pixel (m), 0 for none.
    pub depth: Vec<f32>,
    /// Object index per pixel, `u32::MAX` for none.
    pub object: Vec<u32>,
    /// Object-to-world transforms during capture (column-major), by object.
    pub object_transforms: Vec<[f64; 16]>,
}

fn fail(field: impl Into<String>, problem: impl Into<String>) -> Result<(), ValidationError> {
    Err(ValidationError {
        field: field.into(),
        problem: problem.into(),
    })
}

fn level_ok(field: &str, level: &[f32; 3]) -> Result<(), ValidationError> {
    if level
        .iter()
        .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
    {
        Ok(())
    } else {
        fail(field, format!("{level:?} is not within [0, 1]"))
    }
}

fn size_ok(w: u32, h: u32) -> Result<(), ValidationError> {
    if w == 0 || h == 0 || w > MAX_RESOLUTION || h > MAX_RESOLUTION {
        fail(
            "width",
            format!("size {w}x{h} is outside 1..={MAX_RESOLUTION}"),
        )
    } else {
        Ok(())
    }
}

impl Validate for Pattern {
    fn validate(&self) -> Result<(), ValidationError> {
        match self {
            Pattern::Full { level } => level_ok("level", level),
            Pattern::Mask {
                width,
                height,
                runs,
                level,
            } => {
                level_ok("level", level)?;
                size_ok(*width, *height)?;
                if runs.len() > MAX_PATTERN_RUNS {
                    return fail(
                        "runs",
                        format!("{} runs, at most {MAX_PATTERN_RUNS}", runs.len()),
                    );
                }
                let sum: u64 = runs.iter().map(|r| *r as u64).sum();
                let n = *width as u64 * *height as u64;
                if sum != n {
                    return fail(
                        "runs",
                        format!("the runs cover {sum} pixels, the image has {n}"),
                    );
                }
                Ok(())
            }
            Pattern::GrayCode { bit, level, .. } => {
                level_ok("level", level)?;
                if *bit >= 16 {
                    return fail("bit", format!("{bit} is beyond 15"));
                }
                Ok(())
            }
        }
    }
}

impl Validate for CaptureFrames {
    fn validate(&self) -> Result<(), ValidationError> {
        if !(self.exposure_s.is_finite()
            && self.exposure_s > 0.0
            && self.exposure_s <= MAX_EXPOSURE_S)
        {
            return fail(
                "exposure_s",
                format!("{} s is not in (0, {MAX_EXPOSURE_S}]", self.exposure_s),
            );
        }
        if !(self.gain.is_finite() && self.gain > 0.0) {
            return fail("gain", format!("{} must be positive", self.gain));
        }
        if !(self.period_s.is_finite() && (0.0..=1.0).contains(&self.period_s)) {
            return fail("period_s", format!("{} s is not in [0, 1]", self.period_s));
        }
        if self.count == 0 || self.count > MAX_CAPTURE_FRAMES {
            return fail(
                "count",
                format!("{} frames is not in 1..={MAX_CAPTURE_FRAMES}", self.count),
            );
        }
        Ok(())
    }
}

impl Validate for FrameChunk {
    fn validate(&self) -> Result<(), ValidationError> {
        size_ok(self.width, self.height)?;
        if self.bits == 0 || self.bits > 16 {
            return fail("bits", format!("{} is not in 1..=16", self.bits));
        }
        if self.frames == 0 || self.frames > MAX_CAPTURE_FRAMES || self.frame >= self.frames {
            return fail(
                "frame",
                format!(
                    "frame {} of {} (at most {MAX_CAPTURE_FRAMES})",
                    self.frame, self.frames
                ),
            );
        }
        if self.chunks == 0 || self.chunk >= self.chunks {
            return fail("chunk", format!("chunk {} of {}", self.chunk, self.chunks));
        }
        if self.bytes.len() > MAX_CHUNK_BYTES {
            return fail(
                "bytes",
                format!(
                    "{} bytes, at most {MAX_CHUNK_BYTES} per chunk",
                    self.bytes.len()
                ),
            );
        }
        let frame = self.width as usize * self.height as usize * BYTES_PER_PIXEL;
        if self.chunks as usize > frame {
            return fail(
                "chunks",
                format!("{} chunks for a frame of {frame} bytes", self.chunks),
            );
        }
        Ok(())
    }
}

impl Validate for CaptureFailed {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.reason.len() > MAX_REASON_LEN {
            return fail("reason", format!("longer than {MAX_REASON_LEN} bytes"));
        }
        Ok(())
    }
}

impl Validate for CapturedMap {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.name.is_empty() || self.name.len() > crate::validate::MAX_NAME_LEN {
            return fail("name", "empty or too long");
        }
        self.camera.validate().map_err(|e| ValidationError {
            field: format!("camera.{}", e.field),
            problem: e.problem,
        })?;
        let n = self.camera.width as usize * self.camera.height as usize;
        for (f, len) in [
            ("reflectance", self.reflectance.len()),
            ("weight", self.weight.len()),
            ("depth", self.depth.len()),
            ("object", self.object.len()),
        ] {
            if len != n {
                return fail(
                    f,
                    format!(
                        "{len} values for a {}x{} camera",
                        self.camera.width, self.camera.height
                    ),
                );
            }
        }
        if let Some(i) = self
            .reflectance
            .iter()
            .position(|v| v.iter().any(|c| !c.is_finite() || *c < 0.0))
        {
            return fail(format!("reflectance[{i}]"), "negative or not finite");
        }
        if let Some(i) = self
            .weight
            .iter()
            .position(|w| !(w.is_finite() && (0.0..=1.0).contains(w)))
        {
            return fail(format!("weight[{i}]"), "not within [0, 1]");
        }
        if let Some(i) = self.depth.iter().position(|d| !d.is_finite()) {
            return fail(format!("depth[{i}]"), "not finite");
        }
        if let Some(i) = self
            .object_transforms
            .iter()
            .position(|m| m.iter().any(|v| !v.is_finite()))
        {
            return fail(format!("object_transforms[{i}]"), "not finite");
        }
        Ok(())
    }
}
