//! Incremental update after a virtual object moves: the corrected form
//! factors equal those of a fresh solve of the moved scene, and shooting
//! the difference reaches a fresh solve's solution with fewer shots.

use super::tests::{cuboid, quads_object};
use super::*;
use crate::ObjectFilter;
use glam::Vec3;
use showcase_proto::{Material, ObjectKind, Showcase};

/// A closed unit box (inward faces, the top emitting) with a virtual cube
/// of side `a` floating inside (outward faces), translated by `shift`.
pub(super) fn box_with_block(shift: Vec3) -> Showcase {
    let mut s = Showcase::default();
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    let wall = Material::diffuse(Vec3::new(0.7, 0.6, 0.5));
    let mut top = Material::diffuse(Vec3::splat(0.6));
    top.emission = Vec3::splat(0.5);
    let o = Vec3::ZERO;
    quads_object(
        &mut s,
        "walls",
        &[(o, z, x), (o, y, z), (x, z, y), (z, y, x), (o, x, y)],
        wall,
        ObjectKind::Real,
    );
    quads_object(&mut s, "top", &[(y, x, z)], top, ObjectKind::Real);
    let c = Vec3::new(0.3, 0.2, 0.35);
    quads_object(
        &mut s,
        "block",
        &cuboid(c, Vec3::splat(0.25)),
        Material::diffuse(Vec3::new(0.2, 0.5, 0.8)),
        ObjectKind::Virtual,
    );
    s.objects[2].transform.translation = shift;
    s
}

pub(super) fn mesh_of(s: &Showcase) -> (RadiosityMesh, SceneGeometry) {
    let g = SceneGeometry::build(s, &ObjectFilter::All).unwrap();
    let m = RadiosityMesh::build(
        s,
        &g,
        &MeshOptions {
            max_patch_area: 0.13,
            element_depth: 1,
            ..MeshOptions::default()
        },
    )
    .unwrap();
    (m, g)
}

fn ray_cast(threshold: f64) -> SolveOptions {
    SolveOptions {
        threshold,
        method: FormFactorMethod::RayCast,
        ..SolveOptions::default()
    }
}

#[test]
fn incremental_update_matches_a_fresh_solve_after_an_object_moves() {
    let light = Light::Point {
        position: Vec3::new(0.6, 0.8, 0.5),
        intensity: Vec3::splat(0.3),
    };
    let before = box_with_block(Vec3::ZERO);
    let after = box_with_block(Vec3::new(0.07, 0.0, -0.04));
    let (m0, g0) = mesh_of(&before);
    let (m1, g1) = mesh_of(&after);
    let o = ray_cast(1e-4);
    let mut sh = Shooter::new(&m0, &g0, None, &o).unwrap();
    sh.add_surface_emission();
    sh.add_light(&light, 1.0);
    sh.run();
    let limit = o.threshold * sh.injected_power();
    let (mut moved, stats) = sh
        .move_object(&m1, &g1, 2, std::slice::from_ref(&light))
        .unwrap();

    // The corrected rows are the moved scene's rows, entry for entry.
    assert_rows_are_fresh(&moved, &Shooter::new(&m1, &g1, None, &o).unwrap());
    // Only part of the static pairs had to be recomputed.
    let block_patches = m1.patches.iter().filter(|p| p.object == 2).count();
    assert_eq!(stats.rows_recomputed, block_patches);
    assert_eq!(stats.rows_patched, m1.patches.len() - block_patches);
    let static_pairs = stats.rows_patched * m1.elements.len();
    assert!(
        stats.entries_recomputed > 0 && 2 * stats.entries_recomputed < static_pairs,
        "{stats:?} of {static_pairs} pairs"
    );
    // Some static entries were updated from their rays' recorded
    // visibility instead of being ray-cast again.
    assert!(stats.entries_rescaled > 0, "{stats:?}");
    // The scan looked at every static receiver outside each patched
    // row's own patch; every ray of each near pair was tested (all rows
    // recorded their rays), and only some of them were traced again.
    let scanned: usize = m1
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| p.object != 2)
        .map(|(i, _)| {
            m1.elements
                .iter()
                .filter(|e| e.object != 2 && e.patch as usize != i)
                .count()
        })
        .sum();
    assert_eq!(stats.receivers_scanned, scanned);
    assert!(
        stats.pairs_near > 0 && stats.pairs_near < scanned,
        "{stats:?}"
    );
    assert_eq!(
        stats.rays_tested,
        o.visibility_samples as usize * stats.pairs_near
    );
    assert!(
        stats.rays_traced > 0 && 2 * stats.rays_traced < stats.rays_tested,
        "{stats:?}"
    );

    let incremental_shots = moved.run_to_power(limit);
    let b = moved.radiosity();
    let largest = b.iter().map(|v| v.max_element()).fold(0.0, f64::max);
    assert!(b.iter().all(|v| v.is_finite()));
    let lowest = b.iter().map(|v| v.min_element()).fold(0.0, f64::min);
    assert!(lowest > -1e-3 * largest, "negative B {lowest} of {largest}");

    let full = solve(&m1, &g1, std::slice::from_ref(&light), &o).unwrap();
    let reference = solve(&m1, &g1, std::slice::from_ref(&light), &ray_cast(1e-7)).unwrap();
    let err = |x: &[DVec3]| relative_error(&m1, x, &m1, &reference.radiosity, 4).unwrap();
    let (inc_err, full_err) = (err(b), err(&full.radiosity));
    assert!(inc_err < 0.005, "incremental {inc_err}, full {full_err}");
    assert!(full_err < 0.005, "full {full_err}");
    let vs_full = relative_error(&m1, b, &m1, &full.radiosity, 4).unwrap();
    assert!(vs_full < 0.005, "incremental vs fresh: {vs_full}");
    // The block really changed the light: the old solution is far off.
    let stale = relative_error(
        &m0,
        &moved_stale(&m0, &g0, &light, &o),
        &m1,
        &reference.radiosity,
        4,
    )
    .unwrap();
    assert!(
        stale > 5.0 * inc_err.max(1e-3),
        "stale {stale}, incremental {inc_err}"
    );
    assert!(
        incremental_shots < full.shots,
        "{incremental_shots} vs {}",
        full.shots
    );
}

/// Two moves in a row, beside a real pillar that blocks some rays for
/// good: the second works from the rows (and the rays' visibility) that
/// the first corrected, and its rows still equal a fresh solve's of the
/// scene after both moves, ray by ray.
#[test]
fn a_second_move_works_from_the_corrected_rows() {
    let o = ray_cast(1e-3);
    let with_pillar = |shift: Vec3| {
        let mut s = box_with_block(shift);
        let (a, h) = (0.13, 0.6);
        let (ax, ay, az) = (a * Vec3::X, h * Vec3::Y, a * Vec3::Z);
        let c = Vec3::new(0.72, 0.0, 0.6);
        quads_object(
            &mut s,
            "pillar",
            &[
                (c + ay, az, ax),
                (c, az, ay),
                (c + ax, ay, az),
                (c, ay, ax),
                (c + az, ax, ay),
            ],
            Material::diffuse(Vec3::splat(0.5)),
            ObjectKind::Real,
        );
        mesh_of(&s)
    };
    let scenes: Vec<(RadiosityMesh, SceneGeometry)> = [
        Vec3::ZERO,
        Vec3::new(0.07, 0.0, -0.04),
        Vec3::new(-0.05, 0.1, 0.06),
    ]
    .into_iter()
    .map(with_pillar)
    .collect();
    let mut sh = Shooter::new(&scenes[0].0, &scenes[0].1, None, &o).unwrap();
    sh.add_surface_emission();
    sh.run();
    let (sh, first) = sh.move_object(&scenes[1].0, &scenes[1].1, 2, &[]).unwrap();
    let (moved, second) = sh.move_object(&scenes[2].0, &scenes[2].1, 2, &[]).unwrap();
    assert!(
        first.entries_rescaled > 0 && second.entries_rescaled > 0,
        "{first:?} {second:?}"
    );
    let (m2, g2) = &scenes[2];
    assert_rows_are_fresh(&moved, &Shooter::new(m2, g2, None, &o).unwrap());
}

/// A drag: sixteen moves round a loop and back to the start, one of them a
/// jump across the box (its places leave a gap in their union box, so the
/// centre-segment cull is taken), each move working from the rows, ray
/// visibility and signed unshot energy the one before left, under a
/// light the block shadows. After every move the solution shot on to the
/// tolerance stays finite and non-negative (to the signed energy's
/// round-off); back at the start the rows equal a fresh solve's, ray by
/// ray, and the solution is as close to the converged one as a full
/// re-solve: nothing drifts over the moves.
#[test]
fn a_drag_of_many_moves_does_not_drift() {
    let light = Light::Point {
        position: Vec3::new(0.6, 0.8, 0.5),
        intensity: Vec3::splat(0.3),
    };
    let o = ray_cast(1e-4);
    let path: Vec<Vec3> = (0..=16)
        .map(|k| match k {
            0 | 16 => Vec3::ZERO,
            8 => Vec3::new(0.35, 0.3, -0.3),
            _ => {
                let t = k as f32 * std::f32::consts::TAU / 16.0;
                0.08 * Vec3::new(t.cos() - 1.0, 0.5 * t.sin(), t.sin())
            }
        })
        .collect();
    let scenes: Vec<(RadiosityMesh, SceneGeometry)> =
        path.iter().map(|&p| mesh_of(&box_with_block(p))).collect();
    let (m0, g0) = &scenes[0];
    let mut sh = Shooter::new(m0, g0, None, &o).unwrap();
    sh.add_surface_emission();
    sh.add_light(&light, 1.0);
    sh.run();
    let limit = o.threshold * sh.injected_power();
    let mut near = Vec::new();
    for (m, g) in &scenes[1..] {
        let (mut moved, stats) = sh
            .move_object(m, g, 2, std::slice::from_ref(&light))
            .unwrap();
        moved.run_to_power(limit);
        let b = moved.radiosity();
        let largest = b.iter().map(|v| v.max_element()).fold(0.0, f64::max);
        let lowest = b.iter().map(|v| v.min_element()).fold(0.0, f64::min);
        assert!(b.iter().all(|v| v.is_finite()));
        assert!(lowest > -1e-3 * largest, "negative B {lowest} of {largest}");
        assert!(moved.unshot_power() <= limit, "{}", moved.unshot_power());
        near.push(stats.pairs_near);
        sh = moved;
    }
    // The jump and the return from it reach more pairs than a step.
    assert!(near[7] > near[0] && near[8] > near[0], "{near:?}");
    assert_rows_are_fresh(&sh, &Shooter::new(m0, g0, None, &o).unwrap());
    let full = solve(m0, g0, std::slice::from_ref(&light), &o).unwrap();
    let reference = solve(m0, g0, std::slice::from_ref(&light), &ray_cast(1e-7)).unwrap();
    let err = |x: &[DVec3]| relative_error(m0, x, m0, &reference.radiosity, 4).unwrap();
    let (inc_err, full_err) = (err(sh.radiosity()), err(&full.radiosity));
    assert!(
        inc_err < 1.5 * full_err + 0.002,
        "after the drag {inc_err}, full {full_err}"
    );
}

/// Every row of `moved` equals `fresh`'s (a solve of the same scene that
/// computes its rows anew), entry for entry to round-off, and so does the
/// record of which of each entry's rays see the shooter.
fn assert_rows_are_fresh(moved: &Shooter<'_>, fresh: &Shooter<'_>) {
    let mut worst = 0.0_f64;
    for p in 0..fresh.unshot().len() {
        let (a, b) = (
            moved.form_factor_row(p).unwrap(),
            fresh.form_factor_row(p).unwrap(),
        );
        assert_eq!(
            a.iter().map(|e| e.0).collect::<Vec<_>>(),
            b.iter().map(|e| e.0).collect::<Vec<_>>(),
            "row {p}"
        );
        for (x, y) in a.iter().zip(&b) {
            worst = worst.max((x.1 - y.1).abs());
        }
        assert_eq!(moved.row_rays(p), fresh.row_rays(p), "row {p}");
    }
    assert!(worst < 1e-12, "largest form-factor difference {worst}");
}

/// The solution before the move (what a display would keep without an
/// update).
fn moved_stale(
    m: &RadiosityMesh,
    g: &SceneGeometry,
    light: &Light,
    o: &SolveOptions,
) -> Vec<DVec3> {
    solve(m, g, std::slice::from_ref(light), o)
        .unwrap()
        .radiosity
}

#[test]
fn a_move_that_changes_more_than_the_object_is_refused() {
    let before = box_with_block(Vec3::ZERO);
    let (m0, g0) = mesh_of(&before);
    let (m1, g1) = mesh_of(&box_with_block(Vec3::new(0.05, 0.0, 0.0)));
    let o = ray_cast(1e-2);
    let start = || {
        let mut s = Shooter::new(&m0, &g0, None, &o).unwrap();
        s.add_surface_emission();
        s.run();
        s
    };
    // The block is object 2; the walls (object 0) did not move.
    let Err(e) = start().move_object(&m1, &g1, 0, &[]) else {
        panic!("a move of the walls was accepted although the block moved");
    };
    assert!(
        matches!(e, MoveError::StaticElementChanged { object: 0, .. }),
        "{e}"
    );
    assert_eq!(
        start().move_object(&m1, &g1, 9, &[]).err(),
        Some(MoveError::StaticElementChanged {
            element: m0.elements.iter().position(|e| e.object == 2).unwrap() as u32,
            object: 9
        })
    );
    let (m2, g2) = mesh_of(&box_with_block(Vec3::ZERO));
    assert_eq!(
        start().move_object(&m2, &g2, 9, &[]).err(),
        Some(MoveError::NoSuchObject(9))
    );
    let mut coarse = before.clone();
    coarse.objects.pop();
    let (m3, g3) = mesh_of(&coarse);
    assert!(matches!(
        start().move_object(&m3, &g3, 2, &[]).err(),
        Some(MoveError::MeshMismatch { .. })
    ));
}

/// One element per patch and patches of equal size on the walls and the
/// block: the block's column is taken from its own rows by reciprocity,
/// but for the emitting top's rows, where it is ray-cast.
/// The reciprocal entries satisfy `F_iq A_i = F_qi A_q` with the fresh
/// rows of the moved scene, every other entry equals the fresh one, and
/// the solution reaches the converged one as closely as a full re-solve
/// (the reciprocal entries are a different estimate of the same form
/// factors, so the bound allows the discretisation error: 1.5 times the
/// full re-solve's error plus 0.002).
#[test]
fn reciprocal_column_matches_the_fresh_rows_and_the_converged_solution() {
    let mesh_flat = |s: &Showcase| {
        let g = SceneGeometry::build(s, &ObjectFilter::All).unwrap();
        let m = RadiosityMesh::build(
            s,
            &g,
            &MeshOptions {
                max_patch_area: 0.04,
                element_depth: 0,
                ..MeshOptions::default()
            },
        )
        .unwrap();
        (m, g)
    };
    let (m0, g0) = mesh_flat(&box_with_block(Vec3::ZERO));
    let (m1, g1) = mesh_flat(&box_with_block(Vec3::new(0.07, 0.0, -0.04)));
    let o = ray_cast(1e-3);
    let mut sh = Shooter::new(&m0, &g0, None, &o).unwrap();
    sh.add_surface_emission();
    let limit = o.threshold * sh.injected_power();
    // Every patch shoots, so every static row is patched.
    sh.run_to_power(0.1 * limit);
    let (mut moved, stats) = sh.move_object(&m1, &g1, 2, &[]).unwrap();
    assert!(stats.entries_reciprocal > 0, "{stats:?}");

    let fresh = Shooter::new(&m1, &g1, None, &o).unwrap();
    let block: Vec<usize> = (0..m1.patches.len())
        .filter(|&p| m1.patches[p].object == 2)
        .collect();
    let rows: Vec<Vec<(u32, f64)>> = (0..m1.patches.len())
        .map(|p| fresh.form_factor_row(p).unwrap())
        .collect();
    let entry =
        |row: &[(u32, f64)], j: usize| row.iter().find(|e| e.0 as usize == j).map_or(0.0, |e| e.1);
    // A row that summed above 1 was normalised to sum 1 (every entry
    // scaled): only rows below are compared entry by entry.
    let unscaled = |row: &[(u32, f64)]| row.iter().map(|e| e.1).sum::<f64>() < 1.0 - 1e-9;
    let (mut reciprocal, mut emitted, mut worst_static) = (0, 0, 0.0_f64);
    assert_eq!(stats.rows_patched, m1.patches.len() - block.len());
    for i in (0..m1.patches.len()).filter(|p| !block.contains(p)) {
        let row = moved.form_factor_row(i).unwrap();
        let a_i = m1.patches[i].area;
        if !unscaled(&row) || !unscaled(&rows[i]) {
            continue;
        }
        let emits = m1.elements[m1.patches[i].elements[0] as usize].emission != DVec3::ZERO;
        for &(j, f) in &row {
            let j = j as usize;
            let q = m1.elements[j].patch as usize;
            if emits && block.contains(&q) {
                // Ray-cast: the fresh entry to round-off.
                emitted += 1;
                worst_static = worst_static.max((f - entry(&rows[i], j)).abs());
            } else if block.contains(&q) {
                let a_q = m1.patches[q].area;
                if a_i <= 2.0 * a_q && unscaled(&rows[q]) {
                    // The block patch's single element is the patch.
                    let expected = entry(&rows[q], m1.patches[i].elements[0] as usize) * a_q;
                    assert!(
                        (f * a_i - expected).abs() <= 1e-9 * expected.max(1e-12),
                        "row {i} entry {j}: {f} * {a_i} vs {expected}"
                    );
                    reciprocal += 1;
                }
            } else {
                worst_static = worst_static.max((f - entry(&rows[i], j)).abs());
            }
        }
    }
    assert!(reciprocal > 0 && emitted > 0, "{reciprocal} {emitted}");
    assert!(
        worst_static < 1e-12,
        "static entries differ by {worst_static}"
    );

    moved.run_to_power(limit);
    let full = solve(&m1, &g1, &[], &o).unwrap();
    let reference = solve(&m1, &g1, &[], &ray_cast(1e-6)).unwrap();
    let err = |x: &[DVec3]| relative_error(&m1, x, &m1, &reference.radiosity, 4).unwrap();
    let (inc_err, full_err) = (err(moved.radiosity()), err(&full.radiosity));
    assert!(
        inc_err < 1.5 * full_err + 0.002,
        "incremental {inc_err}, full {full_err}"
    );
}
