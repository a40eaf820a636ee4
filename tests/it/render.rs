//! Integration tests: render. The projector role's irradiance maps
//! against analytic values and their CPU references (GPU), the end-to-end
//! direct-light consistency check, the pass list's skips (the pass did not
//! run, and the output is identical), and golden images.
//!
//! GPU tests follow `gpu.rs`'s policy: without an adapter they fail when
//! `CI` is set and otherwise print "skipping" and pass.

mod bench;
mod cube_map;
mod face;
mod golden;
mod parallax;
mod passes;
pub(crate) mod projector;
pub(crate) mod scenes;
mod window;

use anyhow::{Context, Result, bail};
use showcase_render::gpu::{GpuContext, GpuError};

/// Open a headless GPU, or explain why the test is skipped (see `gpu.rs`).
fn gpu_or_skip(test: &str) -> Result<Option<GpuContext>> {
    match GpuContext::new_headless() {
        Ok(ctx) => {
            eprintln!("{test}: adapter {}", ctx.describe());
            Ok(Some(ctx))
        }
        Err(GpuError::NoAdapter(e)) => {
            if std::env::var_os("CI").is_some() {
                bail!("{test}: no GPU adapter and CI is set (install mesa-vulkan-drivers): {e}");
            }
            eprintln!("{test}: skipping: no GPU adapter ({e}) (set CI to make this fatal)");
            Ok(None)
        }
        Err(e) => Err(e).context(format!("{test}: opening a GPU device")),
    }
}
