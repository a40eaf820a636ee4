//! The seam between the cluster runtime and rendering: a node drives one
//! output through a [`Renderer`] and gets a [`RenderOutput`] or a
//! [`RenderError`] back. The real-time renderers (`projector_gpu`,
//! `face_gpu`) implement it here; the node runtime (`crate::node`) only
//! calls it, so the dependency points one way, from `node` to `render`.

use std::sync::Arc;

use showcase_proto::session::Solution;
use showcase_proto::{CrtPhotometry, FrameState, Role, Showcase};

use crate::gpu::GpuError;
use showcase_light::render::RenderSetupError;

/// What one render produced.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOutput {
    /// A hash of the output pixels (or of the state, for renderers without
    /// pixels). Equal inputs must give equal hashes on every run.
    pub hash: u64,
    /// The rendered image, linear RGBA f32, when the renderer keeps one
    /// (headless nodes write selected frames to disk).
    pub image: Option<OutputImage>,
}

/// A rendered image.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major linear RGBA.
    pub rgba: Vec<[f32; 4]>,
    /// How the values become drive values at the device boundary (the
    /// window): a CRT face's radiance through its photometric profile
    /// ([`CrtPhotometry::drive`]); `None` for values that already are
    /// (a projector's).
    pub encoding: Option<CrtPhotometry>,
}

/// Why a frame could not be rendered, read back or shown; a node reports
/// it and leaves the cluster.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The frame's scene or inputs cannot be rendered.
    #[error(transparent)]
    Setup(#[from] RenderSetupError),
    /// A frame was read back before one was drawn.
    #[error("no frame has been drawn yet")]
    NothingDrawn,
    /// A GPU operation failed.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// A frame names another scene version than the one the renderer holds.
    #[error("{output}: frame {frame} is for scene version {wanted} but the renderer has {have:?}")]
    SceneVersion {
        /// The renderer's output, e.g. `projector 0`.
        output: String,
        /// The frame.
        frame: u64,
        /// The scene version the frame is for.
        wanted: u64,
        /// The scene version the renderer holds (`None`: no scene yet).
        have: Option<u64>,
    },
    /// A frame arrived before the renderer was given any scene.
    #[error("output {output:?}: frame {frame} arrived before any scene")]
    NoScene {
        /// The output's name.
        output: String,
        /// The frame.
        frame: u64,
    },
    /// The scene has no output of the name a node renders.
    #[error("the scene has no {role} {name:?} (it has {have:?})")]
    NoOutput {
        /// `projector` or `face`.
        role: &'static str,
        /// The name looked for.
        name: String,
        /// The names of that role the scene has.
        have: Vec<String>,
    },
    /// A node's role has no renderer (only projectors and faces render).
    #[error("output {output:?}: role {role:?} has no renderer (only projectors and faces render)")]
    NoRenderer {
        /// The output's name.
        output: String,
        /// Its role.
        role: Role,
    },
    /// The scene has no face of this index.
    #[error("the scene has no face {index}")]
    NoFace {
        /// The face's index in the scene.
        index: usize,
    },
    /// Nobody stands in front of a face's mirror, so it serves no observer.
    #[error("face {face:?}: no observer stands in front of its mirror")]
    NoObserver {
        /// The face's name.
        face: String,
    },
    /// A frame lacks the head of the observer a face serves.
    #[error("frame {frame} has no head {observer}")]
    NoHead {
        /// The frame.
        frame: u64,
        /// The observer's index.
        observer: usize,
    },
    /// A projector's frame failed; `error` says why.
    #[error("projector {projector}: frame {frame}: {error}")]
    ProjectorFrame {
        /// The projector's index in the scene.
        projector: usize,
        /// The frame.
        frame: u64,
        /// Why (in the message, so not chained as a source too).
        error: Box<RenderError>,
    },
    /// The window the frames are shown in was closed.
    #[error("the window was closed")]
    WindowClosed,
    /// A global-illumination solution cannot be drawn.
    #[error("illumination version {version}: {problem}")]
    Illumination {
        /// The solution's version.
        version: u64,
        /// Why.
        problem: String,
    },
}

impl From<showcase_light::GeometryError> for RenderError {
    fn from(e: showcase_light::GeometryError) -> Self {
        Self::Setup(e.into())
    }
}

impl From<showcase_light::DeviceError> for RenderError {
    fn from(e: showcase_light::DeviceError) -> Self {
        Self::Setup(e.into())
    }
}

/// Renders one output of the showcase (a face, a projector or a camera).
pub trait Renderer: Send {
    /// A new scene arrived (join, rejoin or scene change).
    fn set_scene(&mut self, version: u64, scene: Arc<Showcase>) -> Result<(), RenderError>;
    /// Render `frame` of `scene` into the back buffer.
    fn render(&mut self, frame: &FrameState, scene: &Showcase)
    -> Result<RenderOutput, RenderError>;
    /// Show the last rendered frame (the swap).
    fn present(&mut self, frame: u64) -> Result<(), RenderError>;
    /// A solution arrived, before any frame that names it: do now the
    /// work drawing with it needs (build its field, digest it), so
    /// [`Self::set_illumination`] at the first frame that names it finds
    /// it done. Best effort: what cannot be prepared now (its scene is not
    /// the one held) is done, or refused with its error, at that frame. A
    /// wrapper must pass it on.
    fn prepare_illumination(&mut self, solution: &Arc<Solution>) {
        let _ = solution;
    }
    /// The global-illumination solution the next frames are drawn with
    /// (`None`: direct light), given before each frame that names one. A
    /// renderer that draws no global illumination ignores it; a wrapper
    /// must pass it on.
    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<Solution>>,
    ) -> Result<(), RenderError> {
        let _ = illumination;
        Ok(())
    }
}

/// The error of a renderer (`output`, e.g. "projector 0") asked to draw
/// `frame` while it holds scene version `have`; `Ok` when they match.
pub fn check_scene_version(
    output: &str,
    frame: &FrameState,
    have: Option<u64>,
) -> Result<(), RenderError> {
    if have == Some(frame.scene_version) {
        Ok(())
    } else {
        Err(RenderError::SceneVersion {
            output: output.to_owned(),
            frame: frame.frame,
            wanted: frame.scene_version,
            have,
        })
    }
}

impl<R: Renderer + ?Sized> Renderer for Box<R> {
    fn set_scene(&mut self, version: u64, scene: Arc<Showcase>) -> Result<(), RenderError> {
        (**self).set_scene(version, scene)
    }
    fn render(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        (**self).render(frame, scene)
    }
    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<Solution>>,
    ) -> Result<(), RenderError> {
        (**self).set_illumination(illumination)
    }
    fn prepare_illumination(&mut self, solution: &Arc<Solution>) {
        (**self).prepare_illumination(solution)
    }
    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        (**self).present(frame)
    }
}
