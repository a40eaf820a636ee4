//! Unit tests of the scene model: device projection round trips, mesh
//! hashing, validation of scene parts.

use super::*;
use crate::validate::Validate;
use glam::{DVec2, DVec3};

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
