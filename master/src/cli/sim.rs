//! `showcase-master sim ...`: tools of the simulated showcase.

use super::parse_size;
use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;

/// Subcommands of `sim`.
#[derive(Debug, Subcommand)]
pub enum SimCommand {
    /// Render a view of a scene lit by its own emitters, as linear radiance.
    Render(SimRenderArgs),
}

/// Arguments of `sim render`.
#[derive(Debug, Args)]
pub struct SimRenderArgs {
    /// Scene file.
    #[arg(long)]
    pub scene: PathBuf,
    /// Eye position `x,y,z`.
    #[arg(long, allow_hyphen_values = true)]
    pub eye: String,
    /// Look-at target `x,y,z`.
    #[arg(long, allow_hyphen_values = true)]
    pub target: String,
    /// Up vector `x,y,z`.
    #[arg(long, allow_hyphen_values = true, default_value = "0,1,0")]
    pub up: String,
    /// Horizontal field of view in degrees.
    #[arg(long)]
    pub fov_deg: f64,
    /// Image size `WxH`.
    #[arg(long, default_value = "512x512")]
    pub size: String,
    /// Output file (.pfm).
    #[arg(long)]
    pub out: PathBuf,
}

/// Run a `sim` subcommand.
pub(super) fn sim(command: &SimCommand) -> Result<()> {
    match command {
        SimCommand::Render(a) => render(a),
    }
}

/// `sim render`: one view of a scene as a PFM.
fn render(a: &SimRenderArgs) -> Result<()> {
    let (width, height) = parse_size(&a.size)?;
    crate::capture::sim_render_command(
        &a.scene,
        parse_vec3("--eye", &a.eye)?,
        parse_vec3("--target", &a.target)?,
        parse_vec3("--up", &a.up)?,
        a.fov_deg,
        width,
        height,
        &a.out,
    )?;
    eprintln!("wrote {}", a.out.display());
    Ok(())
}

/// Parse the value `s` of `flag` as three finite numbers `x,y,z`.
pub(super) fn parse_vec3(flag: &str, s: &str) -> Result<glam::DVec3> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{flag} {s:?}: expected x,y,z"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(glam::DVec3::new(x, y, z)),
        _ => anyhow::bail!("{flag} {s:?}: expected three finite numbers x,y,z"),
    }
}
