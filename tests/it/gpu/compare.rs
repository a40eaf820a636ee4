//! Pixel-wise comparison of a GPU image with the CPU reference, with a stated tolerance; on failure it writes `-actual`, `-expected` and `-diff` PNGs.

use std::path::Path;

use anyhow::{Context, Result, bail, ensure};
use showcase_light::raster::RasterImage;

/// How far the GPU may stray from the CPU reference.
pub(super) struct Tolerance {
    /// Largest colour difference (any channel) where both agree on the triangle.
    pub(super) colour: f32,
    /// Largest depth difference where both agree on the triangle.
    pub(super) depth: f32,
    /// Most mismatching pixels, as a fraction of the reference's drawn
    /// pixels; mismatches are allowed only at uncertain pixels.
    pub(super) mismatch_fraction: f64,
}

/// The tolerance of the bunny and Cornell box comparisons: f32 shading and
/// depth arithmetic on the GPU against f64 on the CPU (depth loses most:
/// `z_ndc = a + b / z` cancels, about 2e-6 seen on lavapipe; 1e-5 is
/// 36 um at 0.6 m with near 0.1 m), and coverage or visibility that may
/// differ only where the reference marks the pixel uncertain (within
/// 1/64 px of an edge or 1e-5 in relative depth).
pub(super) const MESH_TOLERANCE: Tolerance = Tolerance {
    colour: 1e-5,
    depth: 1e-5,
    mismatch_fraction: 0.005,
};

/// Compare GPU and CPU images pixel by pixel; on failure write
/// `<name>-actual.png`, `<name>-expected.png` and `<name>-diff.png`.
pub(super) fn compare(
    name: &str,
    cpu: &RasterImage,
    gpu_colour: &[[f32; 4]],
    gpu_depth: &[f32],
    tol: &Tolerance,
) -> Result<()> {
    let n = cpu.colour.len();
    ensure!(
        gpu_colour.len() == n && gpu_depth.len() == n,
        "{name}: image sizes differ"
    );
    let drawn = cpu.colour.iter().filter(|c| c[3] == 1.0).count();
    let uncertain = cpu.uncertain.iter().filter(|&&u| u).count();
    let mut hard = Vec::new();
    let mut soft = 0usize;
    let mut max_colour = 0.0f32;
    let mut max_depth = 0.0f32;
    let mut diff = vec![[0u8; 3]; n];
    for i in 0..n {
        let (c, g) = (cpu.colour[i], gpu_colour[i]);
        let colour_err = (0..4).map(|k| (c[k] - g[k]).abs()).fold(0.0, f32::max);
        let depth_err = (cpu.depth[i] - gpu_depth[i]).abs();
        let ok = colour_err <= tol.colour && depth_err <= tol.depth;
        if ok {
            max_colour = max_colour.max(colour_err);
            max_depth = max_depth.max(depth_err);
            continue;
        }
        if cpu.uncertain[i] {
            soft += 1;
            diff[i] = [255, 255, 0];
        } else {
            hard.push(i);
            diff[i] = [255, 0, 0];
        }
    }
    let width = cpu.width as usize;
    eprintln!(
        "{name}: {drawn} drawn, {uncertain} uncertain, {soft} mismatches at uncertain pixels, \
         {} elsewhere; max |colour| {max_colour:.2e}, max |depth| {max_depth:.2e} where agreeing",
        hard.len()
    );
    let allowed = (tol.mismatch_fraction * drawn as f64).floor() as usize;
    if hard.is_empty() && soft <= allowed {
        return Ok(());
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    write_png(
        &dir.join(format!("{name}-actual.png")),
        cpu.width,
        cpu.height,
        &to_rgb8(gpu_colour),
    )?;
    write_png(
        &dir.join(format!("{name}-expected.png")),
        cpu.width,
        cpu.height,
        &to_rgb8(&cpu.colour),
    )?;
    write_png(
        &dir.join(format!("{name}-diff.png")),
        cpu.width,
        cpu.height,
        &diff,
    )?;
    let first: Vec<String> = hard
        .iter()
        .take(5)
        .map(|&i| {
            format!(
                "({}, {}): gpu {:?} depth {} vs cpu {:?} depth {}",
                i % width,
                i / width,
                gpu_colour[i],
                gpu_depth[i],
                cpu.colour[i],
                cpu.depth[i]
            )
        })
        .collect();
    bail!(
        "{name}: {} mismatches at certain pixels (first: {first:?}), {soft} at uncertain pixels \
         (allowed {allowed}); images in {}",
        hard.len(),
        dir.display()
    )
}

fn to_rgb8(pixels: &[[f32; 4]]) -> Vec<[u8; 3]> {
    pixels
        .iter()
        .map(|p| {
            std::array::from_fn(|k| (p[k].clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8)
        })
        .collect()
}

fn write_png(path: &Path, width: u32, height: u32, rgb: &[[u8; 3]]) -> Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()?
        .write_image_data(rgb.as_flattened())
        .with_context(|| format!("writing {}", path.display()))
}
