//! One command encoder for a frame's passes that can also time them: a
//! plain frame is one submission; a timed frame (the render bench) submits
//! and waits after each step, so that each step's wall time is its own.

use std::time::Instant;

use crate::gpu::{GpuContext, GpuError, wait_idle};

/// Wall time of each step of a frame in milliseconds (each submitted and
/// waited for separately): `setup` (CPU work and uploads), then the passes
/// by [`crate::render::passes::Pass::name`].
pub type PassTimes = Vec<(&'static str, f64)>;

/// The encoder a frame's passes record into, and the times of its steps.
#[derive(Debug)]
pub struct TimedEncoder<'a> {
    ctx: &'a GpuContext,
    encoder: wgpu::CommandEncoder,
    timed: bool,
    since: Instant,
    times: PassTimes,
}

impl<'a> TimedEncoder<'a> {
    /// Start a frame now (its first step's time counts from here); with
    /// `timed`, each [`Self::step`] submits and waits.
    pub fn new(ctx: &'a GpuContext, timed: bool) -> Self {
        Self {
            ctx,
            encoder: ctx.device.create_command_encoder(&Default::default()),
            timed,
            since: Instant::now(),
            times: PassTimes::new(),
        }
    }

    /// The encoder the current step records into.
    pub fn encoder(&mut self) -> &mut wgpu::CommandEncoder {
        &mut self.encoder
    }

    /// End the step `name`. When timed, submit what it recorded, wait for
    /// the GPU and note its wall time since the step before; otherwise
    /// keep recording into the same encoder.
    pub fn step(&mut self, name: &'static str) -> Result<(), GpuError> {
        if self.timed {
            let next = self.ctx.device.create_command_encoder(&Default::default());
            let done = std::mem::replace(&mut self.encoder, next);
            self.ctx.queue.submit([done.finish()]);
            wait_idle(&self.ctx.device)?;
            self.times
                .push((name, self.since.elapsed().as_secs_f64() * 1e3));
            self.since = Instant::now();
        }
        Ok(())
    }

    /// Submit what is left (everything, untimed) and return the steps'
    /// times (none, untimed).
    pub fn submit(self) -> PassTimes {
        self.ctx.queue.submit([self.encoder.finish()]);
        self.times
    }
}
