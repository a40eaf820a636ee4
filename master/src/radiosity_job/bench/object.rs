//! The `incremental_object` records of `bench radiosity`: a virtual
//! object (the Cornell box's short block, or a small cube) moves a few
//! centimetres, and the incremental update ([`Shooter::move_object`]) is
//! timed against a cold and a warm full re-solve at equal tolerance; and
//! which of these records to make (`--object-records`, `--repeats`).

use super::{BenchRecord, gathered_config, mesh_with};
use anyhow::Context;
use glam::{DVec3, Vec3};
use serde_json::json;
use showcase_light::radiosity::{self, RadiosityMesh, Shooter};
use showcase_light::{ObjectFilter, SceneGeometry};
use showcase_proto::{ObjectKind, Showcase};
use std::time::Instant;

/// Which `incremental_object` records to make, and how often to time
/// each (`bench radiosity --object-records ... --repeats N`).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectRecords {
    /// `(object, max patch area)` pairs; the object is `short_block` (the
    /// Cornell box's) or `small_cube` (a 6 cm cube added to it).
    pub records: Vec<(String, f64)>,
    /// Timed runs per record (the fastest and the paired median are
    /// reported).
    pub repeats: usize,
}

/// The objects of the `incremental_object` records.
pub const MOVED_OBJECTS: [&str; 2] = ["short_block", "small_cube"];

impl Default for ObjectRecords {
    /// Both objects at 0.02 and 0.005 m^2, 5 runs each.
    fn default() -> Self {
        let records = [0.02, 0.005]
            .into_iter()
            .flat_map(|area| MOVED_OBJECTS.map(|o| (o.to_string(), area)))
            .collect();
        Self {
            records,
            repeats: 5,
        }
    }
}

impl ObjectRecords {
    /// From `OBJECT@AREA` specs (all default records when empty) and a
    /// repeat count (5 when `None`); an unknown object, an unreadable or
    /// non-positive area, or zero repeats is an error naming it.
    pub fn parse(specs: &[String], repeats: Option<usize>) -> anyhow::Result<Self> {
        let mut out = Self::default();
        if let Some(n) = repeats {
            anyhow::ensure!(n > 0, "--repeats must be at least 1");
            out.repeats = n;
        }
        if specs.is_empty() {
            return Ok(out);
        }
        out.records = specs
            .iter()
            .map(|spec| {
                let (object, area) = spec.split_once('@').with_context(|| {
                    format!("object record {spec:?} is not OBJECT@AREA (e.g. short_block@0.02)")
                })?;
                anyhow::ensure!(
                    MOVED_OBJECTS.contains(&object),
                    "unknown moved object {object:?} in {spec:?}; known: {}",
                    MOVED_OBJECTS.join(", ")
                );
                let area: f64 = area
                    .parse()
                    .ok()
                    .filter(|a: &f64| a.is_finite() && *a > 0.0)
                    .with_context(|| {
                        format!("patch area {area:?} in {spec:?} is not a positive number (m^2)")
                    })?;
                Ok((object.to_string(), area))
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(out)
    }
}

/// The Cornell box with a virtual cube of side `side` (metres, albedo 0.5)
/// floating above the floor, named `small_cube`: the record's case of a
/// small object.
pub fn cornell_with_small_cube(cornell: &Showcase, side: f32) -> Showcase {
    let mut s = cornell.clone();
    let (x, y, z) = (side * Vec3::X, side * Vec3::Y, side * Vec3::Z);
    let c = Vec3::new(0.3, 0.2, 0.2);
    let faces = [
        (c, x, z),
        (c + y, z, x),
        (c, z, y),
        (c + x, y, z),
        (c, y, x),
        (c + z, x, y),
    ];
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for (corner, u, v) in faces {
        let k = positions.len() as u32;
        positions.extend([corner, corner + u, corner + u + v, corner + v]);
        triangles.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
    }
    let mesh = s.add_mesh(showcase_proto::Mesh {
        positions,
        normals: vec![],
        uvs: vec![],
        triangles,
    });
    s.objects.push(showcase_proto::Object {
        name: "small_cube".into(),
        mesh,
        material: showcase_proto::Material::diffuse(Vec3::splat(0.5)),
        kind: ObjectKind::Virtual,
        transform: showcase_proto::Transform::IDENTITY,
    });
    s
}

/// Visibility rays per patch-element pair of the `*_fine` reference.
const FINE_VISIBILITY_RAYS: u32 = 64;

/// Area-weighted relative RMSE of `b` against `reference` (per element) over
/// the elements of `mesh` on `object`; `None` where the reference is zero
/// there.
fn object_error(
    mesh: &RadiosityMesh,
    object: u32,
    b: &[DVec3],
    reference: &[DVec3],
) -> Option<f64> {
    let (mut sq, mut sum) = (0.0, 0.0);
    for ((e, x), r) in mesh.elements.iter().zip(b).zip(reference) {
        if e.object == object {
            sq += e.area * (*x - *r).length_squared();
            sum += e.area * r.length_squared();
        }
    }
    (sum > 0.0).then(|| (sq / sum).sqrt())
}

/// Object `name` of `scene` (e.g. the Cornell box's `short_block`) made
/// virtual and moved by `shift` (metres), in the gathered configuration's
/// shooting stage ([`gathered_config`]: ray-cast form factors, one element
/// per patch; no final gather, which would need its own update) on patches
/// of at most `max_patch_area` (m^2; the configuration's is 0.02). Three
/// ways to the moved scene's solution, all to the
/// same absolute unshot-power tolerance, each timed from the moment the
/// object moved and each including the time to build the moved scene's
/// geometry and mesh (`scene_seconds`, also reported alone); the fastest
/// of `repeats` runs (they take milliseconds):
/// - `full`: a cold re-solve: every form factor, shooting from scratch;
/// - `warm`: the cached rows corrected for the move
///   ([`Shooter::move_object`]), then shooting from scratch with them;
/// - `incremental`: the rows corrected, the difference shot
///   (`S_i (F' - F)` from every patch that shot), shooting on from there.
///
/// Each repeat runs a full re-solve and then an update, one after the
/// other; `speedup` is the fastest full over the fastest update,
/// `speedup_paired_median` the (nearest-rank) median over repeats of each repeat's own
/// ratio (the steadier figure on a loaded machine).
///
/// `receivers_scanned`, `pairs_near`, `rays_tested`, `rays_traced`,
/// `entries_recomputed`, `entries_rescaled` and `entries_reciprocal`
/// count the update's work ([`radiosity::MoveStats`]).
///
/// Errors are area-weighted relative RMSE of the interpolated element
/// values against a fresh solve of the moved scene to 1e-5; `stale_rel_error`
/// is the unmoved solution's (what a display shows without an update).
/// That reference uses the same form-factor estimator (two visibility rays
/// per pair), so it rewards reproducing the estimator's own noise; the
/// `*_fine` errors are against a fresh solve to 1e-5 with 64 rays per
/// pair instead, the better estimate of the true solution.
/// `object_*_rel_error_fine` are taken over the moved object's elements
/// alone (displayed element values, area-weighted): the object is a few
/// percent of the area, so the scene-wide figures would hide an error in
/// its own values, which come from its column (ray-cast, or by
/// reciprocity from its own rows).
pub fn incremental_object_record(
    scene: &Showcase,
    name: &str,
    shift: Vec3,
    max_patch_area: f64,
    repeats: usize,
) -> anyhow::Result<BenchRecord> {
    let solve = gathered_config().solve;
    let (area, repeats) = (max_patch_area, repeats.max(1));
    let mut before = scene.clone();
    let object = before
        .objects
        .iter()
        .position(|o| o.name == name)
        .with_context(|| format!("the scene has no object {name}"))?;
    before.objects[object].kind = ObjectKind::Virtual;
    let mut after = before.clone();
    after.objects[object].transform.translation += shift;
    let all0 = SceneGeometry::build(&before, &ObjectFilter::All)?;
    let mesh0 = mesh_with(&before, &all0, area, 0)?;
    // As in the light record, the static solution is precomputed to a
    // tenth of the interactive tolerance.
    let mut limit = 0.0;
    let base_solve = |limit: &mut f64| -> anyhow::Result<Shooter<'_>> {
        let mut s = Shooter::new(&mesh0, &all0, None, &solve)?;
        s.add_surface_emission();
        *limit = solve.threshold * s.injected_power();
        s.run_to_power(0.1 * *limit);
        Ok(s)
    };
    let stale = base_solve(&mut limit)?.radiosity().to_vec();

    let mut best = [f64::INFINITY; 5];
    let (mut full_b, mut full_shots) = (Vec::new(), 0);
    let (mut inc_b, mut inc_shots, mut stats) = (Vec::new(), 0, Default::default());
    let (mut warm_b, mut warm_shots, mut lowest, mut negative) = (Vec::new(), 0, 0.0, 0);
    // Full and incremental alternate, so that both see the machine in the
    // same state; each repeat's pair also gives a speed-up of its own.
    let mut paired = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let start = Instant::now();
        let all1 = SceneGeometry::build(&after, &ObjectFilter::All)?;
        let mesh1 = mesh_with(&after, &all1, area, 0)?;
        best[0] = best[0].min(start.elapsed().as_secs_f64());
        let mut full = Shooter::new(&mesh1, &all1, None, &solve)?;
        full.add_surface_emission();
        full.run_to_power(limit);
        full_b = full.display_radiosity();
        full_shots = full.shots();
        let full_seconds = start.elapsed().as_secs_f64();
        best[1] = best[1].min(full_seconds);

        let base = base_solve(&mut limit)?;
        let start = Instant::now();
        let all1 = SceneGeometry::build(&after, &ObjectFilter::All)?;
        let mesh1 = mesh_with(&after, &all1, area, 0)?;
        let (mut inc, s) = base.move_object(&mesh1, &all1, object as u32, &[])?;
        let move_seconds = start.elapsed().as_secs_f64();
        best[2] = best[2].min(move_seconds);
        inc_shots = inc.run_to_power(limit);
        inc_b = inc.display_radiosity();
        let inc_seconds = start.elapsed().as_secs_f64();
        best[3] = best[3].min(inc_seconds);
        paired.push(full_seconds / inc_seconds.max(1e-9));
        stats = s;
        lowest = inc
            .radiosity()
            .iter()
            .map(|b| b.min_element())
            .fold(0.0, f64::min);
        negative = inc
            .radiosity()
            .iter()
            .filter(|b| b.min_element() < 0.0)
            .count();
        let start = Instant::now();
        let mut warm = inc;
        warm.restart();
        warm.add_surface_emission();
        warm.run_to_power(limit);
        warm_b = warm.display_radiosity();
        warm_shots = warm.shots();
        best[4] = best[4].min(move_seconds + start.elapsed().as_secs_f64());
    }
    let [
        scene_seconds,
        full_seconds,
        move_seconds,
        inc_seconds,
        warm_seconds,
    ] = best;

    let all1 = SceneGeometry::build(&after, &ObjectFilter::All)?;
    let mesh1 = mesh_with(&after, &all1, area, 0)?;
    let mut tight = solve.clone();
    tight.threshold = 1e-5;
    let converged = radiosity::solve(&mesh1, &all1, &[], &tight)?;
    let err = |m: &RadiosityMesh, b: &[DVec3]| {
        radiosity::relative_error(m, b, &mesh1, &converged.display, 6)
    };
    tight.visibility_samples = FINE_VISIBILITY_RAYS;
    let fine = radiosity::solve(&mesh1, &all1, &[], &tight)?;
    let fine_err = |b: &[DVec3]| radiosity::relative_error(&mesh1, b, &mesh1, &fine.display, 6);
    let object_err = |b: &[DVec3]| object_error(&mesh1, object as u32, b, &fine.display);
    let pairs = mesh1.patches.len() * mesh1.elements.len();
    let object_patches = mesh1
        .patches
        .iter()
        .filter(|p| p.object as usize == object)
        .count();
    Ok(json!({
        "kind": "incremental_object",
        "object": name,
        "max_patch_area": area,
        "object_patches": object_patches,
        "shift_m": [shift.x, shift.y, shift.z],
        "patches": mesh1.patches.len(),
        "elements": mesh1.elements.len(),
        "threshold": solve.threshold,
        "repeats": repeats,
        "scene_seconds": scene_seconds,
        "full_seconds": full_seconds,
        "full_shots": full_shots,
        "full_rel_error": err(&mesh1, &full_b),
        "warm_seconds": warm_seconds,
        "warm_shots": warm_shots,
        "warm_rel_error": err(&mesh1, &warm_b),
        "move_seconds": move_seconds,
        "incremental_seconds": inc_seconds,
        "incremental_shots": inc_shots,
        "incremental_rel_error": err(&mesh1, &inc_b),
        "incremental_negative_elements": negative,
        "incremental_lowest_b": lowest,
        "stale_rel_error": err(&mesh0, &stale),
        "full_rel_error_fine": fine_err(&full_b),
        "incremental_rel_error_fine": fine_err(&inc_b),
        "object_full_rel_error_fine": object_err(&full_b),
        "object_incremental_rel_error_fine": object_err(&inc_b),
        "rows_patched": stats.rows_patched,
        "rows_recomputed": stats.rows_recomputed,
        "pairs": pairs,
        "receivers_scanned": stats.receivers_scanned,
        "pairs_near": stats.pairs_near,
        "rays_tested": stats.rays_tested,
        "rays_traced": stats.rays_traced,
        "entries_recomputed": stats.entries_recomputed,
        "entries_reciprocal": stats.entries_reciprocal,
        "entries_rescaled": stats.entries_rescaled,
        "speedup": full_seconds / inc_seconds.max(1e-9),
        "speedup_paired_median": showcase_light::metrics::percentile(&paired, 50.0),
        "speedup_without_scene": (full_seconds - scene_seconds)
            / (inc_seconds - scene_seconds).max(1e-9),
        "speedup_over_warm": warm_seconds / inc_seconds.max(1e-9),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::load_any;
    use std::path::Path;

    /// `--object-records` and `--repeats`: the default is every record at
    /// 5 runs; specs pick records; a bad spec is an error naming it.
    #[test]
    fn object_record_specs_parse_and_bad_ones_are_named() {
        let all = ObjectRecords::parse(&[], None).unwrap();
        assert_eq!(all, ObjectRecords::default());
        assert_eq!(all.records.len(), 4);
        assert_eq!(all.repeats, 5);
        let specs = [
            "short_block@0.02".to_string(),
            "small_cube@5e-3".to_string(),
        ];
        let picked = ObjectRecords::parse(&specs, Some(30)).unwrap();
        assert_eq!(
            picked.records,
            vec![("short_block".into(), 0.02), ("small_cube".into(), 0.005)]
        );
        assert_eq!(picked.repeats, 30);
        for (spec, named) in [
            ("tall_block@0.02", "tall_block"),
            ("short_block", "OBJECT@AREA"),
            ("short_block@big", "big"),
            ("short_block@-1", "-1"),
            ("short_block@NaN", "NaN"),
        ] {
            let e = ObjectRecords::parse(&[spec.to_string()], None).unwrap_err();
            assert!(e.to_string().contains(named), "{spec}: {e}");
        }
        let e = ObjectRecords::parse(&[], Some(0)).unwrap_err();
        assert!(e.to_string().contains("--repeats"), "{e}");
    }

    /// The object record on the real Cornell box: the incremental update
    /// reaches the moved scene's converged solution as closely as a full
    /// re-solve does, on the whole scene and on the moved object alone,
    /// and the move mattered (the unmoved solution is off).
    #[test]
    fn incremental_object_record_reaches_the_converged_solution() {
        let cornell = load_any(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../shared/data/cornell-box.obj"
        )))
        .unwrap();
        let shift = Vec3::new(0.03, 0.0, 0.02);
        for (scene, name) in [
            (cornell.clone(), "short_block"),
            (cornell_with_small_cube(&cornell, 0.06), "small_cube"),
        ] {
            let r = incremental_object_record(&scene, name, shift, 0.02, 1).unwrap();
            println!("{r}");
            let f = |k: &str| r[k].as_f64().unwrap();
            let (inc, full, stale) = (
                f("incremental_rel_error"),
                f("full_rel_error"),
                f("stale_rel_error"),
            );
            assert!(inc < 0.02 && inc < 1.5 * full + 0.002, "{r}");
            // The moved object's own values, against the finer reference:
            // as close as a full re-solve's (its column may come by
            // reciprocity, a different estimate of the same form factors).
            let (inc_obj, full_obj) = (
                f("object_incremental_rel_error_fine"),
                f("object_full_rel_error_fine"),
            );
            assert!(inc_obj < 1.5 * full_obj + 0.002, "{r}");
            assert!(stale > 2.0 * inc, "{r}");
            assert!(f("entries_recomputed") < 0.5 * f("pairs"), "{r}");
            assert!(f("incremental_lowest_b") > -1e-6, "{r}");
        }
    }
}
