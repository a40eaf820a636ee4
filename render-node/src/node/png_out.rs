//! Writing rendered frames as 8-bit sRGB PNG files.

use super::renderer::OutputImage;
use showcase_light::finite::finite_or_zero;
use std::path::Path;

/// Linear to sRGB-encoded 8-bit.
pub fn srgb8(linear: f32) -> u8 {
    let c = finite_or_zero(linear).clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Write `img` as an 8-bit sRGB RGB PNG.
pub fn write_png(path: &Path, img: &OutputImage) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), img.width, img.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(|e| e.to_string())?;
    let data: Vec<u8> = img
        .rgba
        .iter()
        .flat_map(|p| [srgb8(p[0]), srgb8(p[1]), srgb8(p[2])])
        .collect();
    w.write_image_data(&data).map_err(|e| e.to_string())
}
