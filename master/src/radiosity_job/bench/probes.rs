//! Path-traced probes: the exitance at points spread over a scene's
//! surfaces, traced by the simulated showcase
//! ([`SimWorld::exitance_at`]) and so independent of the radiosity solver,
//! and a solution's error against them. Issue #23's target is stated
//! against them: on the Cornell box, a median error no worse than today's
//! in at most 0.2 s.
//!
//! # Where the probes are
//! Probe `i` of `n` is drawn in the `i`-th of `n` equal strata of the
//! cumulative area of the scene's non-emitting triangles: the stratum's
//! jittered point picks a triangle (area-weighted) and one coordinate in
//! it, a second number the other (area-uniform). A point inside a closed
//! object (the floor under a Cornell block), where no light can reach and
//! a relative error means nothing, is drawn again: a point is inside when
//! the first surface the ray along its normal meets shows its back (every
//! closed mesh faces out; the gather's rule too). After eight draws in its
//! stratum a probe is drawn from the whole area. Every number comes from
//! `(seed, i)`, so the probes are a function of the scene and the seed,
//! whatever the thread count.
//!
//! # Error
//! A probe's error is `|sum(got) - sum(B)| / sum(B)` over the RGB channels,
//! with `got` the solution interpolated at the probe's barycentric point
//! of its triangle; medians and percentiles by nearest rank.

use super::{BenchRecord, Config, base, gathered, measure, method_name, reference_config};
use anyhow::Context;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde_json::json;
use showcase_light::metrics::percentile;
use showcase_light::radiosity::RadiosityMesh;
use showcase_light::radiosity::mesh::barycentric_point;
use showcase_light::sampling::{pixel_seed, unit};
use showcase_light::sim::{SimLights, SimWorld};
use showcase_light::{ObjectFilter, Ray, SceneGeometry, WorldTriangle};
use showcase_proto::Showcase;
use std::time::Instant;

/// Probes of the `probes` record. With [`PROBE_SPP`] paths each, the
/// Cornell box's reference noise (median relative standard error) is
/// 0.22 % (0.31 % at 65,536 paths, 1.2 % at 4,096: it falls as
/// `1/sqrt(spp)`). The whole record (release, the 2-core machine) takes
/// 55 s of CPU, so about 30 s on an idle machine; while other builds ran
/// it took 47 s and 83 s (tracing 42 s and 75 s, the fine reference's
/// solve 5-7 s). The gathered configuration's median error moved only
/// between 2.70 % and 2.88 % from 4,096 to 131,072 paths per probe.
pub const PROBE_COUNT: usize = 256;
/// Paths per probe of the `probes` record.
pub const PROBE_SPP: u32 = 131_072;
/// The seed of every probe set the benches compare solvers on.
pub const PROBE_SEED: u64 = 23;
/// Draws of a probe inside its own stratum before it is drawn from the
/// whole area.
const STRATUM_TRIES: u64 = 8;
/// Draws of one probe before the scene is declared to have no open surface.
const MAX_TRIES: u64 = 1000;

/// The path-traced exitance at one surface point.
#[derive(Clone, Debug, PartialEq)]
pub struct Probe {
    /// Index into `Showcase::objects`.
    pub object: u32,
    /// Index of the triangle within that object's mesh.
    pub triangle: u32,
    /// Barycentric weights of the triangle's second and third vertex (the
    /// convention of [`RadiosityMesh::interpolate`]).
    pub barycentric: DVec2,
    /// The point in world space.
    pub point: DVec3,
    /// The triangle's unit front normal.
    pub normal: DVec3,
    /// Path-traced exitance `B` of the front side (W/m^2 per channel),
    /// emitters on.
    pub exitance: DVec3,
    /// Standard error of [`Self::exitance`] (an upper estimate, see
    /// [`SimWorld::exitance_at`]).
    pub std_error: DVec3,
}

/// `count` probes of `showcase` (see the module docs), each path-traced
/// with `spp` paths in the world of every object with its emitters on.
/// Errors when the scene has no non-emitting surface outside closed
/// objects.
pub fn path_traced_probes(
    showcase: &Showcase,
    count: usize,
    spp: u32,
    seed: u64,
) -> anyhow::Result<Vec<Probe>> {
    let world = SimWorld::new(showcase, &ObjectFilter::All, true)?;
    let receivers: Vec<WorldTriangle> = world
        .geometry()
        .triangles()
        .filter(|t| t.area > 0.0)
        .filter(|t| {
            showcase
                .objects
                .get(t.object as usize)
                .is_some_and(|o| !o.material.is_emitter())
        })
        .collect();
    let mut cumulative = Vec::with_capacity(receivers.len());
    let mut total = 0.0;
    for t in &receivers {
        total += t.area;
        cumulative.push(total);
    }
    anyhow::ensure!(total > 0.0, "the scene has no non-emitting surface");
    let places: Vec<Probe> = (0..count)
        .map(|i| {
            place_probe(
                world.geometry(),
                &receivers,
                &cumulative,
                (i, count),
                pixel_seed(seed, 2 * i as u64),
            )
        })
        .collect::<anyhow::Result<_>>()?;
    places
        .into_par_iter()
        .enumerate()
        .map(|(i, p)| {
            let paths = pixel_seed(seed, 2 * i as u64 + 1);
            let e = world
                .exitance_at(p.point, p.normal, &SimLights::none(), spp, paths)
                .with_context(|| format!("probe {i} at {} is on no surface", p.point))?;
            Ok(Probe {
                exitance: e.exitance,
                std_error: e.std_error,
                ..p
            })
        })
        .collect()
}

/// Probe `i` of `n` (exitance not yet traced), from the stream `stream`.
fn place_probe(
    geometry: &SceneGeometry,
    receivers: &[WorldTriangle],
    cumulative: &[f64],
    (i, n): (usize, usize),
    stream: u64,
) -> anyhow::Result<Probe> {
    let total = cumulative.last().copied().unwrap_or(0.0);
    for attempt in 0..MAX_TRIES {
        let jitter = unit(pixel_seed(stream, 2 * attempt));
        let u = if attempt < STRATUM_TRIES {
            (i as f64 + jitter) / n as f64
        } else {
            jitter
        } * total;
        let k = cumulative
            .partition_point(|c| *c <= u)
            .min(receivers.len() - 1);
        let t = &receivers[k];
        let start = if k == 0 { 0.0 } else { cumulative[k - 1] };
        // Area-uniform: sqrt of the first coordinate, the second along.
        let r = ((u - start) / t.area).clamp(0.0, 1.0).sqrt();
        let s = unit(pixel_seed(stream, 2 * attempt + 1));
        let barycentric = DVec2::new(r * (1.0 - s), r * s);
        let point = barycentric_point(&t.vertices, barycentric);
        if inside_closed_object(geometry, point, t.normal) {
            continue;
        }
        return Ok(Probe {
            object: t.object,
            triangle: t.triangle,
            barycentric,
            point,
            normal: t.normal,
            exitance: DVec3::ZERO,
            std_error: DVec3::ZERO,
        });
    }
    anyhow::bail!("no probe {i} outside closed objects after {MAX_TRIES} draws")
}

/// Whether the first surface in front of `point` (along `normal`) shows
/// its back: the point is inside a closed, outward-facing mesh.
fn inside_closed_object(geometry: &SceneGeometry, point: DVec3, normal: DVec3) -> bool {
    let origin = geometry.offset_point(point, normal, point + normal);
    geometry
        .closest_hit(&Ray::new(origin, normal), 0.0, f64::INFINITY)
        .is_some_and(|h| !h.front_face)
}

/// A solution's error against probes (relative, sums of RGB channels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeErrors {
    /// Median error (nearest rank).
    pub median: f64,
    /// 90th-percentile error (nearest rank).
    pub p90: f64,
    /// Mean error.
    pub mean: f64,
    /// Median of the signed errors `(sum(got) - sum(B)) / sum(B)`: below
    /// zero when the solution is mostly too dark.
    pub median_signed: f64,
    /// Probes counted: those with a positive reference.
    pub probes: usize,
    /// Median of the probes' relative standard errors (the sum of the
    /// channels' standard errors over the sum of the channels, an upper
    /// estimate): the reference's own noise.
    pub reference_noise_median: f64,
}

/// The error of the per-vertex solution `vertex_values` of `mesh` at
/// `probes` (module docs). Probes no light reaches (reference zero) are
/// left out. `None` when no probe is left, or a probe's triangle is not in
/// `mesh` (a mesh of another scene) or a value is missing.
pub fn probe_errors(
    mesh: &RadiosityMesh,
    vertex_values: &[DVec3],
    probes: &[Probe],
) -> Option<ProbeErrors> {
    let mut signed = Vec::with_capacity(probes.len());
    let mut noise = Vec::with_capacity(probes.len());
    for p in probes {
        let reference = p.exitance.element_sum();
        if !reference.is_finite() || reference <= 0.0 {
            continue;
        }
        let primitive = mesh.primitive_of(p.object, p.triangle)?;
        let got = mesh.interpolate(primitive, p.barycentric, vertex_values)?;
        signed.push((got.element_sum() - reference) / reference);
        noise.push(p.std_error.element_sum() / reference);
    }
    let errors: Vec<f64> = signed.iter().map(|e| e.abs()).collect();
    Some(ProbeErrors {
        median: percentile(&errors, 50.0)?,
        p90: percentile(&errors, 90.0)?,
        mean: errors.iter().sum::<f64>() / errors.len() as f64,
        median_signed: percentile(&signed, 50.0)?,
        probes: errors.len(),
        reference_noise_median: percentile(&noise, 50.0)?,
    })
}

/// A configuration the `probes` record measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProbedConfig {
    /// The fast configuration, [`super::gathered_config`].
    Gathered,
    /// The sweep's base: hybrid form factors (32-pixel hemi-cubes) between
    /// 0.04 m^2 patches of 4 elements, refined once, to 1e-2 unshot.
    Base,
    /// The fine solution the other records' `rel_error` is measured
    /// against (see the module docs of `bench`): how far that yardstick is
    /// from the light the simulator traces.
    Reference,
}

impl ProbedConfig {
    /// All of them, in the records' order.
    pub const ALL: [Self; 3] = [Self::Gathered, Self::Base, Self::Reference];

    /// The record's name for it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Gathered => "gathered",
            Self::Base => "base",
            Self::Reference => "reference",
        }
    }

    fn config(self) -> Config {
        match self {
            Self::Gathered => gathered(),
            Self::Base => base(),
            Self::Reference => reference_config(),
        }
    }
}

/// A timed solution as per-vertex values.
#[derive(Debug)]
pub struct ProbedSolution {
    /// The mesh the values are at (the gather's, where there is one).
    pub mesh: RadiosityMesh,
    /// Exitance at each vertex of `mesh`.
    pub vertex_values: Vec<DVec3>,
    /// Wall-clock seconds of meshing, solving and gathering.
    pub seconds: f64,
}

/// Solve `showcase` with `config`, timed.
pub fn solve_probed(showcase: &Showcase, config: ProbedConfig) -> anyhow::Result<ProbedSolution> {
    let m = measure(showcase, &config.config())?;
    Ok(ProbedSolution {
        mesh: m.mesh,
        vertex_values: m.vertex_values,
        seconds: m.seconds,
    })
}

/// The `probes` records: [`PROBE_COUNT`] probes of [`PROBE_SPP`] paths
/// (seed [`PROBE_SEED`]), then each [`ProbedConfig`] solved and measured
/// against them.
pub(super) fn probes_records(showcase: &Showcase) -> anyhow::Result<Vec<BenchRecord>> {
    let start = Instant::now();
    let probes = path_traced_probes(showcase, PROBE_COUNT, PROBE_SPP, PROBE_SEED)?;
    let trace_seconds = start.elapsed().as_secs_f64();
    ProbedConfig::ALL
        .iter()
        .map(|&c| {
            let s = solve_probed(showcase, c)?;
            let e = probe_errors(&s.mesh, &s.vertex_values, &probes)
                .with_context(|| format!("the {} solution at the probes", c.name()))?;
            Ok(json!({
                "kind": "probes",
                "config": c.name(),
                "method": method_name(c.config().solve.method),
                "patches": s.mesh.patches.len(),
                "elements": s.mesh.elements.len(),
                "seconds": s.seconds,
                "probe_median_error": e.median,
                "probe_p90_error": e.p90,
                "probe_mean_error": e.mean,
                "probe_median_signed_error": e.median_signed,
                "probes": e.probes,
                "probe_spp": PROBE_SPP,
                "probe_seed": PROBE_SEED,
                "reference_noise_median": e.reference_noise_median,
                "probe_trace_seconds": trace_seconds,
            }))
        })
        .collect()
}
