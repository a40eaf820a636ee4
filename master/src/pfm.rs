//! Portable float maps (PFM), the one reader and writer of the images the
//! jobs write and read (reflectance maps, irradiance maps, `sim render`):
//! colour (`PF`) and grey (`Pf`), little-endian (negative scale), rows
//! stored bottom to top as the format requires.

use glam::Vec3;
use showcase_light::finite::finite_or_zero;
use showcase_light::{Image, RgbImage};
use std::path::Path;

/// Why a PFM could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum PfmError {
    /// File system error.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        error: std::io::Error,
    },
    /// The bytes are not a PFM this reader understands.
    #[error("not a pfm: {0}")]
    Format(String),
}

/// Encode a colour image as PFM bytes (non-finite values become 0).
pub fn encode_pfm(image: &RgbImage) -> Vec<u8> {
    let mut out = format!("PF\n{} {}\n-1.0\n", image.width, image.height).into_bytes();
    for y in (0..image.height).rev() {
        for x in 0..image.width {
            let v = image.get(x, y).copied().unwrap_or(Vec3::ZERO);
            for c in v.to_array() {
                let c = finite_or_zero(c);
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    out
}

/// Encode a grey image as PFM bytes (non-finite values become 0).
pub fn encode_pfm_grey(image: &Image<f32>) -> Vec<u8> {
    let mut out = format!("Pf\n{} {}\n-1.0\n", image.width, image.height).into_bytes();
    for y in (0..image.height).rev() {
        for x in 0..image.width {
            let c = image.get(x, y).copied().unwrap_or(0.0);
            let c = finite_or_zero(c);
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    out
}

/// Decode PFM bytes (colour or grey; grey is replicated to RGB).
pub fn decode_pfm(bytes: &[u8]) -> Result<RgbImage, PfmError> {
    let bad = |m: &str| PfmError::Format(m.to_string());
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err(bad("truncated header"));
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).to_string());
    }
    pos += 1; // the single whitespace after the scale
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        other => return Err(PfmError::Format(format!("magic {other:?}"))),
    };
    let width: u32 = fields[1].parse().map_err(|_| bad("width"))?;
    let height: u32 = fields[2].parse().map_err(|_| bad("height"))?;
    let scale: f32 = fields[3].parse().map_err(|_| bad("scale"))?;
    if !(scale != 0.0 && scale.is_finite()) {
        return Err(PfmError::Format(format!("scale {scale}")));
    }
    let count = width as usize * height as usize * channels;
    let body = bytes.get(pos..).unwrap_or(&[]);
    if body.len() < count * 4 {
        return Err(PfmError::Format(format!(
            "{} data bytes for {width}x{height}x{channels} floats",
            body.len()
        )));
    }
    let value = |i: usize| {
        let b = [
            body[4 * i],
            body[4 * i + 1],
            body[4 * i + 2],
            body[4 * i + 3],
        ];
        let v = if scale < 0.0 {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        };
        finite_or_zero(v)
    };
    Ok(Image::from_fn(width, height, |x, y| {
        let base = ((height - 1 - y) as usize * width as usize + x as usize) * channels;
        if channels == 3 {
            Vec3::new(value(base), value(base + 1), value(base + 2))
        } else {
            Vec3::splat(value(base))
        }
    }))
}

/// Write a colour image as a PFM file.
pub fn write_pfm(path: &Path, image: &RgbImage) -> Result<(), PfmError> {
    std::fs::write(path, encode_pfm(image)).map_err(|error| PfmError::Io {
        path: path.display().to_string(),
        error,
    })
}

/// Read a PFM file (grey files come back as RGB).
pub fn read_pfm(path: &Path) -> Result<RgbImage, PfmError> {
    let bytes = std::fs::read(path).map_err(|error| PfmError::Io {
        path: path.display().to_string(),
        error,
    })?;
    decode_pfm(&bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_is_bottom_up_little_endian() {
        let img = Image::from_fn(2, 2, |x, y| Vec3::new(x as f32, y as f32, 0.5));
        let bytes = encode_pfm(&img);
        let header = b"PF\n2 2\n-1.0\n";
        assert_eq!(&bytes[..header.len()], header);
        let first = f32::from_le_bytes(
            bytes[header.len() + 4..header.len() + 8]
                .try_into()
                .unwrap(),
        );
        assert_eq!(first, 1.0); // the green of pixel (0, 1), the bottom row
        assert_eq!(bytes.len(), header.len() + 2 * 2 * 3 * 4);
    }

    #[test]
    fn round_trip_keeps_values_and_orientation() {
        let img = Image::from_fn(3, 2, |x, y| Vec3::new(x as f32, y as f32, -0.5));
        let bytes = encode_pfm(&img);
        assert!(bytes.starts_with(b"PF\n3 2\n-1.0\n"));
        assert_eq!(decode_pfm(&bytes).unwrap(), img);
        let grey = Image::from_fn(2, 2, |x, y| (x + 2 * y) as f32);
        let back = decode_pfm(&encode_pfm_grey(&grey)).unwrap();
        assert_eq!(back.get(1, 1), Some(&Vec3::splat(3.0)));
        assert!(decode_pfm(b"PF\n3 2\n-1.0\n\0\0").is_err());
        assert!(decode_pfm(b"P6\n1 1\n255\n").is_err());
    }
}
