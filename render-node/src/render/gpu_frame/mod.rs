//! The GPU frame layer both roles draw through: a frame's inputs on the
//! CPU ([`inputs`]: light samples with their cube views, the eyes with
//! views fitted around the virtual objects' bounds, the shadow far
//! plane), the scene's vertex buffers ([`scene_buffers`]), the shadow
//! stage ([`shadow_stage`]: maps, bind group, layer encoding, occluder
//! culling as the role's choice) and the encoder that times a frame's
//! steps ([`timed`]). A role's pipeline adds only its own pass.

pub mod inputs;
pub mod scene_buffers;
pub mod shadow_stage;
pub mod timed;

pub use inputs::{FrameInputs, light_inputs, shadow_far, stable_far};
pub use scene_buffers::{
    ObjectRange, SceneBuffers, VertexSet, WorldVertices, world_vertices_by_object,
};
pub use shadow_stage::{DEFAULT_SHADOW_RES, LightOccluders, ShadowStage};
pub use timed::{PassTimes, TimedEncoder};
