//! The complete view against what must hold whatever the noise: the same
//! light from a projector and from a virtual lamp gives the same image,
//! and the irradiance cache agrees with brute-force path tracing.

use super::*;
use crate::metrics::relative_rmse;
use showcase_proto::{
    Light, LightSource, Material, Mesh, Object, ObjectKind, Projector, ProjectorResponse, Showcase,
    Transform,
};

/// A 1 m real floor (y = 0) and a real wall at x = -0.3 facing +x, both
/// grey, so light bounces between them.
fn corner() -> Showcase {
    let mut s = Showcase::default();
    let quad = |s: &mut Showcase, name: &str, q: [Vec3; 4]| {
        let mesh = s.add_mesh(Mesh {
            positions: q.to_vec(),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        });
        s.objects.push(Object {
            name: name.into(),
            mesh,
            material: Material::diffuse(Vec3::splat(0.6)),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
    };
    quad(
        &mut s,
        "floor",
        [
            Vec3::new(-0.5, 0.0, -0.5),
            Vec3::new(-0.5, 0.0, 0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(0.5, 0.0, -0.5),
        ],
    );
    quad(
        &mut s,
        "wall",
        [
            Vec3::new(-0.3, 0.0, -0.4),
            Vec3::new(-0.3, 0.4, -0.4),
            Vec3::new(-0.3, 0.4, 0.4),
            Vec3::new(-0.3, 0.0, 0.4),
        ],
    );
    s
}

/// A projector 1.2 m above the origin looking down, wide enough to cover
/// the whole corner, with a linear response of 1 W/sr at value 1.
fn projector() -> Projector {
    let device = PinholeDevice::look_at(
        DVec3::new(0.0, 1.2, 0.0),
        DVec3::ZERO,
        DVec3::Z,
        100.0,
        64,
        64,
    );
    Projector {
        name: "p".into(),
        device,
        response: ProjectorResponse {
            gamma: 1.0,
            eta: 1.0,
            black_level: 0.0,
            wheel_segments: Vec::new(),
            wheel_period_s: 0.0,
            photometry: None,
        },
    }
}

fn camera() -> PinholeDevice {
    PinholeDevice::look_at(
        DVec3::new(0.6, 0.8, 0.8),
        DVec3::new(-0.1, 0.1, 0.0),
        DVec3::Y,
        60.0,
        32,
        24,
    )
}

/// The virtual lamp where the projector is, as bright as its pixels.
fn lamp(value: f32) -> LightSource {
    LightSource {
        name: "lamp".into(),
        light: Light::Point {
            position: Vec3::new(0.0, 1.2, 0.0),
            intensity: Vec3::splat(value),
        },
    }
}

#[test]
fn a_projector_lighting_like_the_lamp_sees_the_target_exactly() {
    // Every point the camera sees is inside the projector's image, so the
    // projector showing 0.5 everywhere is the lamp of 0.5 W/sr: both
    // worlds are the same physics, traced with the same random numbers,
    // so their images agree to rounding while each is noisy on its own.
    let mut scene = corner();
    scene.lights.push(lamp(0.5));
    let frame = FrameScene::from_parts(scene, &[]).unwrap();
    let p = projector();
    let value = Image::new(64, 64, Vec3::splat(0.5));
    let view = complete_view(
        &frame,
        &camera(),
        &[ProjectedLight {
            projector: &p,
            value: &value,
        }],
        CompleteOptions {
            paths_per_point: 64,
            seed: 5,
        },
    )
    .unwrap();
    let same = relative_rmse(&view.real.radiance, &view.target.radiance, None).unwrap();
    assert!(same < 1e-5, "real against target: {same}");
    let compared = view.difference_noise_rel_rmse(None).unwrap();
    assert!(compared < 1e-5, "noise of the difference: {compared}");
    let own = view.target.noise_rel_rmse(None).unwrap();
    assert!(own > 1e-3, "the target's own noise: {own}");
    // The wall lights the floor and back: interreflection is there.
    let share = relative_rmse(&view.real.direct, &view.real.radiance, None).unwrap();
    assert!(share > 0.05, "interreflection share {share}");
    // The projector dark: only the target is lit.
    let dark = Image::new(64, 64, Vec3::ZERO);
    let off = complete_view(
        &frame,
        &camera(),
        &[ProjectedLight {
            projector: &p,
            value: &dark,
        }],
        CompleteOptions {
            paths_per_point: 16,
            seed: 5,
        },
    )
    .unwrap();
    assert!(off.real.radiance.data.iter().all(|v| *v == Vec3::ZERO));
    assert!(
        off.target
            .radiance
            .data
            .iter()
            .any(|v| v.max_element() > 0.0)
    );
}

#[test]
fn a_target_traced_under_other_projector_images_gives_the_same_view_bit_for_bit() {
    let mut scene = corner();
    scene.lights.push(lamp(0.5));
    let frame = FrameScene::from_parts(scene, &[]).unwrap();
    let p = projector();
    let options = CompleteOptions {
        paths_per_point: 16,
        seed: 9,
    };
    let (lit, dark) = (
        Image::new(64, 64, Vec3::splat(0.5)),
        Image::new(64, 64, Vec3::ZERO),
    );
    fn under<'a>(p: &'a Projector, value: &'a RgbImage) -> [ProjectedLight<'a>; 1] {
        [ProjectedLight {
            projector: p,
            value,
        }]
    }
    let fresh = complete_view(&frame, &camera(), &under(&p, &lit), options).unwrap();
    let other = complete_view(&frame, &camera(), &under(&p, &dark), options).unwrap();
    let reused = complete_view_with_target(
        &frame,
        &camera(),
        &under(&p, &lit),
        options,
        Some(other.target),
    )
    .unwrap();
    assert_eq!(reused.real.radiance.data, fresh.real.radiance.data);
    assert_eq!(reused.target.radiance.data, fresh.target.radiance.data);
    assert_eq!(reused.target.halves[1].data, fresh.target.halves[1].data);
    // A target of another size is traced again.
    let small = CompleteImage {
        radiance: Image::new(8, 8, Vec3::ONE),
        direct: Image::new(8, 8, Vec3::ONE),
        halves: [Image::new(8, 8, Vec3::ONE), Image::new(8, 8, Vec3::ONE)],
    };
    let retraced =
        complete_view_with_target(&frame, &camera(), &under(&p, &lit), options, Some(small))
            .unwrap();
    assert_eq!(retraced.target.radiance.data, fresh.target.radiance.data);
}

#[test]
fn the_irradiance_cache_agrees_with_brute_force_path_tracing() {
    // The same image by brute force: every subsample ray with 2048 paths
    // of its own. The cache may differ by its noise and a small
    // interpolation bias; both are measured here.
    let mut scene = corner();
    scene.lights.push(lamp(0.5));
    let world = SimWorld::new(&scene, &ObjectFilter::All, true).unwrap();
    let lights = SimLights::virtual_lights(&scene.lights, scene.ambient).unwrap();
    let cam = camera();
    let rays = DeviceRays::new(&cam).unwrap();
    let cached = trace_image(
        &world,
        &lights,
        &rays,
        CompleteOptions {
            paths_per_point: 2048,
            seed: 9,
        },
    );
    let n = SUBSAMPLES * SUBSAMPLES;
    let brute = Image::from_fn(cam.width, cam.height, |x, y| {
        let mut sum = DVec3::ZERO;
        for k in 0..n {
            let offset = DVec2::new(
                ((k % SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
                ((k / SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
            );
            let ray = rays
                .ray_through(DVec2::new(x as f64, y as f64) + offset)
                .unwrap();
            let seed = pixel_seed(77, u64::from(y * cam.width + x) * 4 + u64::from(k));
            let [e, d, i] = world.trace(&ray, &lights, 2048, seed);
            sum += e + d + i;
        }
        (sum / f64::from(n)).as_vec3()
    });
    let noise = cached.noise_rel_rmse(None).unwrap();
    let error = relative_rmse(&cached.radiance, &brute, None).unwrap();
    let mean = |img: &RgbImage| img.data.iter().map(|v| v.as_dvec3()).sum::<DVec3>();
    let bias = (mean(&cached.radiance) / mean(&brute) - DVec3::ONE)
        .abs()
        .max_element();
    eprintln!("cache noise {noise:.5}, against brute force {error:.5}, bias of the mean {bias:.5}");
    assert!(noise < 0.005, "cache noise {noise}");
    assert!(error < 0.01, "cache against brute force: {error}");
    assert!(bias < 0.003, "bias of the mean: {bias}");
}

/// [`corner`] with a red virtual block standing on the floor in front of
/// the wall, lit by the lamp: in the target it bleeds red onto the real
/// wall and floor and shades them, which direct light cannot show.
fn corner_with_block() -> Showcase {
    let mut s = corner();
    let (lo, hi) = (Vec3::new(-0.2, 0.0, -0.2), Vec3::new(-0.1, 0.25, 0.2));
    let corner = |i: usize| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    // Outward faces, counter-clockwise seen from outside.
    let faces: [[usize; 4]; 6] = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let mut triangles = Vec::new();
    let mut positions = Vec::new();
    for f in faces {
        let k = positions.len() as u32;
        positions.extend(f.map(corner));
        triangles.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
    }
    let mesh = s.add_mesh(Mesh {
        positions,
        triangles,
        ..Mesh::default()
    });
    s.objects.push(Object {
        name: "block".into(),
        mesh,
        material: Material::diffuse(Vec3::new(0.9, 0.1, 0.1)),
        kind: ObjectKind::Virtual,
        transform: Transform::IDENTITY,
    });
    s.lights.push(lamp(0.5));
    s
}

/// The projector's map with the correction of
/// [`crate::radiosity::augmented::indirect_correction`] against its map of
/// direct light, both judged in the complete world over the real pixels
/// off edges: 0.0083 against 0.0282 measured (noise 0.0026); the same
/// with 4x finer patches (0.0086), so what is left is the solution's own
/// error, not its mesh. Without the block the correction is below 0.001
/// W/m^2 everywhere and both maps agree with the target to 0.001.
#[test]
fn the_global_illumination_correction_brings_the_real_surfaces_to_the_complete_target() {
    use crate::radiosity::augmented::{indirect_correction, projector_reach};
    use crate::radiosity::{HierarchyOptions, MeshOptions, RadiosityMesh};
    use crate::render::projector::irradiance_map_cpu;
    use crate::render::{IndirectField, Occluders, ProjectorOptions};
    use crate::{SceneGeometry, observer_view};
    use std::sync::Arc;

    let scene = corner_with_block();
    let frame = FrameScene::from_parts(scene.clone(), &[]).unwrap();
    let occluders = Occluders::new(&frame).unwrap();
    let p = projector();

    let all = SceneGeometry::build(&scene, &ObjectFilter::All).unwrap();
    let real = SceneGeometry::build(&scene, &ObjectFilter::Real).unwrap();
    let mesh = RadiosityMesh::build(
        &scene,
        &all,
        &MeshOptions {
            max_patch_area: 0.002,
            ..MeshOptions::default()
        },
    )
    .unwrap();
    let lights: Vec<_> = scene.lights.iter().map(|l| l.light.clone()).collect();
    let lit = projector_reach(&mesh, &real, &[DeviceRays::new(&p.device).unwrap()]);
    assert!(lit.iter().any(|l| *l) && lit.iter().any(|l| !l));
    let delta = indirect_correction(
        &mesh,
        &all,
        &real,
        &lights,
        Some(&lit),
        &HierarchyOptions::default(),
    )
    .unwrap();
    virtual_elements_carry_their_path_traced_indirect_light(&scene, &mesh, &delta);
    let field = Arc::new(IndirectField::new(Arc::new(mesh), &delta).unwrap());
    let cam = camera();
    let judge = |frame: &FrameScene| {
        let map = irradiance_map_cpu(frame, &occluders, &p, ProjectorOptions::default()).unwrap();
        let projected = [ProjectedLight {
            projector: &p,
            value: &map.value,
        }];
        let direct =
            observer_view::observer_view(frame, &occluders, &cam, &projected, None).unwrap();
        let complete = complete_view(
            frame,
            &cam,
            &projected,
            CompleteOptions {
                paths_per_point: 1024,
                seed: 3,
            },
        )
        .unwrap();
        let mask = Image {
            width: cam.width,
            height: cam.height,
            data: (0..direct.covered.data.len())
                .map(|i| {
                    direct.covered.data[i]
                        && !direct.sees_virtual.data[i]
                        && !direct.edge.data[i]
                        && direct.reachable.data[i]
                })
                .collect(),
        };
        let error = relative_rmse(
            &complete.real.radiance,
            &complete.target.radiance,
            Some(&mask),
        )
        .unwrap();
        let noise = complete.difference_noise_rel_rmse(Some(&mask)).unwrap();
        (error, noise)
    };
    let (direct, noise_d) = judge(&frame);
    let (global, noise_g) = judge(&frame.clone().with_indirect(field));
    eprintln!(
        "complete world: direct maps {direct:.4} (noise {noise_d:.4}), global maps {global:.4} (noise {noise_g:.4})"
    );
    assert!(
        direct > 5.0 * noise_d,
        "direct maps {direct}, noise {noise_d}"
    );
    assert!(
        global < direct / 3.0,
        "global maps {global} against direct {direct}"
    );
}

/// On the virtual elements (drawn by the CRT faces) the field is their
/// whole indirect irradiance: each face of the virtual block, its
/// elements' values averaged by area, against the sim's path-traced
/// indirect irradiance at the same element centres (independent of the
/// radiosity), within 10 % (or 2 % of the largest face's, for faces that
/// get little), and the face towards the lit wall gets several times what
/// the top gets.
fn virtual_elements_carry_their_path_traced_indirect_light(
    scene: &Showcase,
    mesh: &crate::radiosity::RadiosityMesh,
    delta: &[crate::render::IndirectLight],
) {
    let world = SimWorld::new(scene, &ObjectFilter::All, true).unwrap();
    let lights = SimLights::virtual_lights(&scene.lights, scene.ambient).unwrap();
    // Per face of the block (by normal): area-weighted sums of the field
    // and of the path-traced indirect irradiance (red: the block's colour
    // bleeds least into it, the grey room's most).
    let mut faces: Vec<(DVec3, f64, f64, f64)> = Vec::new();
    for (i, e) in mesh.elements.iter().enumerate().filter(|(_, e)| !e.real) {
        let ray = crate::Ray::new(e.center + 0.01 * e.normal, -e.normal);
        let Some(surface) = world.surface_along(&ray, &lights).surface else {
            continue;
        };
        let (traced, _) = world.indirect_irradiance(&surface, &lights, 256, i as u64);
        let k = match faces.iter().position(|f| f.0.dot(e.normal) > 0.99) {
            Some(k) => k,
            None => {
                faces.push((e.normal, 0.0, 0.0, 0.0));
                faces.len() - 1
            }
        };
        faces[k].1 += e.area;
        faces[k].2 += e.area * delta[i].add.y;
        faces[k].3 += e.area * traced.y;
    }
    assert_eq!(faces.len(), 6, "the block has six faces");
    let largest = faces.iter().map(|f| f.3 / f.1).fold(0.0, f64::max);
    assert!(largest > 0.0);
    for (n, area, field, traced) in &faces {
        let (field, traced) = (field / area, traced / area);
        eprintln!("block face {n}: field {field:.4}, path-traced {traced:.4} W/m^2");
        assert!(
            (field - traced).abs() <= (0.1 * traced).max(0.02 * largest),
            "face {n}: field {field} against path-traced {traced}"
        );
    }
    let mean = |n: DVec3| {
        let f = faces.iter().find(|f| f.0.dot(n) > 0.99).unwrap();
        f.2 / f.1
    };
    assert!(
        mean(-DVec3::X) > 3.0 * mean(DVec3::Y),
        "towards the wall {} against the top {}",
        mean(-DVec3::X),
        mean(DVec3::Y)
    );
}
