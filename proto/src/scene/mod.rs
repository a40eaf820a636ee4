//! The scene model: meshes by content hash, materials, lights, devices
//! (projectors, cameras, CRT faces), observers, and the `Showcase` that
//! ties them together. Units are metres, the world is right-handed with y
//! up, colour is linear RGB.

use glam::Vec3;
use serde::{Deserialize, Serialize};

mod device;
mod face;
mod light;
mod mesh;
mod object;

pub use device::*;
pub use face::*;
pub use light::*;
pub use mesh::*;
pub use object::*;

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
    /// What the outputs show of the light: direct light only, or global
    /// illumination.
    #[serde(default)]
    pub illumination: IlluminationMode,
    /// The largest radiosity patch (m^2) this scene is meshed with for
    /// global illumination (scene file key `patch_area`); `None`: the
    /// solver's default. A command's own setting overrides it.
    #[serde(default)]
    pub patch_area: Option<f64>,
}

/// The range [`Showcase::patch_area`] must lie in (m^2): from 1 mm^2 to
/// 100 m^2.
pub const PATCH_AREA_RANGE: std::ops::RangeInclusive<f64> = 1e-6..=100.0;

/// What a scene's outputs show (scene file key `illumination`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IlluminationMode {
    /// Direct light (paper section 5): sharp shadows and occlusion
    /// shadows, no interreflection.
    #[default]
    Direct,
    /// Direct light plus the radiosity solution's indirect light (paper
    /// section 4), solved by the master and sent to the nodes.
    Global,
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
    /// The global-illumination solution this frame is drawn with
    /// ([`crate::message::Illumination::version`]); `None`: direct light.
    #[serde(default)]
    pub illumination_version: Option<u64>,
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
mod tests;
