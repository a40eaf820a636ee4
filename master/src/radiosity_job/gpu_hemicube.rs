//! GPU against CPU hemi-cube item buffers on the Cornell box: seconds per shot (ray-cast item buffer on the CPU, rasterised on the GPU one shot per submission and batched) and the full solve time with each, with the relative difference of the two solutions.
//!
//! On lavapipe (Mesa's software Vulkan, what CI and this project's
//! machines have) the "GPU" is the same CPU cores running a software
//! rasteriser, so these records say nothing about a hardware GPU, where
//! rasterising a few thousand triangles into five faces costs
//! microseconds and the readback dominates.

use super::bench::BenchRecord;
use crate::scene_file::load_any;
use serde_json::json;
use showcase_light::radiosity::hemicube::{HemiCube, HemiCubeShot, ItemTriangle};
use showcase_light::radiosity::shooting::ItemBufferBackend;
use showcase_light::radiosity::{
    FormFactorMethod, MeshOptions, RadiosityMesh, Shooter, SolveOptions, relative_error,
};
use showcase_light::{ObjectFilter, SceneGeometry};
use showcase_render::gpu::GpuContext;
use showcase_render::gpu::hemicube::GpuHemiCube;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Shots timed per item-buffer measurement.
const SHOTS: usize = 64;

/// Records of kind `gpu_hemicube_shot` (per resolution) and
/// `gpu_hemicube_solve` (per resolution and method) on the Cornell box
/// OBJ at `cornell`, meshed like the `radiosity` command's default
/// (0.01 m^2 patches), with the GPU of `ctx`.
pub fn gpu_hemicube_records(cornell: &Path, ctx: &GpuContext) -> anyhow::Result<Vec<BenchRecord>> {
    let showcase = load_any(cornell)?;
    let geometry = SceneGeometry::build(&showcase, &ObjectFilter::All)?;
    let mesh = RadiosityMesh::build(
        &showcase,
        &geometry,
        &MeshOptions {
            max_patch_area: super::DEFAULT_PATCH_AREA,
            element_depth: 1,
            ..MeshOptions::default()
        },
    )?;
    let adapter = ctx.describe();
    let gpu = Arc::new(GpuHemiCube::new(ctx));
    let mut records = Vec::new();
    for n in [64, 128, 256] {
        records.push(shot_record(&mesh, &geometry, &gpu, n, &adapter)?);
    }
    for (n, method) in [
        (64, FormFactorMethod::HemiCube),
        (128, FormFactorMethod::HemiCube),
        (64, FormFactorMethod::Hybrid),
    ] {
        records.push(solve_record(&mesh, &geometry, &gpu, n, method, &adapter)?);
    }
    Ok(records)
}

/// Seconds per item buffer at resolution `n`, CPU and GPU, over [`SHOTS`]
/// shooters spread over the patches.
fn shot_record(
    mesh: &RadiosityMesh,
    geometry: &SceneGeometry,
    gpu: &GpuHemiCube,
    n: u32,
    adapter: &str,
) -> anyhow::Result<BenchRecord> {
    let cube = HemiCube::new(n)?;
    let triangles: Vec<ItemTriangle> = mesh
        .elements
        .iter()
        .enumerate()
        .map(|(j, e)| ItemTriangle {
            item: j as u32,
            vertices: e.vertices,
            normal: e.normal,
        })
        .collect();
    let step = (mesh.patches.len() / SHOTS).max(1);
    let shots: Vec<HemiCubeShot> = (0..mesh.patches.len())
        .step_by(step)
        .take(SHOTS)
        .enumerate()
        .map(|(i, p)| HemiCubeShot {
            origin: mesh.patches[p].center,
            normal: mesh.patches[p].normal,
            rotation: i as f64 * 0.7,
        })
        .collect();
    let k = shots.len() as f64;
    let t = Instant::now();
    let mut ff = vec![0.0; mesh.elements.len()];
    for s in &shots {
        let items = cube.item_buffer(geometry, s.origin, s.normal, s.rotation, |hit| {
            if !hit.front_face {
                return None;
            }
            let prim = mesh.primitive_of(hit.object, hit.triangle)?;
            mesh.locate(prim, hit.barycentric).map(|(e, _)| e)
        });
        cube.accumulate(&items, &mut ff);
    }
    let cpu = t.elapsed().as_secs_f64() / k;
    let t = Instant::now();
    let scene = gpu.upload_triangles(n, &triangles)?;
    let upload = t.elapsed().as_secs_f64();
    // Warm-up (pipeline, first touch of the batch's textures and
    // readback memory), then timed runs.
    scene.render_shots(&shots)?;
    let t = Instant::now();
    for s in &shots {
        for items in scene.render_shots(std::slice::from_ref(s))? {
            cube.accumulate(&items, &mut ff);
        }
    }
    let single = t.elapsed().as_secs_f64() / k;
    let t = Instant::now();
    for items in scene.render_shots(&shots)? {
        cube.accumulate(&items, &mut ff);
    }
    let batched = t.elapsed().as_secs_f64() / k;
    Ok(json!({
        "kind": "gpu_hemicube_shot",
        "adapter": adapter,
        "hemicube": n,
        "patches": mesh.patches.len(),
        "elements": mesh.elements.len(),
        "shots": shots.len(),
        "batch": scene.batch(),
        "cpu_seconds_per_shot": cpu,
        "gpu_seconds_per_shot": single,
        "gpu_batched_seconds_per_shot": batched,
        "gpu_upload_seconds": upload,
    }))
}

/// One timed shooting solve of [`solve_record`].
struct TimedSolve {
    /// Wall-clock seconds of the solve.
    seconds: f64,
    /// Element radiosity.
    radiosity: Vec<glam::DVec3>,
    /// Patches shot.
    shots: usize,
    /// Item-buffer rows the GPU left to the CPU.
    fallbacks: usize,
}

/// A full solve to 1e-3 with CPU and with GPU item buffers.
fn solve_record(
    mesh: &RadiosityMesh,
    geometry: &SceneGeometry,
    gpu: &Arc<GpuHemiCube>,
    n: u32,
    method: FormFactorMethod,
    adapter: &str,
) -> anyhow::Result<BenchRecord> {
    let cpu_options = SolveOptions {
        hemicube: n,
        threshold: 1e-3,
        method,
        ..SolveOptions::default()
    };
    let gpu_options = SolveOptions {
        item_buffer: ItemBufferBackend::Raster(gpu.clone()),
        ..cpu_options.clone()
    };
    let run = |o: &SolveOptions| -> anyhow::Result<TimedSolve> {
        let t = Instant::now();
        let mut s = Shooter::new(mesh, geometry, None, o)?;
        s.add_surface_emission();
        s.run();
        Ok(TimedSolve {
            seconds: t.elapsed().as_secs_f64(),
            radiosity: s.radiosity().to_vec(),
            shots: s.shots(),
            fallbacks: s.item_buffer_fallbacks(),
        })
    };
    let cpu = run(&cpu_options)?;
    let gpu = run(&gpu_options)?;
    let fallbacks = gpu.fallbacks;
    anyhow::ensure!(fallbacks == 0, "{fallbacks} gpu rows fell back to the cpu");
    Ok(json!({
        "kind": "gpu_hemicube_solve",
        "adapter": adapter,
        "method": match method {
            FormFactorMethod::HemiCube => "hemicube",
            FormFactorMethod::Hybrid => "hybrid",
            FormFactorMethod::RayCast => "raycast",
        },
        "hemicube": n,
        "threshold": cpu_options.threshold,
        "patches": mesh.patches.len(),
        "elements": mesh.elements.len(),
        "shots": cpu.shots,
        "gpu_shots": gpu.shots,
        "cpu_seconds": cpu.seconds,
        "gpu_seconds": gpu.seconds,
        "rel_error_gpu_vs_cpu": relative_error(mesh, &gpu.radiosity, mesh, &cpu.radiosity, 4),
    }))
}
