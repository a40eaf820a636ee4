//! Objects: real or virtual, their materials (albedo, procedural texture,
//! reflectance-map reference, emission, specular and reflective flags) and
//! their placement in the world.

use super::MeshId;
use glam::{Mat4, Quat, Vec2, Vec3};
use serde::{Deserialize, Serialize};

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
