//! Golden images of key views: the projector's device values for the
//! bench scene's first frame, from the CPU reference and from the GPU.
//! A missing reference fails; `BLESS=1` writes it. Stored as 16-bit RGB
//! PNG under `tests/golden/`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail, ensure};
use glam::Vec3;
use showcase_light::render::{FrameScene, Occluders, ProjectorOptions, irradiance_map_cpu};
use showcase_render::render::bench::{bench_frame, bench_projector};
use showcase_render::render::passes::PassList;
use showcase_render::render::projector_gpu::ProjectorPipeline;

use super::gpu_or_skip;
use super::scenes::bench;

/// A pixel channel may differ by this much (16-bit levels of 0..1)...
const LEVEL_TOLERANCE: u16 = 64;
/// ...and this fraction of pixels may differ by more (shadow edges on
/// another adapter).
const EDGE_FRACTION: f64 = 5e-3;

fn golden_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("golden")
        .join(name)
}

fn to_levels(pixels: &[Vec3]) -> Vec<u16> {
    pixels
        .iter()
        .flat_map(|p| p.to_array())
        .map(|c| (c.clamp(0.0, 1.0) * 65535.0).round() as u16)
        .collect()
}

fn write_png(path: &PathBuf, width: u32, height: u32, levels: &[u16]) -> Result<()> {
    std::fs::create_dir_all(path.parent().context("golden path has a parent")?)?;
    let file = std::fs::File::create(path)?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Sixteen);
    let bytes: Vec<u8> = levels.iter().flat_map(|l| l.to_be_bytes()).collect();
    enc.write_header()?.write_image_data(&bytes)?;
    Ok(())
}

fn read_png(path: &PathBuf) -> Result<(u32, u32, Vec<u16>)> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path)?));
    let mut reader = decoder.read_info()?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf)?;
    ensure!(
        info.color_type == png::ColorType::Rgb && info.bit_depth == png::BitDepth::Sixteen,
        "{}: expected 16-bit RGB",
        path.display()
    );
    let levels = buf[..info.buffer_size()]
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    Ok((info.width, info.height, levels))
}

/// Compare with (or, with `BLESS=1`, write) the golden image `name`.
fn check_golden(name: &str, width: u32, height: u32, pixels: &[Vec3]) -> Result<()> {
    let path = golden_path(name);
    let levels = to_levels(pixels);
    if std::env::var_os("BLESS").is_some() {
        write_png(&path, width, height, &levels)?;
        eprintln!("blessed {}", path.display());
        return Ok(());
    }
    if !path.exists() {
        bail!(
            "golden image {} is missing; run with BLESS=1 to write it",
            path.display()
        );
    }
    let (w, h, reference) = read_png(&path)?;
    ensure!(
        (w, h) == (width, height),
        "{name}: golden is {w}x{h}, output {width}x{height}"
    );
    let off = levels
        .chunks_exact(3)
        .zip(reference.chunks_exact(3))
        .filter(|(a, b)| {
            a.iter()
                .zip(b.iter())
                .any(|(x, y)| x.abs_diff(*y) > LEVEL_TOLERANCE)
        })
        .count();
    let fraction = off as f64 / (w * h) as f64;
    eprintln!("{name}: {off} pixels off ({fraction})");
    ensure!(
        fraction <= EDGE_FRACTION,
        "{name}: {off} pixels differ from the golden image"
    );
    Ok(())
}

#[test]
fn projector_values_match_the_golden_image() -> Result<()> {
    let scene = bench()?;
    let frame = FrameScene::resolve(&scene, &bench_frame(&scene, "full", 0))?;
    let projector = bench_projector(160, 120);
    let occ = Occluders::new(&frame)?;
    let cpu = irradiance_map_cpu(&frame, &occ, &projector, ProjectorOptions::default())?;
    check_golden("projector_bench_cpu_160x120.png", 160, 120, &cpu.value.data)?;
    let Some(ctx) = gpu_or_skip("projector_values_match_the_golden_image")? else {
        return Ok(());
    };
    let gpu = ProjectorPipeline::new(&ctx.device, 1024).render(
        &ctx,
        &frame,
        &projector,
        &PassList::full(),
    )?;
    let values: Vec<Vec3> = gpu
        .value
        .iter()
        .map(|p| Vec3::new(p[0], p[1], p[2]))
        .collect();
    check_golden("projector_bench_gpu_160x120.png", 160, 120, &values)
}
