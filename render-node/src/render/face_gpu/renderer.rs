//! The [`Renderer`] a face node runs: both eyes of one observer through
//! one face, side by side, the whole frame reused when nothing it shows
//! changed.

use std::sync::Arc;

use showcase_proto::{FrameState, Showcase};

use super::{FacePipeline, other_eyes};
use crate::gpu::GpuContext;
use crate::render::illumination::{FieldCache, LiveIllumination};
use crate::render::passes::{FrameKey, Pass, PassList};
use crate::render::renderer::{
    OutputImage, RenderError, RenderOutput, Renderer, check_scene_version,
};
use showcase_light::digest::hash_pixels;
use showcase_light::render::IndirectField;
use showcase_light::render::frame::FrameScene;
use showcase_proto::session::Solution;

/// The [`Renderer`] of a face node: both eyes of one observer through one
/// face, left eye in the left half of the output image.
#[derive(Debug)]
pub struct FaceRenderer {
    ctx: GpuContext,
    pipeline: FacePipeline,
    face: usize,
    observer: usize,
    scene_version: Option<u64>,
    /// The scene of `scene_version`.
    scene: Option<Arc<Showcase>>,
    /// The global-illumination field drawn with every frame.
    illumination: LiveIllumination,
    last_passes: Vec<Pass>,
    last: Option<(FrameKey, RenderOutput)>,
}

impl FaceRenderer {
    /// A renderer for `Showcase::faces[face]` seen by head `observer`.
    pub fn new(ctx: GpuContext, face: usize, observer: usize, shadow_res: u32) -> Self {
        let pipeline = FacePipeline::new(&ctx.device, shadow_res);
        Self {
            ctx,
            pipeline,
            face,
            observer,
            scene_version: None,
            scene: None,
            illumination: LiveIllumination::default(),
            last_passes: Vec::new(),
            last: None,
        }
    }

    /// The mesh cache of the master's solutions, to hand to the renderer
    /// that replaces this one (a new scene or a rejoin).
    pub fn take_fields(&mut self) -> FieldCache {
        self.illumination.take_fields()
    }

    /// This renderer with `fields` (from [`Self::take_fields`]).
    pub fn with_fields(mut self, fields: FieldCache) -> Self {
        self.illumination = LiveIllumination::with_fields(fields);
        self
    }

    /// Draw every following frame with the global-illumination field
    /// `field` (global mode), or direct light only (`None`, the default).
    pub fn set_indirect(&mut self, field: Option<Arc<IndirectField>>) {
        self.illumination.set_field(field);
        self.last = None;
    }

    /// Passes the last frame ran (empty when it reused the frame before).
    pub fn last_passes(&self) -> &[Pass] {
        &self.last_passes
    }

    fn render_frame(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        let face = scene
            .faces
            .get(self.face)
            .ok_or(RenderError::NoFace { index: self.face })?;
        let head = frame.heads.get(self.observer).ok_or(RenderError::NoHead {
            frame: frame.frame,
            observer: self.observer,
        })?;
        let ipd = scene
            .observers
            .get(self.observer)
            .map_or(showcase_proto::Observer::DEFAULT_IPD, |o| o.ipd);
        let eyes = showcase_proto::Observer::eyes(head, ipd).map(|e| e.as_dvec3());
        let key = FrameKey::face(self.face, self.observer, frame);
        if let Some((last_key, output)) = &self.last
            && *last_key == key
        {
            self.last_passes.clear();
            return Ok(output.clone());
        }
        let mut resolved = FrameScene::resolve(scene, frame)?;
        if let Some(field) = self.illumination.field() {
            resolved = resolved.with_indirect(field.clone());
        }
        let other_eyes = other_eyes(&resolved, self.observer);
        let passes = PassList::for_face(&resolved, other_eyes.len() + eyes.len() - 1);
        let images =
            self.pipeline
                .render(&self.ctx, &resolved, face, &eyes, &other_eyes, &passes)?;
        let (w, h) = (face.width as usize, face.height as usize);
        let mut rgba = Vec::with_capacity(2 * w * h);
        for y in 0..h {
            for image in &images {
                rgba.extend_from_slice(&image[y * w..(y + 1) * w]);
            }
        }
        self.last_passes = passes.passes;
        let output = RenderOutput {
            hash: hash_pixels(&rgba),
            image: Some(OutputImage {
                width: 2 * face.width,
                height: face.height,
                rgba,
                encoding: Some(face.photometry),
            }),
        };
        self.last = Some((key, output.clone()));
        Ok(output)
    }
}

impl Renderer for FaceRenderer {
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
        check_scene_version(&format!("face {}", self.face), frame, self.scene_version)?;
        self.render_frame(frame, scene)
    }

    fn present(&mut self, _frame: u64) -> Result<(), RenderError> {
        // Headless: the frame's image is already in its render output; a
        // window shows it (`window.rs`).
        Ok(())
    }
}
