//! A node's side of global illumination: the master's solution
//! ([`Solution`], per element of the scene's radiosity mesh) made into the
//! field a projector or a face draws ([`IndirectField`]). The node meshes its own
//! copy of the scene with the solution's mesh options, which gives the
//! master's elements in the master's order; the mesh is kept while the
//! scene (its content, not only its version: a restarted master starts
//! again at version 1) and the options are, so a new version only
//! re-averages the values to the vertices.

use std::sync::Arc;

use glam::DVec3;
use showcase_light::radiosity::{MeshOptions, RadiosityMesh};
use showcase_light::render::{IndirectField, IndirectLight};
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
        let rgb = |v: [f32; 3]| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        let values: Vec<IndirectLight> = solution
            .values
            .iter()
            .map(|v| IndirectLight {
                add: rgb(v.add),
                cabinet: rgb(v.cabinet),
            })
            .collect();
        let field = IndirectField::new(mesh, &values).map_err(|e| {
            problem(format!(
                "{e}: the master and this node mesh the scene differently"
            ))
        })?;
        Ok(Arc::new(field))
    }
}

/// A renderer's global-illumination state: the field drawn with every
/// frame, the solution version it was made from, and the mesh cache.
/// Both roles hold one ([`super::projector_gpu::ProjectorRenderer`],
/// [`super::face_gpu::FaceRenderer`]).
#[derive(Debug, Default)]
pub struct LiveIllumination {
    /// The field drawn with every frame (global mode), if any.
    field: Option<Arc<IndirectField>>,
    /// The version of the master's solution `field` was made from.
    version: Option<u64>,
    /// The field of the solution that arrived last, made on arrival.
    prepared: Option<(Arc<Solution>, Arc<IndirectField>)>,
    fields: FieldCache,
}

impl LiveIllumination {
    /// No field, with the mesh cache `fields` (from [`Self::take_fields`]).
    pub fn with_fields(fields: FieldCache) -> Self {
        Self {
            fields,
            ..Self::default()
        }
    }

    /// The mesh cache, to hand to the renderer that replaces this one (a
    /// new scene or a rejoin), so a rejoining node does not mesh the
    /// scene again.
    pub fn take_fields(&mut self) -> FieldCache {
        std::mem::take(&mut self.fields)
    }

    /// The field drawn with every frame.
    pub fn field(&self) -> Option<&Arc<IndirectField>> {
        self.field.as_ref()
    }

    /// Draw `field` (not from a master's solution: benches and tests).
    pub fn set_field(&mut self, field: Option<Arc<IndirectField>>) {
        self.field = field;
        self.version = None;
    }

    /// A solution arrived: make its field now, on `scene` (the renderer's
    /// scene and its version), for the first frame that names it. Best
    /// effort: a field that cannot be made now is made, or refused with
    /// its error, by [`Self::update`] at that frame.
    pub fn prepare(&mut self, scene: Option<(&Arc<Showcase>, u64)>, solution: &Arc<Solution>) {
        self.prepared = scene.and_then(|(scene, version)| {
            let field = self.fields.field(scene, version, solution).ok()?;
            Some((solution.clone(), field))
        });
    }

    /// Follow the master: `solution` (`None`: direct light) on `scene`,
    /// the renderer's scene and its version. Returns whether the field
    /// changed, so the renderer draws its next frame afresh.
    pub fn update(
        &mut self,
        scene: Option<(&Arc<Showcase>, u64)>,
        solution: Option<&Arc<Solution>>,
    ) -> Result<bool, RenderError> {
        let Some(solution) = solution else {
            if self.version.take().is_some() {
                self.field = None;
                return Ok(true);
            }
            return Ok(false);
        };
        if self.version == Some(solution.version) {
            return Ok(false);
        }
        let prepared = self.prepared.take().filter(|(s, _)| {
            Arc::ptr_eq(s, solution) && scene.is_some_and(|(_, v)| v == solution.scene_version)
        });
        if let Some((_, field)) = prepared {
            self.field = Some(field);
            self.version = Some(solution.version);
            return Ok(true);
        }
        let Some((scene, version)) = scene else {
            return Err(RenderError::Illumination {
                version: solution.version,
                problem: "it arrived before any scene".into(),
            });
        };
        self.field = Some(self.fields.field(scene, version, solution)?);
        self.version = Some(solution.version);
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solution(version: u64, scene_version: u64) -> Arc<Solution> {
        Arc::new(Solution {
            version,
            scene_version,
            mesh: IlluminationMesh {
                max_patch_area: 0.01,
                element_depth: 1,
                min_element_area: 1e-4,
            },
            values: Vec::new(),
        })
    }

    /// The field made when a solution arrives is the one drawn from the
    /// first frame that names that very solution; any other (another
    /// solution of the same version, a solution of another scene version)
    /// is made at its frame, or refused there.
    #[test]
    fn a_field_made_on_arrival_is_drawn_from_its_first_frame() {
        let scene = Arc::new(Showcase::default());
        let held = Some((&scene, 1));
        let mut live = LiveIllumination::default();
        let a = solution(1, 1);
        live.prepare(held, &a);
        let made = live.prepared.as_ref().expect("a field made").1.clone();
        assert!(live.update(held, Some(&a)).unwrap());
        assert!(Arc::ptr_eq(live.field().unwrap(), &made));
        assert!(live.prepared.is_none(), "used once");

        let b = solution(2, 1);
        live.prepare(held, &b);
        let made = live.prepared.as_ref().unwrap().1.clone();
        assert!(live.update(held, Some(&solution(2, 1))).unwrap());
        assert!(!Arc::ptr_eq(live.field().unwrap(), &made));

        let c = solution(3, 1);
        live.prepare(held, &c);
        assert!(live.update(Some((&scene, 2)), Some(&c)).is_err());

        // Nothing is made without a scene, or for another scene version;
        // the frame reports why.
        live.prepare(None, &solution(4, 1));
        live.prepare(Some((&scene, 2)), &solution(5, 1));
        assert!(live.prepared.is_none());
    }
}
