//! Integration tests: radiosity. The `radiosity` job on the shipped Cornell
//! box (OBJ as it is) writes a PLY whose radiosity is checked against
//! closed forms (the light's exitance pi * Ke, the floor's direct light by
//! Lambert's polygon formula), and augmented radiosity on the paper's
//! figure-3 scene (walls real, blocks and light virtual), end to end
//! through the simulated showcase.

use glam::DVec3;
use showcase_light::radiosity::{
    B1Pass, FormFactorMethod, GatherOptions, MeshOptions, RadiosityMesh, SolveOptions,
    augmented_radiosity, augmented_radiosity_with, gathered_b2_vertices, irradiance_map,
};
use showcase_light::{ObjectFilter, SceneGeometry, polygon_irradiance};
use showcase_master::radiosity_job::bench::figure3_scene;
use showcase_master::radiosity_job::consistency::{Promise, consistency};
use showcase_master::radiosity_job::{RadiosityOptions, run_radiosity};
use showcase_master::scene_file::load_any;
use showcase_proto::PinholeDevice;
use std::path::Path;

const CORNELL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cornell-box.obj"
);

/// A PLY vertex: position, normal, radiosity.
type PlyVertex = (DVec3, DVec3, DVec3);

/// Vertices and face count of an ASCII PLY as written by the job.
fn read_ply(text: &str) -> anyhow::Result<(Vec<PlyVertex>, usize)> {
    let (header, body) = text
        .split_once("end_header\n")
        .ok_or_else(|| anyhow::anyhow!("no header"))?;
    let count = |what: &str| -> anyhow::Result<usize> {
        let line = header
            .lines()
            .find(|l| l.starts_with(&format!("element {what} ")))
            .ok_or_else(|| anyhow::anyhow!("no {what} count"))?;
        Ok(line.rsplit(' ').next().unwrap_or("").parse()?)
    };
    let (nv, nf) = (count("vertex")?, count("face")?);
    let mut lines = body.lines();
    let mut vertices = Vec::new();
    for _ in 0..nv {
        let v: Vec<f64> = lines
            .next()
            .ok_or_else(|| anyhow::anyhow!("short body"))?
            .split(' ')
            .map(str::parse)
            .collect::<Result<_, _>>()?;
        anyhow::ensure!(v.len() == 9, "vertex has {} values", v.len());
        vertices.push((
            DVec3::new(v[0], v[1], v[2]),
            DVec3::new(v[3], v[4], v[5]),
            DVec3::new(v[6], v[7], v[8]),
        ));
    }
    let faces = lines.filter(|l| l.starts_with("3 ")).count();
    anyhow::ensure!(faces == nf, "{faces} faces for {nf} declared");
    Ok((vertices, nf))
}

/// Input whose solution would be zero, or grey for want of its materials,
/// is refused with an error naming the file and the problem, and nothing
/// is written: the shipped Cornell box without its material library or
/// with a `usemtl` it does not define, a scene where nothing emits, a
/// file without faces, and one whose only triangle has no area.
#[test]
fn radiosity_refuses_a_scene_without_materials_light_or_surfaces() -> anyhow::Result<()> {
    let dir = std::env::temp_dir().join(format!("showcase-radiosity-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let out = dir.join("out");
    let options = RadiosityOptions {
        max_patch_area: Some(0.05),
        hemicube: Some(16),
        threshold: Some(0.1),
        ..Default::default()
    };
    let refused = |file: &str, text: &str| -> anyhow::Result<String> {
        let path = dir.join(file);
        std::fs::write(&path, text)?;
        match run_radiosity(&path, &out, &options) {
            Ok(s) => anyhow::bail!("{file} was solved: {s:?}"),
            Err(e) => Ok(format!("{e:#}")),
        }
    };
    let e = refused(
        "cornell-without-mtl.obj",
        &std::fs::read_to_string(CORNELL)?,
    )?;
    assert!(
        e.contains("cornell-without-mtl.obj") && e.contains("material library"),
        "{e}"
    );
    // With its library, but one `usemtl` misspelt.
    std::fs::copy(
        Path::new(CORNELL).with_extension("mtl"),
        dir.join("cornell-box.mtl"),
    )?;
    let misspelt = std::fs::read_to_string(CORNELL)?.replacen("usemtl red", "usemtl rde", 1);
    let e = refused("cornell-misspelt.obj", &misspelt)?;
    assert!(
        e.contains("cornell-misspelt.obj") && e.contains("usemtl rde"),
        "{e}"
    );
    let e = refused("dark.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")?;
    assert!(e.contains("dark.obj") && e.contains("emits light"), "{e}");
    let e = refused("junk.obj", "nothing an OBJ reader knows\n")?;
    assert!(e.contains("junk.obj") && e.contains("no triangles"), "{e}");
    let e = refused("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")?;
    assert!(e.contains("flat.obj") && e.contains("no surface"), "{e}");
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}

#[test]
fn cornell_box_solution_ply_matches_closed_forms() -> anyhow::Result<()> {
    let out = std::env::temp_dir().join(format!("showcase-radiosity-{}", std::process::id()));
    let summary = run_radiosity(
        Path::new(CORNELL),
        &out,
        &RadiosityOptions {
            max_patch_area: Some(0.02),
            hemicube: Some(32),
            threshold: Some(1e-2),
            ..Default::default()
        },
    )?;
    assert!(summary.unshot_fraction < 1e-2);
    let (vertices, faces) = read_ply(&std::fs::read_to_string(&summary.solution)?)?;
    assert!(faces >= summary.elements);
    assert!(
        vertices
            .iter()
            .all(|(_, _, b)| b.is_finite() && b.min_element() >= 0.0)
    );
    // The light (just below the ceiling, facing down) emits pi * Ke and
    // reflects what it receives: B between pi * Ke and pi * Ke + rho * E,
    // where E is at most the largest exitance of anything else.
    let emitted = DVec3::new(17.0, 12.0, 4.0) * std::f64::consts::PI;
    let brightest_other = vertices
        .iter()
        .filter(|(p, _, _)| p.y < 0.548)
        .fold(DVec3::ZERO, |m, (_, _, b)| m.max(*b));
    assert!(brightest_other.cmpgt(DVec3::ZERO).all());
    let light: Vec<&DVec3> = vertices
        .iter()
        .filter(|(p, n, _)| p.y > 0.548 && p.y < 0.5488 && n.y < -0.9)
        .map(|(_, _, b)| b)
        .collect();
    assert!(!light.is_empty());
    for b in light {
        assert!(
            b.cmpge(emitted).all() && b.cmple(emitted * 1.05).all(),
            "{b}"
        );
    }
    // Floor vertices that see the whole light: B is rho times the direct
    // irradiance (Lambert) plus indirect light, and the indirect irradiance
    // is at most the largest exitance of the surfaces other than the light.
    let showcase = load_any(Path::new(CORNELL))?;
    let all = SceneGeometry::build(&showcase, &ObjectFilter::All)?;
    let light_tris: Vec<[DVec3; 3]> = all
        .triangles()
        .filter(|t| showcase.objects[t.object as usize].name == "light")
        .map(|t| t.vertices)
        .collect();
    let mut checked = 0;
    for (p, n, b) in &vertices {
        let on_floor = p.y.abs() < 1e-6 && n.y > 0.9;
        if !on_floor
            || !light_tris
                .iter()
                .flatten()
                .all(|c| all.visible(*p, *n, *c, true))
        {
            continue;
        }
        let direct: f64 = light_tris
            .iter()
            .map(|t| polygon_irradiance(*p, *n, t, 17.0).unwrap())
            .sum();
        let low = 0.725 * direct;
        let high = low + 0.725 * brightest_other.x;
        assert!(
            b.x > 0.95 * low && b.x < high,
            "{p}: {} vs direct {low}",
            b.x
        );
        checked += 1;
    }
    assert!(checked > 0);
    std::fs::remove_dir_all(&out).ok();
    Ok(())
}

/// The figure-3 scene (Cornell walls real, blocks and light virtual) at
/// 0.02 m^2 patches, with the hybrid solve the augmented tests use.
struct Figure3 {
    s: showcase_proto::Showcase,
    all: SceneGeometry,
    real: SceneGeometry,
    mesh: RadiosityMesh,
    options: SolveOptions,
}

fn figure3() -> anyhow::Result<Figure3> {
    let s = figure3_scene(&load_any(Path::new(CORNELL))?);
    let all = SceneGeometry::build(&s, &ObjectFilter::All)?;
    let real = SceneGeometry::build(&s, &ObjectFilter::Real)?;
    let mesh = RadiosityMesh::build(
        &s,
        &all,
        &MeshOptions {
            max_patch_area: 0.02,
            element_depth: 1,
            ..MeshOptions::default()
        },
    )?;
    let options = SolveOptions {
        hemicube: 32,
        threshold: 1e-2,
        method: FormFactorMethod::Hybrid,
        ..SolveOptions::default()
    };
    Ok(Figure3 {
        s,
        all,
        real,
        mesh,
        options,
    })
}

#[test]
fn augmented_radiosity_on_the_figure_3_scene() -> anyhow::Result<()> {
    let Figure3 {
        s,
        all,
        real,
        mesh,
        options,
    } = figure3()?;
    let a = augmented_radiosity(&mesh, &all, &real, &[], &options)?;
    for b in [&a.b0, &a.b1, &a.b2, &a.b3] {
        assert!(b.iter().all(|v| v.is_finite() && v.min_element() >= 0.0));
    }
    // B1 adds the real interreflection on top of B0; B2 removes it again,
    // so B3 lands nearer B0 than B1 did (to second order in the real
    // surfaces' transport, which is strong in a closed white box).
    for c in 0..3 {
        assert!(a.b1_b0_deviation_rgb[c] > 0.0);
        assert!(
            a.b3_b0_deviation_rgb[c] < 0.8 * a.b1_b0_deviation_rgb[c],
            "channel {c}: {:?} vs {:?}",
            a.b3_b0_deviation_rgb,
            a.b1_b0_deviation_rgb
        );
    }
    assert!(a.clipped_elements <= a.real_elements);
    // With a one-bounce B1, B2 = (I - K) B0 and B3 = B0 up to clipping.
    let one = augmented_radiosity_with(&mesh, &all, &real, &[], &options, B1Pass::OneBounce)?;
    for c in 0..3 {
        assert!(
            one.b3_b0_deviation_rgb[c] < 0.5 * a.b3_b0_deviation_rgb[c],
            "channel {c}: one bounce {:?} vs paper {:?}",
            one.b3_b0_deviation_rgb,
            a.b3_b0_deviation_rgb
        );
    }
    let b2 = mesh.vertex_values(&a.b2);
    let map = irradiance_map(&mesh, &real, &b2, &s.projectors, 0)?;
    assert!(map.valid > 0);
    let f = map.clipped_fraction();
    assert!((0.0..=1.0).contains(&f));
    assert!(
        map.drive
            .data
            .iter()
            .all(|d| d.is_finite() && d.min_element() >= 0.0 && d.max_element() <= 1.0)
    );
    // Virtual objects get no drive: the blocks are not in the real geometry.
    assert!(
        mesh.elements
            .iter()
            .zip(&a.b2)
            .all(|(e, b)| e.real || *b == DVec3::ZERO)
    );
    Ok(())
}

#[test]
fn projected_maps_reproduce_b0_in_the_simulated_showcase() -> anyhow::Result<()> {
    // The sim path-traces the real walls lit by the projector through its
    // own device model, independently of our solver: its direct light must
    // reproduce B2 (the map's target), and with the one-bounce B1 its total
    // (direct plus the real interreflection) must land near B0, much nearer
    // than with the paper's converged B1, which over-subtracts.
    let s = figure3_scene(&load_any(Path::new(CORNELL))?);
    let all = SceneGeometry::build(&s, &ObjectFilter::All)?;
    let real = SceneGeometry::build(&s, &ObjectFilter::Real)?;
    let mesh = RadiosityMesh::build(
        &s,
        &all,
        &MeshOptions {
            max_patch_area: 0.04,
            element_depth: 1,
            ..MeshOptions::default()
        },
    )?;
    let options = SolveOptions {
        threshold: 1e-2,
        method: FormFactorMethod::RayCast,
        ..SolveOptions::default()
    };
    let camera = PinholeDevice::look_at(
        DVec3::new(0.25, 0.3, -0.85),
        DVec3::new(0.278, 0.274, 0.28),
        DVec3::Y,
        42.0,
        40,
        30,
    );
    let mut figures = Vec::new();
    for pass in [B1Pass::Converged, B1Pass::OneBounce] {
        let a = augmented_radiosity_with(&mesh, &all, &real, &[], &options, pass)?;
        let b2 = mesh.vertex_values(&a.b2);
        let map = irradiance_map(&mesh, &real, &b2, &s.projectors, 0)?;
        let unclipped: Vec<bool> =
            a.b0.iter()
                .zip(&a.b1)
                .map(|(b0, b1)| (2.0 * *b0 - *b1).min_element() >= 0.0)
                .collect();
        let c = consistency(
            &s,
            &Promise {
                mesh: &mesh,
                real: &real,
                b0_vertices: &mesh.vertex_values(&a.b0),
                b2_vertices: &b2,
                unclipped: &unclipped,
            },
            std::slice::from_ref(&map),
            &camera,
            32,
        )?;
        assert!(c.pixels > c.real_pixels / 2, "{c:?}");
        assert!(c.direct_rel_rmse < 0.1, "{pass:?}: {c:?}");
        figures.push(c);
    }
    let (paper, one) = (&figures[0], &figures[1]);
    assert!(one.rel_rmse < 0.3 * paper.rel_rmse, "{one:?} vs {paper:?}");
    assert!((one.level - 1.0).abs() < 0.1, "{one:?}");
    Ok(())
}

#[test]
fn gathered_one_bounce_maps_reach_the_consistency_target() -> anyhow::Result<()> {
    // The consistency target: the real walls, lit only by the projector showing
    // its irradiance map and by their own interreflection (path-traced by
    // the sim, independent of the solver), show B0 to a relative RMSE of
    // at most 0.03 over the unclipped real surface the camera sees. This
    // takes the one-bounce B1 pass with the real interreflection gathered
    // at the vertices; the element B2 of the same pass, averaged to the
    // vertices, misses it at the walls' edges and corners.
    let Figure3 {
        s,
        all,
        real,
        mesh,
        options,
    } = figure3()?;
    let one = augmented_radiosity_with(&mesh, &all, &real, &[], &options, B1Pass::OneBounce)?;
    let unclipped: Vec<bool> = one
        .b0
        .iter()
        .zip(&one.b1)
        .map(|(b0, b1)| (2.0 * *b0 - *b1).min_element() >= 0.0)
        .collect();
    let b0 = mesh.vertex_values(&one.b0);
    let camera = PinholeDevice::look_at(
        DVec3::new(0.25, 0.3, -0.85),
        DVec3::new(0.278, 0.274, 0.28),
        DVec3::Y,
        42.0,
        48,
        36,
    );
    let mut figures = Vec::new();
    for b2 in [
        gathered_b2_vertices(&mesh, &real, &one, &GatherOptions::default()),
        mesh.vertex_values(&one.b2),
    ] {
        let map = irradiance_map(&mesh, &real, &b2, &s.projectors, 0)?;
        figures.push(consistency(
            &s,
            &Promise {
                mesh: &mesh,
                real: &real,
                b0_vertices: &b0,
                b2_vertices: &b2,
                unclipped: &unclipped,
            },
            std::slice::from_ref(&map),
            &camera,
            1024,
        )?);
    }
    let (gathered, element) = (&figures[0], &figures[1]);
    // Most of the real surface the camera sees is compared.
    assert!(
        gathered.pixels * 10 > gathered.real_pixels * 8,
        "{gathered:?}"
    );
    assert!(gathered.rel_rmse <= 0.03, "{gathered:?}");
    assert!(
        gathered.rel_rmse < element.rel_rmse,
        "{gathered:?} vs {element:?}"
    );
    assert!((gathered.level - 1.0).abs() < 0.02, "{gathered:?}");
    // The per-surface figures are the overall one split by surface.
    let sq: f64 = gathered
        .per_object
        .iter()
        .map(|o| o.rel_rmse * o.rel_rmse * o.pixels as f64)
        .sum();
    assert!(((sq / gathered.pixels as f64).sqrt() - gathered.rel_rmse).abs() < 1e-9);
    Ok(())
}

/// `radiosity` says in one line what it did and where the summary is,
/// and keeps stdout for `--json`: the summary file parses and agrees with
/// what `--json` prints.
#[test]
fn radiosity_command_writes_its_summary_to_a_file_and_one_line() {
    let dir = std::env::temp_dir().join(format!("showcase-radiosity-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let exe = std::env::current_exe().unwrap();
    let cornell = std::fs::canonicalize(CORNELL).unwrap();
    let args = |out: &'static str| {
        vec![
            "radiosity".to_string(),
            "--scene".into(),
            cornell.to_str().unwrap().into(),
            "--out".into(),
            out.into(),
            "--max-patch-area".into(),
            "0.05".into(),
            "--hemicube".into(),
            "16".into(),
            "--threshold".into(),
            "0.1".into(),
        ]
    };
    let quiet = args("quiet");
    let quiet: Vec<&str> = quiet.iter().map(String::as_str).collect();
    let run = crate::demo::run_cli(&exe, &dir, &quiet);
    assert!(run.success, "{}", run.stderr);
    assert_eq!(run.stdout, "", "stdout is for --json only");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("quiet/summary.json")).unwrap())
            .unwrap();
    let line = run
        .stderr
        .lines()
        .find(|l| l.starts_with("radiosity: ") && l.contains("summary.json"))
        .unwrap_or_else(|| panic!("no summary line in {}", run.stderr));
    assert!(
        line.contains(&format!("{} elements", summary["elements"])),
        "{line}"
    );
    let mut json = args("json");
    json.push("--json".into());
    let json: Vec<&str> = json.iter().map(String::as_str).collect();
    let run = crate::demo::run_cli(&exe, &dir, &json);
    assert!(run.success, "{}", run.stderr);
    let printed: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(printed["elements"], summary["elements"]);
    assert_eq!(printed["shots"], summary["shots"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The hierarchical solver through `radiosity`: a mesh that cannot fit
/// the memory budget is refused before solving, with the estimate and
/// what to change; a time budget stops the solve and the summary says it
/// is not complete; otherwise it writes its solution with its links.
#[test]
fn hierarchical_radiosity_keeps_to_its_memory_and_time_budgets() {
    let dir = std::env::temp_dir().join(format!("showcase-radiosity-hr-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let exe = std::env::current_exe().unwrap();
    let cornell = std::fs::canonicalize(CORNELL).unwrap();
    let cornell = cornell.to_str().unwrap();
    let base = |out: &'static str| {
        vec![
            "radiosity",
            "--scene",
            cornell,
            "--out",
            out,
            "--solver",
            "hierarchical",
            "--max-patch-area",
            "0.05",
        ]
    };
    let mut tight = base("tight");
    tight.extend(["--max-memory-mb", "0.01"]);
    let run = crate::demo::run_cli(&exe, &dir, &tight);
    assert!(!run.success);
    assert!(
        run.stderr.contains("needs at least")
            && run.stderr.contains("--max-patch-area")
            && run.stderr.contains("elements"),
        "{}",
        run.stderr
    );
    assert!(!dir.join("tight/summary.json").exists());

    let mut hurried = base("hurried");
    hurried.extend(["--time-budget", "0.000001"]);
    let run = crate::demo::run_cli(&exe, &dir, &hurried);
    assert!(run.success, "{}", run.stderr);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("hurried/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["complete"], false, "{summary}");
    assert_eq!(
        summary["shots"], 1,
        "one gather, then the budget: {summary}"
    );
    assert!(
        run.stderr.contains("stopped by the time budget"),
        "{}",
        run.stderr
    );

    let run = crate::demo::run_cli(&exe, &dir, &base("whole"));
    assert!(run.success, "{}", run.stderr);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("whole/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["solver"], "hierarchical");
    assert_eq!(summary["complete"], true);
    assert!(summary["links"].as_u64().unwrap() > 0, "{summary}");
    std::fs::remove_dir_all(&dir).unwrap();
}
