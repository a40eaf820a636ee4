//! The demo's image files: 8-bit PNGs of radiance (exposed), of values,
//! and CIEDE2000 heat maps.

use anyhow::{Context, Result};
use glam::Vec3;
use showcase_light::RgbImage;
use std::path::Path;

/// Write an 8-bit RGB PNG from a per-pixel colour function.
pub(in crate::demo) fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    pixel: impl Fn(u32, u32) -> [u8; 3],
) -> Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc
        .write_header()
        .with_context(|| format!("cannot write {}", path.display()))?;
    let mut data = Vec::with_capacity((width * height * 3) as usize);
    for y in 0..height {
        for x in 0..width {
            data.extend_from_slice(&pixel(x, y));
        }
    }
    w.write_image_data(&data)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Linear radiance times `exposure`, sRGB-encoded.
pub(in crate::demo) fn write_radiance(path: &Path, image: &RgbImage, exposure: f64) -> Result<()> {
    let enc = showcase_render::node::png_out::srgb8;
    write_png(path, image.width, image.height, |x, y| {
        let c = image.get(x, y).copied().unwrap_or(Vec3::ZERO) * exposure as f32;
        [enc(c.x), enc(c.y), enc(c.z)]
    })
}

/// Projector pixel values as they are sent to the device (already
/// compensated: no further encoding).
pub(in crate::demo) fn write_values(path: &Path, image: &RgbImage) -> Result<()> {
    let b = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    write_png(path, image.width, image.height, |x, y| {
        let c = image.get(x, y).copied().unwrap_or(Vec3::ZERO);
        [b(c.x), b(c.y), b(c.z)]
    })
}

/// The CIEDE2000 heat maps' colour scale: ΔE00 and its colour (linear
/// 0 to 1 per channel, interpolated between stops; 10 and above red).
pub(in crate::demo) const HEAT_STOPS: [(f64, [f64; 3]); 5] = [
    (0.0, [0.0, 0.0, 0.0]),
    (2.5, [0.0, 0.2, 1.0]),
    (5.0, [0.0, 0.85, 0.3]),
    (7.5, [1.0, 0.9, 0.0]),
    (10.0, [1.0, 0.0, 0.0]),
];

/// The colour of pixels no eye covers in a heat map.
pub(in crate::demo) const HEAT_UNCOVERED: [u8; 3] = [40, 40, 40];

/// How a heat map's file name ends, so the page can set its colour bar
/// beside it.
pub(in crate::demo) const HEAT_MAP_SUFFIX: &str = "-delta-e.png";

/// A stop's colour as 8-bit values.
pub(in crate::demo) fn heat_stop_rgb(c: [f64; 3]) -> [u8; 3] {
    c.map(|v| (v * 255.0 + 0.5) as u8)
}

/// A CIEDE2000 heat map on the [`HEAT_STOPS`] scale; uncovered pixels
/// [`HEAT_UNCOVERED`].
pub(in crate::demo) fn write_heat_map(
    path: &Path,
    width: u32,
    height: u32,
    delta_e: &[f64],
) -> Result<()> {
    const STOPS: [(f64, [f64; 3]); 5] = HEAT_STOPS;
    write_png(path, width, height, |x, y| {
        let d = delta_e[(y * width + x) as usize];
        if !d.is_finite() {
            return HEAT_UNCOVERED;
        }
        let d = d.clamp(0.0, 10.0);
        let i = STOPS
            .windows(2)
            .position(|w| d <= w[1].0)
            .unwrap_or(STOPS.len() - 2);
        let (a, b) = (STOPS[i], STOPS[i + 1]);
        let t = (d - a.0) / (b.0 - a.0);
        let c = |k: usize| ((a.1[k] + t * (b.1[k] - a.1[k])) * 255.0 + 0.5) as u8;
        [c(0), c(1), c(2)]
    })
}
