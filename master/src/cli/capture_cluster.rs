//! `capture --config` (a capture through the configured cluster) and
//! `bench capture-cluster` (the loopback cluster against the in-process
//! capture).

use super::bench::BenchArgs;
use super::jobs::CaptureArgs;
use crate::capture::cluster::ClusterCaptureOptions;
use crate::capture::cluster_job::{
    ClusterBenchOptions, ConfigCaptureOptions, bench_capture_cluster,
    bench_structured_light_cluster, run_config_capture,
};
use crate::capture::pipeline::{CaptureConfig, Method};
use anyhow::Result;
use std::sync::Arc;
use std::time::Duration;

/// `capture --config CLUSTER.toml`: naive, piecewise and corrected maps
/// (or `--method`'s) through the cluster's nodes; with `--sim`, the nodes
/// run in sim mode and each map is judged against the sim's albedo.
pub(super) fn capture(args: &CaptureArgs, config: &std::path::Path) -> Result<()> {
    let methods = match args.method.as_deref() {
        None | Some("all") => vec![Method::Naive, Method::Piecewise, Method::Corrected],
        Some("naive") => vec![Method::Naive],
        Some("piecewise") => vec![Method::Piecewise],
        Some("corrected") => vec![Method::Corrected],
        Some(m) => anyhow::bail!("--method {m}: use naive, piecewise, corrected or all"),
    };
    let opts = ConfigCaptureOptions {
        config: config.to_path_buf(),
        out: args.out.clone(),
        capture: ClusterCaptureOptions {
            methods,
            capture: CaptureConfig {
                frames: args.frames.max(1),
                ..CaptureConfig::default()
            },
            sim: args.sim.then(showcase_light::sim::SimConfig::default),
            wait: Duration::from_secs(args.wait_s.max(1)),
        },
    };
    let summary = run_config_capture(&opts, Arc::new(|s: &str| eprintln!("capture: {s}...")))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    }
    for m in &summary.methods {
        eprintln!(
            "capture: {} map through {} and {}: rel RMSE {:.4} over {:.0}% of the object pixels, {:.1} s",
            m.method,
            summary.nodes[0],
            summary.nodes[1],
            m.rel_rmse,
            100.0 * m.coverage,
            m.seconds
        );
    }
    eprintln!(
        "capture: {} frames ({} bytes) over QUIC; maps published as scene version {}; wrote {}",
        summary.frames,
        summary.frame_bytes,
        summary.published_version,
        args.out.join("summary.json").display()
    );
    Ok(())
}

/// `bench capture-cluster`: the capture's records, then structured
/// light's (the demo cabinet, a 240 x 180 camera).
pub(super) fn bench(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    let opts = ClusterBenchOptions::default();
    pb.set_length(opts.methods.len() as u64 + 1);
    let mut records = bench_capture_cluster(&opts, &|k, what| {
        pb.set_position(k as u64);
        pb.set_message(what.to_string());
    })?
    .into_iter()
    .map(serde_json::to_value)
    .collect::<Result<Vec<_>, _>>()?;
    pb.set_position(opts.methods.len() as u64);
    pb.set_message("structured light");
    records.push(serde_json::to_value(bench_structured_light_cluster(
        (240, 180),
        crate::calibrate::structured_light::SIM_SAMPLES,
        &opts.scratch.join("structured-light"),
    )?)?);
    super::bench::emit(args, pb, &records)
}
