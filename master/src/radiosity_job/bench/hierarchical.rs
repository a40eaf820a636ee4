//! `bench radiosity` records of the hierarchical solver (issue #23):
//!
//! - `hierarchical_demo`: the demo cabinet (`builtin:showcase`) at the
//!   demo's settings, the whole `radiosity` job (augmented B0..B3 and
//!   both projectors' irradiance maps, files written), median of 3, with
//!   the peak resident memory of the job.
//! - `hierarchical_cornell`: B0 on the Cornell box, median of 5 solves
//!   (mesh and vertex values included), against the path-traced probes
//!   ([`super::probes`]), at a few patch sizes and refinement thresholds.
//! - `hierarchical_light_move` (kind `hierarchical_moves`): B0 of the
//!   demo cabinet updated after its lamp moves 5 cm, 21 times
//!   ([`radiosity::Hierarchy::update`]: the moved light's direct
//!   irradiance, then gathers from the old B on the same links), per-move
//!   times, the error against a fresh solve of the last position, and the
//!   floor: one gather and the light's direct term alone.
//! - `hierarchical_object_move` (kind `hierarchical_moves`): B0 of the
//!   demo cabinet updated after its virtual bunny moves 5 cm, 21 times
//!   ([`radiosity::Hierarchy::move_object`], then
//!   [`radiosity::Hierarchy::update`]). Each move's time holds all of it:
//!   the moved mesh, the bunny's own BVH, the links and direct light
//!   remade, the gathers. The errors are against a fresh solve of the
//!   last place (with the bunny a mover too); beside them the unmoved
//!   solution's, and a fresh solve with another seed's (the solver's own
//!   noise between two equally good answers).
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

/// The `hierarchical_moves` records: the demo cabinet's lamp moved, then
/// its virtual bunny (see the module docs).
pub fn hierarchical_move_records(making: &dyn Fn(&str)) -> anyhow::Result<Vec<BenchRecord>> {
    let demo = load_any(Path::new("builtin:showcase"))?;
    making("hierarchical_light_move");
    let light = light_move_record(&demo)?;
    making("hierarchical_object_move");
    let object = object_move_record(&demo, "virtual-bunny")?;
    Ok(vec![light, object])
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
        position: position + square_step(k),
        intensity,
    };
    let options = demo_options().hierarchy();
    let emission: Vec<glam::DVec3> = mesh.elements.iter().map(|e| e.emission).collect();
    let mut h = Hierarchy::new(&mesh, &all, None, &options)?;
    let mut b = h.solve(&emission, &h.direct_of(&at(0)))?.radiosity;
    let stale = b.clone();
    let (mut times, mut gathers) = (Vec::new(), Vec::new());
    // An odd count, so that the last place is not the first.
    let moves = 21;
    for k in 1..=moves {
        let t = Instant::now();
        let direct = h.direct_of(&at(k));
        gathers.push(h.update(&mut b, &emission, &direct));
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let fresh = radiosity::solve_hierarchical(&mesh, &all, &[at(moves)], &options)?;
    let error = radiosity::relative_error(&mesh, &b, &mesh, &fresh.radiosity, 4);
    let stale_error = radiosity::relative_error(&mesh, &stale, &mesh, &fresh.radiosity, 4);
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
        "stale_rel_error_vs_fresh": stale_error,
        "fresh_gathers": fresh.iterations,
        "floor_direct_ms": direct_ms,
        "floor_one_gather_ms": gather_ms,
    }))
}

/// Where the moved object or light is after move `k`: the corners of a
/// 5 cm square, in turn (after 4, 8, ... moves back at the start).
fn square_step(k: usize) -> glam::Vec3 {
    glam::Vec3::new(0.05 * (k % 2) as f32, 0.0, 0.05 * (k / 2 % 2) as f32)
}

/// The `hierarchical_object_move` record (see the module docs).
fn object_move_record(demo: &Showcase, name: &str) -> anyhow::Result<BenchRecord> {
    use showcase_light::radiosity::{self, Hierarchy, RadiosityMesh};
    use showcase_light::{ObjectFilter, SceneGeometry};
    let object = demo
        .objects
        .iter()
        .position(|o| o.name == name)
        .with_context(|| format!("the demo scene has no object {name}"))?;
    let others: Vec<usize> = (0..demo.objects.len()).filter(|&i| i != object).collect();
    // The bunny's own occluders, and where a move takes them (as the
    // hierarchy moves them: by the mesh's motion).
    let mover = SceneGeometry::build(demo, &ObjectFilter::Indices(vec![object]))?;
    let mover_at = |k: usize| {
        let to = glam::DAffine3::from_translation(square_step(k).as_dvec3());
        vec![(object as u32, mover.moved(&to))]
    };
    let all = SceneGeometry::build(demo, &ObjectFilter::All)?;
    let fixed = SceneGeometry::build(demo, &ObjectFilter::Indices(others))?;
    // An odd count, so that the last place is not the first.
    let moves = 21;
    let mesh0 = RadiosityMesh::build(demo, &all, &demo_options().hierarchical_mesh())?;
    let lights: Vec<showcase_proto::Light> = demo.lights.iter().map(|l| l.light.clone()).collect();
    let options = demo_options().hierarchy();
    let emission: Vec<glam::DVec3> = mesh0.elements.iter().map(|e| e.emission).collect();
    let mut h = Hierarchy::with_movers(&mesh0, &fixed, mover_at(0), None, &options)?;
    let mut direct = h.direct(&lights);
    let mut b = h.solve(&emission, &direct)?.radiosity;
    let stale = b.clone();
    let (mut times, mut link_ms, mut gather_ms, mut gathers, mut stats) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for k in 1..=moves {
        let t = Instant::now();
        let motion =
            glam::DAffine3::from_translation((square_step(k) - square_step(k - 1)).as_dvec3());
        let step = radiosity::ObjectMove {
            object: object as u32,
            motion,
        };
        let (next, s) = h.move_object(step, &b, &lights, &mut direct)?;
        h = next;
        let linked = t.elapsed().as_secs_f64() * 1e3;
        gathers.push(h.update(&mut b, &emission, &direct));
        let total = t.elapsed().as_secs_f64() * 1e3;
        times.push(total);
        link_ms.push(linked);
        gather_ms.push(total - linked);
        stats.push(s);
    }
    let last = h.mesh().clone();
    let last = &last;
    let fresh_of = |seed: u64| -> anyhow::Result<radiosity::HierarchySolution> {
        let o = radiosity::HierarchyOptions {
            seed,
            ..options.clone()
        };
        let mut f = Hierarchy::with_movers(last, &fixed, mover_at(moves), None, &o)?;
        let d = f.direct(&lights);
        Ok(f.solve(&emission, &d)?)
    };
    let t = Instant::now();
    let fresh = fresh_of(options.seed)?;
    let fresh_ms = t.elapsed().as_secs_f64() * 1e3;
    let reseeded = fresh_of(options.seed + 1)?;
    let err = |x: &[glam::DVec3]| radiosity::relative_error(last, x, last, &fresh.radiosity, 4);
    let t = Instant::now();
    let _ = h.reflect(&b);
    let one_gather_ms = t.elapsed().as_secs_f64() * 1e3;
    let p99 = |v: &[f64]| showcase_light::metrics::percentile(v, 99.0);
    let first = stats.first().copied().unwrap_or_default();
    Ok(json!({
        "kind": "hierarchical_object_move",
        "object": name,
        "object_elements": last.elements.iter().filter(|e| e.object == object as u32).count(),
        "elements": last.elements.len(),
        "links": h.links(),
        "moves": moves,
        "move_m": 0.05,
        "ms_median": median(times.clone()),
        "ms_p99": p99(&times),
        "ms": times,
        "links_ms_median": median(link_ms.clone()),
        "gathers_ms_median": median(gather_ms.clone()),
        "gathers": gathers,
        "first_move": first,
        "rel_error_vs_fresh": err(&b),
        "stale_rel_error_vs_fresh": err(&stale),
        "reseeded_fresh_rel_error_vs_fresh": err(&reseeded.radiosity),
        "fresh_gathers": fresh.iterations,
        "fresh_ms": fresh_ms,
        "floor_one_gather_ms": one_gather_ms,
    }))
}
