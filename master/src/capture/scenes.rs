//! Scenes for capture and its bench: the textured plate, the Cornell box,
//! the reference target of known reflectance, and the default projector
//! and camera of a capture rig.

use anyhow::Context;
use glam::{DVec3, Vec2, Vec3};
use showcase_proto::{
    AlbedoTexture, Camera, CameraResponse, Material, Mesh, Object, ObjectKind, PinholeDevice,
    Projector, ProjectorResponse, Showcase, Transform,
};
use std::path::Path;

/// True projector photometry of the simulated rig: gamma 2.2, eta 1 W/sr,
/// black level 1% of eta, an RGB colour wheel turning at 120 Hz.
pub fn rig_projector_response() -> ProjectorResponse {
    ProjectorResponse {
        gamma: 2.2,
        eta: 1.0,
        black_level: 0.01,
        wheel_segments: vec![Vec3::X, Vec3::Y, Vec3::Z],
        wheel_period_s: 1.0 / 120.0,
        photometry: None,
    }
}

/// Camera photometry of the rig: linear, 8 bits, read noise 1% of full
/// scale, an exposure of three quarters of a wheel turn (so one frame sees
/// only part of the colours). `gain` is set per scene by
/// [`super::adjust_camera_gain`].
pub fn rig_camera_response(noise: bool) -> CameraResponse {
    CameraResponse {
        gain: 1.0,
        exposure_s: 0.75 / 120.0,
        read_noise: if noise { 0.01 } else { 0.0 },
        shot_noise: if noise { 1e-4 } else { 0.0 },
        bits: 8,
        ..CameraResponse::default()
    }
}

/// A rectangle `corner + s*u + t*v` as a two-triangle mesh with texture
/// coordinates `(s, t)`, front side along `u x v`.
pub fn quad_mesh(corner: Vec3, u: Vec3, v: Vec3) -> Mesh {
    Mesh {
        positions: vec![corner, corner + u, corner + u + v, corner + v],
        normals: Vec::new(),
        uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// Add a capture rig: projector and camera looking at `target` from
/// `projector_eye` and `camera_eye`.
pub fn add_rig(
    scene: &mut Showcase,
    camera_eye: DVec3,
    projector_eye: DVec3,
    target: DVec3,
    camera_size: (u32, u32),
    noise: bool,
) {
    scene.projectors.push(Projector {
        name: "projector-0".into(),
        device: PinholeDevice::look_at(projector_eye, target, DVec3::Y, 50.0, 160, 160),
        response: rig_projector_response(),
    });
    scene.cameras.push(Camera {
        name: "camera-0".into(),
        device: PinholeDevice::look_at(
            camera_eye,
            target,
            DVec3::Y,
            40.0,
            camera_size.0,
            camera_size.1,
        ),
        response: rig_camera_response(noise),
    });
}

/// The textured plate (the paper's wooden plate): a 0.4 m x 0.3 m board on
/// the floor with the procedural wood texture (smooth ring gradients and a
/// sharp inlay band), seen from above at an angle.
pub fn plate_scene(camera_size: (u32, u32), noise: bool) -> Showcase {
    let mut s = Showcase {
        name: "plate".into(),
        ..Showcase::default()
    };
    let mesh = s.add_mesh(quad_mesh(
        Vec3::new(-0.2, 0.0, 0.15),
        Vec3::new(0.4, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -0.3),
    ));
    let mut material = Material::diffuse(Vec3::splat(0.5));
    material.texture = Some(AlbedoTexture::Wood {
        light: Vec3::new(0.8, 0.6, 0.4),
        dark: Vec3::new(0.3, 0.15, 0.07),
        rings: 5.0,
    });
    s.objects.push(Object {
        name: "plate".into(),
        mesh,
        material,
        kind: ObjectKind::Real,
        transform: Transform::IDENTITY,
    });
    add_rig(
        &mut s,
        DVec3::new(0.0, 0.45, -0.45),
        DVec3::new(0.15, 0.55, -0.35),
        DVec3::ZERO,
        camera_size,
        noise,
    );
    s
}

/// The Cornell box from `path` (its light off), with the rig in front of
/// its open side.
pub fn cornell_scene(
    path: &Path,
    camera_size: (u32, u32),
    noise: bool,
) -> anyhow::Result<Showcase> {
    let mut s = crate::scene_file::load_any(path)?;
    s.name = "cornell".into();
    add_rig(
        &mut s,
        DVec3::new(0.278, 0.273, -0.75),
        DVec3::new(0.35, 0.30, -0.70),
        DVec3::new(0.278, 0.273, 0.28),
        camera_size,
        noise,
    );
    Ok(s)
}

/// Known albedo of the reference target.
pub const REFERENCE_ALBEDO: f32 = 0.8;

/// The reference target for the projector fit: a flat grey board of known
/// albedo [`REFERENCE_ALBEDO`], facing the camera at the point the rig of
/// `scene` aims at, alone in the showcase, with `scene`'s devices.
pub fn reference_scene(scene: &Showcase) -> anyhow::Result<Showcase> {
    let camera = scene.cameras.first().context("the scene has no camera")?;
    let projector = scene
        .projectors
        .first()
        .context("the scene has no projector")?;
    let eye = camera.device.center();
    let axis = camera.device.rotation.row(2); // device z in world space
    let target = eye + 1.0 * axis;
    // Aim at the midpoint of the camera's and projector's view directions.
    let dir = (axis + projector.device.rotation.row(2)).normalize();
    let normal = -dir;
    let u = normal.cross(DVec3::Y).normalize_or(DVec3::X);
    let v = normal.cross(u);
    let size = 1.5;
    let corner = target - 0.5 * size * (u + v);
    let mut s = Showcase {
        name: "reference".into(),
        projectors: scene.projectors.clone(),
        cameras: scene.cameras.clone(),
        ..Showcase::default()
    };
    // Wind so the front faces the devices: (u x v) must point along normal.
    let (a, b) = if u.cross(v).dot(normal) > 0.0 {
        (u, v)
    } else {
        (v, u)
    };
    let mesh = s.add_mesh(quad_mesh(
        corner.as_vec3(),
        (size * a).as_vec3(),
        (size * b).as_vec3(),
    ));
    s.objects.push(Object {
        name: "reference".into(),
        mesh,
        material: Material::diffuse(Vec3::splat(REFERENCE_ALBEDO)),
        kind: ObjectKind::Real,
        transform: Transform::IDENTITY,
    });
    Ok(s)
}
