//! The scene model: meshes by content hash, materials, lights, devices
//! (projectors, cameras, CRT faces), observers, and the `Showcase` that
//! ties them together. Units are metres, the world is right-handed with y
//! up, colour is linear RGB.

use glam::{DMat3, DMat4, DVec3, DVec4, Mat4, Quat, Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Content hash of a [`Mesh`] (BLAKE3 over its canonical little-endian bytes).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct MeshId(pub [u8; 32]);

impl fmt::Display for MeshId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in &self.0[..8] {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for MeshId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MeshId({self})")
    }
}

/// An indexed triangle mesh in object space. Triangles wind counter-clockwise
/// seen from the side their normal points to.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex normals: empty (use face normals) or one per position.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates: empty or one per position.
    pub uvs: Vec<Vec2>,
    /// Triangles as indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// The content hash that names this mesh on the wire and in caches.
    pub fn id(&self) -> MeshId {
        let mut h = blake3::Hasher::new();
        h.update(&(self.positions.len() as u64).to_le_bytes());
        for p in &self.positions {
            for c in p.to_array() {
                h.update(&c.to_le_bytes());
            }
        }
        h.update(&(self.normals.len() as u64).to_le_bytes());
        for n in &self.normals {
            for c in n.to_array() {
                h.update(&c.to_le_bytes());
            }
        }
        h.update(&(self.uvs.len() as u64).to_le_bytes());
        for t in &self.uvs {
            for c in t.to_array() {
                h.update(&c.to_le_bytes());
            }
        }
        h.update(&(self.triangles.len() as u64).to_le_bytes());
        for t in &self.triangles {
            for i in t {
                h.update(&i.to_le_bytes());
            }
        }
        MeshId(*h.finalize().as_bytes())
    }

    /// Axis-aligned bounds `(min, max)`; `None` for a mesh with no vertices.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }

    /// Total surface area of all triangles.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }
}

/// A mesh with its content hash, as carried inline in a snapshot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshEntry {
    /// Must equal `mesh.id()`; checked on validation.
    pub id: MeshId,
    /// The mesh data.
    pub mesh: Mesh,
}

impl MeshEntry {
    /// Wrap a mesh with its computed content hash.
    pub fn new(mesh: Mesh) -> Self {
        Self {
            id: mesh.id(),
            mesh,
        }
    }
}

/// Whether an object physically exists in the cabinet or is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ObjectKind {
    /// A physical object; its mesh is the registered phantom.
    Real,
    /// A purely virtual object, drawn on the CRT faces.
    Virtual,
}

/// A procedural albedo texture, evaluated from the mesh's texture coordinates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum AlbedoTexture {
    /// Squares of `cells` x `cells` alternating between `a` and `b`.
    Checker {
        /// Cells along each texture axis.
        cells: u32,
        /// First colour.
        a: Vec3,
        /// Second colour.
        b: Vec3,
    },
    /// A wood-like pattern: smooth ring gradients plus sharp-edged inlay
    /// bands, standing in for the paper's wooden plate.
    Wood {
        /// Colour of the light wood.
        light: Vec3,
        /// Colour of the dark grain.
        dark: Vec3,
        /// Number of growth rings across the plate.
        rings: f32,
    },
}

impl AlbedoTexture {
    /// Albedo at texture coordinate `uv` (wrapped into `[0, 1)`).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let u = uv.x - uv.x.floor();
        let v = uv.y - uv.y.floor();
        match self {
            AlbedoTexture::Checker { cells, a, b } => {
                let n = (*cells).max(1) as f32;
                let (i, j) = ((u * n) as u32, (v * n) as u32);
                if (i + j) % 2 == 0 { *a } else { *b }
            }
            AlbedoTexture::Wood { light, dark, rings } => {
                // Inlay border: a sharp dark band near the plate's edge.
                let edge = u.min(v).min(1.0 - u).min(1.0 - v);
                if (0.04..0.07).contains(&edge) {
                    return *dark;
                }
                // Rings around an off-centre pith: a smooth gradient.
                let d = ((u - 0.3) * (u - 0.3) + (v - 1.4) * (v - 1.4)).sqrt();
                let t = 0.5 + 0.5 * (d * rings * std::f32::consts::TAU).sin();
                light.lerp(*dark, t * t * 0.8)
            }
        }
    }
}

/// Surface appearance of an object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Diffuse albedo in `[0, 1)` per channel. For a real object in the
    /// simulated showcase this is its true reflectance.
    pub albedo: Vec3,
    /// Spatially varying albedo; replaces `albedo` where present.
    pub texture: Option<AlbedoTexture>,
    /// A captured reflectance map (by name) to use instead of `albedo` when
    /// rendering a real object's surface.
    pub reflectance_map: Option<String>,
    /// Emitted radiance (W/m^2/sr); its exitance is `pi * emission`.
    pub emission: Vec3,
    /// The surface has a specular lobe (excluded from reflectance capture).
    pub specular: bool,
    /// The surface mirrors its environment (a cube map is rendered for it).
    pub reflective: bool,
}

impl Material {
    /// A plain diffuse material.
    pub fn diffuse(albedo: Vec3) -> Self {
        Self {
            albedo,
            texture: None,
            reflectance_map: None,
            emission: Vec3::ZERO,
            specular: false,
            reflective: false,
        }
    }

    /// Albedo at a texture coordinate (the texture if any, else `albedo`).
    pub fn albedo_at(&self, uv: Vec2) -> Vec3 {
        match &self.texture {
            Some(t) => t.sample(uv),
            None => self.albedo,
        }
    }

    /// True where the material emits light.
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// A rigid transform with non-uniform scale: `T * R * S`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation in metres.
    pub translation: Vec3,
    /// Rotation (unit quaternion).
    pub rotation: Quat,
    /// Scale per axis.
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        translation: Vec3::ZERO,
        rotation: Quat::IDENTITY,
        scale: Vec3::ONE,
    };

    /// Object-to-world matrix.
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// A placed object of the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Object {
    /// Unique name, e.g. `room/floor`.
    pub name: String,
    /// The mesh, by content hash.
    pub mesh: MeshId,
    /// Its material.
    pub material: Material,
    /// Real (phantom) or virtual.
    pub kind: ObjectKind,
    /// Object-to-world transform.
    pub transform: Transform,
}

/// A virtual light source. Intensities are radiometric and linear RGB.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Light {
    /// An isotropic point light of radiant intensity `intensity` (W/sr).
    Point {
        /// Position in world space.
        position: Vec3,
        /// Radiant intensity per channel (W/sr).
        intensity: Vec3,
    },
    /// A spot light: a point light restricted to a cone with a smooth edge.
    Spot {
        /// Position in world space.
        position: Vec3,
        /// Axis of the cone (need not be normalised; must be non-zero).
        direction: Vec3,
        /// Radiant intensity on the axis (W/sr).
        intensity: Vec3,
        /// Full intensity inside this half-angle (degrees).
        inner_deg: f32,
        /// Zero intensity outside this half-angle (degrees).
        outer_deg: f32,
    },
    /// A one-sided parallelogram emitter `corner + s*edge_u + t*edge_v`,
    /// `s, t` in `[0, 1]`, emitting along `edge_u x edge_v`.
    Area {
        /// One corner.
        corner: Vec3,
        /// First edge.
        edge_u: Vec3,
        /// Second edge.
        edge_v: Vec3,
        /// Emitted radiance (W/m^2/sr).
        radiance: Vec3,
        /// Point samples used by interactive passes (at least 1).
        samples: u32,
    },
}

impl Light {
    /// A representative position (the centre of an area light).
    pub fn position(&self) -> Vec3 {
        match self {
            Light::Point { position, .. } | Light::Spot { position, .. } => *position,
            Light::Area {
                corner,
                edge_u,
                edge_v,
                ..
            } => *corner + 0.5 * (*edge_u + *edge_v),
        }
    }
}

/// A named light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightSource {
    /// Unique name.
    pub name: String,
    /// The light.
    pub light: Light,
}

/// A pinhole device in the OpenCV convention: `x_cam = R X + t`,
/// pixel `~ K x_cam`, x right, y down, z forward, pixel centres at
/// integer + 0.5 with the origin at the top-left.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PinholeDevice {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Intrinsic matrix K (upper triangular, includes skew).
    pub k: DMat3,
    /// World-to-device rotation R.
    pub rotation: DMat3,
    /// World-to-device translation t.
    pub translation: DVec3,
    /// Distortion `[k1, k2, p1, p2, k3]` (OpenCV order).
    pub dist_coeffs: [f64; 5],
    /// Near plane distance (metres, along +z).
    pub near: f64,
    /// Far plane distance (metres, along +z).
    pub far: f64,
}

impl PinholeDevice {
    /// A device at `eye` looking at `target`, with `up` roughly up and a
    /// horizontal field of view of `fov_x_deg` degrees; square pixels, no
    /// skew, principal point at the image centre.
    pub fn look_at(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        fov_x_deg: f64,
        width: u32,
        height: u32,
    ) -> Self {
        let z = (target - eye).normalize();
        // OpenCV y points down, so x = z x up points right.
        let x = z.cross(up).normalize();
        let y = z.cross(x);
        let rotation = DMat3::from_cols(x, y, z).transpose();
        let f = 0.5 * width as f64 / (0.5 * fov_x_deg.to_radians()).tan();
        let k = DMat3::from_cols(
            DVec3::new(f, 0.0, 0.0),
            DVec3::new(0.0, f, 0.0),
            DVec3::new(0.5 * width as f64, 0.5 * height as f64, 1.0),
        );
        Self {
            width,
            height,
            k,
            rotation,
            translation: -(rotation * eye),
            dist_coeffs: [0.0; 5],
            near: 0.01,
            far: 100.0,
        }
    }

    /// Centre of projection in world space, `-R^T t`.
    pub fn center(&self) -> DVec3 {
        -(self.rotation.transpose() * self.translation)
    }

    /// The 3x4 projection matrix `P = K [R | t]`, as rows.
    pub fn projection(&self) -> [[f64; 4]; 3] {
        let kr = self.k * self.rotation;
        let kt = self.k * self.translation;
        std::array::from_fn(|r| {
            let row = kr.row(r);
            [row.x, row.y, row.z, kt[r]]
        })
    }

    /// World point to device coordinates `x_cam = R X + t`.
    pub fn to_device(&self, world: DVec3) -> DVec3 {
        self.rotation * world + self.translation
    }

    /// Project a world point to a pixel (ignores distortion). `None` when
    /// the point is not in front of the device.
    pub fn project(&self, world: DVec3) -> Option<glam::DVec2> {
        let c = self.to_device(world);
        if c.z <= 0.0 {
            return None;
        }
        let p = self.k * (c / c.z);
        Some(glam::DVec2::new(p.x, p.y))
    }

    /// The world-space unit direction of the ray through `pixel` (ignores
    /// distortion). Rays start at [`Self::center`].
    pub fn unproject(&self, pixel: glam::DVec2) -> DVec3 {
        let d = self.k.inverse() * DVec3::new(pixel.x, pixel.y, 1.0);
        (self.rotation.transpose() * d).normalize()
    }

    /// World-to-device 4x4 matrix (OpenCV camera space).
    pub fn view_matrix(&self) -> DMat4 {
        let r = self.rotation;
        DMat4::from_cols(
            r.x_axis.extend(0.0),
            r.y_axis.extend(0.0),
            r.z_axis.extend(0.0),
            self.translation.extend(1.0),
        )
    }

    /// The one documented mapping of this device to wgpu clip space:
    /// OpenCV camera space (y down, z forward) to clip space (y up, depth
    /// `0..1` from `near` to `far`), such that the device's pixel position
    /// `(u, v)` maps to the framebuffer position `(u, v)` of a
    /// `width x height` target, so pixel centres `(i + 0.5, j + 0.5)` line
    /// up on both sides.
    pub fn clip_from_world(&self) -> DMat4 {
        let (w, h) = (self.width as f64, self.height as f64);
        let (n, f) = (self.near, self.far);
        let k = self.k;
        let (fx, s, cx) = (k.x_axis.x, k.y_axis.x, k.z_axis.x);
        let (fy, cy) = (k.y_axis.y, k.z_axis.y);
        // ndc_x = 2u/w - 1, ndc_y = 1 - 2v/h, ndc_z = f(z - n) / (z (f - n)).
        let proj = DMat4::from_cols(
            DVec4::new(2.0 * fx / w, 0.0, 0.0, 0.0),
            DVec4::new(2.0 * s / w, -2.0 * fy / h, 0.0, 0.0),
            DVec4::new(2.0 * cx / w - 1.0, 1.0 - 2.0 * cy / h, f / (f - n), 1.0),
            DVec4::new(0.0, 0.0, -f * n / (f - n), 0.0),
        );
        proj * self.view_matrix()
    }
}

/// Projector photometry: radiance out = `eta * response(pixel) + black_level`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProjectorResponse {
    /// Exponent of the pixel-value response curve (`value^gamma`).
    pub gamma: f32,
    /// Peak intensity eta (W/sr at pixel value 1).
    pub eta: f32,
    /// Light emitted at pixel value 0 (W/sr).
    pub black_level: f32,
    /// DLP colour-wheel segments as RGB transmissions over one wheel turn;
    /// empty for a projector without time slicing.
    pub wheel_segments: Vec<Vec3>,
    /// Duration of one wheel turn in seconds.
    pub wheel_period_s: f32,
}

impl Default for ProjectorResponse {
    fn default() -> Self {
        Self {
            gamma: 2.2,
            eta: 1.0,
            black_level: 0.0,
            wheel_segments: Vec::new(),
            wheel_period_s: 1.0 / 120.0,
        }
    }
}

/// Camera photometry: value = response(exposure * radiance + noise), then
/// 8-bit quantisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraResponse {
    /// Exponent applied to the normalised signal (`signal^(1/gamma)`).
    pub gamma: f32,
    /// Signal per unit radiance and second.
    pub gain: f32,
    /// Exposure time in seconds.
    pub exposure_s: f32,
    /// Standard deviation of read noise, as a fraction of full scale.
    pub read_noise: f32,
    /// Shot-noise scale: the variance is `shot_noise * signal`.
    pub shot_noise: f32,
    /// Bits per channel of the quantised output.
    pub bits: u32,
}

impl Default for CameraResponse {
    fn default() -> Self {
        Self {
            gamma: 1.0,
            gain: 1.0,
            exposure_s: 1.0 / 30.0,
            read_noise: 0.0,
            shot_noise: 0.0,
            bits: 8,
        }
    }
}

/// A video projector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Projector {
    /// Unique name, e.g. `projector-0`.
    pub name: String,
    /// Geometry.
    pub device: PinholeDevice,
    /// Photometry.
    pub response: ProjectorResponse,
}

/// A video camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Unique name, e.g. `camera-0`.
    pub name: String,
    /// Geometry.
    pub device: PinholeDevice,
    /// Photometry.
    pub response: CameraResponse,
}

/// A planar rectangle `origin + s*right + t*down`, `s, t` in `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rect3 {
    /// The top-left corner (pixel `(0, 0)` of a screen).
    pub origin: Vec3,
    /// The top edge, left to right.
    pub right: Vec3,
    /// The left edge, top to bottom.
    pub down: Vec3,
}

impl Rect3 {
    /// Unit normal, `down x right` (towards the viewer of a screen).
    pub fn normal(&self) -> Vec3 {
        self.down.cross(self.right).normalize_or_zero()
    }
}

/// A plane `normal . x = offset` with a unit normal.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    /// Unit normal.
    pub normal: Vec3,
    /// Signed distance of the plane from the origin along `normal`.
    pub offset: f32,
}

impl Plane {
    /// The plane through `point` with normal `normal` (normalised here).
    pub fn from_point_normal(point: Vec3, normal: Vec3) -> Self {
        let n = normal.normalize_or_zero();
        Self {
            normal: n,
            offset: n.dot(point),
        }
    }

    /// Mirror image of a point in this plane.
    pub fn reflect_point(&self, p: Vec3) -> Vec3 {
        p - 2.0 * (self.normal.dot(p) - self.offset) * self.normal
    }
}

/// A CRT screen seen through a half-silvered mirror.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CrtFace {
    /// Unique name, e.g. `face-0`.
    pub name: String,
    /// The screen's displayed area in world coordinates.
    pub screen: Rect3,
    /// The beam-splitter plane that reflects the screen.
    pub mirror: Plane,
    /// Horizontal resolution.
    pub width: u32,
    /// Vertical resolution.
    pub height: u32,
    /// Display gamma applied at the device boundary.
    pub gamma: f32,
}

/// A rigid pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position in metres.
    pub position: Vec3,
    /// Orientation; the head looks along its local -z with y up.
    pub orientation: Quat,
}

impl Default for Pose {
    fn default() -> Self {
        Self {
            position: Vec3::ZERO,
            orientation: Quat::IDENTITY,
        }
    }
}

/// A head-tracked observer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Observer {
    /// Unique name.
    pub name: String,
    /// Head pose (centre between the eyes).
    pub head: Pose,
    /// Interpupillary distance in metres.
    pub ipd: f32,
}

impl Observer {
    /// Interpupillary distance (metres) of an observer whose scene does
    /// not give one, and of tracked heads beyond the scene's observers:
    /// the adult mean.
    pub const DEFAULT_IPD: f32 = 0.064;

    /// Left and right eye positions for a head pose.
    pub fn eyes(head: &Pose, ipd: f32) -> [Vec3; 2] {
        let right = head.orientation * Vec3::X;
        [
            head.position - 0.5 * ipd * right,
            head.position + 0.5 * ipd * right,
        ]
    }
}

/// The whole showcase: geometry, materials, lights, devices and observers.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Showcase {
    /// A human-readable name.
    pub name: String,
    /// Meshes, inline, by content hash.
    pub meshes: Vec<MeshEntry>,
    /// Placed objects.
    pub objects: Vec<Object>,
    /// Virtual lights.
    pub lights: Vec<LightSource>,
    /// Projectors.
    pub projectors: Vec<Projector>,
    /// Cameras.
    pub cameras: Vec<Camera>,
    /// CRT faces.
    pub faces: Vec<CrtFace>,
    /// Observers (their initial head poses).
    pub observers: Vec<Observer>,
    /// Ambient irradiance blended into shadows (W/m^2 per channel).
    pub ambient: Vec3,
}

impl Showcase {
    /// The mesh with this content hash.
    pub fn mesh(&self, id: &MeshId) -> Option<&Mesh> {
        self.meshes.iter().find(|m| &m.id == id).map(|m| &m.mesh)
    }

    /// Add a mesh (deduplicated by content hash) and return its id.
    pub fn add_mesh(&mut self, mesh: Mesh) -> MeshId {
        let id = mesh.id();
        if self.mesh(&id).is_none() {
            self.meshes.push(MeshEntry { id, mesh });
        }
        id
    }

    /// The index of the object with this name.
    pub fn object_index(&self, name: &str) -> Option<usize> {
        self.objects.iter().position(|o| o.name == name)
    }
}

/// The per-frame state the master broadcasts to every node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameState {
    /// Frame number, increasing by one per frame.
    pub frame: u64,
    /// Show time in seconds (drives animation; seeds per-frame randomness).
    pub time_s: f64,
    /// Version of the scene this frame refers to (matches the snapshot).
    pub scene_version: u64,
    /// Head pose of each observer, in `Showcase::observers` order.
    pub heads: Vec<Pose>,
    /// Current lights, replacing `Showcase::lights` for this frame.
    pub lights: Vec<LightSource>,
    /// Object transforms that differ from the snapshot.
    pub object_transforms: Vec<ObjectTransform>,
    /// Master-clock time (ns) of the newest tracking sample in this frame.
    pub tracking_time_ns: Option<u64>,
}

/// A new transform for one object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectTransform {
    /// Index into `Showcase::objects`.
    pub object: u32,
    /// The transform for this frame.
    pub transform: Transform,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::Validate;
    use glam::DVec2;

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
}
