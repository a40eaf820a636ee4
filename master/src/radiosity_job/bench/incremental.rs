//! The `incremental` records of `bench radiosity`: a virtual point light
//! moves inside the Cornell box, and shooting the difference is timed
//! against a cold and a warm re-solve at equal tolerance.

use super::{BenchRecord, GatherConfig, GatheredConfig, gathered_config, mesh_with};
use glam::{DVec3, Vec3};
use serde_json::json;
use showcase_light::radiosity::{self, Shooter, VertexGather};
use showcase_light::{ObjectFilter, SceneGeometry};
use showcase_proto::{Light, Showcase};
use std::time::Instant;

/// A virtual point light of `intensity` (W/sr) moves inside the box beside
/// the box's own light, in the gathered configuration
/// ([`gathered_config`], without the gather's refinement so both sides
/// share one output mesh). Three ways to the new per-vertex solution, all
/// to the same absolute unshot-power tolerance, each timed from the moment
/// the light moved:
/// - `full`: from scratch: form factors, shooting, gather matrix, gather;
/// - `warm`: shooting from scratch but with the cached form-factor rows
///   and gather matrix (geometry is unchanged);
/// - `incremental`: shoot the difference: remove the old light's direct
///   deposit (negative energy), add the new one, shoot what is unshot with
///   the cached rows, and gather again with the cached matrix.
///
/// Errors are against a solve of the new state to 1e-5 gathered with the
/// same matrix.
pub fn incremental_record(cornell: &Showcase, intensity: f32) -> anyhow::Result<BenchRecord> {
    let GatheredConfig {
        max_patch_area: area,
        solve,
        gather:
            GatherConfig {
                depth,
                options: gather_options,
                ..
            },
    } = gathered_config();
    let all = SceneGeometry::build(cornell, &ObjectFilter::All)?;
    let mesh = mesh_with(cornell, &all, area, 0)?;
    let target = mesh_with(cornell, &all, area, depth)?;
    let light = |x: f32| Light::Point {
        position: Vec3::new(x, 0.4, 0.3),
        intensity: Vec3::splat(intensity),
    };
    let (old, new) = (light(0.15), light(0.4));
    let mut base_solve = Shooter::new(&mesh, &all, None, &solve)?;
    base_solve.add_surface_emission();
    base_solve.add_light(&old, 1.0);
    // The static solution is precomputed offline to a tenth of the
    // interactive tolerance, so an update need not first pay off the
    // residual the precompute left at exactly the limit.
    let limit = solve.threshold * base_solve.injected_power();
    base_solve.run_to_power(0.1 * limit);
    let gather = VertexGather::build(&mesh, &target, &all, &gather_options, None);
    let lights = [new.clone()];

    let start = Instant::now();
    let mut full = Shooter::new(&mesh, &all, None, &solve)?;
    full.add_surface_emission();
    full.add_light(&new, 1.0);
    full.run_to_power(limit);
    let full_gather = VertexGather::build(&mesh, &target, &all, &gather_options, None);
    let full_v = full_gather.apply(&mesh, &full.display_radiosity(), &target, &all, &lights);
    let full_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let mut inc = base_solve;
    inc.add_light(&old, -1.0);
    inc.add_light(&new, 1.0);
    let inc_shots = inc.run_to_power(limit);
    let inc_v = gather.apply(&mesh, &inc.display_radiosity(), &target, &all, &lights);
    let inc_seconds = start.elapsed().as_secs_f64();

    let mut tight = solve.clone();
    tight.threshold = 1e-5;
    let converged = radiosity::solve(&mesh, &all, &lights, &tight)?;
    let converged_v = gather.apply(&mesh, &converged.display, &target, &all, &lights);
    let err =
        |v: &[DVec3]| radiosity::relative_error_vertices(&target, v, &target, &converged_v, 6);
    let (full_err, inc_err) = (err(&full_v), err(&inc_v));

    let start = Instant::now();
    let mut warm = inc;
    warm.restart();
    warm.add_surface_emission();
    warm.add_light(&new, 1.0);
    warm.run_to_power(limit);
    let warm_v = gather.apply(&mesh, &warm.display_radiosity(), &target, &all, &lights);
    let warm_seconds = start.elapsed().as_secs_f64();
    Ok(json!({
        "kind": "incremental",
        "light_intensity": intensity,
        "patches": mesh.patches.len(),
        "vertices": target.vertices.len(),
        "threshold": solve.threshold,
        "full_seconds": full_seconds,
        "full_shots": full.shots(),
        "full_rel_error": full_err,
        "warm_seconds": warm_seconds,
        "warm_shots": warm.shots(),
        "warm_rel_error": err(&warm_v),
        "incremental_seconds": inc_seconds,
        "incremental_shots": inc_shots,
        "incremental_rel_error": inc_err,
        "speedup": full_seconds / inc_seconds.max(1e-9),
        "speedup_over_warm": warm_seconds / inc_seconds.max(1e-9),
    }))
}
