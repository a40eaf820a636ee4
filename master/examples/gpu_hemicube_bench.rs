//! GPU against CPU hemi-cube item buffers on the Cornell box, as JSON
//! records (`radiosity_job::gpu_hemicube`). Run from the repository root:
//! `cargo run --release -p showcase-master --example gpu_hemicube_bench`.

use showcase_master::radiosity_job::bench::CORNELL_BOX;
use showcase_master::radiosity_job::gpu_hemicube::gpu_hemicube_records;
use showcase_render::gpu::GpuContext;
use std::path::Path;

fn main() -> anyhow::Result<()> {
    let ctx = GpuContext::new_headless()?;
    eprintln!("adapter: {}", ctx.describe());
    let records = gpu_hemicube_records(Path::new(CORNELL_BOX), &ctx)?;
    println!("{}", serde_json::to_string_pretty(&records)?);
    Ok(())
}
