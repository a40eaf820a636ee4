//! The [`Renderer`] a projector node runs: the pass list per frame, the
//! whole frame reused when nothing it depends on changed.

use std::sync::Arc;

use showcase_proto::{FrameState, Showcase};

use crate::gpu::GpuContext;
use crate::render::RenderSetupError;
use crate::render::illumination::{FieldCache, LiveIllumination};
use crate::render::passes::{FrameKey, Pass, PassList};
use crate::render::renderer::{
    OutputImage, RenderError, RenderOutput, Renderer, check_scene_version,
};
use showcase_light::digest::hash_pixels;
use showcase_light::render::IndirectField;
use showcase_light::render::frame::FrameScene;
use showcase_proto::session::Solution;

use super::ProjectorPipeline;

/// What the last [`ProjectorRenderer::render`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    /// Passes run (empty when the last frame was reused).
    pub passes_run: Vec<Pass>,
    /// True when the previous output was reused unchanged.
    pub reused: bool,
    /// Clipped fraction of the output.
    pub clipped_fraction: f64,
}

/// The [`Renderer`] of a projector node.
#[derive(Debug)]
pub struct ProjectorRenderer {
    ctx: GpuContext,
    pipeline: ProjectorPipeline,
    projector: usize,
    scene_version: Option<u64>,
    /// The scene of `scene_version`.
    scene: Option<Arc<Showcase>>,
    /// The global-illumination field drawn with every frame.
    illumination: LiveIllumination,
    /// Run every pass regardless of the pass list (for comparisons).
    pub force_all_passes: bool,
    last: Option<(FrameKey, RenderOutput, f64)>,
    report: FrameReport,
}

impl ProjectorRenderer {
    /// A renderer for `Showcase::projectors[projector]` on `ctx`.
    pub fn new(ctx: GpuContext, projector: usize, shadow_res: u32) -> Self {
        let pipeline = ProjectorPipeline::new(&ctx.device, shadow_res);
        Self {
            ctx,
            pipeline,
            projector,
            scene_version: None,
            scene: None,
            illumination: LiveIllumination::default(),
            force_all_passes: false,
            last: None,
            report: FrameReport::default(),
        }
    }

    /// The mesh cache of the master's solutions, to hand to the renderer
    /// that replaces this one (a new scene or a rejoin), so a rejoining
    /// node does not mesh the scene again.
    pub fn take_fields(&mut self) -> FieldCache {
        self.illumination.take_fields()
    }

    /// This renderer with `fields` (from [`Self::take_fields`]).
    pub fn with_fields(mut self, fields: FieldCache) -> Self {
        self.illumination = LiveIllumination::with_fields(fields);
        self
    }

    /// Draw every following frame with the global-illumination correction
    /// `field` (global mode), or direct light only (`None`, the default).
    pub fn set_indirect(&mut self, field: Option<Arc<IndirectField>>) {
        self.illumination.set_field(field);
        self.last = None;
    }

    /// What the last render did.
    pub fn report(&self) -> &FrameReport {
        &self.report
    }

    /// The GPU context.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    fn render_frame(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        let projector =
            scene
                .projectors
                .get(self.projector)
                .ok_or(RenderSetupError::NoProjector {
                    index: self.projector,
                })?;
        let mut resolved = FrameScene::resolve(scene, frame)?;
        if let Some(field) = self.illumination.field() {
            resolved = resolved.with_indirect(field.clone());
        }
        let passes = if self.force_all_passes {
            PassList::full()
        } else {
            PassList::for_projector(&resolved)
        };
        let key = FrameKey::projector(self.projector, frame, &passes);
        if let Some((last_key, output, clipped)) = &self.last
            && *last_key == key
            && !self.force_all_passes
        {
            self.report = FrameReport {
                passes_run: Vec::new(),
                reused: true,
                clipped_fraction: *clipped,
            };
            return Ok(output.clone());
        }
        self.pipeline
            .draw(&self.ctx, &resolved, projector, &passes, false)?;
        let mut map = self.pipeline.read_output(&self.ctx)?;
        // The device boundary: the model's values become the device's
        // through its photometric profile, if it has one.
        if projector.response.photometry.is_some() {
            for p in &mut map.value {
                let v = projector.response.encode(glam::Vec3::new(p[0], p[1], p[2]));
                [p[0], p[1], p[2]] = v.to_array();
            }
        }
        let output = RenderOutput {
            hash: hash_pixels(&map.value),
            image: Some(OutputImage {
                width: map.width,
                height: map.height,
                rgba: map.value,
                encoding: None,
            }),
        };
        self.report = FrameReport {
            passes_run: passes.passes.clone(),
            reused: false,
            clipped_fraction: map.clipped_fraction,
        };
        self.last = Some((key, output.clone(), map.clipped_fraction));
        Ok(output)
    }
}

impl Renderer for ProjectorRenderer {
    fn set_scene(&mut self, version: u64, scene: Arc<Showcase>) -> Result<(), RenderError> {
        self.scene_version = Some(version);
        self.scene = Some(scene);
        self.last = None;
        Ok(())
    }

    fn prepare_illumination(&mut self, solution: &Arc<Solution>) {
        let scene = self.scene.as_ref().zip(self.scene_version);
        self.illumination.prepare(scene, solution);
    }

    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<Solution>>,
    ) -> Result<(), RenderError> {
        let scene = self.scene.as_ref().zip(self.scene_version);
        if self.illumination.update(scene, illumination)? {
            self.last = None;
        }
        Ok(())
    }

    fn render(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        check_scene_version(
            &format!("projector {}", self.projector),
            frame,
            self.scene_version,
        )?;
        self.render_frame(frame, scene)
            .map_err(|e| RenderError::ProjectorFrame {
                projector: self.projector,
                frame: frame.frame,
                error: Box::new(e),
            })
    }

    fn present(&mut self, _frame: u64) -> Result<(), RenderError> {
        // Headless: the frame's image is already in its render output; a
        // window shows it (`window.rs`).
        Ok(())
    }
}
