//! Integration tests: the GPU hemi-cube. Its rasterised item buffers against the CPU's ray-cast ones on the Cornell box (pixel ids, form-factor rows, the closed-form form factor to the light), and a full progressive-refinement solve with GPU item buffers against the CPU solve.
//!
//! GPU adapter policy as in `gpu.rs` ([`crate::gpu::gpu_or_skip`]): with
//! `CI` set a missing adapter fails these tests.

use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Result, ensure};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use showcase_light::radiosity::hemicube::{HemiCube, HemiCubeShot, ItemTriangle, NO_ITEM};
use showcase_light::radiosity::shooting::ItemBufferBackend;
use showcase_light::radiosity::{
    FormFactorMethod, MeshOptions, RadiosityMesh, Shooter, SolveOptions, relative_error,
};
use showcase_light::{ObjectFilter, SceneGeometry, form_factor_point_polygon};
use showcase_master::scene_file::load_any;
use showcase_render::gpu::hemicube::GpuHemiCube;

const CORNELL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cornell-box.obj"
);

/// The Cornell box meshed with patches of at most `area` m^2.
fn cornell(area: f64) -> Result<(RadiosityMesh, SceneGeometry)> {
    let s = load_any(Path::new(CORNELL))?;
    let g = SceneGeometry::build(&s, &ObjectFilter::All)?;
    let m = RadiosityMesh::build(
        &s,
        &g,
        &MeshOptions {
            max_patch_area: area,
            element_depth: 1,
            ..MeshOptions::default()
        },
    )?;
    Ok((m, g))
}

fn triangles(mesh: &RadiosityMesh) -> Vec<ItemTriangle> {
    mesh.elements
        .iter()
        .enumerate()
        .map(|(j, e)| ItemTriangle {
            item: j as u32,
            vertices: e.vertices,
            normal: e.normal,
        })
        .collect()
}

/// The CPU item buffer of `shot`: elements seen front-on, as the solver
/// resolves ray hits.
fn cpu_items(
    cube: &HemiCube,
    mesh: &RadiosityMesh,
    geometry: &SceneGeometry,
    shot: &HemiCubeShot,
) -> Vec<u32> {
    cube.item_buffer(geometry, shot.origin, shot.normal, shot.rotation, |hit| {
        if !hit.front_face {
            return None;
        }
        let prim = mesh.primitive_of(hit.object, hit.triangle)?;
        mesh.locate(prim, hit.barycentric).map(|(e, _)| e)
    })
}

/// `(face, first row, rows)` of pixel `index` in a hemi-cube of `n`.
fn face_of(index: usize, n: usize) -> (usize, usize, usize) {
    let row = index / n;
    if row < n {
        (0, 0, n)
    } else {
        let k = (row - n) / (n / 2);
        (1 + k, n + k * (n / 2), n / 2)
    }
}

/// True when a pixel within one pixel of `index` in the same face of
/// `buffer` sees something else than `index` does: `index` lies on an
/// edge between items (or at a silhouette).
fn on_edge(buffer: &[u32], index: usize, n: usize) -> bool {
    let (_, first, rows) = face_of(index, n);
    let (row, col) = ((index / n) as i64, (index % n) as i64);
    for dr in -1..=1 {
        for dc in -1..=1 {
            let (r, c) = (row + dr, col + dc);
            if r < first as i64 || r >= (first + rows) as i64 || c < 0 || c >= n as i64 {
                continue;
            }
            if buffer[(r as usize) * n + c as usize] != buffer[index] {
                return true;
            }
        }
    }
    false
}

/// GPU and CPU item buffers of one shooter per Cornell-box patch (a
/// sample of them), at resolution 128 with random rotations:
/// - pixels disagree only on edges between items (where the 3x3
///   neighbourhood in either buffer is not one id), at most 0.5% of the
///   covered pixels;
/// - per-element rows: sums within 0.1% of the hemisphere (1e-3),
///   relative L1 below 1%;
/// - the form factor to the light, from points that see all of it,
///   within 1% of Lambert's closed form on both.
#[test]
fn gpu_item_buffers_match_the_cpu_on_the_cornell_box() -> Result<()> {
    let Some(ctx) = crate::gpu::gpu_or_skip("gpu_item_buffers_match_the_cpu_on_the_cornell_box")?
    else {
        return Ok(());
    };
    let n = 128u32;
    let (mesh, geometry) = cornell(0.01)?;
    let cube = HemiCube::new(n)?;
    let gpu = GpuHemiCube::new(&ctx).upload_triangles(n, &triangles(&mesh))?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let step = (mesh.patches.len() / 24).max(1);
    // A sample of all patches, and every third floor patch (most of
    // them see the whole light, for the closed-form check).
    let floor = (0..mesh.patches.len())
        .filter(|&p| mesh.patches[p].normal.y > 0.99 && mesh.patches[p].center.y < 1e-3)
        .step_by(3);
    let shots: Vec<HemiCubeShot> = (0..mesh.patches.len())
        .step_by(step)
        .chain(floor)
        .map(|p| HemiCubeShot {
            origin: mesh.patches[p].center,
            normal: mesh.patches[p].normal,
            rotation: rng.random::<f64>() * std::f64::consts::TAU,
        })
        .collect();
    ensure!(shots.len() >= 30, "only {} shots", shots.len());
    let gpu_buffers = gpu.render_shots(&shots)?;
    ensure!(gpu_buffers.len() == shots.len());
    // Lambert's closed form to the light (the emitting primitives).
    let light: Vec<[DVec3; 3]> = mesh
        .primitives
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            mesh.elements
                .iter()
                .any(|e| e.primitive == *i as u32 && e.emission.max_element() > 0.0)
        })
        .map(|(_, p)| p.vertices)
        .collect();
    let light_items: HashSet<u32> = mesh
        .elements
        .iter()
        .enumerate()
        .filter(|(_, e)| e.emission.max_element() > 0.0)
        .map(|(j, _)| j as u32)
        .collect();
    ensure!(!light.is_empty() && !light_items.is_empty(), "no light");
    let (mut covered, mut differ, mut off_edge) = (0usize, 0usize, 0usize);
    let (mut worst_sum, mut worst_l1) = (0.0f64, 0.0f64);
    let (mut light_checks, mut blind) = (0, 0);
    for (shot, g) in shots.iter().zip(&gpu_buffers) {
        let c = cpu_items(&cube, &mesh, &geometry, shot);
        ensure!(g.len() == c.len() && c.len() == cube.pixel_count());
        for (i, (&a, &b)) in g.iter().zip(&c).enumerate() {
            if b != NO_ITEM || a != NO_ITEM {
                covered += 1;
            }
            if a != b {
                differ += 1;
                if !(on_edge(&c, i, n as usize) || on_edge(g, i, n as usize)) {
                    off_edge += 1;
                }
            }
        }
        let mut fg = vec![0.0; mesh.elements.len()];
        let mut fc = vec![0.0; mesh.elements.len()];
        cube.accumulate(g, &mut fg);
        cube.accumulate(&c, &mut fc);
        let (sg, sc): (f64, f64) = (fg.iter().sum(), fc.iter().sum());
        if sc < 0.1 {
            // A patch inside a block (the floor under it) sees only back
            // faces: both buffers must agree that it sees nothing.
            ensure!(sg < 1e-3, "shot {shot:?}: gpu sees {sg}, cpu {sc}");
            blind += 1;
            continue;
        }
        let l1: f64 = fg.iter().zip(&fc).map(|(a, b)| (a - b).abs()).sum::<f64>() / sc;
        // In units of the whole hemisphere (its form factors sum to 1).
        worst_sum = worst_sum.max((sg - sc).abs());
        worst_l1 = worst_l1.max(l1);
        // Against the closed form where the whole light is in view.
        let sees_light = light.iter().all(|t| {
            let centre = (t[0] + t[1] + t[2]) / 3.0;
            t.iter()
                .chain([&centre])
                .all(|&v| geometry.visible(shot.origin, shot.normal, v, true))
        });
        let exact: f64 = light
            .iter()
            .map(|t| form_factor_point_polygon(shot.origin, shot.normal, t).unwrap_or(0.0))
            .sum();
        if sees_light && exact > 0.01 {
            light_checks += 1;
            for (name, f) in [("gpu", &fg), ("cpu", &fc)] {
                let to_light: f64 = light_items.iter().map(|&j| f[j as usize]).sum();
                ensure!(
                    (to_light - exact).abs() < 0.01 * exact,
                    "{name}: form factor to the light {to_light} vs closed form {exact}"
                );
            }
        }
    }
    eprintln!(
        "{} shots at {n}: {differ} of {covered} covered pixels differ ({off_edge} off an edge); \
         worst row-sum difference {worst_sum:.2e}, worst relative L1 {worst_l1:.4}; \
         {light_checks} light checks, {blind} shots inside a block",
        shots.len()
    );
    ensure!(
        blind < shots.len() / 4,
        "{blind} of {} shots see nothing",
        shots.len()
    );
    ensure!(covered > shots.len() * cube.pixel_count() / 2);
    ensure!(off_edge == 0, "{off_edge} differing pixels off any edge");
    ensure!(
        (differ as f64) < 0.005 * covered as f64,
        "{differ} of {covered} pixels differ"
    );
    ensure!(worst_sum < 1e-3, "row sums differ by {worst_sum}");
    ensure!(worst_l1 < 0.01, "relative L1 of a row {worst_l1}");
    ensure!(
        light_checks >= 3,
        "only {light_checks} shots see the whole light"
    );
    Ok(())
}

/// A full Cornell-box solve (hemi-cube form factors everywhere, 64^2)
/// with GPU item buffers against the same solve with CPU ones: the
/// relative RMS difference of B is below 1%, the rasteriser never fell
/// back to the CPU, both conserve energy the same way, and the solver's
/// form-factor rows of a sample of patches differ by a relative L1 below
/// 1%.
#[test]
fn gpu_hemicube_solve_matches_the_cpu_solve() -> Result<()> {
    let Some(ctx) = crate::gpu::gpu_or_skip("gpu_hemicube_solve_matches_the_cpu_solve")? else {
        return Ok(());
    };
    let (mesh, geometry) = cornell(0.01)?;
    let cpu_options = SolveOptions {
        hemicube: 64,
        threshold: 1e-3,
        method: FormFactorMethod::HemiCube,
        ..SolveOptions::default()
    };
    let gpu_options = SolveOptions {
        item_buffer: ItemBufferBackend::Raster(Arc::new(GpuHemiCube::new(&ctx))),
        ..cpu_options.clone()
    };
    // The solver's own rows (item buffer filtered to receivers, shooter's
    // patch excluded) agree patch by patch.
    let cpu_shooter = Shooter::new(&mesh, &geometry, None, &cpu_options)?;
    let gpu_shooter = Shooter::new(&mesh, &geometry, None, &gpu_options)?;
    let mut worst_row = 0.0f64;
    for p in (0..mesh.patches.len()).step_by(17) {
        let dense = |row: Option<Vec<(u32, f64)>>| -> Vec<f64> {
            let mut f = vec![0.0; mesh.elements.len()];
            for (j, v) in row.unwrap_or_default() {
                f[j as usize] += v;
            }
            f
        };
        let (c, g) = (
            dense(cpu_shooter.form_factor_row(p)),
            dense(gpu_shooter.form_factor_row(p)),
        );
        let total: f64 = c.iter().sum();
        if total < 0.1 {
            continue;
        }
        let l1: f64 = c.iter().zip(&g).map(|(a, b)| (a - b).abs()).sum();
        worst_row = worst_row.max(l1 / total);
    }
    ensure!(
        worst_row < 0.01,
        "solver rows differ by relative L1 {worst_row}"
    );
    let run = |options: &SolveOptions| -> Result<(Vec<DVec3>, usize, usize, f64)> {
        let mut s = Shooter::new(&mesh, &geometry, None, options)?;
        s.add_surface_emission();
        s.run();
        Ok((
            s.radiosity().to_vec(),
            s.shots(),
            s.item_buffer_fallbacks(),
            s.unshot_fraction(),
        ))
    };
    let (cpu, cpu_shots, _, cpu_unshot) = run(&cpu_options)?;
    let (gpu, gpu_shots, fallbacks, gpu_unshot) = run(&gpu_options)?;
    ensure!(fallbacks == 0, "{fallbacks} rows fell back to the CPU");
    ensure!(gpu.iter().all(|b| b.is_finite() && b.min_element() >= 0.0));
    ensure!(cpu_unshot < 1e-3 && gpu_unshot < 1e-3);
    let e = relative_error(&mesh, &gpu, &mesh, &cpu, 4)
        .ok_or_else(|| anyhow::anyhow!("no relative error"))?;
    let power = |b: &[DVec3]| -> f64 {
        b.iter()
            .zip(&mesh.elements)
            .map(|(b, el)| (b.x + b.y + b.z) * el.area)
            .sum()
    };
    let (pc, pg) = (power(&cpu), power(&gpu));
    eprintln!(
        "Cornell solve, hemi-cube 64: rel error of B (gpu vs cpu) {e:.2e}; shots cpu {cpu_shots} \
         gpu {gpu_shots}; power cpu {pc:.4} gpu {pg:.4}; worst solver row L1 {worst_row:.2e}"
    );
    ensure!(e < 0.01, "relative error of B {e}");
    ensure!((pg - pc).abs() < 0.005 * pc, "power {pg} vs {pc}");
    Ok(())
}
