//! `bench radiosity` records of the hierarchical solver (issue #23):
//!
//! - `hierarchical_demo`: the demo cabinet (`builtin:showcase`) at the
//!   demo's settings, the whole `radiosity` job (augmented B0..B3 and
//!   both projectors' irradiance maps, files written), median of 3, with
//!   the peak resident memory of the job.
//! - `hierarchical_cornell`: B0 on the Cornell box, median of 5 solves
//!   (mesh and vertex values included), against the path-traced probes
//!   ([`super::probes`]), at a few patch sizes and refinement thresholds.
//! - `hierarchical_light_move`: B0 of the demo cabinet updated after its
//!   lamp moves 5 cm, 20 times ([`radiosity::Hierarchy::update`]: the
//!   moved light's direct irradiance, then gathers from the old B on the
//!   same links), per-move times, the error against a fresh solve of the
//!   last position, and the floor: one gather and the light's direct term
//!   alone.
//! - `hierarchical_scaling`: the demo cabinet with its real bunny split
//!   0..=3 times (each split turns a triangle into four), one element per
//!   triangle (0.02 m^2 patches elsewhere): time, memory and links against
//!   input triangles.

use super::probes::{PROBE_COUNT, PROBE_SEED, PROBE_SPP, path_traced_probes, probe_errors};
use super::{BenchRecord, CORNELL_BOX};
use crate::cluster::soak::{peak_rss_mb, reset_peak_rss};
use crate::radiosity_job::{RadiosityOptions, Solver, run_radiosity_scene, solve_showcase};
use crate::scene_file::load_any;
use anyhow::Context;
use serde_json::json;
use showcase_proto::{Mesh, Showcase};
use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

/// The demo's radiosity settings on the hierarchical solver.
fn demo_options() -> RadiosityOptions {
    RadiosityOptions {
        max_patch_area: Some(0.02),
        threshold: Some(1e-2),
        solver: Solver::Hierarchical,
        ..RadiosityOptions::default()
    }
}

/// Nearest-rank median ([`showcase_light::metrics::percentile`]).
fn median(v: Vec<f64>) -> Option<f64> {
    showcase_light::metrics::percentile(&v, 50.0)
}

/// The records, `making` told each one's name as it starts.
pub fn hierarchical_records(making: &dyn Fn(&str)) -> anyhow::Result<Vec<BenchRecord>> {
    let mut records = Vec::new();
    making("hierarchical_demo");
    let demo = load_any(Path::new("builtin:showcase"))?;
    let out = std::env::temp_dir().join(format!("showcase-bench-hr-{}", std::process::id()));
    let mut seconds = Vec::new();
    let mut peak = Vec::new();
    let mut last = None;
    for _ in 0..3 {
        let reset = reset_peak_rss();
        let t = Instant::now();
        let s = run_radiosity_scene(
            &demo,
            "builtin:showcase",
            &out,
            &demo_options(),
            crate::radiosity_job::FormFactorDevice::Cpu,
        )?;
        seconds.push(t.elapsed().as_secs_f64());
        if reset {
            peak.extend(peak_rss_mb());
        }
        last = Some(s);
    }
    let _ = std::fs::remove_dir_all(&out);
    let s = last.context("no run")?;
    records.push(json!({
        "kind": "hierarchical_demo",
        "scene": "builtin:showcase",
        "elements": s.elements,
        "links": s.links,
        "gathers": s.shots,
        "irradiance_maps": s.irradiance_maps.len(),
        "seconds_median": median(seconds.clone()),
        "seconds": seconds,
        "peak_rss_mb_median": (!peak.is_empty()).then(|| median(peak.clone())),
        "b3_b0_deviation_rgb": s.b3_b0_deviation_rgb,
    }));

    making("hierarchical_cornell (tracing the probes first)");
    let cornell = load_any(Path::new(CORNELL_BOX))?;
    let probes = path_traced_probes(&cornell, PROBE_COUNT, PROBE_SPP, PROBE_SEED)?;
    for (area, epsilon) in [
        (0.02, 1e-6),
        (0.02, 1e-5),
        (0.04, 1e-5),
        (0.04, 1e-4),
        (0.01, 1e-6),
    ] {
        let options = RadiosityOptions {
            max_patch_area: Some(area),
            epsilon: Some(epsilon),
            ..demo_options()
        };
        let mut seconds = Vec::new();
        let mut solved = None;
        for _ in 0..5 {
            let t = Instant::now();
            solved = Some(solve_showcase(&cornell, &options)?);
            seconds.push(t.elapsed().as_secs_f64());
        }
        let solved = solved.context("no run")?;
        let errors = probe_errors(&solved.output_mesh, &solved.b0_vertices, &probes);
        records.push(json!({
            "kind": "hierarchical_cornell",
            "max_patch_area": area,
            "epsilon": epsilon,
            "elements": solved.mesh.elements.len(),
            "links": solved.links,
            "gathers": solved.shots,
            "seconds_median": median(seconds.clone()),
            "seconds": seconds,
            "probe_median": errors.as_ref().map(|e| e.median),
            "probe_p90": errors.as_ref().map(|e| e.p90),
            "probe_median_signed": errors.as_ref().map(|e| e.median_signed),
            "probes": errors.as_ref().map(|e| e.probes),
        }));
    }

    making("hierarchical_light_move");
    records.push(light_move_record(&demo)?);

    for splits in 0..=3 {
        making(&format!(
            "hierarchical_scaling (bunny split {splits} times)"
        ));
        let scene = split_object(&demo, "bunny", splits)?;
        let triangles: usize = scene
            .objects
            .iter()
            .filter_map(|o| scene.mesh(&o.mesh))
            .map(|m| m.triangles.len())
            .sum();
        let options = RadiosityOptions {
            element_depth: Some(0),
            ..demo_options()
        };
        let reset = reset_peak_rss();
        let t = Instant::now();
        let solved = solve_showcase(&scene, &options)?;
        let seconds = t.elapsed().as_secs_f64();
        records.push(json!({
            "kind": "hierarchical_scaling",
            "bunny_splits": splits,
            "input_triangles": triangles,
            "elements": solved.mesh.elements.len(),
            "links": solved.links,
            "gathers": solved.shots,
            "seconds": seconds,
            "peak_rss_mb": if reset { peak_rss_mb() } else { None },
        }));
    }
    Ok(records)
}

/// `scene` with object `name`'s mesh split `times` times (each triangle
/// into four at its edge midpoints; normals and texture coordinates are
/// dropped).
pub fn split_object(scene: &Showcase, name: &str, times: u32) -> anyhow::Result<Showcase> {
    let mut scene = scene.clone();
    let i = scene
        .object_index(name)
        .with_context(|| format!("the scene has no object {name:?}"))?;
    let mut mesh = scene
        .mesh(&scene.objects[i].mesh)
        .with_context(|| format!("object {name:?} has no mesh"))?
        .clone();
    for _ in 0..times {
        mesh = split_mesh(&mesh);
    }
    scene.objects[i].mesh = scene.add_mesh(mesh);
    Ok(scene)
}

fn split_mesh(mesh: &Mesh) -> Mesh {
    let mut positions = mesh.positions.clone();
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    let mut midpoint = |a: u32, b: u32, positions: &mut Vec<glam::Vec3>| -> u32 {
        *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
            positions.push(0.5 * (positions[a as usize] + positions[b as usize]));
            positions.len() as u32 - 1
        })
    };
    let mut triangles = Vec::with_capacity(4 * mesh.triangles.len());
    for &[a, b, c] in &mesh.triangles {
        let ab = midpoint(a, b, &mut positions);
        let bc = midpoint(b, c, &mut positions);
        let ca = midpoint(c, a, &mut positions);
        triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    Mesh {
        positions,
        normals: Vec::new(),
        uvs: Vec::new(),
        triangles,
    }
}

/// The `hierarchical_light_move` record (see the module docs).
fn light_move_record(demo: &Showcase) -> anyhow::Result<BenchRecord> {
    use showcase_light::radiosity::{self, Hierarchy, RadiosityMesh};
    use showcase_light::{ObjectFilter, SceneGeometry};
    let all = SceneGeometry::build(demo, &ObjectFilter::All)?;
    let mesh = RadiosityMesh::build(demo, &all, &demo_options().hierarchical_mesh())?;
    let light = demo
        .lights
        .first()
        .context("the demo scene has no light")?
        .light
        .clone();
    let showcase_proto::Light::Point {
        position,
        intensity,
    } = light
    else {
        anyhow::bail!("the demo's light is not a point light");
    };
    let at = |k: usize| showcase_proto::Light::Point {
        position: position + glam::Vec3::new(0.05 * (k % 2) as f32, 0.0, 0.05 * (k / 2 % 2) as f32),
        intensity,
    };
    let options = demo_options().hierarchy();
    let emission: Vec<glam::DVec3> = mesh.elements.iter().map(|e| e.emission).collect();
    let mut h = Hierarchy::new(&mesh, &all, None, &options)?;
    let mut b = h.solve(&emission, &h.direct_of(&at(0)))?.radiosity;
    let (mut times, mut gathers) = (Vec::new(), Vec::new());
    let moves = 20;
    for k in 1..=moves {
        let t = Instant::now();
        let direct = h.direct_of(&at(k));
        gathers.push(h.update(&mut b, &emission, &direct));
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let fresh = radiosity::solve_hierarchical(&mesh, &all, &[at(moves)], &options)?;
    let error = radiosity::relative_error(&mesh, &b, &mesh, &fresh.radiosity, 4);
    // The floor: what any update that keeps B exact must at least do once.
    let t = Instant::now();
    let direct = h.direct_of(&at(0));
    let direct_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let _ = h.reflect(&b);
    let gather_ms = t.elapsed().as_secs_f64() * 1e3;
    drop(direct);
    let p99 = showcase_light::metrics::percentile(&times, 99.0);
    Ok(json!({
        "kind": "hierarchical_light_move",
        "elements": mesh.elements.len(),
        "links": h.links(),
        "moves": moves,
        "move_m": 0.05,
        "ms_median": median(times.clone()),
        "ms_p99": p99,
        "ms": times,
        "gathers": gathers,
        "rel_error_vs_fresh": error,
        "fresh_gathers": fresh.iterations,
        "floor_direct_ms": direct_ms,
        "floor_one_gather_ms": gather_ms,
    }))
}
