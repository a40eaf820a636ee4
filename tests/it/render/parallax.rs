//! Distance-corrected (parallax-corrected) cube-map reflections: a mirror
//! sphere inside a closed box room whose walls are close to it. Ground
//! truth is the exact trace of each reflected ray from its surface point
//! (`environment`, what the demo's target does); the corrected lookup
//! must land on the traced surface point within the map's resolution and
//! match its radiance, far better than the single-centre lookup along the
//! reflected direction; with one wall removed, rays leaving through the
//! opening are black, as traced. The GPU face view must agree with the CPU
//! reference on the same scene, and its cube maps' distance channel with
//! the CPU's distances.

use anyhow::{Result, bail, ensure};
use glam::{DVec2, DVec3, Vec3};
use showcase_light::metrics::{percentile, relative_rmse};
use showcase_light::render::cube_map::{
    CUBE_FACES, CubeMap, NO_SURFACE_DISTANCE, PARALLAX_LINEAR_STEPS, PARALLAX_SECANT_STEPS,
    PARALLAX_SURFACE_TOLERANCE, cube_map_cpu, environment, reflect, reflective_centres,
    texel_direction, world_to_face,
};
use showcase_light::render::face::face_image_cpu_with;
use showcase_light::render::projector::edge_mask;
use showcase_light::render::{FrameScene, Occluders};
use showcase_light::{Image, Ray};
use showcase_proto::{Material, Mesh, ObjectKind, Showcase};
use showcase_render::render::bench::{bench_face, uv_sphere};
use showcase_render::render::compare::EDGE_RADIUS_PX;
use showcase_render::render::face_gpu::FacePipeline;
use showcase_render::render::passes::PassList;

use super::gpu_or_skip;
use super::projector::{GPU_CPU_REL_RMSE, OFF_EDGE_OUTLIERS};
use super::scenes::point;

/// The room's corners (metres): the bench face's observers look at its
/// mirror sphere (`bench_face`), the eye is inside it.
const LO: DVec3 = DVec3::new(-0.1, 0.14, -0.65);
const HI: DVec3 = DVec3::new(0.5, 0.74, 0.55);
/// The mirror sphere: centre and radius, low and off-centre so that the
/// floor and two walls are close.
const SPHERE: DVec3 = DVec3::new(0.28, 0.27, 0.3);
const RADIUS: f32 = 0.1;
const EYE: DVec3 = DVec3::new(0.28, 0.27, -0.55);
/// Cube map resolution of the tests.
const RES: u32 = 128;

/// A quad `corner + s u + t v`, `s, t` in `[0, 1]`.
fn quad(corner: Vec3, u: Vec3, v: Vec3) -> Mesh {
    Mesh {
        positions: vec![corner, corner + u, corner + u + v, corner + v],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        ..Mesh::default()
    }
}

/// A closed box room of six real walls, each its own colour, lit by a
/// point light under the ceiling, with ambient light, and a virtual mirror
/// sphere (albedo 1) at [`SPHERE`]; with `open`, without the wall
/// `x = HI.x` nearest the sphere, as the demo's room is open at its sides.
fn room(open: bool) -> Showcase {
    let mut s = Showcase {
        ambient: Vec3::splat(0.05),
        ..Showcase::default()
    };
    let (lo, size) = (LO.as_vec3(), (HI - LO).as_vec3());
    let (x, y, z) = (size.x * Vec3::X, size.y * Vec3::Y, size.z * Vec3::Z);
    let walls = [
        (lo, x, z, Vec3::new(0.8, 0.8, 0.8)),
        (lo + y, x, z, Vec3::new(0.6, 0.6, 0.7)),
        (lo, y, z, Vec3::new(0.8, 0.2, 0.2)),
        (lo + z, x, y, Vec3::new(0.8, 0.7, 0.2)),
        (lo, x, y, Vec3::new(0.3, 0.3, 0.8)),
        (lo + x, y, z, Vec3::new(0.2, 0.8, 0.2)),
    ];
    let walls = &walls[..if open { 5 } else { 6 }];
    for (i, &(corner, u, v, albedo)) in walls.iter().enumerate() {
        let id = s.add_mesh(quad(corner, u, v));
        s.objects.push(showcase_proto::Object {
            name: format!("wall {i}"),
            mesh: id,
            material: Material::diffuse(albedo),
            kind: ObjectKind::Real,
            transform: showcase_proto::Transform::IDENTITY,
        });
    }
    let id = s.add_mesh(uv_sphere(RADIUS, 48, 24));
    let mut mirror = Material::diffuse(Vec3::ONE);
    mirror.reflective = true;
    s.objects.push(showcase_proto::Object {
        name: "mirror sphere".into(),
        mesh: id,
        material: mirror,
        kind: ObjectKind::Virtual,
        transform: showcase_proto::Transform {
            translation: SPHERE.as_vec3(),
            ..showcase_proto::Transform::IDENTITY
        },
    });
    s.lights = vec![point(Vec3::new(0.1, 0.56, 0.25), 0.4)];
    s
}

/// The room's frame, occluders and the sphere's cube map (`open`: [`room`]).
fn room_map(open: bool) -> Result<(FrameScene, Occluders, CubeMap)> {
    let frame = FrameScene::from_parts(room(open), &[])?;
    let occ = Occluders::new(&frame)?;
    let centres = reflective_centres(&frame);
    ensure!(centres.len() == 1, "{centres:?}");
    ensure!((centres[0].1 - SPHERE).length() < 1e-6, "{centres:?}");
    let map = cube_map_cpu(&frame, &occ, centres[0].0, centres[0].1, RES)?;
    Ok((frame, occ, map))
}

/// Angle (radians) between two directions.
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.normalize().dot(b.normalize()).clamp(-1.0, 1.0).acos()
}

#[test]
fn cube_texels_hold_the_distance_to_the_room() -> Result<()> {
    let (_, _, map) = room_map(false)?;
    for face in 0..CUBE_FACES {
        for (x, y) in [(0, 0), (5, 90), (64, 64), (127, 127), (100, 3)] {
            let d = texel_direction(face, x, y, RES);
            // The nearest wall plane along d (the room is convex).
            let t = (0..3)
                .map(|k| (if d[k] > 0.0 { HI[k] } else { LO[k] } - SPHERE[k]) / d[k])
                .fold(f64::INFINITY, f64::min);
            let got = f64::from(*map.distance[face].get(x, y).unwrap());
            ensure!(
                (got - t).abs() <= 1e-5 * t,
                "face {face} texel {x},{y}: {got} vs {t}"
            );
        }
    }
    Ok(())
}

/// Points `p` on the sphere seen from [`EYE`] and their reflected
/// directions, over a Fibonacci spiral of normals.
fn reflections() -> Vec<(DVec3, DVec3)> {
    let n = 4000;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .filter_map(|i| {
            let z = 1.0 - 2.0 * (f64::from(i) + 0.5) / f64::from(n);
            let rho = (1.0 - z * z).sqrt();
            let phi = golden * f64::from(i);
            let normal = DVec3::new(rho * phi.cos(), rho * phi.sin(), z);
            let p = SPHERE + f64::from(RADIUS) * normal;
            let d = (p - EYE).normalize();
            (d.dot(normal) < 0.0).then(|| (p, reflect(d, normal)))
        })
        .collect()
}

/// Whether the bilinear lookup along `d` reads a texel of `edges` (per
/// face): the sample blends across a silhouette, crease or shadow edge.
fn on_edge(edges: &[Image<bool>], d: DVec3, res: u32) -> bool {
    let (face, c) = world_to_face(d);
    let res = f64::from(res);
    let f = DVec2::new(
        (c.x / c.z * 0.5 + 0.5) * res - 0.5,
        (0.5 - c.y / c.z * 0.5) * res - 0.5,
    )
    .floor();
    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .iter()
        .any(|(dx, dy)| {
            let x = (f.x + dx).clamp(0.0, res - 1.0) as u32;
            let y = (f.y + dy).clamp(0.0, res - 1.0) as u32;
            *edges[face].get(x, y).unwrap_or(&true)
        })
}

#[test]
fn corrected_lookup_lands_on_the_traced_surface_point() -> Result<()> {
    let (frame, occ, map) = room_map(false)?;
    let samples = reflections();
    ensure!(samples.len() > 1500, "{} samples", samples.len());
    // The map resolves directions to one texel: at most 2 / RES radians
    // (a face's centre texel; smaller towards its edges).
    let texel = 2.0 / f64::from(RES);
    // Texels next to a wall crease (two colours) or the sphere's shadow
    // edge: where neighbouring texels' states differ.
    let edges: Vec<Image<bool>> = map.state.iter().map(|s| edge_mask(s, 1, false)).collect();
    let (mut corrected, mut single) = (Vec::new(), Vec::new());
    let (mut exact, mut ours, mut theirs) = (Vec::new(), Vec::new(), Vec::new());
    let mut off_edges = Vec::new();
    for &(p, r) in &samples {
        let hit = occ
            .real_only
            .closest_hit(&Ray::new(p, r), 0.0, f64::INFINITY);
        let Some(hit) = hit else {
            bail!("the closed room has no wall along {r} from {p}");
        };
        let truth = hit.point - map.centre;
        let u = map.reflection_direction(p, r);
        corrected.push(angle(u, truth) / texel);
        single.push(angle(r, truth) / texel);
        exact.push(environment(&frame, &occ, p, r).0);
        ours.push(map.reflection(p, r));
        theirs.push(map.sample(r));
        off_edges.push(!on_edge(&edges, u, RES));
    }
    let (c, s) = (corrected, single);
    let at = |v: &[f64], q: f64| percentile(v, 100.0 * q).unwrap_or(f64::NAN);
    let image = |v: &[Vec3]| Image {
        width: v.len() as u32,
        height: 1,
        data: v.to_vec(),
    };
    let mask = Image {
        width: off_edges.len() as u32,
        height: 1,
        data: off_edges.clone(),
    };
    let rel_ours = relative_rmse(&image(&ours), &image(&exact), None)?;
    let rel_theirs = relative_rmse(&image(&theirs), &image(&exact), None)?;
    let rel_ours_off = relative_rmse(&image(&ours), &image(&exact), Some(&mask))?;
    let n_off = off_edges.iter().filter(|b| **b).count();
    eprintln!(
        "{} samples ({n_off} off edges), {PARALLAX_LINEAR_STEPS} linear + \
         {PARALLAX_SECANT_STEPS} secant steps: angular error in texels: corrected median \
         {:.4} p99 {:.4} max {:.4}, single-centre median {:.2} max {:.2}; radiance rel RMSE: \
         corrected {rel_ours:.4} ({rel_ours_off:.5} off edges), single-centre {rel_theirs:.4}",
        c.len(),
        at(&c, 0.5),
        at(&c, 0.99),
        at(&c, 1.0),
        at(&s, 0.5),
        at(&s, 1.0),
    );
    // The room is close: the single-centre lookup is many texels off.
    ensure!(at(&s, 0.5) > 5.0, "single-centre median {}", at(&s, 0.5));
    // Planar walls: the secant steps land on the stored surface up to the
    // distances' interpolation, well inside the texel the lookup reads
    // (half a texel would read a neighbour's weight wrongly).
    ensure!(at(&c, 1.0) <= 0.5, "corrected max {} texels", at(&c, 1.0));
    // Radiance: as every pass against its reference, at most 1 % off
    // edges (bilinear filtering blends across a crease or shadow edge
    // within one texel), and far below the single-centre lookup overall.
    ensure!(n_off * 10 > samples.len() * 8, "{n_off} samples off edges");
    ensure!(rel_ours_off <= GPU_CPU_REL_RMSE, "off edges {rel_ours_off}");
    ensure!(
        rel_ours * 5.0 < rel_theirs,
        "corrected {rel_ours} vs single-centre {rel_theirs}"
    );
    Ok(())
}

#[test]
fn the_shader_runs_the_same_steps_as_the_cpu_reference() {
    let source = showcase_render::gpu::face_view::SOURCE;
    for line in [
        format!("const PARALLAX_LINEAR_STEPS: u32 = {PARALLAX_LINEAR_STEPS}u;"),
        format!("const PARALLAX_SECANT_STEPS: u32 = {PARALLAX_SECANT_STEPS}u;"),
        format!("const NO_SURFACE_DISTANCE: f32 = {NO_SURFACE_DISTANCE:.1e};"),
        format!("const PARALLAX_SURFACE_TOLERANCE: f32 = {PARALLAX_SURFACE_TOLERANCE:?};"),
    ] {
        assert!(source.contains(&line), "face_view.wgsl lacks `{line}`");
    }
}

#[test]
fn gpu_room_reflections_match_the_cpu_reference() -> Result<()> {
    let (frame, occ, map) = room_map(false)?;
    let face = bench_face(320, 240);
    let cpu = face_image_cpu_with(&frame, &occ, &face, EYE, &[], std::slice::from_ref(&map))?;
    let sphere = frame.showcase.objects.len() as u32 - 1;
    let on_sphere: Vec<bool> = cpu
        .state
        .data
        .iter()
        .map(|s| s.object == Some(sphere))
        .collect();
    let n = on_sphere.iter().filter(|b| **b).count();
    ensure!(n > 3000, "the sphere covers {n} pixels");
    let Some(ctx) = gpu_or_skip("gpu_room_reflections_match_the_cpu_reference")? else {
        return Ok(());
    };
    let mut pipeline = FacePipeline::with_cube_res(&ctx.device, 1024, RES);
    let gpu = pipeline.render(
        &ctx,
        &frame,
        &face,
        &[EYE],
        &[],
        &PassList::for_face(&frame, 0),
    )?;
    // The GPU's distance channel holds the room's distances.
    let cubes = pipeline.read_cube_maps(&ctx)?;
    ensure!(cubes.len() == 1, "{} maps", cubes.len());
    for (f, (texels, distance)) in cubes[0].iter().zip(&map.distance).enumerate() {
        let worst = texels
            .iter()
            .zip(&distance.data)
            .map(|(g, c)| f64::from((g[3] - c).abs() / c))
            .fold(0.0, f64::max);
        ensure!(
            worst <= 1e-3,
            "face {f}: distance off by {worst} (relative)"
        );
    }
    // The reflections: as every pass against its reference, relative RMSE
    // at most 1 % off edges (EDGE_RADIUS_PX of a state change, here also
    // the reflected environment's edges) and at most 0.1 % outliers.
    let g = Image {
        width: face.width,
        height: face.height,
        data: gpu[0].iter().map(|p| Vec3::from_slice(&p[..3])).collect(),
    };
    let edges = edge_mask(&cpu.state, EDGE_RADIUS_PX, false);
    let off = Image {
        width: face.width,
        height: face.height,
        data: (0..on_sphere.len())
            .map(|i| on_sphere[i] && !edges.data[i])
            .collect::<Vec<bool>>(),
    };
    let n_off = off.data.iter().filter(|b| **b).count();
    ensure!(n_off * 4 > n, "{n_off} of {n} sphere pixels off edges");
    let rel = relative_rmse(&g, &cpu.radiance, Some(&off))?;
    let outliers = (0..g.data.len())
        .filter(|&i| off.data[i])
        .filter(|&i| {
            let r = cpu.radiance.data[i];
            (g.data[i] - r).abs().max_element() > 0.01 * r.max_element().max(1e-6)
        })
        .count();
    eprintln!("room sphere: GPU vs CPU rel RMSE {rel:.5} over {n_off} pixels, {outliers} outliers");
    ensure!(rel <= GPU_CPU_REL_RMSE, "rel RMSE {rel}");
    ensure!(
        outliers as f64 <= OFF_EDGE_OUTLIERS * n_off as f64 + 1.0,
        "{outliers} outliers"
    );
    Ok(())
}

#[test]
fn rays_out_of_an_open_room_escape() -> Result<()> {
    let (frame, occ, map) = room_map(true)?;
    let (mut exact, mut ours, mut theirs) = (Vec::new(), Vec::new(), Vec::new());
    let mut escaping = 0;
    let mut black = 0;
    for (p, r) in reflections() {
        let e = environment(&frame, &occ, p, r).0;
        let o = map.reflection(p, r);
        if e == Vec3::ZERO {
            escaping += 1;
            black += usize::from(o == Vec3::ZERO);
        }
        exact.push(e);
        ours.push(o);
        theirs.push(map.sample(r));
    }
    let image = |v: &[Vec3]| Image {
        width: v.len() as u32,
        height: 1,
        data: v.to_vec(),
    };
    let rel_ours = relative_rmse(&image(&ours), &image(&exact), None)?;
    let rel_theirs = relative_rmse(&image(&theirs), &image(&exact), None)?;
    eprintln!(
        "open room: {escaping} of {} rays escape, {black} of them black; rel RMSE corrected \
         {rel_ours:.4}, single-centre {rel_theirs:.4}",
        exact.len()
    );
    ensure!(escaping > 300, "{escaping} rays escape");
    ensure!(
        black * 100 >= escaping * 95,
        "{black} of {escaping} escaping rays black"
    );
    ensure!(
        rel_ours * 5.0 < rel_theirs,
        "corrected {rel_ours} vs single-centre {rel_theirs}"
    );
    Ok(())
}
