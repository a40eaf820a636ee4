//! Decoding of camera frames into [`CameraFrame`]s: the raw formats that
//! UVC cameras send (YUYV, UYVY, NV12, YU12, GREY, Y16, RGB24, BGR24) and
//! MJPEG, including the frames without Huffman tables that many UVC cameras
//! send (the decoder inserts the JPEG standard's Annex K tables, as the
//! AVI MJPEG format prescribes).
//!
//! Raw YUV is BT.601, limited range unless the driver reports full range;
//! JPEG is full-range YCbCr (JFIF). Every decoder checks the buffer's
//! length before it reads and returns an error, never panics, on a short
//! or malformed frame.

use showcase_light::Image;
use showcase_light::hardware::CameraFrame;
use std::borrow::Cow;
use std::fmt;

/// A pixel format a camera can deliver, by its V4L2 fourcc.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PixelFormat {
    /// Packed 4:2:2 YUV, `Y0 U Y1 V` (V4L2 `YUYV`).
    Yuyv,
    /// Packed 4:2:2 YUV, `U Y0 V Y1` (V4L2 `UYVY`).
    Uyvy,
    /// Motion JPEG: one JPEG per frame, Huffman tables optional (`MJPG`).
    Mjpeg,
    /// JPEG (`JPEG`), decoded like MJPEG.
    Jpeg,
    /// 4:2:0, a Y plane then interleaved `U V` at half resolution (`NV12`).
    Nv12,
    /// 4:2:0 planar, Y then U then V planes (`YU12`, I420).
    Yu12,
    /// 8-bit grey (`GREY`).
    Grey,
    /// 16-bit little-endian grey (`Y16 `).
    Y16,
    /// Packed 8-bit `R G B` (`RGB3`).
    Rgb24,
    /// Packed 8-bit `B G R` (`BGR3`).
    Bgr24,
}

/// Builds a fourcc code from its four characters.
pub const fn fourcc(code: &[u8; 4]) -> u32 {
    (code[0] as u32) | (code[1] as u32) << 8 | (code[2] as u32) << 16 | (code[3] as u32) << 24
}

/// A fourcc code as its four characters (non-printable ones as `?`).
pub fn fourcc_string(code: u32) -> String {
    code.to_le_bytes()
        .iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '?'
            }
        })
        .collect()
}

impl PixelFormat {
    /// Every format this module decodes, in the order a negotiation
    /// prefers them when the request names none: uncompressed 4:2:2 first
    /// (no compression artefacts, full-resolution luma), then the others.
    pub const ALL: [PixelFormat; 10] = [
        PixelFormat::Yuyv,
        PixelFormat::Uyvy,
        PixelFormat::Rgb24,
        PixelFormat::Bgr24,
        PixelFormat::Nv12,
        PixelFormat::Yu12,
        PixelFormat::Mjpeg,
        PixelFormat::Jpeg,
        PixelFormat::Y16,
        PixelFormat::Grey,
    ];

    /// The V4L2 fourcc code.
    pub const fn fourcc(self) -> u32 {
        fourcc(match self {
            PixelFormat::Yuyv => b"YUYV",
            PixelFormat::Uyvy => b"UYVY",
            PixelFormat::Mjpeg => b"MJPG",
            PixelFormat::Jpeg => b"JPEG",
            PixelFormat::Nv12 => b"NV12",
            PixelFormat::Yu12 => b"YU12",
            PixelFormat::Grey => b"GREY",
            PixelFormat::Y16 => b"Y16 ",
            PixelFormat::Rgb24 => b"RGB3",
            PixelFormat::Bgr24 => b"BGR3",
        })
    }

    /// The format of a fourcc code, if this module decodes it.
    pub fn from_fourcc(code: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.fourcc() == code)
    }

    /// The format named by `name`: its fourcc (`YUYV`, `MJPG`, `Y16`) or a
    /// common alias (`mjpeg`, `rgb24`, `i420`), any case.
    pub fn parse(name: &str) -> Option<Self> {
        let upper = name.trim().to_ascii_uppercase();
        let alias = match upper.as_str() {
            "MJPEG" => Some(PixelFormat::Mjpeg),
            "RGB24" | "RGB" => Some(PixelFormat::Rgb24),
            "BGR24" | "BGR" => Some(PixelFormat::Bgr24),
            "I420" | "YUV420" => Some(PixelFormat::Yu12),
            "YUY2" => Some(PixelFormat::Yuyv),
            "GRAY" | "Y8" => Some(PixelFormat::Grey),
            _ => None,
        };
        alias.or_else(|| {
            let mut code = [b' '; 4];
            let bytes = upper.as_bytes();
            if bytes.is_empty() || bytes.len() > 4 {
                return None;
            }
            code[..bytes.len()].copy_from_slice(bytes);
            Self::from_fourcc(fourcc(&code))
        })
    }

    /// Bits per channel of the decoded frame.
    pub const fn bits(self) -> u32 {
        match self {
            PixelFormat::Y16 => 16,
            _ => 8,
        }
    }

    /// True for the JPEG formats (the frame's size varies).
    pub const fn is_compressed(self) -> bool {
        matches!(self, PixelFormat::Mjpeg | PixelFormat::Jpeg)
    }

    /// Bytes per pixel of the first plane's rows (0 for JPEG).
    const fn bytes_per_pixel(self) -> u32 {
        match self {
            PixelFormat::Yuyv | PixelFormat::Uyvy | PixelFormat::Y16 => 2,
            PixelFormat::Rgb24 | PixelFormat::Bgr24 => 3,
            PixelFormat::Nv12 | PixelFormat::Yu12 | PixelFormat::Grey => 1,
            PixelFormat::Mjpeg | PixelFormat::Jpeg => 0,
        }
    }
}

impl fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(fourcc_string(self.fourcc()).trim_end())
    }
}

/// How a frame's bytes are laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameLayout {
    /// Pixel format.
    pub format: PixelFormat,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Bytes from one row of the first plane to the next (V4L2's
    /// `bytesperline`); 0 for tightly packed rows.
    pub bytes_per_line: u32,
    /// Whether YUV uses the full `0..=255` range (V4L2's quantization
    /// `FULL_RANGE`) rather than BT.601's limited `16..=235`.
    pub full_range: bool,
}

impl FrameLayout {
    /// A tightly packed, limited-range layout.
    pub const fn packed(format: PixelFormat, width: u32, height: u32) -> Self {
        Self {
            format,
            width,
            height,
            bytes_per_line: 0,
            full_range: false,
        }
    }

    /// Bytes the pixels of one row of the first plane take: whole 4:2:2
    /// pairs, whole 4:2:0 chroma pairs (the same bytes for NV12's
    /// interleaved chroma rows).
    fn tight_row(&self) -> usize {
        let w = self.width as usize;
        match self.format {
            PixelFormat::Yuyv | PixelFormat::Uyvy => w.div_ceil(2) * 4,
            PixelFormat::Nv12 => w.div_ceil(2) * 2,
            _ => w * self.format.bytes_per_pixel() as usize,
        }
    }

    /// Bytes per row of the first plane.
    pub fn stride(&self) -> usize {
        (self.bytes_per_line as usize).max(self.tight_row())
    }

    /// Bytes a whole uncompressed frame needs (0 for JPEG; packed formats
    /// need no padding after the last row).
    pub fn frame_bytes(&self) -> usize {
        let stride = self.stride();
        let h = self.height as usize;
        let tight = self.tight_row();
        match self.format {
            PixelFormat::Mjpeg | PixelFormat::Jpeg => 0,
            PixelFormat::Nv12 => stride * h + stride * h.div_ceil(2),
            PixelFormat::Yu12 => stride * h + 2 * stride.div_ceil(2) * h.div_ceil(2),
            // The last row's padding may be missing.
            _ => stride * h.saturating_sub(1) + tight,
        }
    }
}

/// Why a frame could not be decoded.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DecodeError {
    /// The frame has no pixels.
    #[error("{format} frame of {width}x{height} pixels: the size must not be zero")]
    Empty {
        /// Format.
        format: PixelFormat,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// The buffer is shorter than the layout needs.
    #[error(
        "{format} frame of {width}x{height}: {got} bytes, {expected} needed (a truncated frame: \
         check the USB bandwidth or lower the resolution or frame rate)"
    )]
    Short {
        /// Format.
        format: PixelFormat,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Bytes needed.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// The JPEG decoder failed.
    #[error("{format} frame: not a decodable JPEG ({reason})")]
    Jpeg {
        /// Format.
        format: PixelFormat,
        /// The decoder's message.
        reason: String,
    },
    /// The JPEG is not the size the camera was set to.
    #[error("{format} frame is {got_width}x{got_height}, the camera was set to {width}x{height}")]
    WrongSize {
        /// Format.
        format: PixelFormat,
        /// Expected width.
        width: u32,
        /// Expected height.
        height: u32,
        /// Width of the JPEG.
        got_width: u32,
        /// Height of the JPEG.
        got_height: u32,
    },
}

/// Decodes one frame laid out as `layout` from `data` (extra bytes at the
/// end, as drivers pad buffers, are ignored).
pub fn decode(layout: &FrameLayout, data: &[u8]) -> Result<CameraFrame, DecodeError> {
    let FrameLayout {
        format,
        width,
        height,
        ..
    } = *layout;
    if width == 0 || height == 0 {
        return Err(DecodeError::Empty {
            format,
            width,
            height,
        });
    }
    if format.is_compressed() {
        // The JPEG decoder is a dependency fuzzed by its authors; should a
        // damaged frame still panic it, that frame is an error, not the
        // end of a capture.
        return std::panic::catch_unwind(|| decode_jpeg(layout, data)).unwrap_or_else(|_| {
            Err(DecodeError::Jpeg {
                format,
                reason: "the JPEG decoder failed on this frame".into(),
            })
        });
    }
    let expected = layout.frame_bytes();
    if data.len() < expected {
        return Err(DecodeError::Short {
            format,
            width,
            height,
            expected,
            got: data.len(),
        });
    }
    let stride = layout.stride();
    let (w, h) = (width as usize, height as usize);
    let yuv = Yuv::new(layout.full_range);
    let codes = match format {
        PixelFormat::Yuyv | PixelFormat::Uyvy => {
            // Byte offsets of Y0, U, Y1, V in each 4-byte pair.
            let [y0, u, y1, v] = if format == PixelFormat::Yuyv {
                [0, 1, 2, 3]
            } else {
                [1, 0, 3, 2]
            };
            Image::from_fn(width, height, |x, y| {
                let (x, y) = (x as usize, y as usize);
                let pair = &data[y * stride + (x / 2) * 4..][..4];
                let luma = if x % 2 == 0 { pair[y0] } else { pair[y1] };
                yuv.rgb(luma, pair[u], pair[v])
            })
        }
        PixelFormat::Nv12 => {
            let uv_plane = &data[stride * h..];
            Image::from_fn(width, height, |x, y| {
                let (x, y) = (x as usize, y as usize);
                let uv = &uv_plane[(y / 2) * stride + (x / 2) * 2..][..2];
                yuv.rgb(data[y * stride + x], uv[0], uv[1])
            })
        }
        PixelFormat::Yu12 => {
            let chroma_stride = stride.div_ceil(2);
            let chroma_plane = chroma_stride * h.div_ceil(2);
            let u_plane = &data[stride * h..];
            let v_plane = &u_plane[chroma_plane..];
            Image::from_fn(width, height, |x, y| {
                let (x, y) = (x as usize, y as usize);
                let c = (y / 2) * chroma_stride + x / 2;
                yuv.rgb(data[y * stride + x], u_plane[c], v_plane[c])
            })
        }
        PixelFormat::Grey => Image::from_fn(width, height, |x, y| {
            let g = u16::from(data[y as usize * stride + x as usize]);
            [g; 3]
        }),
        PixelFormat::Y16 => Image::from_fn(width, height, |x, y| {
            let i = y as usize * stride + x as usize * 2;
            [u16::from_le_bytes([data[i], data[i + 1]]); 3]
        }),
        PixelFormat::Rgb24 | PixelFormat::Bgr24 => Image::from_fn(width, height, |x, y| {
            let p = &data[y as usize * stride + x as usize * 3..][..3];
            let (r, b) = if format == PixelFormat::Rgb24 {
                (p[0], p[2])
            } else {
                (p[2], p[0])
            };
            [u16::from(r), u16::from(p[1]), u16::from(b)]
        }),
        PixelFormat::Mjpeg | PixelFormat::Jpeg => unreachable!("handled above"),
    };
    debug_assert_eq!(codes.data.len(), w * h);
    Ok(CameraFrame {
        codes,
        bits: format.bits(),
    })
}

/// BT.601 YCbCr to 8-bit RGB.
struct Yuv {
    /// Luma offset and scale.
    y0: f32,
    ys: f32,
    /// Chroma scale.
    cs: f32,
}

impl Yuv {
    fn new(full_range: bool) -> Self {
        if full_range {
            Self {
                y0: 0.0,
                ys: 1.0,
                cs: 1.0,
            }
        } else {
            Self {
                y0: 16.0,
                ys: 255.0 / 219.0,
                cs: 255.0 / 224.0,
            }
        }
    }

    fn rgb(&self, y: u8, u: u8, v: u8) -> [u16; 3] {
        // Kr = 0.299, Kb = 0.114 (BT.601).
        let l = (f32::from(y) - self.y0) * self.ys;
        let cb = (f32::from(u) - 128.0) * self.cs;
        let cr = (f32::from(v) - 128.0) * self.cs;
        let r = l + 1.402 * cr;
        let g = l - 0.344_136 * cb - 0.714_136 * cr;
        let b = l + 1.772 * cb;
        [r, g, b].map(|c| c.round().clamp(0.0, 255.0) as u16)
    }
}

/// The JPEG standard's typical Huffman tables (ITU T.81 Annex K.3: DC and
/// AC, luminance and chrominance) as one DHT segment: what an MJPEG frame
/// without tables is coded with.
pub const DEFAULT_DHT: [u8; 420] = [
    0xff, 0xc4, 0x01, 0xa2, 0x00, 0x00, 0x01, 0x05, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0a,
    0x0b, 0x01, 0x00, 0x03, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0a, 0x0b, 0x10, 0x00,
    0x02, 0x01, 0x03, 0x03, 0x02, 0x04, 0x03, 0x05, 0x05, 0x04, 0x04, 0x00, 0x00, 0x01, 0x7d, 0x01,
    0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61, 0x07, 0x22,
    0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52, 0xd1, 0xf0, 0x24,
    0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25, 0x26, 0x27, 0x28, 0x29,
    0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a,
    0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a,
    0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a,
    0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8,
    0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5, 0xc6,
    0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2, 0xe3,
    0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9,
    0xfa, 0x11, 0x00, 0x02, 0x01, 0x02, 0x04, 0x04, 0x03, 0x04, 0x07, 0x05, 0x04, 0x04, 0x00, 0x01,
    0x02, 0x77, 0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07,
    0x61, 0x71, 0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33,
    0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18, 0x19,
    0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46,
    0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66,
    0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x82, 0x83, 0x84, 0x85,
    0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3,
    0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba,
    0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8,
    0xd9, 0xda, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6,
    0xf7, 0xf8, 0xf9, 0xfa,
];

/// `jpeg` with [`DEFAULT_DHT`] inserted before its first frame header when
/// it has no DHT segment of its own (borrowed unchanged otherwise, and for
/// data too malformed to find the header in: the decoder reports those).
pub fn with_huffman_tables(jpeg: &[u8]) -> Cow<'_, [u8]> {
    if jpeg.len() < 4 || jpeg[0] != 0xFF || jpeg[1] != 0xD8 {
        return Cow::Borrowed(jpeg);
    }
    let mut i = 2;
    let mut insert_at = None;
    while i + 4 <= jpeg.len() {
        if jpeg[i] != 0xFF {
            return Cow::Borrowed(jpeg);
        }
        let marker = jpeg[i + 1];
        match marker {
            // Fill bytes before a marker.
            0xFF => {
                i += 1;
                continue;
            }
            0xC4 => return Cow::Borrowed(jpeg),
            // Start of scan: no DHT came before it.
            0xDA => break,
            // SOF0..SOF15 (not DHT, JPG or DAC): tables go before it.
            0xC0..=0xCF if marker != 0xC8 && marker != 0xCC => {
                insert_at.get_or_insert(i);
            }
            _ => {}
        }
        let length = usize::from(u16::from_be_bytes([jpeg[i + 2], jpeg[i + 3]]));
        i += 2 + length;
    }
    let at = insert_at.unwrap_or(i.min(jpeg.len()));
    let mut out = Vec::with_capacity(jpeg.len() + DEFAULT_DHT.len());
    out.extend_from_slice(&jpeg[..at]);
    out.extend_from_slice(&DEFAULT_DHT);
    out.extend_from_slice(&jpeg[at..]);
    Cow::Owned(out)
}

fn decode_jpeg(layout: &FrameLayout, data: &[u8]) -> Result<CameraFrame, DecodeError> {
    use zune_jpeg::zune_core::bytestream::ZCursor;
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    use zune_jpeg::zune_core::options::DecoderOptions;

    let format = layout.format;
    let jpeg_error = |reason: String| DecodeError::Jpeg { format, reason };
    let data = with_huffman_tables(data);
    let options = DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::RGB)
        .set_max_width(layout.width as usize)
        .set_max_height(layout.height as usize);
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(&data[..]), options);
    decoder
        .decode_headers()
        .map_err(|e| jpeg_error(e.to_string()))?;
    let info = decoder
        .info()
        .ok_or_else(|| jpeg_error("no frame header".into()))?;
    let (got_width, got_height) = (u32::from(info.width), u32::from(info.height));
    if (got_width, got_height) != (layout.width, layout.height) {
        return Err(DecodeError::WrongSize {
            format,
            width: layout.width,
            height: layout.height,
            got_width,
            got_height,
        });
    }
    let pixels = decoder.decode().map_err(|e| jpeg_error(e.to_string()))?;
    let n = layout.width as usize * layout.height as usize;
    let channels = decoder
        .output_colorspace()
        .map_or(3, |c| c.num_components());
    if pixels.len() < n * channels || channels == 0 {
        return Err(jpeg_error(format!(
            "{} bytes decoded, {} expected",
            pixels.len(),
            n * channels
        )));
    }
    let data = pixels
        .chunks_exact(channels)
        .take(n)
        .map(|p| {
            if channels >= 3 {
                [p[0], p[1], p[2]].map(u16::from)
            } else {
                [u16::from(p[0]); 3]
            }
        })
        .collect();
    Ok(CameraFrame {
        codes: Image {
            width: layout.width,
            height: layout.height,
            data,
        },
        bits: 8,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Any bytes in any layout decode or fail, never panic.
        #[test]
        fn arbitrary_bytes_never_panic(
            format in 0..PixelFormat::ALL.len(),
            width in 0u32..9,
            height in 0u32..9,
            bytes_per_line in 0u32..40,
            full_range: bool,
            bytes in prop::collection::vec(any::<u8>(), 0..400),
        ) {
            let layout = FrameLayout {
                format: PixelFormat::ALL[format],
                width,
                height,
                bytes_per_line,
                full_range,
            };
            if let Ok(f) = decode(&layout, &bytes) {
                prop_assert_eq!(f.codes.data.len(), (width * height) as usize);
            }
        }

        /// JPEG-looking bytes (SOI, then markers and noise) never panic
        /// the table insertion or the decoder.
        #[test]
        fn jpeg_like_bytes_never_panic(
            segments in prop::collection::vec(
                (0xC0u8..=0xFE, prop::collection::vec(any::<u8>(), 0..40)),
                0..6,
            ),
        ) {
            let mut data = vec![0xFF, 0xD8];
            for (marker, body) in segments {
                data.extend_from_slice(&[0xFF, marker]);
                data.extend_from_slice(&(body.len() as u16 + 2).to_be_bytes());
                data.extend_from_slice(&body);
            }
            let _ = with_huffman_tables(&data);
            let _ = decode(&FrameLayout::packed(PixelFormat::Mjpeg, 8, 8), &data);
        }
    }

    #[test]
    fn fourcc_round_trips() {
        for f in PixelFormat::ALL {
            assert_eq!(PixelFormat::from_fourcc(f.fourcc()), Some(f));
            assert_eq!(PixelFormat::parse(&f.to_string()), Some(f), "{f}");
        }
        assert_eq!(fourcc_string(fourcc(b"YUYV")), "YUYV");
        assert_eq!(PixelFormat::parse("mjpeg"), Some(PixelFormat::Mjpeg));
        assert_eq!(PixelFormat::parse("H264"), None);
        assert_eq!(PixelFormat::parse(""), None);
    }

    #[test]
    fn default_tables_are_well_formed() {
        // Each table: class/id, 16 counts, then that many symbols.
        let body = &DEFAULT_DHT[4..];
        assert_eq!(
            usize::from(u16::from_be_bytes([DEFAULT_DHT[2], DEFAULT_DHT[3]])),
            body.len() + 2
        );
        let mut i = 0;
        let mut ids = Vec::new();
        while i < body.len() {
            ids.push(body[i]);
            let n: usize = body[i + 1..i + 17].iter().map(|&c| usize::from(c)).sum();
            i += 17 + n;
        }
        assert_eq!(i, body.len());
        assert_eq!(ids, [0x00, 0x01, 0x10, 0x11]);
    }

    #[test]
    fn yuv_extremes_are_exact() {
        let limited = Yuv::new(false);
        assert_eq!(limited.rgb(16, 128, 128), [0, 0, 0]);
        assert_eq!(limited.rgb(235, 128, 128), [255, 255, 255]);
        assert_eq!(limited.rgb(126, 128, 128), [128, 128, 128]);
        // BT.601 red (255, 0, 0): Y 81, Cb 90, Cr 240.
        let [r, g, b] = limited.rgb(81, 90, 240);
        assert!(r >= 254 && g <= 1 && b <= 1, "{r} {g} {b}");
        let full = Yuv::new(true);
        assert_eq!(full.rgb(0, 128, 128), [0, 0, 0]);
        assert_eq!(full.rgb(255, 128, 128), [255, 255, 255]);
    }

    #[test]
    fn raw_layouts_read_their_pixels() {
        // 2x2 frames with a row stride of 8 bytes (padding bytes 0xEE).
        let yuyv = [16, 128, 235, 128, 0xEE, 0xEE, 0xEE, 0xEE, 235, 128, 16, 128];
        let mut layout = FrameLayout::packed(PixelFormat::Yuyv, 2, 2);
        layout.bytes_per_line = 8;
        let f = decode(&layout, &yuyv).unwrap();
        assert_eq!(f.codes.data, [[0; 3], [255; 3], [255; 3], [0; 3]]);
        assert_eq!(f.bits, 8);

        let uyvy = [128, 16, 128, 235];
        let f = decode(&FrameLayout::packed(PixelFormat::Uyvy, 2, 1), &uyvy).unwrap();
        assert_eq!(f.codes.data, [[0; 3], [255; 3]]);

        let bgr = [1, 2, 3, 4, 5, 6];
        let f = decode(&FrameLayout::packed(PixelFormat::Bgr24, 2, 1), &bgr).unwrap();
        assert_eq!(f.codes.data, [[3, 2, 1], [6, 5, 4]]);
        let f = decode(&FrameLayout::packed(PixelFormat::Rgb24, 2, 1), &bgr).unwrap();
        assert_eq!(f.codes.data, [[1, 2, 3], [4, 5, 6]]);

        let y16 = [0x34, 0x12, 0xFF, 0xFF];
        let f = decode(&FrameLayout::packed(PixelFormat::Y16, 2, 1), &y16).unwrap();
        assert_eq!(f.codes.data, [[0x1234; 3], [0xFFFF; 3]]);
        assert_eq!(f.bits, 16);

        let grey = [7, 9];
        let f = decode(&FrameLayout::packed(PixelFormat::Grey, 1, 2), &grey).unwrap();
        assert_eq!(f.codes.data, [[7; 3], [9; 3]]);

        // 2x2 4:2:0: four lumas, one chroma pair.
        let nv12 = [16, 235, 235, 16, 128, 128];
        let f = decode(&FrameLayout::packed(PixelFormat::Nv12, 2, 2), &nv12).unwrap();
        assert_eq!(f.codes.data, [[0; 3], [255; 3], [255; 3], [0; 3]]);
        let f = decode(&FrameLayout::packed(PixelFormat::Yu12, 2, 2), &nv12).unwrap();
        assert_eq!(f.codes.data, [[0; 3], [255; 3], [255; 3], [0; 3]]);
    }

    #[test]
    fn short_and_malformed_frames_are_errors() {
        for format in PixelFormat::ALL {
            let layout = FrameLayout::packed(format, 4, 4);
            let needed = layout.frame_bytes().max(1);
            for len in [0, 1, 5, needed - 1] {
                assert!(decode(&layout, &vec![0x55; len]).is_err(), "{format} {len}");
            }
            if !format.is_compressed() {
                assert!(decode(&layout, &vec![0x55; needed]).is_ok(), "{format}");
            }
            assert!(matches!(
                decode(&FrameLayout::packed(format, 0, 4), &[0; 64]),
                Err(DecodeError::Empty { .. })
            ));
        }
        let e = decode(&FrameLayout::packed(PixelFormat::Yuyv, 4, 4), &[0; 31]).unwrap_err();
        assert!(e.to_string().contains("31 bytes, 32 needed"), "{e}");
        // JPEG-looking garbage: markers with lengths that overrun.
        for bad in [
            &[0xFF, 0xD8][..],
            &[0xFF, 0xD8, 0xFF, 0xC0, 0xFF, 0xFF, 1, 2],
            &[0xFF, 0xD8, 0xFF, 0xDA, 0, 2, 0xFF, 0xD9],
        ] {
            assert!(decode(&FrameLayout::packed(PixelFormat::Mjpeg, 4, 4), bad).is_err());
        }
    }
}
