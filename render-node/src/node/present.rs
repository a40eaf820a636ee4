//! Showing presented frames on a display. [`Presenting`] wraps a node's
//! renderer and hands the image of each frame to a [`FrameSink`] at the
//! swap (`present`), not before: what the sink shows follows the frame
//! lock. The `window` feature's full-screen window is such a sink
//! (`crate::window`).

use super::renderer::{OutputImage, RenderError, RenderOutput, Renderer};
use showcase_proto::{FrameState, Showcase};
use std::sync::Arc;

/// Where presented frames go.
pub trait FrameSink: Send {
    /// Show `image`, the output of `frame`, now.
    fn show(&mut self, frame: u64, image: OutputImage) -> Result<(), RenderError>;
}

/// A renderer whose presented frames are shown by a sink.
#[derive(Debug)]
pub struct Presenting<R, S> {
    inner: R,
    sink: S,
    pending: Option<(u64, OutputImage)>,
}

impl<R: Renderer, S: FrameSink> Presenting<R, S> {
    /// Show what `inner` renders through `sink`.
    pub fn new(inner: R, sink: S) -> Self {
        Self {
            inner,
            sink,
            pending: None,
        }
    }

    /// The sink.
    pub fn sink(&self) -> &S {
        &self.sink
    }
}

impl<R: Renderer, S: FrameSink> Renderer for Presenting<R, S> {
    fn set_scene(&mut self, version: u64, scene: Arc<Showcase>) -> Result<(), RenderError> {
        self.pending = None;
        self.inner.set_scene(version, scene)
    }

    fn render(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        let out = self.inner.render(frame, scene)?;
        self.pending = out.image.clone().map(|img| (frame.frame, img));
        Ok(out)
    }

    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<showcase_proto::session::Solution>>,
    ) -> Result<(), RenderError> {
        self.inner.set_illumination(illumination)
    }

    fn prepare_illumination(&mut self, solution: &Arc<showcase_proto::session::Solution>) {
        self.inner.prepare_illumination(solution)
    }

    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        self.inner.present(frame)?;
        match self.pending.take() {
            Some((f, image)) if f == frame => self.sink.show(frame, image),
            // A renderer without pixels, or a swap for a frame this node
            // did not render (it joined late): nothing to show.
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::StateHashRenderer;
    use showcase_proto::Role;

    #[derive(Default)]
    struct Shown(Vec<(u64, u32)>);

    impl FrameSink for Shown {
        fn show(&mut self, frame: u64, image: OutputImage) -> Result<(), RenderError> {
            self.0.push((frame, image.width));
            Ok(())
        }
    }

    /// Draws a 1-pixel-high image as wide as the frame number plus one.
    struct Widths;

    impl Renderer for Widths {
        fn set_scene(&mut self, _: u64, _: Arc<Showcase>) -> Result<(), RenderError> {
            Ok(())
        }
        fn render(&mut self, f: &FrameState, _: &Showcase) -> Result<RenderOutput, RenderError> {
            let width = f.frame as u32 + 1;
            Ok(RenderOutput {
                hash: f.frame,
                image: Some(OutputImage {
                    width,
                    height: 1,
                    rgba: vec![[0.0; 4]; width as usize],
                    encoding: None,
                }),
            })
        }
        fn present(&mut self, _: u64) -> Result<(), RenderError> {
            Ok(())
        }
    }

    fn frame(n: u64) -> FrameState {
        FrameState {
            frame: n,
            time_s: 0.0,
            scene_version: 1,
            heads: Vec::new(),
            lights: Vec::new(),
            object_transforms: Vec::new(),
            tracking_time_ns: None,
            illumination_version: None,
        }
    }

    #[test]
    fn each_presented_frame_is_shown_once_at_its_swap() {
        let scene = Showcase::default();
        let mut p = Presenting::new(Widths, Shown::default());
        for n in 0..3 {
            p.render(&frame(n), &scene).unwrap();
            assert_eq!(p.sink().0.len(), n as usize, "shown before the swap");
            p.present(n).unwrap();
        }
        assert_eq!(p.sink().0, [(0, 1), (1, 2), (2, 3)]);
        // A swap without a render of that frame shows nothing.
        p.render(&frame(7), &scene).unwrap();
        p.present(8).unwrap();
        p.present(7).unwrap();
        assert_eq!(p.sink().0.len(), 3);
        // A renderer without pixels shows nothing.
        let mut p = Presenting::new(StateHashRenderer::new("f", Role::Face), Shown::default());
        p.set_scene(1, Arc::new(Showcase::default())).unwrap();
        p.render(&frame(0), &scene).unwrap();
        p.present(0).unwrap();
        assert!(p.sink().0.is_empty());
    }
}
