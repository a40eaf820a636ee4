//! Unit tests of the scene model: device projection round trips, mesh
//! hashing, validation of scene parts.

use super::*;
use crate::validate::Validate;
use glam::{DVec2, DVec3, Vec3};

fn device() -> PinholeDevice {
    PinholeDevice::look_at(
        DVec3::new(0.3, 0.8, -1.0),
        DVec3::new(0.0, 0.1, 0.2),
        DVec3::Y,
        50.0,
        1024,
        768,
    )
}

#[test]
fn look_at_puts_target_at_image_centre_and_up_at_top() {
    let d = device();
    let c = d.project(DVec3::new(0.0, 0.1, 0.2)).unwrap();
    assert!((c - DVec2::new(512.0, 384.0)).length() < 1e-9, "{c}");
    // A point above the target appears higher in the image (smaller v).
    let up = d.project(DVec3::new(0.0, 0.2, 0.2)).unwrap();
    assert!(up.y < c.y, "{up} vs {c}");
    assert!((d.center() - DVec3::new(0.3, 0.8, -1.0)).length() < 1e-12);
    assert!((d.rotation.determinant() - 1.0).abs() < 1e-12);
    assert_eq!(d.validate(), Ok(()));
}

#[test]
fn unproject_inverts_project() {
    let d = device();
    for p in [
        DVec3::new(0.1, 0.0, 0.3),
        DVec3::new(-0.2, 0.4, 0.0),
        DVec3::new(0.25, 0.05, 0.5),
    ] {
        let px = d.project(p).unwrap();
        let dir = d.unproject(px);
        let expect = (p - d.center()).normalize();
        assert!((dir - expect).length() < 1e-12, "{dir} vs {expect}");
    }
    assert!(d.project(DVec3::new(0.3, 0.8, -2.0)).is_none(), "behind");
}

#[test]
fn projection_matrix_matches_project() {
    let mut d = device();
    d.k.y_axis.x = 3.5; // skew
    let p = DVec3::new(0.1, 0.2, 0.3);
    let pm = d.projection();
    let h: [f64; 3] =
        std::array::from_fn(|r| pm[r][0] * p.x + pm[r][1] * p.y + pm[r][2] * p.z + pm[r][3]);
    let px = d.project(p).unwrap();
    assert!((DVec2::new(h[0] / h[2], h[1] / h[2]) - px).length() < 1e-9);
}

/// The documented mapping: pixel (u, v) -> wgpu framebuffer coordinate
/// (u, v) (framebuffer y grows downwards), depth 0 at near, 1 at far.
#[test]
fn clip_from_world_maps_pixels_to_framebuffer_coordinates() {
    let mut d = device();
    d.k.y_axis.x = 2.0;
    d.near = 0.05;
    d.far = 20.0;
    let m = d.clip_from_world();
    for p in [DVec3::new(0.1, 0.2, 0.3), DVec3::new(-0.3, 0.0, 0.4)] {
        let clip = m * p.extend(1.0);
        let ndc = clip.truncate() / clip.w;
        let fb = DVec2::new(
            (ndc.x + 1.0) * 0.5 * d.width as f64,
            (1.0 - ndc.y) * 0.5 * d.height as f64,
        );
        let px = d.project(p).unwrap();
        assert!((fb - px).length() < 1e-6, "{fb} vs {px}");
        assert!((0.0..1.0).contains(&ndc.z));
    }
    let on_axis = |z: f64| {
        let p = d.center() + d.rotation.transpose() * DVec3::new(0.0, 0.0, z);
        let c = m * p.extend(1.0);
        c.z / c.w
    };
    assert!(on_axis(0.05).abs() < 1e-9);
    assert!((on_axis(20.0) - 1.0).abs() < 1e-9);
}

#[test]
fn degenerate_devices_are_rejected_naming_the_field() {
    let mut d = device();
    d.rotation.x_axis *= 2.0;
    assert!(
        d.validate()
            .unwrap_err()
            .to_string()
            .contains("rotation is not orthonormal")
    );
    let mut d = device();
    d.k.x_axis.x = 0.0;
    assert!(
        d.validate()
            .unwrap_err()
            .to_string()
            .starts_with("k: focal lengths")
    );
    let mut d = device();
    d.translation.z = f64::INFINITY;
    assert!(
        d.validate()
            .unwrap_err()
            .to_string()
            .starts_with("translation: value inf")
    );
    let mut d = device();
    d.rotation = -d.rotation;
    assert!(d.validate().unwrap_err().to_string().contains("reflection"));
}

#[test]
fn mesh_hash_depends_on_content() {
    let a = Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        triangles: vec![[0, 1, 2]],
        ..Mesh::default()
    };
    let mut b = a.clone();
    assert_eq!(a.id(), b.id());
    b.triangles[0] = [0, 2, 1];
    assert_ne!(a.id(), b.id());
    assert!((a.area() - 0.5).abs() < 1e-12);
    let mut s = Showcase::default();
    assert_eq!(s.add_mesh(a.clone()), s.add_mesh(a));
    assert_eq!(s.meshes.len(), 1);
}

#[test]
fn showcase_validation_names_the_object() {
    let mut s = Showcase::default();
    let mesh = s.add_mesh(Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        triangles: vec![[0, 1, 3]],
        ..Mesh::default()
    });
    let err = s.validate().unwrap_err().to_string();
    assert_eq!(
        err,
        "meshes[0].triangles[0]: vertex index 3 is out of range for 3 positions"
    );
    s.meshes[0].mesh.triangles[0] = [0, 1, 2];
    assert_ne!(s.meshes[0].id, s.meshes[0].mesh.id());
    assert!(
        s.validate()
            .unwrap_err()
            .to_string()
            .contains("content hash")
    );
    s.meshes[0].id = s.meshes[0].mesh.id();
    s.objects.push(Object {
        name: "plate".into(),
        mesh,
        material: Material::diffuse(Vec3::splat(0.5)),
        kind: ObjectKind::Real,
        transform: Transform::IDENTITY,
    });
    assert!(
        s.validate()
            .unwrap_err()
            .to_string()
            .starts_with("objects[0].mesh")
    );
    s.objects[0].mesh = s.meshes[0].id;
    s.objects[0].transform.scale.y = f32::NAN;
    assert_eq!(
        s.validate().unwrap_err().to_string(),
        "objects[0].transform.scale: value NaN is not finite"
    );
    s.objects[0].transform.scale.y = 1.0;
    s.patch_area = Some(0.0025);
    assert_eq!(s.validate(), Ok(()));
    s.patch_area = Some(0.0);
    assert_eq!(
        s.validate().unwrap_err().to_string(),
        "patch_area: 0 m^2 is outside 1e-6..=100 m^2"
    );
    s.patch_area = Some(f64::INFINITY);
    assert_eq!(
        s.validate().unwrap_err().to_string(),
        "patch_area: value inf is not finite"
    );
}

#[test]
fn mirror_reflection_is_an_involution() {
    let p = Plane::from_point_normal(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 1.0));
    let x = Vec3::new(0.3, -0.2, 0.9);
    let r = p.reflect_point(x);
    assert!((p.reflect_point(r) - x).length() < 1e-6);
    let mid = 0.5 * (x + r);
    assert!((p.normal.dot(mid) - p.offset).abs() < 1e-6);
}

/// A mismatched chain like the demo scene's: tinted splitter, a CRT of
/// its own gamma per channel with a black level.
fn mismatched() -> CrtPhotometry {
    CrtPhotometry {
        crt: CrtResponse {
            gamma: Vec3::new(2.4, 2.5, 2.3),
            peak: Vec3::new(2.0, 1.8, 2.2),
            black_level: Vec3::splat(0.004),
        },
        splitter: BeamSplitter {
            transmission: Vec3::new(0.62, 0.6, 0.57),
            reflection: Vec3::new(0.33, 0.35, 0.37),
        },
    }
}

#[test]
fn crt_drive_inverts_what_the_observer_sees_inside_the_range() {
    let ph = mismatched();
    for l in [0.01f32, 0.1, 0.5, 1.0] {
        let radiance = Vec3::new(l, 0.7 * l, 1.1 * l);
        let seen = ph.seen(ph.drive(radiance));
        assert!(
            (seen - radiance).abs().max_element() < 1e-4 * radiance.max_element().max(1.0),
            "{radiance} -> {seen}"
        );
    }
    // Below black and above peak the CRT clips: it cannot show less than
    // its black level, nor more than drive 1.
    let seen_black = ph.seen(ph.drive(Vec3::ZERO));
    assert_eq!(ph.drive(Vec3::ZERO), Vec3::ZERO);
    assert!(seen_black.min_element() > 0.0, "{seen_black}");
    assert_eq!(ph.drive(Vec3::splat(1e6)), Vec3::ONE);
    assert_eq!(ph.drive(Vec3::splat(f32::NAN)), Vec3::ZERO);
    assert_eq!(ph.crt.emit(Vec3::splat(f32::INFINITY)), ph.crt.black_level);
}

#[test]
fn nominal_crt_is_the_plain_inverse_gamma() {
    let ph = CrtPhotometry::nominal(2.2);
    let d = ph.drive(Vec3::new(0.25, 0.5, 1.0));
    for (c, l) in [0.25f32, 0.5, 1.0].into_iter().enumerate() {
        assert!((d[c] - l.powf(1.0 / 2.2)).abs() < 1e-6, "{d}");
    }
}

#[test]
fn face_photometry_out_of_range_is_named() {
    let face = CrtFace {
        name: "face-0".into(),
        screen: Rect3 {
            origin: Vec3::ZERO,
            right: Vec3::X,
            down: Vec3::NEG_Y,
        },
        mirror: Plane::from_point_normal(Vec3::ZERO, Vec3::Y),
        width: 64,
        height: 48,
        photometry: mismatched(),
    };
    assert!(face.validate().is_ok());
    for (field, change) in [
        ("photometry.splitter.reflection", {
            let mut f = face.clone();
            f.photometry.splitter.reflection.y = 0.0;
            f
        }),
        ("photometry.splitter.transmission", {
            let mut f = face.clone();
            f.photometry.splitter.transmission.x = 1.5;
            f
        }),
        ("photometry.crt.gamma", {
            let mut f = face.clone();
            f.photometry.crt.gamma.z = -1.0;
            f
        }),
        ("photometry.crt.peak", {
            let mut f = face.clone();
            f.photometry.crt.peak.z = f32::NAN;
            f
        }),
    ] {
        let err = change.validate().unwrap_err().to_string();
        assert!(err.contains(field), "{field}: {err}");
    }
}

#[test]
fn camera_response_decode_inverts_encode_below_saturation() {
    let r = CameraResponse {
        gamma: Vec3::new(2.1, 2.25, 1.95),
        knee: 0.8,
        shoulder: 0.45,
        ..CameraResponse::default()
    };
    for c in 0..3 {
        let mut last = -1.0;
        for k in 0..=100 {
            let s = k as f64 / 100.0;
            let v = r.encode(c, s);
            assert!(
                v >= last && (0.0..=1.0).contains(&v),
                "channel {c} signal {s}: {v}"
            );
            last = v;
            if v < 1.0 {
                assert!((r.decode(c, v) - s).abs() < 1e-9, "channel {c} signal {s}");
            }
        }
        // Above the knee the slope is the shoulder's share of the curve's,
        // and the full signal reaches the top code.
        let g = f64::from(r.gamma[c]);
        let knee = f64::from(r.knee);
        let gain = knee + (1.0 - knee) / f64::from(r.shoulder);
        let s_knee = (knee / gain).powf(g);
        let (a, b) = (r.encode(c, s_knee * 1.01), r.encode(c, s_knee));
        let plain = gain * (s_knee * 1.01).powf(1.0 / g) - knee;
        assert!(((a - b) / plain - 0.45).abs() < 1e-6, "{}", (a - b) / plain);
        assert!((r.encode(c, 1.0) - 1.0).abs() < 1e-12);
        assert!(r.encode(c, 0.999) < 1.0);
    }
    assert_eq!(r.encode(0, f64::NAN), 0.0);
    assert_eq!(r.encode(0, 1e9), 1.0);
}

/// A projector's node sends the device values whose light is the model's:
/// through its own curve per channel, the model's light comes out; with
/// no curve the values go as they are; a value the device cannot show
/// clips to its range.
#[test]
fn a_projector_encodes_the_model_through_its_photometry() {
    let model = ProjectorResponse {
        gamma: 2.2,
        eta: 4.0,
        black_level: 0.002,
        ..ProjectorResponse::default()
    };
    let v = Vec3::new(0.3, 0.6, 0.9);
    assert_eq!(model.encode(v), v);
    assert_eq!(model.light(v), model.model(v));
    let device = ProjectorResponse {
        photometry: Some(CrtResponse {
            gamma: Vec3::new(2.35, 2.1, 2.5),
            peak: Vec3::new(3.997, 3.998, 3.996),
            black_level: Vec3::new(0.005, 0.004, 0.006),
        }),
        ..model.clone()
    };
    for x in [0.1f32, 0.5, 1.0] {
        let v = Vec3::new(x, 0.8 * x, 0.9 * x);
        let got = device.light(device.encode(v));
        let want = model.model(v);
        assert!(
            ((got - want) / want).abs().max_element() < 1e-4,
            "{v}: {got} against {want}"
        );
        assert_ne!(device.encode(v), v);
    }
    // The model's black (0.002) is below the device's: it shows its black.
    assert_eq!(device.encode(Vec3::ZERO), Vec3::ZERO);
    assert_eq!(device.encode(Vec3::splat(f32::NAN)), Vec3::ZERO);
    let mut bad = device.clone();
    bad.photometry.as_mut().unwrap().gamma.y = -1.0;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("photometry.gamma"), "{e}");
}
