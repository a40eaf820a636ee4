//! The renderer a real node runs: it drives the scene output it is named
//! for (a projector or a CRT face), found by name in each scene snapshot,
//! with the wgpu renderers of `crate::render`.
//!
//! A face serves the observer standing in front of its mirror
//! ([`observer_in_front`]), chosen again with every snapshot.

use super::renderer::{RenderError, RenderOutput, Renderer};
use crate::gpu::GpuContext;
use crate::render::face_gpu::FaceRenderer;
use crate::render::illumination::FieldCache;
use crate::render::projector_gpu::ProjectorRenderer;
use showcase_proto::{FrameState, Role, Showcase};
use std::sync::Arc;

/// The observer a face serves: the one farthest in front of its mirror
/// (on the side the mirror's normal points to); `None` when nobody stands
/// in front of it.
pub fn observer_in_front(scene: &Showcase, face: usize) -> Option<usize> {
    let m = scene.faces.get(face)?.mirror;
    scene
        .observers
        .iter()
        .enumerate()
        .map(|(i, o)| (i, m.normal.dot(o.head.position) - m.offset))
        .filter(|(_, d)| *d > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

enum Inner {
    None,
    Projector(Box<ProjectorRenderer>),
    Face(Box<FaceRenderer>),
}

/// Renders the output called `output` in role `role` of whatever scene the
/// master sends.
pub struct OutputRenderer {
    ctx: GpuContext,
    output: String,
    role: Role,
    shadow_res: u32,
    inner: Inner,
}

impl std::fmt::Debug for OutputRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OutputRenderer")
            .field("output", &self.output)
            .field("role", &self.role)
            .field("shadow_res", &self.shadow_res)
            .finish_non_exhaustive()
    }
}

impl OutputRenderer {
    /// The current renderer's mesh cache of the master's solutions: its
    /// scene mesh outlives a rejoin (meshing again would make the node
    /// late for its first frames).
    fn take_fields(&mut self) -> FieldCache {
        match &mut self.inner {
            Inner::Projector(r) => r.take_fields(),
            Inner::Face(r) => r.take_fields(),
            Inner::None => FieldCache::default(),
        }
    }

    /// A renderer for `output` (a projector's or a face's name) in `role`
    /// on `ctx`, with shadow maps of `shadow_res` texels a side. Cameras
    /// capture rather than render: `role` must be a projector or a face.
    pub fn new(
        ctx: GpuContext,
        output: impl Into<String>,
        role: Role,
        shadow_res: u32,
    ) -> Result<Self, RenderError> {
        let output = output.into();
        if !matches!(role, Role::Projector | Role::Face) {
            return Err(RenderError::NoRenderer { output, role });
        }
        Ok(Self {
            ctx,
            output,
            role,
            shadow_res,
            inner: Inner::None,
        })
    }
}

impl Renderer for OutputRenderer {
    fn set_scene(&mut self, version: u64, scene: Arc<Showcase>) -> Result<(), RenderError> {
        let inner = match self.role {
            Role::Projector => {
                let index = scene
                    .projectors
                    .iter()
                    .position(|p| p.name == self.output)
                    .ok_or_else(|| RenderError::NoOutput {
                        role: "projector",
                        name: self.output.clone(),
                        have: scene.projectors.iter().map(|p| p.name.clone()).collect(),
                    })?;
                let fields = self.take_fields();
                Inner::Projector(Box::new(
                    ProjectorRenderer::new(self.ctx.clone(), index, self.shadow_res)
                        .with_fields(fields),
                ))
            }
            _ => {
                let index = scene
                    .faces
                    .iter()
                    .position(|f| f.name == self.output)
                    .ok_or_else(|| RenderError::NoOutput {
                        role: "face",
                        name: self.output.clone(),
                        have: scene.faces.iter().map(|f| f.name.clone()).collect(),
                    })?;
                let observer =
                    observer_in_front(&scene, index).ok_or_else(|| RenderError::NoObserver {
                        face: self.output.clone(),
                    })?;
                let fields = self.take_fields();
                Inner::Face(Box::new(
                    FaceRenderer::new(self.ctx.clone(), index, observer, self.shadow_res)
                        .with_fields(fields),
                ))
            }
        };
        self.inner = inner;
        match &mut self.inner {
            Inner::Projector(r) => r.set_scene(version, scene),
            Inner::Face(r) => r.set_scene(version, scene),
            Inner::None => Ok(()),
        }
    }

    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<showcase_proto::session::Solution>>,
    ) -> Result<(), RenderError> {
        match &mut self.inner {
            Inner::Projector(r) => r.set_illumination(illumination),
            Inner::Face(r) => r.set_illumination(illumination),
            Inner::None => Ok(()),
        }
    }

    fn prepare_illumination(&mut self, solution: &Arc<showcase_proto::session::Solution>) {
        match &mut self.inner {
            Inner::Projector(r) => r.prepare_illumination(solution),
            Inner::Face(r) => r.prepare_illumination(solution),
            Inner::None => {}
        }
    }

    fn render(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        match &mut self.inner {
            Inner::Projector(r) => r.render(frame, scene),
            Inner::Face(r) => r.render(frame, scene),
            Inner::None => Err(RenderError::NoScene {
                output: self.output.clone(),
                frame: frame.frame,
            }),
        }
    }

    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        match &mut self.inner {
            Inner::Projector(r) => r.present(frame),
            Inner::Face(r) => r.present(frame),
            Inner::None => Ok(()),
        }
    }
}
