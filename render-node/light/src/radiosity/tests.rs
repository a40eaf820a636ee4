//! Radiosity checks against closed forms: energy balance in a closed box,
//! parallel-plate form factors, direct light against Lambert's polygon
//! formula, incremental updates, and augmented radiosity on a plane.

use super::*;
use crate::{ObjectFilter, polygon_irradiance};
use glam::{DVec2, DVec3, Vec3};
use showcase_proto::{
    Material, Mesh, Object, ObjectKind, PinholeDevice, Projector, ProjectorResponse, Showcase,
    Transform,
};
use std::f64::consts::PI;

/// Add a quad `corner, corner + u, corner + u + v, corner + v` facing
/// `u x v`.
pub(super) fn add_quad(
    s: &mut Showcase,
    name: &str,
    c: Vec3,
    u: Vec3,
    v: Vec3,
    m: Material,
    kind: ObjectKind,
) {
    quads_object(s, name, &[(c, u, v)], m, kind);
}

/// The six outward faces, as [`quads_object`] quads, of the box with
/// corner `c` and edges `a.x`, `a.y`, `a.z` along the axes.
pub(super) fn cuboid(c: Vec3, a: Vec3) -> [(Vec3, Vec3, Vec3); 6] {
    let (ax, ay, az) = (Vec3::X * a.x, Vec3::Y * a.y, Vec3::Z * a.z);
    [
        (c, ax, az),
        (c + ay, az, ax),
        (c, az, ay),
        (c + ax, ay, az),
        (c, ay, ax),
        (c + az, ax, ay),
    ]
}

/// Add one object made of quads `(corner, u, v)` facing `u x v`.
pub(super) fn quads_object(
    s: &mut Showcase,
    name: &str,
    quads: &[(Vec3, Vec3, Vec3)],
    m: Material,
    kind: ObjectKind,
) {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for &(c, u, v) in quads {
        let k = positions.len() as u32;
        positions.extend([c, c + u, c + u + v, c + v]);
        triangles.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
    }
    let id = s.add_mesh(Mesh {
        positions,
        normals: vec![],
        uvs: vec![],
        triangles,
    });
    s.objects.push(Object {
        name: name.into(),
        mesh: id,
        material: m,
        kind,
        transform: Transform::IDENTITY,
    });
}

fn emitter(radiance: f32) -> Material {
    let mut m = Material::diffuse(Vec3::ZERO);
    m.emission = Vec3::splat(radiance);
    m
}

/// A closed unit cube with inward faces; the top face emits `radiance`,
/// every face has albedo `rho`.
pub(super) fn closed_box(rho: f32, radiance: f32) -> Showcase {
    let mut s = Showcase::default();
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    let mut top = emitter(radiance);
    top.albedo = Vec3::splat(rho);
    let wall = Material::diffuse(Vec3::splat(rho));
    let k = ObjectKind::Real;
    add_quad(&mut s, "floor", Vec3::ZERO, z, x, wall.clone(), k);
    add_quad(&mut s, "top", y, x, z, top, k);
    add_quad(&mut s, "left", Vec3::ZERO, y, z, wall.clone(), k);
    add_quad(&mut s, "right", x, z, y, wall.clone(), k);
    add_quad(&mut s, "back", z, y, x, wall.clone(), k);
    add_quad(&mut s, "front", Vec3::ZERO, x, y, wall, k);
    s
}

pub(super) fn mesh_of(s: &Showcase, area: f64, depth: u32) -> (RadiosityMesh, SceneGeometry) {
    let g = SceneGeometry::build(s, &ObjectFilter::All).unwrap();
    let m = RadiosityMesh::build(
        s,
        &g,
        &MeshOptions {
            max_patch_area: area,
            element_depth: depth,
            ..MeshOptions::default()
        },
    )
    .unwrap();
    (m, g)
}

pub(super) fn options(method: FormFactorMethod, hemicube: u32, threshold: f64) -> SolveOptions {
    SolveOptions {
        hemicube,
        threshold,
        method,
        ..SolveOptions::default()
    }
}

#[test]
fn closed_box_balances_emission_against_the_closed_form() {
    // In a closed enclosure of uniform rho every shot reflects rho of its
    // power, so sum(B A) = Phi_emit / (1 - rho) exactly (with the ambient
    // term standing in for what is still unshot).
    for (rho, method) in [
        (0.5, FormFactorMethod::HemiCube),
        (0.8, FormFactorMethod::Hybrid),
        (0.99, FormFactorMethod::HemiCube),
    ] {
        let s = closed_box(rho as f32, 1.0);
        let (m, g) = mesh_of(&s, 0.13, 0);
        let mut o = options(method, 128, 1e-3);
        o.max_shots = 400;
        let mut sh = Shooter::new(&m, &g, None, &o).unwrap();
        sh.add_surface_emission();
        let phi = PI; // pi * L over one square metre
        let mut last = f64::INFINITY;
        while sh.shots() < o.max_shots && sh.unshot_fraction() > o.threshold {
            assert!(sh.step());
            let u = sh.unshot_power();
            assert!(u < last, "unshot power must fall: {u} after {last}");
            last = u;
        }
        assert!(
            sh.radiosity()
                .iter()
                .all(|b| b.is_finite() && b.min_element() >= 0.0)
        );
        let total: f64 = sh
            .display_radiosity()
            .iter()
            .zip(&m.elements)
            .map(|(b, e)| b.x * e.area)
            .sum();
        let exact = phi / (1.0 - rho);
        // Tolerance: the hemi-cube's sum of delta form factors is 1 only to
        // about 1e-4, amplified by 1 / (1 - rho).
        let tol = 2e-3 + 3e-4 * rho / (1.0 - rho);
        assert!(
            (total - exact).abs() < tol * exact,
            "rho {rho}: {total} vs {exact}"
        );
    }
}

/// Form factor between two parallel, directly opposed `a x b` rectangles
/// at distance `c` (Howell's catalogue, C-11).
fn parallel_rectangles(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (x2, y2) = (x * x, y * y);
    2.0 / (PI * x * y)
        * (((1.0 + x2) * (1.0 + y2) / (1.0 + x2 + y2)).sqrt().ln()
            + x * (1.0 + y2).sqrt() * (x / (1.0 + y2).sqrt()).atan()
            + y * (1.0 + x2).sqrt() * (y / (1.0 + x2).sqrt()).atan()
            - x * x.atan()
            - y * y.atan())
}

#[test]
fn parallel_plates_receive_the_analytic_form_factor() {
    assert!((parallel_rectangles(1.0, 1.0, 1.0) - 0.1998).abs() < 1e-4);
    for (gap, method) in [
        (1.0, FormFactorMethod::HemiCube),
        (1.0, FormFactorMethod::RayCast),
        (0.2, FormFactorMethod::Hybrid),
        (0.2, FormFactorMethod::RayCast),
    ] {
        let mut s = Showcase::default();
        let k = ObjectKind::Real;
        add_quad(
            &mut s,
            "floor",
            Vec3::ZERO,
            Vec3::Z,
            Vec3::X,
            Material::diffuse(Vec3::splat(0.5)),
            k,
        );
        add_quad(
            &mut s,
            "light",
            Vec3::new(0.0, gap, 0.0),
            Vec3::X,
            Vec3::Z,
            emitter(1.0),
            k,
        );
        let (m, g) = mesh_of(&s, 0.02, 1);
        let sol = solve(&m, &g, &[], &options(method, 128, 1e-6)).unwrap();
        let received: f64 = m
            .elements
            .iter()
            .zip(&sol.radiosity)
            .filter(|(e, _)| e.object == 0)
            .map(|(e, b)| b.x * e.area)
            .sum();
        let exact = 0.5 * PI * parallel_rectangles(1.0, 1.0, gap as f64);
        assert!(
            (received - exact).abs() < 0.01 * exact,
            "{method:?} gap {gap}: {received} vs {exact}"
        );
    }
}

#[test]
fn direct_light_matches_lambert_at_interpolated_points() {
    // A small square emitter over a floor: the floor's B is rho * E_direct,
    // compared at points between the element centres with the closed form.
    let mut s = Showcase::default();
    let k = ObjectKind::Real;
    add_quad(
        &mut s,
        "floor",
        Vec3::ZERO,
        Vec3::Z,
        Vec3::X,
        Material::diffuse(Vec3::splat(0.6)),
        k,
    );
    let (c, u, v) = (
        Vec3::new(0.4, 0.5, 0.4),
        Vec3::new(0.2, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.2),
    );
    add_quad(&mut s, "light", c, u, v, emitter(10.0), k);
    let (m, g) = mesh_of(&s, 0.005, 1);
    let polygon = [c, c + u, c + u + v, c + v].map(|p| p.as_dvec3());
    for method in [FormFactorMethod::Hybrid, FormFactorMethod::HemiCube] {
        let sol = solve(&m, &g, &[], &options(method, 256, 1e-4)).unwrap();
        let values = m.vertex_values(&sol.radiosity);
        let floor = m.primitive_of(0, 0).unwrap();
        let prim = &m.primitives[floor as usize];
        for b in [
            DVec2::new(0.3, 0.3),
            DVec2::new(0.1, 0.6),
            DVec2::new(0.45, 0.2),
        ] {
            let x = prim.point(b);
            let exact = 0.6 * polygon_irradiance(x, DVec3::Y, &polygon, 10.0).unwrap();
            let got = m.interpolate(floor, b, &values).unwrap().x;
            assert!(
                (got - exact).abs() < 0.03 * exact,
                "{method:?} at {x}: {got} vs {exact}"
            );
        }
    }
}

#[test]
fn refinement_splits_only_where_radiosity_jumps() {
    let mut s = Showcase::default();
    add_quad(
        &mut s,
        "floor",
        Vec3::ZERO,
        Vec3::Z,
        Vec3::X,
        Material::diffuse(Vec3::ONE),
        ObjectKind::Real,
    );
    let (mut m, _) = mesh_of(&s, 0.02, 1);
    let step = |m: &RadiosityMesh| -> Vec<DVec3> {
        m.elements
            .iter()
            .map(|e| DVec3::splat(if e.center.x < 0.5 { 1.0 } else { 0.0 }))
            .collect()
    };
    let uniform = vec![DVec3::ONE; m.elements.len()];
    let o = RefineOptions::default();
    assert_eq!(refine(&mut m, &uniform, &o), 0);
    let before = m.elements.len();
    let size = m.elements.iter().map(|e| e.area).fold(0.0, f64::max).sqrt() * 2.0;
    let b = step(&m);
    let near: Vec<bool> = m
        .elements
        .iter()
        .map(|e| (e.center.x - 0.5).abs() < size)
        .collect();
    let split = refine(&mut m, &b, &o);
    assert!(split > 0);
    assert_eq!(m.elements.len(), before + 3 * split);
    // Every element that was split was near the edge: elements far from it
    // keep their original area.
    let original = 1.0 / before as f64;
    for e in &m.elements {
        if (e.area - original).abs() > 1e-12 {
            assert!(
                (e.center.x - 0.5).abs() < size,
                "split far from the edge: {}",
                e.center
            );
        }
    }
    assert!(near.iter().any(|n| *n));
    assert!((m.total_area() - 1.0).abs() < 1e-12);
}

#[test]
fn incremental_update_matches_a_fresh_solve_after_a_light_moves() {
    let s = closed_box(0.6, 0.5);
    let (m, g) = mesh_of(&s, 0.13, 1);
    let o = options(FormFactorMethod::RayCast, 64, 1e-4);
    let light = |x: f32| Light::Point {
        position: Vec3::new(x, 0.5, 0.5),
        intensity: Vec3::splat(0.3),
    };
    let mut sh = Shooter::new(&m, &g, None, &o).unwrap();
    sh.add_surface_emission();
    sh.add_light(&light(0.3), 1.0);
    sh.run();
    let limit = o.threshold * sh.injected_power();
    sh.add_light(&light(0.3), -1.0);
    sh.add_light(&light(0.7), 1.0);
    let incremental_shots = sh.run_to_power(limit);
    let fresh = solve(&m, &g, &[light(0.7)], &o).unwrap();
    let err = relative_error(&m, sh.radiosity(), &m, &fresh.radiosity, 4).unwrap();
    assert!(err < 0.01, "incremental vs fresh: {err}");
    assert!(
        incremental_shots < fresh.shots,
        "{incremental_shots} vs {}",
        fresh.shots
    );
}

#[test]
fn augmented_radiosity_on_a_lone_plane_gives_the_exact_projector_drive() {
    // One real floor (no interreflection: B1 = B0 = B2 = B3), a virtual
    // point light above it, and a projector at the light's position with
    // twice its intensity: the drive is 0.5 wherever the floor is lit.
    let mut s = Showcase::default();
    add_quad(
        &mut s,
        "floor",
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, 0.0),
        Material::diffuse(Vec3::new(0.7, 0.5, 0.3)),
        ObjectKind::Real,
    );
    let pos = Vec3::new(0.0, 1.0, 0.0);
    let lights = [Light::Point {
        position: pos,
        intensity: Vec3::splat(2.0),
    }];
    let (m, all) = mesh_of(&s, 0.05, 2);
    let real = SceneGeometry::build(&s, &ObjectFilter::Real).unwrap();
    let a = augmented_radiosity(
        &m,
        &all,
        &real,
        &lights,
        &options(FormFactorMethod::RayCast, 16, 1e-4),
    )
    .unwrap();
    assert_eq!(a.clipped_elements, 0);
    assert!(a.b3_b0_deviation_rgb.iter().all(|d| *d < 1e-9));
    let device = PinholeDevice::look_at(pos.as_dvec3(), DVec3::ZERO, DVec3::Z, 40.0, 64, 48);
    let projector = Projector {
        name: "p".into(),
        device,
        response: ProjectorResponse {
            eta: 4.0,
            black_level: 0.0,
            ..ProjectorResponse::default()
        },
    };
    let b2 = m.vertex_values(&a.b2);
    let map = irradiance_map(&m, &real, &b2, &[projector], 0).unwrap();
    assert_eq!(map.valid, 64 * 48);
    assert_eq!(map.clipped, 0);
    let worst = map
        .drive
        .data
        .iter()
        .map(|d| (d.as_dvec3() - DVec3::splat(0.5)).abs().max_element())
        .fold(0.0, f64::max);
    assert!(worst < 0.02, "drive off by {worst}");
}

#[test]
fn cached_form_factor_rows_give_the_same_solve_as_recomputed_ones() {
    let s = closed_box(0.7, 1.0);
    let (m, g) = mesh_of(&s, 0.13, 1);
    for method in [FormFactorMethod::RayCast, FormFactorMethod::Hybrid] {
        let cached = options(method, 32, 1e-3);
        let uncached = SolveOptions {
            form_factor_cache_bytes: 0,
            ..cached.clone()
        };
        let run = |o: &SolveOptions| {
            let mut sh = Shooter::new(&m, &g, None, o).unwrap();
            sh.add_surface_emission();
            sh.run();
            (sh.radiosity().to_vec(), sh.shots(), sh.rows_computed())
        };
        let (a, shots_a, rows_a) = run(&cached);
        let (b, shots_b, rows_b) = run(&uncached);
        assert_eq!(a, b, "{method:?}");
        assert_eq!(shots_a, shots_b);
        // Without the cache every shot computes its row; with it each
        // patch computes its row once, however often it shoots.
        assert_eq!(rows_b, shots_b);
        assert!(
            rows_a <= m.patches.len() && rows_a < shots_a,
            "{rows_a} {shots_a}"
        );
    }
}

/// A closed unit cube whose six inward faces all emit radiance 1 with
/// albedo `rho`: B = pi / (1 - rho) everywhere (the furnace).
pub(super) fn furnace(rho: f32) -> Showcase {
    let mut s = closed_box(rho, 1.0);
    let mut m = emitter(1.0);
    m.albedo = Vec3::splat(rho);
    for o in &mut s.objects {
        o.material = m.clone();
    }
    s
}

#[test]
fn gathered_vertices_match_the_furnace_closed_form_at_corners_too() {
    let rho = 0.7;
    let s = furnace(rho as f32);
    let (m, g) = mesh_of(&s, 0.13, 0);
    let mut sh = Shooter::new(&m, &g, None, &options(FormFactorMethod::RayCast, 32, 1e-4)).unwrap();
    sh.add_surface_emission();
    sh.run();
    let (target, _) = mesh_of(&s, 0.13, 2);
    let v = gather_vertices(
        &m,
        &sh.display_radiosity(),
        &target,
        &g,
        &[],
        &GatherOptions::default(),
    );
    let exact = PI / (1.0 - rho);
    assert_eq!(v.len(), target.vertices.len());
    for (b, vertex) in v.iter().zip(&target.vertices) {
        assert!(
            (b.x - exact).abs() < 5e-3 * exact,
            "{}: {} vs {exact}",
            vertex.position,
            b.x
        );
    }
}

/// A 1 m floor at y = 0 facing up under a 0.2 m square emitter at
/// `height`, facing down, and optionally a closed box (no bottom) on the
/// floor.
pub(super) fn lamp_over_floor(height: f32, with_box: bool) -> Showcase {
    let mut s = Showcase::default();
    let k = ObjectKind::Real;
    let white = Material::diffuse(Vec3::splat(0.5));
    add_quad(
        &mut s,
        "floor",
        Vec3::ZERO,
        Vec3::Z,
        Vec3::X,
        white.clone(),
        k,
    );
    let c = Vec3::new(0.4, height, 0.4);
    let lamp = emitter(2.0);
    add_quad(&mut s, "lamp", c, Vec3::X * 0.2, Vec3::Z * 0.2, lamp, k);
    if with_box {
        // Outward faces of a 0.3 m cube standing at (0.1, 0, 0.1).
        let (o, a) = (Vec3::new(0.1, 0.0, 0.1), 0.3);
        let (x, y, z) = (Vec3::X * a, Vec3::Y * a, Vec3::Z * a);
        add_quad(&mut s, "top", o + y, z, x, white.clone(), k);
        add_quad(&mut s, "side_a", o, y, x, white.clone(), k);
        add_quad(&mut s, "side_b", o + z, x, y, white.clone(), k);
        add_quad(&mut s, "side_c", o, z, y, white.clone(), k);
        add_quad(&mut s, "side_d", o + x, y, z, white, k);
    }
    s
}

#[test]
fn gathered_direct_light_matches_lambert_at_every_vertex() {
    let s = lamp_over_floor(0.5, false);
    let (m, g) = mesh_of(&s, 0.05, 0);
    let (target, _) = mesh_of(&s, 0.05, 2);
    let emission: Vec<DVec3> = m.elements.iter().map(|e| e.emission).collect();
    let v = VertexGather::build(&m, &target, &g, &GatherOptions::default(), None).apply(
        &m,
        &emission,
        &target,
        &g,
        &[],
    );
    let lamp = [
        DVec3::new(0.4, 0.5, 0.4),
        DVec3::new(0.6, 0.5, 0.4),
        DVec3::new(0.6, 0.5, 0.6),
        DVec3::new(0.4, 0.5, 0.6),
    ];
    let mut checked = 0;
    for (b, vertex) in v.iter().zip(&target.vertices) {
        if vertex.normal.y < 0.9 {
            continue;
        }
        let exact = 0.5 * polygon_irradiance(vertex.position, DVec3::Y, &lamp, 2.0).unwrap();
        // The gather point sits a hundredth of an element off the vertex.
        assert!(
            (b.x - exact).abs() < 2e-3 * exact + 1e-9,
            "{}: {} vs {exact}",
            vertex.position,
            b.x
        );
        checked += 1;
    }
    assert!(checked > 100, "{checked}");
}

#[test]
fn hidden_vertices_under_a_box_take_their_visible_neighbours() {
    let s = lamp_over_floor(0.8, true);
    let (m, g) = mesh_of(&s, 0.02, 0);
    let mut sh = Shooter::new(&m, &g, None, &options(FormFactorMethod::RayCast, 32, 1e-3)).unwrap();
    sh.add_surface_emission();
    sh.run();
    let (target, _) = mesh_of(&s, 0.02, 1);
    let gather = VertexGather::build(&m, &target, &g, &GatherOptions::default(), None);
    let v = gather.apply(&m, &sh.display_radiosity(), &target, &g, &[]);
    let inside =
        |p: DVec3| p.y.abs() < 1e-9 && (0.11..0.39).contains(&p.x) && (0.11..0.39).contains(&p.z);
    let hidden: Vec<usize> = (0..target.vertices.len())
        .filter(|&i| inside(target.vertices[i].position))
        .collect();
    assert!(!hidden.is_empty());
    assert!(gather.hidden_count() >= hidden.len());
    let floor_visible: Vec<f64> = (0..target.vertices.len())
        .filter(|&i| {
            let p = target.vertices[i].position;
            p.y.abs() < 1e-9 && target.vertices[i].normal.y > 0.9 && !inside(p)
        })
        .map(|i| v[i].x)
        .collect();
    let (lo, hi) = floor_visible
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), x| (lo.min(*x), hi.max(*x)));
    assert!(lo > 0.0);
    for i in hidden {
        assert!(
            v[i].x >= lo && v[i].x <= hi,
            "{}: {}",
            target.vertices[i].position,
            v[i].x
        );
    }
    assert!(v.iter().all(|b| b.is_finite() && b.min_element() >= 0.0));
}

#[test]
fn progress_is_told_every_shot_in_order() {
    use std::sync::{Arc, Mutex};
    let s = closed_box(0.8, 1.0);
    let (m, g) = mesh_of(&s, 0.13, 0);
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = seen.clone();
    let mut o = options(FormFactorMethod::Hybrid, 64, 1e-2);
    o.progress = ShotProgress::new(move |p| sink.lock().unwrap().push(p));
    let solution = super::solve(&m, &g, &[], &o).unwrap();
    let seen = seen.lock().unwrap();
    assert!(solution.shots > 1, "{} shots", solution.shots);
    // One call per shot, counting 1, 2, 3, ..., the last at the solve's
    // end, with the unshot fraction the convergence curve records.
    let shots: Vec<usize> = seen.iter().map(|p| p.shots).collect();
    assert_eq!(shots, (1..=solution.shots).collect::<Vec<_>>());
    assert_eq!(&seen[..], &solution.convergence[..]);
    assert!(seen.last().unwrap().unshot_fraction < o.threshold);
}
