//! The master's side of `showcase-master bench render`: the bench's scene
//! built from the shared data set's Cornell box and bunny (the bench
//! itself is `showcase_render::render::bench`).

use crate::scene_file::{SceneError, load_any};
use showcase_proto::Showcase;
use std::path::Path;

/// The Cornell box's objects that make the bench's real room: its walls,
/// without the blocks and the light.
pub const CORNELL_WALLS: [&str; 5] = ["floor", "ceiling", "back", "right_green", "left_red"];

/// Why the render bench's scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BenchSceneError {
    /// A mesh file could not be loaded.
    #[error(transparent)]
    Load(#[from] SceneError),
    /// The bunny's file holds no object with a mesh.
    #[error("{0} has no mesh")]
    NoMesh(String),
}

/// The render bench's scene ([`showcase_render::render::bench::bench_scene`])
/// from the Cornell box OBJ at `cornell` (the walls of [`CORNELL_WALLS`]
/// it has, with their albedo) and the mesh of the first object of the
/// bunny OBJ at `bunny`.
pub fn bench_scene(cornell: &Path, bunny: &Path) -> Result<Showcase, BenchSceneError> {
    let room = load_any(cornell)?;
    let walls = room
        .objects
        .iter()
        .filter(|o| CORNELL_WALLS.contains(&o.name.as_str()))
        .filter_map(|o| {
            Some((
                o.name.clone(),
                room.mesh(&o.mesh)?.clone(),
                o.material.albedo,
            ))
        })
        .collect();
    let model = load_any(bunny)?;
    let bunny_mesh = model
        .objects
        .first()
        .and_then(|o| model.mesh(&o.mesh))
        .ok_or_else(|| BenchSceneError::NoMesh(bunny.display().to_string()))?
        .clone();
    Ok(showcase_render::render::bench::bench_scene(
        walls, bunny_mesh,
    ))
}
