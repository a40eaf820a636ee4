//! A node's side of global illumination: the master's solution
//! ([`Solution`], per element of the scene's radiosity mesh) made into the
//! field a projector draws ([`IndirectField`]). The node meshes its own
//! copy of the scene with the solution's mesh options, which gives the
//! master's elements in the master's order; the mesh is kept while the
//! scene (its content, not only its version: a restarted master starts
//! again at version 1) and the options are, so a new version only
//! re-averages the values to the vertices.

use std::sync::Arc;

use glam::DVec3;
use showcase_light::radiosity::{MeshOptions, RadiosityMesh};
use showcase_light::render::IndirectField;
use showcase_light::{ObjectFilter, SceneGeometry};
use showcase_proto::Showcase;
use showcase_proto::message::IlluminationMesh;
use showcase_proto::session::Solution;

use super::RenderError;

/// The mesh of the last solution's scene, kept across versions.
#[derive(Debug, Default)]
pub struct FieldCache {
    mesh: Option<(Arc<Showcase>, IlluminationMesh, Arc<RadiosityMesh>)>,
}

impl FieldCache {
    /// The field of `solution` on `scene` (scene version `scene_version`,
    /// which must be the solution's).
    pub fn field(
        &mut self,
        scene: &Arc<Showcase>,
        scene_version: u64,
        solution: &Solution,
    ) -> Result<Arc<IndirectField>, RenderError> {
        let problem = |problem: String| RenderError::Illumination {
            version: solution.version,
            problem,
        };
        if solution.scene_version != scene_version {
            return Err(problem(format!(
                "it was solved for scene version {}, the renderer holds {scene_version}",
                solution.scene_version
            )));
        }
        let mesh = match &self.mesh {
            Some((s, options, m))
                if *options == solution.mesh && (Arc::ptr_eq(s, scene) || **s == **scene) =>
            {
                m.clone()
            }
            _ => {
                let geometry = SceneGeometry::build(scene, &ObjectFilter::All)?;
                let options = MeshOptions {
                    max_patch_area: solution.mesh.max_patch_area,
                    element_depth: solution.mesh.element_depth,
                    min_element_area: solution.mesh.min_element_area,
                    ..MeshOptions::default()
                };
                let m = RadiosityMesh::build(scene, &geometry, &options)
                    .map_err(|e| problem(format!("meshing the scene: {e}")))?;
                let m = Arc::new(m);
                self.mesh = Some((scene.clone(), solution.mesh, m.clone()));
                m
            }
        };
        let values: Vec<DVec3> = solution
            .values
            .iter()
            .map(|v| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64))
            .collect();
        let field = IndirectField::new(mesh, &values).map_err(|e| {
            problem(format!(
                "{e}: the master and this node mesh the scene differently"
            ))
        })?;
        Ok(Arc::new(field))
    }
}
