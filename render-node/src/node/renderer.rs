//! The seam a node drives its output through, as the runtime sees it
//! ([`Renderer`], declared with the real-time renderers in
//! `crate::render::renderer`), and [`StateHashRenderer`], a renderer for
//! tests and replay checks that renders nothing but a deterministic
//! digest of exactly what it was asked to draw.

pub use crate::render::renderer::{
    OutputImage, RenderError, RenderOutput, Renderer, check_scene_version,
};
use showcase_light::digest::Fnv64;
use showcase_proto::session::Solution;
use showcase_proto::{FrameState, Role, Showcase};
use std::sync::Arc;

/// A renderer that draws nothing and digests exactly the state a real one
/// would draw for its output: the frame number, the scene version, the
/// heads, the lights, the object transforms and the global-illumination
/// solution (its version and values), bit for bit. Used by the cluster
/// tests and replay checks, which must not wait on a GPU.
#[derive(Debug)]
pub struct StateHashRenderer {
    output: String,
    role: Role,
    scene_version: Option<u64>,
    /// The solution drawn, with a digest of its values.
    illumination: Option<(Arc<Solution>, u64)>,
    /// The solution that arrived last, digested on arrival.
    prepared: Option<(Arc<Solution>, u64)>,
}

/// A digest of a solution's values, bit for bit.
fn values_digest(s: &Solution) -> u64 {
    let mut h = Fnv64::default();
    for c in s.values.iter().flat_map(|v| v.channels()) {
        h.write(&c.to_bits().to_le_bytes());
    }
    h.finish()
}

impl StateHashRenderer {
    /// A renderer for the output called `output` in role `role`.
    pub fn new(output: impl Into<String>, role: Role) -> Self {
        Self {
            output: output.into(),
            role,
            scene_version: None,
            illumination: None,
            prepared: None,
        }
    }
}

impl Renderer for StateHashRenderer {
    fn set_scene(&mut self, version: u64, _scene: Arc<Showcase>) -> Result<(), RenderError> {
        self.scene_version = Some(version);
        Ok(())
    }

    fn prepare_illumination(&mut self, solution: &Arc<Solution>) {
        self.prepared = Some((solution.clone(), values_digest(solution)));
    }

    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<Solution>>,
    ) -> Result<(), RenderError> {
        // Called before every frame: digest a solution once, on arrival
        // where it was announced.
        let Some(s) = illumination else {
            self.illumination = None;
            return Ok(());
        };
        let same = |held: &Option<(Arc<Solution>, u64)>| {
            held.as_ref().is_some_and(|(h, _)| Arc::ptr_eq(h, s))
        };
        if same(&self.illumination) {
            return Ok(());
        }
        self.illumination = if same(&self.prepared) {
            self.prepared.take()
        } else {
            Some((s.clone(), values_digest(s)))
        };
        Ok(())
    }

    fn render(
        &mut self,
        frame: &FrameState,
        _scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        check_scene_version(&self.output, frame, self.scene_version)?;
        let mut h = Fnv64::default();
        h.write(self.output.as_bytes());
        h.write(&[self.role as u8]);
        h.write(&frame.frame.to_le_bytes());
        h.write(&frame.scene_version.to_le_bytes());
        h.write(&frame.time_s.to_bits().to_le_bytes());
        for p in &frame.heads {
            for c in p
                .position
                .to_array()
                .into_iter()
                .chain(p.orientation.to_array())
            {
                h.write(&c.to_bits().to_le_bytes());
            }
        }
        for l in &frame.lights {
            h.write(l.name.as_bytes());
            for c in l.light.position().to_array() {
                h.write(&c.to_bits().to_le_bytes());
            }
        }
        for t in &frame.object_transforms {
            h.write(&t.object.to_le_bytes());
            let m = t.transform.matrix().to_cols_array();
            for c in m {
                h.write(&c.to_bits().to_le_bytes());
            }
        }
        if let Some((solution, values)) = &self.illumination {
            h.write(&solution.version.to_le_bytes());
            h.write(&values.to_le_bytes());
        }
        Ok(RenderOutput {
            hash: h.finish(),
            image: None,
        })
    }

    fn present(&mut self, _frame: u64) -> Result<(), RenderError> {
        // Nothing to show: the hash is the output.
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frame 3 of scene version 1, with nothing in it.
    fn frame_3() -> FrameState {
        FrameState {
            frame: 3,
            time_s: 0.05,
            scene_version: 1,
            heads: vec![],
            lights: vec![],
            object_transforms: vec![],
            tracking_time_ns: Some(7),
            illumination_version: None,
        }
    }

    #[test]
    fn state_hash_depends_on_what_is_drawn() {
        let scene = Arc::new(Showcase::default());
        let mut r = StateHashRenderer::new("face-0", Role::Face);
        let mut f = frame_3();
        assert!(r.render(&f, &scene).is_err(), "no scene yet");
        r.set_scene(1, scene.clone()).unwrap();
        let a = r.render(&f, &scene).unwrap().hash;
        assert_eq!(a, r.render(&f, &scene).unwrap().hash);
        // Tracking timestamps are metadata, not drawn.
        f.tracking_time_ns = Some(8);
        assert_eq!(a, r.render(&f, &scene).unwrap().hash);
        f.time_s = 0.06;
        assert_ne!(a, r.render(&f, &scene).unwrap().hash);
        let mut other = StateHashRenderer::new("face-1", Role::Face);
        other.set_scene(1, scene.clone()).unwrap();
        assert_ne!(
            other.render(&f, &scene).unwrap().hash,
            r.render(&f, &scene).unwrap().hash
        );
    }

    /// A solution digested on arrival draws exactly as one digested at its
    /// first frame, and a prepared one is used only for that very
    /// solution: not for another, even of the same version (a restarted
    /// master numbers its solutions from 1 again).
    #[test]
    fn a_prepared_solution_draws_as_one_digested_at_its_frame() {
        use showcase_proto::message::{ElementLight, IlluminationMesh};
        let solution = |version, add| {
            Arc::new(Solution {
                version,
                scene_version: 1,
                mesh: IlluminationMesh {
                    max_patch_area: 0.01,
                    element_depth: 1,
                    min_element_area: 1e-4,
                },
                values: vec![
                    ElementLight {
                        add: [add, 0.5, 0.25],
                        cabinet: [0.0; 3],
                    };
                    3
                ],
            })
        };
        let (a, b, a_again) = (solution(1, 1.0), solution(2, 2.0), solution(1, 3.0));
        let scene = Arc::new(Showcase::default());
        let f = FrameState {
            illumination_version: Some(1),
            ..frame_3()
        };
        let drawn = |prepare: &[&Arc<Solution>], with: &Arc<Solution>| {
            let mut r = StateHashRenderer::new("projector-0", Role::Projector);
            r.set_scene(1, scene.clone()).unwrap();
            for s in prepare {
                r.prepare_illumination(s);
            }
            r.set_illumination(Some(with)).unwrap();
            r.render(&f, &scene).unwrap().hash
        };
        for with in [&a, &b, &a_again] {
            let unprepared = drawn(&[], with);
            assert_eq!(drawn(&[with], with), unprepared);
            for other in [&a, &b, &a_again] {
                assert_eq!(drawn(&[other], with), unprepared);
            }
        }
        assert_ne!(drawn(&[], &a), drawn(&[], &a_again));
    }
}
