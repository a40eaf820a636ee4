//! Integration tests: sim. The simulated showcase's light transport against
//! closed forms (a white furnace, Lambert's polygon irradiance, equation
//! 3.1), its determinism, the colour wheel and the camera.

use glam::{DVec3, Vec3};
use proptest::prelude::*;
use showcase_light::hardware::{CameraDevice, ProjectorDevice};
use showcase_light::sim::{
    SimConfig, SimLights, SimShowcase, SimWorld, render_view, wheel_weights,
};
use showcase_light::{
    DeviceRays, Image, IntensityLight, ObjectFilter, SceneGeometry, polygon_irradiance,
    render_intensity,
};
use showcase_master::capture::scenes::{plate_scene, quad_mesh};
use showcase_master::pfm::read_pfm;
use showcase_proto::{
    Material, Mesh, Object, ObjectKind, PinholeDevice, ProjectorResponse, Showcase, Transform,
};

const CORNELL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cornell-box.obj"
);

fn add(scene: &mut Showcase, name: &str, mesh: Mesh, material: Material) {
    let id = scene.add_mesh(mesh);
    scene.objects.push(Object {
        name: name.into(),
        mesh: id,
        material,
        kind: ObjectKind::Real,
        transform: Transform::IDENTITY,
    });
}

/// A closed unit cube whose inside faces all emit `le` and reflect `rho`:
/// radiance is `le / (1 - rho)` everywhere inside (a white furnace).
#[test]
fn closed_emitting_box_conserves_energy() {
    let (le, rho) = (Vec3::new(1.0, 0.5, 0.25), 0.6f32);
    let mut s = Showcase::default();
    let c = Vec3::splat(0.5);
    let faces = [
        (Vec3::ZERO, Vec3::X, Vec3::Y),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::ZERO, Vec3::Y, Vec3::Z),
        (Vec3::X, Vec3::Y, Vec3::Z),
        (Vec3::ZERO, Vec3::X, Vec3::Z),
        (Vec3::Y, Vec3::X, Vec3::Z),
    ];
    for (i, (corner, u, v)) in faces.into_iter().enumerate() {
        let centre = corner + 0.5 * (u + v);
        // Wind every face so its front looks into the box.
        let (u, v) = if u.cross(v).dot(c - centre) > 0.0 {
            (u, v)
        } else {
            (v, u)
        };
        let mut m = Material::diffuse(Vec3::splat(rho));
        m.emission = le;
        add(&mut s, &format!("face-{i}"), quad_mesh(corner, u, v), m);
    }
    let camera = PinholeDevice::look_at(
        DVec3::splat(0.5),
        DVec3::new(0.6, 0.4, 1.0),
        DVec3::Y,
        100.0,
        6,
        6,
    );
    // With the emitters switched off the lamps are plain reflectors: the
    // closed box is black, their own glow included.
    let dark = SimWorld::new(&s, &ObjectFilter::All, false).unwrap();
    assert_eq!(dark.emitter_count(), 0);
    let img = dark.render(&DeviceRays::new(&camera).unwrap(), &SimLights::none(), 4, 3);
    assert!(img.total().data.iter().all(|v| *v == Vec3::ZERO));
    let world = SimWorld::new(&s, &ObjectFilter::All, true).unwrap();
    assert_eq!(world.emitter_count(), 12);
    // 1024 paths: the next-event estimate in a closed box is heavy-tailed
    // (1/r^2 near the edges); at 256 paths one render's mean still
    // scatters by about 1.8%, too close to the 2% tolerance.
    let img = world.render(
        &DeviceRays::new(&camera).unwrap(),
        &SimLights::none(),
        1024,
        3,
    );
    let total = img.total();
    let mean = total.data.iter().map(|v| v.as_dvec3()).sum::<DVec3>() / total.data.len() as f64;
    let expect = le.as_dvec3() / (1.0 - rho as f64);
    let err = ((mean - expect) / expect).abs().max_element();
    assert!(err < 0.02, "mean {mean} vs {expect}");
    // Every bounce order is present: the indirect part alone is
    // le * rho^2 / (1 - rho) on average.
    let ind = img
        .indirect
        .data
        .iter()
        .map(|v| v.as_dvec3())
        .sum::<DVec3>()
        / total.data.len() as f64;
    let expect_ind = expect * (rho as f64).powi(2);
    assert!(
        ((ind - expect_ind) / expect_ind).abs().max_element() < 0.03,
        "{ind} vs {expect_ind}"
    );
}

/// Direct light from a square emitter on a floor matches Lambert's closed
/// form pixel by pixel; with a black emitter and a flat floor there is no
/// indirect light.
#[test]
fn direct_light_from_a_polygon_emitter_matches_lambert() {
    let mut s = Showcase::default();
    let rho = 0.5;
    add(
        &mut s,
        "floor",
        quad_mesh(Vec3::new(-1.0, 0.0, 1.0), Vec3::X * 2.0, Vec3::Z * -2.0),
        Material::diffuse(Vec3::splat(rho)),
    );
    let corner = Vec3::new(-0.2, 0.5, -0.2);
    let (u, v) = (Vec3::X * 0.4, Vec3::Z * 0.4); // u x v = -y: facing down
    let mut light = Material::diffuse(Vec3::ZERO);
    light.emission = Vec3::splat(2.0);
    add(&mut s, "light", quad_mesh(corner, u, v), light);
    let world = SimWorld::new(&s, &ObjectFilter::All, true).unwrap();
    let camera = PinholeDevice::look_at(
        DVec3::new(0.0, 1.2, -1.4),
        DVec3::ZERO,
        DVec3::Y,
        60.0,
        12,
        10,
    );
    let rays = DeviceRays::new(&camera).unwrap();
    let img = world.render(&rays, &SimLights::none(), 1024, 5);
    let geometry = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
    let polygon: Vec<DVec3> = [corner, corner + u, corner + u + v, corner + v]
        .iter()
        .map(|p| p.as_dvec3())
        .collect();
    let (mut n, mut sum_err, mut sum_expect, mut max_err) = (0, 0.0, 0.0, 0.0f64);
    for y in 0..camera.height {
        for x in 0..camera.width {
            let ray = rays.pixel_ray(x, y).unwrap();
            let Some(hit) = geometry.closest_hit(&ray, 0.0, f64::INFINITY) else {
                continue;
            };
            let i = (y * camera.width + x) as usize;
            assert_eq!(img.indirect.data[i], Vec3::ZERO);
            if hit.object != 0 {
                assert_eq!(
                    img.emitted.data[i],
                    Vec3::ZERO,
                    "the light's back is seen, not its front"
                );
                continue;
            }
            let e = polygon_irradiance(hit.point, DVec3::Y, &polygon, 2.0).unwrap();
            let expect = rho as f64 / std::f64::consts::PI * e;
            let got = img.direct.data[i].x as f64;
            let rel = (got - expect).abs() / expect;
            sum_err += got - expect;
            sum_expect += expect;
            max_err = max_err.max(rel);
            n += 1;
        }
    }
    assert!(n > 60, "{n} floor pixels");
    assert!(max_err < 0.05, "worst pixel {max_err}");
    assert!(
        (sum_err / sum_expect).abs() < 0.01,
        "bias {}",
        sum_err / sum_expect
    );
}

/// The projector's direct light is equation 3.1 times rho/pi exactly, and
/// a lone plate has no indirect light.
#[test]
fn projector_direct_light_is_equation_3_1() {
    let mut scene = plate_scene((24, 18), false);
    scene.projectors[0].response = ProjectorResponse {
        gamma: 2.2,
        eta: 2.0,
        black_level: 0.1,
        wheel_segments: Vec::new(),
        wheel_period_s: 1.0 / 120.0,
        photometry: None,
    };
    let sim = SimShowcase::new(
        &scene,
        SimConfig {
            samples_per_pixel: 4,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let mut p = sim.projector(0).unwrap();
    let d = p.device().clone();
    p.show(&Image::new(d.width, d.height, Vec3::ONE)).unwrap();
    let t = sim.transport(0, 0).unwrap();
    let geometry = SceneGeometry::build(&scene, &ObjectFilter::Real).unwrap();
    let light = IntensityLight::projector(&d, Vec3::ONE, 2.1).unwrap();
    let cam = DeviceRays::new(&scene.cameras[0].device).unwrap();
    let int = render_intensity(&geometry, &cam, &light, &ObjectFilter::Real);
    let (albedo, _) = sim.ground_truth(0).unwrap();
    let mut lit = 0;
    for i in 0..t.direct.data.len() {
        let expect =
            albedo.data[i].as_dvec3() * int.intensity.data[i].as_dvec3() / std::f64::consts::PI;
        assert!(
            (t.direct.data[i].as_dvec3() - expect).abs().max_element()
                <= 1e-6 * expect.max_element().max(1e-3)
        );
        assert_eq!(t.indirect.data[i], Vec3::ZERO);
        lit += (expect.max_element() > 0.0) as usize;
    }
    assert!(lit > 200, "{lit} lit pixels");
    // Half the pixel value: eta * 0.5^2.2 + black.
    p.show(&Image::new(d.width, d.height, Vec3::splat(0.5)))
        .unwrap();
    let half = sim.transport(0, 0).unwrap();
    let ratio = (2.0 * 0.5f64.powf(2.2) + 0.1) / 2.1;
    for i in 0..t.direct.data.len() {
        let e = t.direct.data[i].x as f64 * ratio;
        assert!((half.direct.data[i].x as f64 - e).abs() <= 1e-5 * e.max(1e-3));
    }
}

#[test]
fn colour_wheel_integrates_only_the_segments_an_exposure_overlaps() {
    let r = ProjectorResponse {
        wheel_segments: vec![Vec3::X, Vec3::Y, Vec3::Z],
        wheel_period_s: 0.3,
        ..ProjectorResponse::default()
    };
    let phase = 0.05;
    let p = r.wheel_period_s as f64;
    let full = wheel_weights(&r, phase, 1.234, p);
    assert!((full - DVec3::ONE).abs().max_element() < 1e-9, "{full}");
    let red = wheel_weights(&r, phase, phase + p * 7.0, p / 3.0);
    assert!(
        (red - DVec3::new(3.0, 0.0, 0.0)).abs().max_element() < 1e-9,
        "{red}"
    );
    // Half of green and half of blue.
    let gb = wheel_weights(&r, phase, phase + p / 2.0, p / 3.0);
    assert!(
        (gb - DVec3::new(0.0, 1.5, 1.5)).abs().max_element() < 1e-9,
        "{gb}"
    );
    // Instantaneous exposure: the segment in front of the lamp.
    assert_eq!(
        wheel_weights(&r, phase, phase + 0.85 * p, 0.0),
        DVec3::new(0.0, 0.0, 3.0)
    );
    // No wheel: always 1.
    assert_eq!(
        wheel_weights(&ProjectorResponse::default(), 0.0, 0.1, 0.01),
        DVec3::ONE
    );
    // K frames spread evenly over the phase average to a full turn.
    let k = 16;
    let avg = (0..k)
        .map(|i| wheel_weights(&r, phase, i as f64 * (4.0 + 1.0 / k as f64) * p, 0.75 * p))
        .sum::<DVec3>()
        / k as f64;
    assert!((avg - DVec3::ONE).abs().max_element() < 0.01, "{avg}");
}

#[test]
fn camera_sees_one_colour_in_a_short_exposure_and_has_the_configured_noise() {
    let mut scene = plate_scene((8, 8), false);
    scene.cameras[0].response.gain = 2000.0;
    let sim = SimShowcase::new(
        &scene,
        SimConfig {
            samples_per_pixel: 1,
            wheel_phase_s: 0.0,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let mut p = sim.projector(0).unwrap();
    let d = p.device().clone();
    p.show(&Image::new(d.width, d.height, Vec3::ONE)).unwrap();
    let mut cam = sim.camera(0).unwrap();
    let period = p.wheel_period_s();
    let frame = cam.capture(0.0, period / 3.0).unwrap();
    let centre = frame.codes.get(4, 4).unwrap();
    assert!(
        centre[0] > 20 && centre[1] == 0 && centre[2] == 0,
        "{centre:?}"
    );
    assert!(cam.capture(f64::NAN, 0.01).is_err());
    assert!(cam.capture(0.0, -1.0).is_err());
    // Read noise of 2% of full scale on a mid-grey signal.
    let mut scene = plate_scene((8, 8), false);
    let r = &mut scene.cameras[0].response;
    r.read_noise = 0.02;
    r.gain = 0.0; // a black image: pure read noise around 0.3 after offset below
    let sim = SimShowcase::new(
        &scene,
        SimConfig {
            samples_per_pixel: 1,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let mut p = sim.projector(0).unwrap();
    p.show(&Image::new(d.width, d.height, Vec3::ONE)).unwrap();
    let mut cam = sim.camera(0).unwrap();
    // With gain 0 the signal is 0 and clamping keeps half the noise: the
    // mean code is sigma / sqrt(2 pi) * 255.
    let mut sum = 0.0;
    let mut n = 0.0;
    for k in 0..40 {
        let f = cam.capture(k as f64 * 0.01, 0.005).unwrap();
        for c in &f.codes.data {
            sum += c[0] as f64;
            n += 1.0;
        }
    }
    let expect = 0.02 / (2.0 * std::f64::consts::PI).sqrt() * 255.0;
    assert!(
        (sum / n - expect).abs() < 0.15 * expect,
        "{} vs {expect}",
        sum / n
    );
}

/// The classic Cornell-box view: the light quad shows its `Ke`, the left
/// wall is red and the right green, and the command writes a readable PFM.
#[test]
fn cornell_box_renders_with_its_own_light() {
    let scene = showcase_master::scene_file::load_any(std::path::Path::new(CORNELL)).unwrap();
    let device = PinholeDevice::look_at(
        DVec3::new(0.278, 0.273, -0.8),
        DVec3::new(0.278, 0.273, 0.0),
        DVec3::Y,
        39.3077,
        24,
        24,
    );
    // The green wall's green-to-red ratio is 2.08 here (1024 paths per
    // pixel, seeds 1-6: 2.07-2.14), close to the bound below: 32 paths
    // gave 1.94-2.17, so the bound needs the converged image.
    let img = render_view(&scene, &device, 1024, 1).unwrap();
    assert!(img.data.iter().all(|v| v.is_finite()));
    let rays = DeviceRays::new(&device).unwrap();
    let p = rays.pixel_of(DVec3::new(0.278, 0.5487, 0.2795)).unwrap();
    let light = img.get(p.0, p.1).unwrap();
    assert!(light.x >= 17.0 && light.x < 17.0 * 1.1, "{light}");
    let left = img.get(1, 12).unwrap();
    let right = img.get(22, 12).unwrap();
    assert!(
        left.x > 2.0 * left.y && right.y > 2.0 * right.x,
        "{left} {right}"
    );
    let dir = std::env::temp_dir().join(format!("showcase-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("cornell.pfm");
    showcase_master::capture::sim_render_command(
        std::path::Path::new(CORNELL),
        DVec3::new(0.278, 0.273, -0.8),
        DVec3::new(0.278, 0.273, 0.0),
        DVec3::Y,
        39.3077,
        8,
        6,
        &out,
    )
    .unwrap();
    let back = read_pfm(&out).unwrap();
    assert_eq!((back.width, back.height), (8, 6));
    assert!(
        showcase_master::capture::sim_render_command(
            std::path::Path::new(CORNELL),
            DVec3::ZERO,
            DVec3::ZERO,
            DVec3::Y,
            40.0,
            8,
            6,
            &out
        )
        .is_err()
    );
    std::fs::remove_dir_all(dir).ok();
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Random (also degenerate) triangles, grazing devices, zero or huge
    /// light: every radiance and every camera code stays finite.
    #[test]
    fn transport_never_returns_nan(
        tris in proptest::collection::vec(proptest::array::uniform3(proptest::array::uniform3(-1.0f32..1.0)), 1..6),
        emission in 0.0f32..1e6,
        eta in 0.0f32..1e6,
        albedo in 0.0f32..1.0,
        eye_y in -0.01f64..2.0,
    ) {
        let mut s = Showcase::default();
        for (i, t) in tris.iter().enumerate() {
            let mut m = Material::diffuse(Vec3::splat(albedo));
            if i == 0 { m.emission = Vec3::splat(emission); }
            let p = t.map(Vec3::from);
            // Make the last one degenerate: a repeated vertex.
            let positions = if i + 1 == tris.len() { vec![p[0], p[1], p[1]] } else { p.to_vec() };
            add(&mut s, &format!("t{i}"), Mesh { positions, triangles: vec![[0, 1, 2]], ..Mesh::default() }, m);
        }
        let camera = PinholeDevice::look_at(DVec3::new(0.0, eye_y, -2.0), DVec3::ZERO, DVec3::Y, 70.0, 6, 5);
        s.projectors.push(showcase_proto::Projector {
            name: "p".into(),
            device: PinholeDevice::look_at(DVec3::new(2.0, 0.0, 0.0), DVec3::ZERO, DVec3::Y, 60.0, 7, 7),
            response: ProjectorResponse { eta, black_level: 0.0, wheel_segments: vec![Vec3::X, Vec3::Y, Vec3::Z], ..ProjectorResponse::default() },
        });
        s.cameras.push(showcase_proto::Camera { name: "c".into(), device: camera, response: Default::default() });
        let sim = SimShowcase::new(&s, SimConfig { samples_per_pixel: 2, emitters: true, objects: ObjectFilter::All, ..SimConfig::default() }).unwrap();
        let mut p = sim.projector(0).unwrap();
        p.show(&Image::new(7, 7, Vec3::new(1.0, f32::NAN, 0.5))).unwrap();
        let t = sim.transport(0, 0).unwrap();
        prop_assert!(t.total().data.iter().all(|v| v.is_finite()));
        let f = sim.camera(0).unwrap().capture(0.001, 0.0).unwrap();
        prop_assert!(f.codes.data.iter().all(|c| c.iter().all(|v| *v <= 255)));
    }
}
