//! `bench radiosity`: run time against error on the Cornell box, sweeping
//! patch size, hemi-cube resolution, threshold and form-factor method,
//! plus scaling to 20,000 elements, incremental updates after a virtual
//! light or a virtual object moves, and one augmented-radiosity record.
//!
//! - `rel_error`: B (with the ambient term) against a fine solution
//!   (ray-cast form factors on 0.01 m^2 patches to a threshold of 1e-4,
//!   then a final gather at the vertices of 64 elements per patch refined
//!   once where B changes fast, 16 visibility rays per patch and 256 per
//!   emitter patch; see `reference_config`), area-weighted relative RMSE
//!   of the interpolated per-vertex solutions
//!   ([`radiosity::relative_error_vertices`]). Records with `"gather"`
//!   solve on patches and gather at the vertices of a finer mesh
//!   ([`radiosity::gather_adaptive`]); the others interpolate element
//!   averages.
//! - `analytic_direct_error`: the solver's direct irradiance (the light's
//!   patches shot once, B / rho interpolated) at 20 floor and wall points
//!   that see the whole light, against Lambert's closed-form polygon
//!   formula; mean relative error.
//! - `probes` records: error against path-traced probes
//!   ([`path_traced_probes`], [`probe_errors`]).

use crate::scene_file::load_any;
use anyhow::Context;
use glam::{DVec2, DVec3, Vec3};
use serde_json::{Value, json};
use showcase_light::radiosity::{
    self, FormFactorMethod, GatherOptions, MeshOptions, RadiosityMesh, RefineOptions, Shooter,
    SolveOptions, VertexGather, gather_adaptive,
};
use showcase_light::sampling::{hash64, unit};
use showcase_light::{ObjectFilter, SceneGeometry, polygon_irradiance};
use showcase_proto::{Light, Showcase};
use std::path::Path;
use std::time::Instant;

mod augmented;
mod hierarchical;
mod incremental;
mod object;
mod probes;
pub use augmented::{CONSISTENCY_SAMPLES, augmented_record, augmented_record_with, figure3_scene};
pub use hierarchical::{hierarchical_move_records, hierarchical_records, split_object};
pub use incremental::incremental_record;
pub use object::{
    MOVED_OBJECTS, ObjectRecords, cornell_with_small_cube, incremental_object_record,
};
pub use probes::{
    PROBE_COUNT, PROBE_SEED, PROBE_SPP, Probe, ProbeErrors, ProbedConfig, ProbedSolution,
    path_traced_probes, probe_errors, solve_probed,
};

/// One benchmark record (a JSON object).
pub type BenchRecord = Value;

/// The Cornell box shipped with the project.
pub const CORNELL_BOX: &str = "../shared/data/cornell-box.obj";

/// One measured configuration.
#[derive(Clone, Debug)]
struct Config {
    max_patch_area: f64,
    element_depth: u32,
    refine: bool,
    solve: SolveOptions,
    /// Final gather at the vertices of a mesh with `4^depth` elements per
    /// patch, refined `refine_rounds` times where B changes fast.
    gather: Option<GatherConfig>,
}

/// A final gather at the vertices of a finer mesh than the solve's.
#[derive(Clone, Debug)]
pub struct GatherConfig {
    /// The gather's mesh has `4^depth` elements per patch.
    pub depth: u32,
    /// Rounds of refinement of the gather's mesh where B changes fast.
    pub refine_rounds: u32,
    /// Visibility rays and seed of the gather.
    pub options: GatherOptions,
}

/// A solution as per-vertex values of `mesh`.
struct Measured {
    mesh: RadiosityMesh,
    vertex_values: Vec<DVec3>,
    seconds: f64,
    shots: usize,
}

fn mesh_with(
    showcase: &Showcase,
    all: &SceneGeometry,
    area: f64,
    depth: u32,
) -> anyhow::Result<RadiosityMesh> {
    Ok(RadiosityMesh::build(
        showcase,
        all,
        &MeshOptions {
            max_patch_area: area,
            element_depth: depth,
            ..MeshOptions::default()
        },
    )?)
}

fn measure(showcase: &Showcase, c: &Config) -> anyhow::Result<Measured> {
    let start = Instant::now();
    let all = SceneGeometry::build(showcase, &ObjectFilter::All)?;
    let mut mesh = mesh_with(showcase, &all, c.max_patch_area, c.element_depth)?;
    let lights: Vec<Light> = showcase.lights.iter().map(|l| l.light.clone()).collect();
    let refine = RefineOptions {
        rounds: u32::from(c.refine),
        ..RefineOptions::default()
    };
    let s = radiosity::solve_adaptive(&mut mesh, &all, &lights, &c.solve, &refine)?;
    let (mesh, vertex_values) = match &c.gather {
        Some(g) => {
            let mut target = mesh_with(showcase, &all, c.max_patch_area, g.depth)?;
            let refine = RefineOptions {
                rounds: g.refine_rounds,
                ..RefineOptions::default()
            };
            let (_, v) = gather_adaptive(
                &mesh,
                &s.display,
                &mut target,
                &all,
                &lights,
                &g.options,
                &refine,
            );
            (target, v)
        }
        None => {
            let v = mesh.vertex_values(&s.display);
            (mesh, v)
        }
    };
    Ok(Measured {
        seconds: start.elapsed().as_secs_f64(),
        shots: s.shots,
        vertex_values,
        mesh,
    })
}

/// The light's world polygons (its triangles) and radiance.
fn light_triangles(showcase: &Showcase, all: &SceneGeometry) -> (Vec<[DVec3; 3]>, DVec3) {
    let mut tris = Vec::new();
    let mut radiance = DVec3::ZERO;
    for t in all.triangles() {
        let o = &showcase.objects[t.object as usize];
        if o.material.is_emitter() {
            tris.push(t.vertices);
            radiance = o.material.emission.as_dvec3();
        }
    }
    (tris, radiance)
}

/// Mean relative error of the solver's direct irradiance at 20 points that
/// see the whole light, against the closed form.
fn analytic_direct_error(showcase: &Showcase, c: &Config) -> anyhow::Result<f64> {
    let all = SceneGeometry::build(showcase, &ObjectFilter::All)?;
    let mesh = RadiosityMesh::build(
        showcase,
        &all,
        &MeshOptions {
            max_patch_area: c.max_patch_area,
            element_depth: c.element_depth,
            ..MeshOptions::default()
        },
    )?;
    let mut shooter = Shooter::new(&mesh, &all, None, &c.solve)?;
    shooter.add_surface_emission();
    let emitters: Vec<usize> = (0..mesh.patches.len())
        .filter(|&p| {
            mesh.patches[p]
                .elements
                .iter()
                .any(|&e| mesh.elements[e as usize].emission != DVec3::ZERO)
        })
        .collect();
    let (mesh, values) = match &c.gather {
        // The gather's direct light: the emitters' own exitance gathered.
        Some(g) => {
            let target = mesh_with(showcase, &all, c.max_patch_area, g.depth)?;
            let emission: Vec<DVec3> = mesh.elements.iter().map(|e| e.emission).collect();
            let v = VertexGather::build(&mesh, &target, &all, &g.options, None).apply(
                &mesh,
                &emission,
                &target,
                &all,
                &[],
            );
            (target, v)
        }
        None => {
            for p in emitters {
                shooter.shoot_patch(p);
            }
            let v = mesh.vertex_values(shooter.radiosity());
            (mesh, v)
        }
    };
    let (light, radiance) = light_triangles(showcase, &all);
    let corners: Vec<DVec3> = light.iter().flatten().copied().collect();
    let receivers: Vec<u32> = (0..mesh.primitives.len() as u32)
        .filter(|&p| {
            let name = &showcase.objects[mesh.primitives[p as usize].object as usize].name;
            ["floor", "back", "left_red", "right_green"].contains(&name.as_str())
        })
        .collect();
    anyhow::ensure!(
        !receivers.is_empty() && !light.is_empty(),
        "no light or walls"
    );
    let (mut sum, mut count, mut k) = (0.0, 0, 0u64);
    while count < 20 && k < 100_000 {
        k += 1;
        let prim = receivers[(hash64(k) % receivers.len() as u64) as usize];
        let (a, b) = (unit(3 * k + 1), unit(3 * k + 2));
        let b = if a + b > 1.0 {
            DVec2::new(1.0 - a, 1.0 - b)
        } else {
            DVec2::new(a, b)
        };
        let p = &mesh.primitives[prim as usize];
        let x = p.point(b);
        if !corners.iter().all(|c| all.visible(x, p.normal, *c, true)) {
            continue;
        }
        let rho = mesh
            .locate(prim, b)
            .map(|(e, _)| mesh.elements[e as usize].reflectance)
            .context("locating a point")?;
        let got = mesh
            .interpolate(prim, b, &values)
            .context("interpolating")?
            / rho;
        let mut exact = 0.0;
        for t in &light {
            exact += polygon_irradiance(x, p.normal, t, radiance.x + radiance.y + radiance.z)?;
        }
        if exact > 0.0 {
            sum += ((got.x + got.y + got.z) - exact).abs() / exact;
            count += 1;
        }
    }
    anyhow::ensure!(count > 0, "no point sees the whole light");
    Ok(sum / count as f64)
}

fn method_name(m: FormFactorMethod) -> &'static str {
    match m {
        FormFactorMethod::HemiCube => "hemicube",
        FormFactorMethod::RayCast => "raycast",
        FormFactorMethod::Hybrid => "hybrid",
    }
}

fn base() -> Config {
    Config {
        max_patch_area: 0.04,
        element_depth: 1,
        refine: true,
        solve: SolveOptions {
            hemicube: 32,
            threshold: 1e-2,
            method: FormFactorMethod::Hybrid,
            ..SolveOptions::default()
        },
        gather: None,
    }
}

/// The fast configuration ([`gathered_config`]): a coarse shooting solve,
/// then a final gather at the vertices of a finer mesh.
#[derive(Clone, Debug)]
pub struct GatheredConfig {
    /// Largest patch area (m^2) of the shooting mesh, one element per
    /// patch.
    pub max_patch_area: f64,
    /// The shooting solve.
    pub solve: SolveOptions,
    /// The final gather.
    pub gather: GatherConfig,
}

/// The fast configuration: ray-cast form factors between 0.02 m^2 patches
/// (one element each) to an unshot fraction of 1e-2, then a final gather
/// at the vertices of 16 elements per patch, refined once where B changes
/// fast, one visibility ray per patch pair and 16 per emitter patch.
pub fn gathered_config() -> GatheredConfig {
    GatheredConfig {
        max_patch_area: 0.02,
        solve: SolveOptions {
            threshold: 1e-2,
            method: FormFactorMethod::RayCast,
            visibility_samples: 2,
            ..SolveOptions::default()
        },
        gather: GatherConfig {
            depth: 2,
            refine_rounds: 1,
            options: GatherOptions {
                samples: 1,
                emitter_samples: 16,
                seed: 1,
            },
        },
    }
}

fn gathered() -> Config {
    let g = gathered_config();
    Config {
        max_patch_area: g.max_patch_area,
        element_depth: 0,
        refine: false,
        solve: g.solve,
        gather: Some(g.gather),
    }
}

/// The converged fine solution every record is compared with: ray-cast
/// form factors between 0.01 m^2 patches (4 elements each) to an unshot
/// fraction of 1e-4, then a final gather at the vertices of 64 elements
/// per patch, refined once, with 16 visibility rays per patch pair and 256
/// per emitter patch. Its own gather makes its per-vertex values point
/// values, not element averages (on a closed furnace box the gather
/// matches the exact `pi L / (1 - rho)` to 0.1%, see the unit tests).
fn reference_config() -> Config {
    Config {
        max_patch_area: 0.01,
        element_depth: 1,
        refine: false,
        solve: SolveOptions {
            threshold: 1e-4,
            method: FormFactorMethod::RayCast,
            visibility_samples: 4,
            ..SolveOptions::default()
        },
        gather: Some(GatherConfig {
            depth: 3,
            refine_rounds: 1,
            options: GatherOptions {
                samples: 16,
                emitter_samples: 256,
                seed: 3,
            },
        }),
    }
}

fn record(
    showcase: &Showcase,
    reference: &Measured,
    c: &Config,
    kind: &str,
) -> anyhow::Result<BenchRecord> {
    let m = measure(showcase, c)?;
    let rel = radiosity::relative_error_vertices(
        &m.mesh,
        &m.vertex_values,
        &reference.mesh,
        &reference.vertex_values,
        6,
    );
    Ok(json!({
        "kind": kind,
        "method": method_name(c.solve.method),
        "gather": c.gather.as_ref().map(|g| json!({
            "depth": g.depth,
            "refine_rounds": g.refine_rounds,
            "samples": g.options.samples,
            "emitter_samples": g.options.emitter_samples,
        })),
        "patches": m.mesh.patches.len(),
        "elements": m.mesh.elements.len(),
        "vertices": m.mesh.vertices.len(),
        "hemicube": c.solve.hemicube,
        "threshold": c.solve.threshold,
        "seconds": m.seconds,
        "shots": m.shots,
        "rel_error": rel,
        "analytic_direct_error": analytic_direct_error(showcase, c)?,
    }))
}

/// Run the radiosity benchmark on the Cornell box at `cornell` (the OBJ).
/// Slow (minutes): build in release.
pub fn bench_radiosity_at(cornell: &Path) -> anyhow::Result<Vec<BenchRecord>> {
    bench_radiosity_kinds(cornell, &[], &ObjectRecords::default(), &|_| {})
}

/// The `"kind"`s of the records of `bench radiosity`, in the order they
/// are made.
pub const RECORD_KINDS: [&str; 10] = [
    "reference",
    "gathered",
    "sweep",
    "scaling",
    "probes",
    "incremental",
    "incremental_object",
    "augmented",
    "hierarchical",
    "hierarchical_moves",
];

/// [`bench_radiosity_at`], making only the records whose `"kind"` is in
/// `kinds` (all of them when `kinds` is empty), and of the
/// `incremental_object` kind those of `objects`; the fine reference
/// solution is solved only when a record that needs it is made;
/// `making(kinds)` is told which records are being made (progress). An
/// unknown kind is an error that lists the known ones.
pub fn bench_radiosity_kinds(
    cornell: &Path,
    kinds: &[String],
    objects: &ObjectRecords,
    making: &dyn Fn(&str),
) -> anyhow::Result<Vec<BenchRecord>> {
    if let Some(bad) = kinds.iter().find(|k| !RECORD_KINDS.contains(&k.as_str())) {
        anyhow::bail!(
            "unknown radiosity record kind {bad:?}; known kinds: {}",
            RECORD_KINDS.join(", ")
        );
    }
    let wanted = |kind: &str| kinds.is_empty() || kinds.iter().any(|k| k == kind);
    let showcase = load_any(cornell)?;
    let mut records = Vec::new();
    if ["reference", "gathered", "sweep", "scaling"]
        .iter()
        .any(|k| wanted(k))
    {
        making("reference, gathered, sweep and scaling");
        bench_against_reference(&showcase, &wanted, &mut records)?;
    }
    if wanted("probes") {
        making("probes");
        records.extend(probes::probes_records(&showcase)?);
    }
    if wanted("incremental") {
        making("incremental");
        for intensity in [0.5, 0.05, 0.005] {
            records.push(incremental_record(&showcase, intensity)?);
        }
    }
    if wanted("incremental_object") {
        making("incremental_object");
        let shift = Vec3::new(0.03, 0.0, 0.02);
        let with_cube = cornell_with_small_cube(&showcase, 0.06);
        for (name, area) in &objects.records {
            let scene = if name == "small_cube" {
                &with_cube
            } else {
                &showcase
            };
            records.push(incremental_object_record(
                scene,
                name,
                shift,
                *area,
                objects.repeats,
            )?);
        }
    }
    if wanted("augmented") {
        making("augmented");
        records.push(augmented_record(&showcase)?);
    }
    if wanted("hierarchical") {
        records.extend(hierarchical_records(making)?);
    }
    if wanted("hierarchical_moves") {
        records.extend(hierarchical_move_records(making)?);
    }
    Ok(records)
}

/// The records measured against the fine reference solution (`reference`,
/// `gathered`, `sweep`, `scaling`), those of them that are `wanted`.
fn bench_against_reference(
    showcase: &Showcase,
    wanted: &dyn Fn(&str) -> bool,
    records: &mut Vec<BenchRecord>,
) -> anyhow::Result<()> {
    let reference = measure(showcase, &reference_config())?;
    if wanted("reference") {
        records.push(json!({
            "kind": "reference",
            "method": "raycast",
            "patches": reference.mesh.patches.len(),
            "elements": reference.mesh.elements.len(),
            "threshold": reference_config().solve.threshold,
            "seconds": reference.seconds,
            "shots": reference.shots,
        }));
    }
    let with = |area: f64, hemicube: u32, threshold: f64, method, samples: u32| {
        let mut c = base();
        c.max_patch_area = area;
        c.solve.hemicube = hemicube;
        c.solve.threshold = threshold;
        c.solve.method = method;
        c.solve.visibility_samples = samples;
        c
    };
    let (hybrid, raycast) = (FormFactorMethod::Hybrid, FormFactorMethod::RayCast);
    if wanted("gathered") {
        for _ in 0..3 {
            records.push(record(showcase, &reference, &gathered(), "gathered")?);
        }
    }
    let configs = [
        with(0.04, 32, 1e-2, hybrid, 4),
        with(0.04, 64, 1e-2, hybrid, 4),
        with(0.04, 32, 1e-3, hybrid, 4),
        with(0.04, 32, 1e-2, raycast, 2),
        with(0.02, 32, 1e-2, hybrid, 4),
        with(0.02, 32, 1e-2, raycast, 1),
    ];
    if wanted("sweep") {
        for c in &configs {
            records.push(record(showcase, &reference, c, "sweep")?);
        }
    }
    if !wanted("scaling") {
        return Ok(());
    }
    let scaling = Config {
        max_patch_area: 0.02,
        element_depth: 3,
        refine: false,
        ..with(0.02, 32, 1e-2, raycast, 1)
    };
    records.push(record(showcase, &reference, &scaling, "scaling")?);
    let mut scaling = gathered();
    if let Some(g) = &mut scaling.gather {
        g.depth = 3;
    }
    records.push(record(showcase, &reference, &scaling, "scaling")?);
    Ok(())
}

/// [`bench_radiosity_at`] on [`CORNELL_BOX`] (relative to the working
/// directory, the repository root).
pub fn bench_radiosity() -> anyhow::Result<Vec<BenchRecord>> {
    bench_radiosity_at(Path::new(CORNELL_BOX))
}
