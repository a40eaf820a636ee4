//! Integration tests: path-traced probes (`bench radiosity`'s `probes`
//! record) on the shipped Cornell box, and today's solvers against them.

use anyhow::Context;
use showcase_master::radiosity_job::bench::{
    PROBE_SEED, ProbedConfig, path_traced_probes, probe_errors, solve_probed,
};
use showcase_master::radiosity_job::{RadiosityOptions, Solver, solve_showcase};
use showcase_master::scene_file::load_any;
use std::path::Path;

const CORNELL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cornell-box.obj"
);

#[test]
fn probes_lie_on_lit_surfaces_and_do_not_depend_on_the_thread_count() -> anyhow::Result<()> {
    let showcase = load_any(Path::new(CORNELL))?;
    let probes = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map(|pool| pool.install(|| path_traced_probes(&showcase, 24, 16, PROBE_SEED)))
    };
    let one = probes(1)??;
    assert_eq!(one, probes(2)??);
    assert_eq!(one.len(), 24);
    for p in &one {
        let object = &showcase.objects[p.object as usize];
        assert!(!object.material.is_emitter(), "a probe on {}", object.name);
        let b = p.barycentric;
        assert!(b.min_element() >= 0.0 && b.x + b.y <= 1.0, "{b}");
        // None inside a block (no light reaches the floor under one).
        assert!(
            p.exitance.min_element() > 0.0,
            "{} at {}",
            object.name,
            p.point
        );
    }
    Ok(())
}

/// 48 probes of 4096 paths. Measured: median errors 0.0282 for the
/// gathered configuration and 0.118 for the base, reference noise
/// 0.0130 (all 256 probes of 131,072 paths of the bench: 0.0283, 0.124,
/// 0.0022). The bound sits between the two, 1.6 times the gathered.
const BOUND: f64 = 0.045;

#[test]
fn gathered_radiosity_meets_the_probes_and_the_coarse_base_does_not() -> anyhow::Result<()> {
    let showcase = load_any(Path::new(CORNELL))?;
    let probes = path_traced_probes(&showcase, 48, 4096, PROBE_SEED)?;
    let errors = |config| -> anyhow::Result<_> {
        let s = solve_probed(&showcase, config)?;
        probe_errors(&s.mesh, &s.vertex_values, &probes).context("no probe on the mesh")
    };
    let gathered = errors(ProbedConfig::Gathered)?;
    let base = errors(ProbedConfig::Base)?;
    assert_eq!(gathered.probes, 48);
    assert!(gathered.reference_noise_median < 0.02, "{gathered:?}");
    assert!(gathered.median < BOUND, "{gathered:?}");
    assert!(base.median > BOUND, "{base:?}");
    Ok(())
}

#[test]
fn hierarchical_radiosity_is_not_dark_against_the_probes() -> anyhow::Result<()> {
    // The hierarchical solver at the demo's 0.02 m^2 patches, element B
    // averaged to the vertices (no final gather). A link whose few
    // visibility rays were all blocked used to be dropped, so it could
    // never be refined: the box came out dark everywhere.
    let showcase = load_any(Path::new(CORNELL))?;
    let probes = path_traced_probes(&showcase, 48, 4096, PROBE_SEED)?;
    let options = RadiosityOptions {
        max_patch_area: Some(0.02),
        solver: Solver::Hierarchical,
        ..RadiosityOptions::default()
    };
    let s = solve_showcase(&showcase, &options)?;
    let averaged = s.mesh.vertex_values(&s.b0);
    let e = probe_errors(&s.mesh, &averaged, &probes).context("no probe on the mesh")?;
    // Measured: median 0.052, median signed -0.025; before the fix 0.181
    // and -0.181.
    assert!(e.median < 0.09 && e.median_signed > -0.06, "{e:?}");
    // The output: on a mesh this small, B0 gathered at the vertices, which
    // meets the progressive solver's gathered bound where the average does
    // not (measured 0.025 gathered, 0.049 averaged).
    let g = probe_errors(&s.output_mesh, &s.b0_vertices, &probes).context("no probe")?;
    assert!(g.median < BOUND, "gathered {g:?}, averaged {e:?}");
    Ok(())
}
