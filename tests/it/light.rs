//! Integration tests: light. Ground truth for the light-transport core:
//! watertight ray casting, BVH against brute force, the intensity image
//! I_int of the Cornell box against analytic cos/r^2 and an independent
//! shadow test, visibility without acne or leaks, and no NaN or Inf
//! anywhere. (Lambert's formula is checked in `light::lambert`'s own tests.)

use glam::{DVec2, DVec3, Quat, Vec3};
use proptest::prelude::*;
use showcase_light::ray::intersect_triangle;
use showcase_light::{
    DeviceRays, IntensityLight, ObjectFilter, Ray, SceneGeometry, render_intensity, world_matrix,
};
use showcase_proto::{Material, Mesh, Object, ObjectKind, PinholeDevice, Showcase, Transform};
use std::f64::consts::PI;

mod visibility;

/// A showcase holding `meshes` as objects (name, mesh, kind, transform).
fn showcase(objects: Vec<(&str, Mesh, ObjectKind, Transform)>) -> Showcase {
    let mut s = Showcase::default();
    for (name, mesh, kind, transform) in objects {
        let id = s.add_mesh(mesh);
        s.objects.push(Object {
            name: name.to_string(),
            mesh: id,
            material: Material::diffuse(Vec3::splat(0.5)),
            kind,
            transform,
        });
    }
    s
}

fn real(name: &str, mesh: Mesh) -> (&str, Mesh, ObjectKind, Transform) {
    (name, mesh, ObjectKind::Real, Transform::IDENTITY)
}

/// Objects of an OBJ file (`o` groups, polygons fan-triangulated), enough
/// for the shared data files; a tiny parser so the test needs no loader.
fn load_obj(path: &str) -> anyhow::Result<Vec<(String, Mesh)>> {
    let text = std::fs::read_to_string(path)?;
    let mut positions: Vec<Vec3> = Vec::new();
    let mut groups: Vec<(String, Vec<[u32; 3]>)> = vec![("default".into(), Vec::new())];
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f32> = it.take(3).map(str::parse).collect::<Result<_, _>>()?;
                positions.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("o") => groups.push((it.next().unwrap_or("").to_string(), Vec::new())),
            Some("f") => {
                let idx: Vec<u32> = it
                    .map(|t| {
                        t.split('/')
                            .next()
                            .unwrap_or("")
                            .parse::<u32>()
                            .map(|i| i - 1)
                    })
                    .collect::<Result<_, _>>()?;
                let tris = &mut groups.last_mut().expect("a group").1;
                for k in 1..idx.len() - 1 {
                    tris.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    // Each object keeps only the vertices it uses, reindexed.
    Ok(groups
        .into_iter()
        .filter(|(_, t)| !t.is_empty())
        .map(|(name, tris)| {
            let mut map = std::collections::HashMap::new();
            let mut mesh = Mesh::default();
            for t in tris {
                let t = t.map(|i| {
                    *map.entry(i).or_insert_with(|| {
                        mesh.positions.push(positions[i as usize]);
                        mesh.positions.len() as u32 - 1
                    })
                });
                mesh.triangles.push(t);
            }
            (name, mesh)
        })
        .collect())
}

fn cornell_box() -> Showcase {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/data/cornell-box.obj"
    );
    let objects = load_obj(path).expect("cornell box");
    assert_eq!(objects.len(), 8, "5 walls, 2 blocks and the light");
    let mut s = Showcase::default();
    for (name, mesh) in objects {
        let id = s.add_mesh(mesh);
        s.objects.push(Object {
            name,
            mesh: id,
            material: Material::diffuse(Vec3::splat(0.7)),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
    }
    s
}

/// A unit sphere mesh: an octahedron subdivided `levels` times, with shared
/// (indexed) vertices, counter-clockwise outwards.
fn icosphere(levels: u32) -> Mesh {
    let mut mesh = Mesh {
        positions: vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z],
        triangles: vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ],
        ..Mesh::default()
    };
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut tris = Vec::new();
        for [a, b, c] in mesh.triangles.clone() {
            let mut m = |i: u32, j: u32| {
                *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    let p = (mesh.positions[i as usize] + mesh.positions[j as usize]).normalize();
                    mesh.positions.push(p);
                    mesh.positions.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            tris.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        mesh.triangles = tris;
    }
    mesh
}

/// A flat `n x n` grid of quads on `y = 0` over `[0, 1]^2`, two triangles each.
fn grid(n: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for j in 0..=n {
        for i in 0..=n {
            mesh.positions
                .push(Vec3::new(i as f32 / n as f32, 0.0, j as f32 / n as f32));
        }
    }
    let v = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            // Normal +y: counter-clockwise seen from above.
            mesh.triangles.push([v(i, j), v(i, j + 1), v(i + 1, j + 1)]);
            mesh.triangles.push([v(i, j), v(i + 1, j + 1), v(i + 1, j)]);
        }
    }
    mesh
}

#[test]
fn rays_through_shared_edges_and_vertices_of_a_grid_are_never_lost() {
    let n = 16;
    let geometry =
        SceneGeometry::build(&showcase(vec![real("grid", grid(n))]), &ObjectFilter::All).unwrap();
    let mut rng_state = 0x9E3779B97F4A7C15u64;
    let mut next = || {
        rng_state ^= rng_state << 13;
        rng_state ^= rng_state >> 7;
        rng_state ^= rng_state << 17;
        (rng_state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut rays = 0;
    // Targets on every inner grid line, diagonal and vertex: shared edges
    // (the outer boundary is not shared, so rounding may lose it there).
    for j in 1..4 * n {
        for i in 1..4 * n {
            let target = DVec3::new(i as f64 / (4 * n) as f64, 0.0, j as f64 / (4 * n) as f64);
            for _ in 0..2 {
                let origin =
                    DVec3::new(next() * 3.0 - 1.0, 0.05 + next() * 2.0, next() * 3.0 - 1.0);
                let ray = Ray::new(origin, target - origin);
                let hit = geometry.closest_hit(&ray, 0.0, f64::INFINITY);
                let hit = hit.unwrap_or_else(|| panic!("lost the ray from {origin} to {target}"));
                assert!((hit.point - target).length() < 1e-9);
                assert!((hit.t - 1.0).abs() < 1e-9);
                assert!(geometry.occluded(origin, target - origin, 1.0 + 1e-9));
                rays += 1;
            }
        }
    }
    assert_eq!(rays, 2 * (4 * n - 1).pow(2) as usize);
}

#[test]
fn every_ray_from_inside_a_closed_mesh_hits_it() {
    let transform = Transform {
        translation: Vec3::new(0.3, 1.2, -0.4),
        rotation: Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 0.7),
        scale: Vec3::new(0.2, 0.35, 0.27),
    };
    let sphere = icosphere(4);
    let s = showcase(vec![(
        "sphere",
        sphere.clone(),
        ObjectKind::Real,
        transform,
    )]);
    let geometry = SceneGeometry::build(&s, &ObjectFilter::Real).unwrap();
    let model = world_matrix(&transform).unwrap();
    let centre = model.transform_point3(DVec3::ZERO);
    let mut lost = 0;
    // Aim at every vertex and edge midpoint (where triangles meet) from
    // interior points.
    let mut targets: Vec<DVec3> = sphere
        .positions
        .iter()
        .map(|p| model.transform_point3(p.as_dvec3()))
        .collect();
    for t in &sphere.triangles {
        for k in 0..3 {
            let (a, b) = (
                sphere.positions[t[k] as usize],
                sphere.positions[t[(k + 1) % 3] as usize],
            );
            targets.push(model.transform_point3((0.5 * (a + b)).as_dvec3()));
        }
    }
    for (i, target) in targets.iter().enumerate() {
        for origin in [
            centre,
            centre + 0.3 * (model.transform_point3(DVec3::new(0.1, -0.2, 0.15)) - centre),
        ] {
            let ray = Ray::new(origin, *target - origin);
            match geometry.closest_hit(&ray, 0.0, f64::INFINITY) {
                Some(h) => {
                    assert!(h.t.is_finite() && h.point.is_finite() && h.shading_normal.is_finite())
                }
                None => lost += 1,
            }
            // Also slightly past the target, so t is not exactly 1.
            let ray = Ray::new(origin, (*target - origin) * (1.0 + i as f64 * 1e-3));
            if geometry.closest_hit(&ray, 0.0, f64::INFINITY).is_none() {
                lost += 1;
            }
        }
    }
    assert_eq!(lost, 0, "rays escaped a closed mesh");
    // Closed: a ray from outside enters and leaves it (front then back face).
    let outside = centre + DVec3::new(5.0, 0.1, 0.2);
    let ray = Ray::new(outside, centre - outside);
    let enter = geometry.closest_hit(&ray, 0.0, f64::INFINITY).unwrap();
    assert!(enter.front_face);
    let exit = geometry.closest_hit(&ray, enter.t, f64::INFINITY).unwrap();
    assert!(!exit.front_face && exit.t > enter.t);
}

#[test]
fn degenerate_triangles_are_never_hit_and_never_nan() {
    let p = Vec3::new(0.5, 0.0, 0.5);
    let mesh = Mesh {
        positions: vec![
            p,
            p,
            p,
            Vec3::ZERO,
            Vec3::X,
            Vec3::X * 2.0,
            Vec3::new(0.0, 1.0, 0.0),
        ],
        // A point triangle, a collinear triangle, and a triangle reusing a vertex.
        triangles: vec![[0, 1, 2], [3, 4, 5], [3, 3, 6]],
        ..Mesh::default()
    };
    let geometry = SceneGeometry::build(
        &showcase(vec![real("degenerate", mesh)]),
        &ObjectFilter::All,
    )
    .unwrap();
    assert_eq!(geometry.triangle_count(), 3);
    assert_eq!(geometry.bvh().usable_triangles(), 0);
    for target in [
        p.as_dvec3(),
        DVec3::X,
        DVec3::new(1.5, 0.0, 0.0),
        DVec3::new(0.0, 0.5, 0.0),
    ] {
        for origin in [
            DVec3::new(0.2, 1.0, 0.3),
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
        ] {
            let ray = Ray::new(origin, target - origin);
            assert!(geometry.closest_hit(&ray, 0.0, f64::INFINITY).is_none());
            assert!(!geometry.occluded(origin, target - origin, 10.0));
        }
    }
}

#[test]
fn bad_scenes_are_errors() {
    let mut s = showcase(vec![real("quad", grid(1))]);
    let mut bad = s.clone();
    bad.meshes.clear();
    assert!(SceneGeometry::build(&bad, &ObjectFilter::All).is_err());
    bad = s.clone();
    bad.meshes[0].mesh.triangles.push([0, 1, 99]);
    assert!(SceneGeometry::build(&bad, &ObjectFilter::All).is_err());
    s.objects[0].transform.scale = Vec3::new(1.0, 0.0, 1.0);
    assert!(SceneGeometry::build(&s, &ObjectFilter::All).is_err());
    s.objects[0].transform.scale = Vec3::ONE;
    s.objects[0].transform.translation.x = f32::NAN;
    assert!(SceneGeometry::build(&s, &ObjectFilter::All).is_err());
    // Filtered-out objects are not even looked at.
    assert!(SceneGeometry::build(&s, &ObjectFilter::Virtual).is_ok());
}

fn arb_vec(range: f32) -> impl Strategy<Value = Vec3> {
    (-range..range, -range..range, -range..range).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn arb_soup() -> impl Strategy<Value = Mesh> {
    prop::collection::vec((arb_vec(1.0), arb_vec(0.3), arb_vec(0.3)), 1..80).prop_map(|tris| {
        let mut mesh = Mesh::default();
        for (a, db, dc) in tris {
            let base = mesh.positions.len() as u32;
            mesh.positions.extend([a, a + db, a + dc]);
            mesh.triangles.push([base, base + 1, base + 2]);
        }
        mesh
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn bvh_agrees_with_brute_force(
        soup in arb_soup(),
        rays in prop::collection::vec((arb_vec(2.0), arb_vec(1.0)), 1..40),
        angle in 0.0f32..6.0,
    ) {
        let transform = Transform {
            translation: Vec3::new(0.1, -0.2, 0.3),
            rotation: Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), angle),
            scale: Vec3::new(1.0, 0.5, 2.0),
        };
        let s = showcase(vec![("soup", soup, ObjectKind::Virtual, transform)]);
        let geometry = SceneGeometry::build(&s, &ObjectFilter::Virtual).unwrap();
        let tris = geometry.bvh().triangles();
        for (o, d) in rays {
            let ray = Ray::new(o.as_dvec3(), d.as_dvec3());
            let mut best: Option<(usize, f64)> = None;
            for (i, t) in tris.iter().enumerate() {
                let t_max = best.map_or(f64::INFINITY, |b| b.1);
                if let Some(h) = intersect_triangle(&ray, *t, 0.0, t_max) {
                    best = Some((i, h.t));
                }
            }
            let got = geometry.closest_hit(&ray, 0.0, f64::INFINITY);
            prop_assert_eq!(got.map(|h| h.t), best.map(|b| b.1));
            if let (Some(h), Some((i, _))) = (got, best) {
                prop_assert!(h.t.is_finite() && h.point.is_finite() && h.geometric_normal.is_finite());
                // Ties at exactly the same t may name either triangle.
                if h.triangle as usize != i {
                    let other = intersect_triangle(&ray, tris[h.triangle as usize], 0.0, f64::INFINITY);
                    prop_assert_eq!(other.map(|x| x.t), Some(h.t));
                }
            }
            prop_assert_eq!(geometry.occluded(ray.origin, ray.direction, f64::INFINITY), best.is_some());
            if let Some((_, t)) = best {
                // Nothing lies before the closest hit.
                prop_assert!(!geometry.occluded(ray.origin, ray.direction, t * (1.0 - 1e-9)));
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Degenerate geometry, zero light, lights on surfaces and grazing
    /// angles never produce NaN or Inf.
    #[test]
    fn intensity_is_finite_for_any_scene(
        soup in arb_soup(),
        eye in arb_vec(3.0),
        target in arb_vec(1.0),
        light_pos in arb_vec(1.5),
        light_on_vertex in any::<bool>(),
        color in prop_oneof![Just(Vec3::ZERO), arb_vec(10.0).prop_map(|v| v.abs())],
        fov in 0.5f64..175.0,
        collapse in any::<bool>(),
    ) {
        let mut soup = soup;
        if collapse {
            // Make every other triangle degenerate.
            for (i, t) in soup.triangles.iter_mut().enumerate() {
                if i % 2 == 0 { t[2] = t[1]; }
            }
        }
        let light_pos = if light_on_vertex { soup.positions[0] } else { light_pos };
        let s = showcase(vec![real("soup", soup)]);
        let geometry = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
        let camera = PinholeDevice::look_at(eye.as_dvec3(), target.as_dvec3(), DVec3::Y, fov, 12, 9);
        let Ok(rays) = DeviceRays::new(&camera) else { return Ok(()) };
        for light in [
            IntensityLight::point(light_pos.as_dvec3(), color.as_dvec3()),
            IntensityLight::projector(&camera, color, 1.0).unwrap(),
        ] {
            let img = render_intensity(&geometry, &rays, &light, &ObjectFilter::All);
            for (v, s) in img.intensity.data.iter().zip(&img.surface.data) {
                prop_assert!(v.is_finite() && v.min_element() >= 0.0);
                if color == Vec3::ZERO { prop_assert_eq!(*v, Vec3::ZERO); }
                if let Some(s) = s {
                    prop_assert!(s.point.is_finite() && s.normal.is_finite() && s.phi.is_finite());
                    prop_assert!((0.0..=PI / 2.0 + 1e-9).contains(&s.phi));
                }
            }
        }
    }
}
