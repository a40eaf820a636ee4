//! The cluster's commands: `run` (a live master from a cluster config),
//! `replay` (a recorded session through a loopback cluster) and
//! `bench cluster`.

use super::cluster_core_defaults;
use super::dashboard::{Dashboard, DashboardOptions};
use super::live::{LivePublisher, PUBLISH_EVERY};
use super::loopback::{LoopbackPlan, LoopbackResult, RendererFactory, run_loopback};
use super::server::{Server, ServerSettings};
use super::show::{Show, Tracking};
use crate::tracking::Tracker;
use crate::tracking::recording;
use crate::tracking::scripted::{FIRST_HEAD_BODY, LIGHT_BODY, OBJECT_BODY, carried_object};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use showcase_light::digest::Fnv64;
use showcase_light::metrics::percentile;
use showcase_proto::config::{BodyMapping, ClusterConfig, TrackingConfig, TrackingSource};
use showcase_proto::session::MasterConfig;
use showcase_proto::{Role, Showcase};
use showcase_render::net::ClusterIdentity;
use showcase_render::node::StateHashRenderer;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// The body mapping of the built-in walk: bodies 0 and 1 are the first two
/// observers' heads, body 2 carries the first light and body 3 the
/// scene's carried virtual object ([`carried_object`]).
pub fn walk_tracking(scene: &Showcase, source: TrackingSource) -> TrackingConfig {
    let mut bodies = Vec::new();
    for (i, o) in scene.observers.iter().take(2).enumerate() {
        bodies.push(BodyMapping {
            id: FIRST_HEAD_BODY + i as u32,
            target: format!("observer:{}", o.name),
        });
    }
    if let Some(l) = scene.lights.first() {
        bodies.push(BodyMapping {
            id: LIGHT_BODY,
            target: format!("light:{}", l.name),
        });
    }
    if let Some(i) = carried_object(scene) {
        bodies.push(BodyMapping {
            id: OBJECT_BODY,
            target: format!("object:{}", scene.objects[i].name),
        });
    }
    TrackingConfig {
        source,
        port: None,
        file: None,
        room_translation: [0.0; 3],
        room_rotation_deg: [0.0; 3],
        predict_ms: 0.0,
        limits: Default::default(),
        bodies,
    }
}

/// One node per face and projector of the scene.
pub fn output_nodes(scene: &Showcase) -> Vec<(String, Role)> {
    scene
        .faces
        .iter()
        .map(|f| (f.name.clone(), Role::Face))
        .chain(
            scene
                .projectors
                .iter()
                .map(|p| (p.name.clone(), Role::Projector)),
        )
        .collect()
}

/// Renderers that digest exactly the state each output would draw.
pub fn state_hash_renderers() -> RendererFactory {
    Arc::new(|name: &str, role: Role| Box::new(StateHashRenderer::new(name, role)))
}

/// One record of `bench cluster --json`.
#[derive(Clone, Debug, Serialize)]
pub struct ClusterBenchRecord {
    /// Render nodes.
    pub nodes: usize,
    /// Target frame rate.
    pub hz: f32,
    /// Frames run.
    pub frames: u64,
    /// Median spread of the nodes' present times (ms).
    pub swap_skew_ms_p50: Option<f64>,
    /// 99th percentile of the same.
    pub swap_skew_ms_p99: Option<f64>,
    /// Median time from the newest tracking sample to the swap (ms).
    pub tracking_to_swap_ms_p50: Option<f64>,
    /// 99th percentile of the same.
    pub tracking_to_swap_ms_p99: Option<f64>,
    /// Frame-clock ticks at which no frame could be submitted.
    pub dropped_frames: u64,
    /// FrameState bytes on the wire per frame, all nodes together.
    pub bytes_per_frame: f64,
    /// Nodes evicted for missing a deadline.
    pub evictions: u64,
    /// From restarting a killed node to its first rendered frame (ms).
    pub rejoin_ms: Option<f64>,
}

/// Summarise a loopback run as a bench record.
pub fn bench_record(nodes: usize, hz: f32, frames: u64, r: &LoopbackResult) -> ClusterBenchRecord {
    let skew: Vec<f64> = r.run.frames.iter().filter_map(|f| f.swap_skew_ms).collect();
    let lat: Vec<f64> = r
        .run
        .frames
        .iter()
        .filter_map(|f| f.tracking_to_swap_ms)
        .collect();
    ClusterBenchRecord {
        nodes,
        hz,
        frames,
        swap_skew_ms_p50: percentile(&skew, 50.0),
        swap_skew_ms_p99: percentile(&skew, 99.0),
        tracking_to_swap_ms_p50: percentile(&lat, 50.0),
        tracking_to_swap_ms_p99: percentile(&lat, 99.0),
        dropped_frames: r.run.dropped_ticks,
        bytes_per_frame: r.run.frame_bytes as f64 / frames.max(1) as f64,
        evictions: r.run.evictions,
        rejoin_ms: r.rejoin.map(|d| d.as_secs_f64() * 1e3),
    }
}

/// A loopback cluster of `nodes` state-hash nodes (faces and projectors
/// in turn) showing the scripted walk on `scene` at `hz` for `frames`; no
/// restart, no metrics, no frames kept.
pub fn walk_plan(scene: &Showcase, nodes: usize, hz: f32, frames: u64) -> Result<LoopbackPlan> {
    let tracking = walk_tracking(scene, TrackingSource::Scripted);
    walk_plan_tracking(scene, &tracking, nodes, hz, frames)
}

/// [`walk_plan`] with the walk's bodies mapped by `tracking` (e.g. some of
/// [`walk_tracking`]'s left out).
pub fn walk_plan_tracking(
    scene: &Showcase,
    tracking: &TrackingConfig,
    nodes: usize,
    hz: f32,
    frames: u64,
) -> Result<LoopbackPlan> {
    let tracker = Tracker::new(tracking, scene)?;
    Ok(LoopbackPlan {
        scene: scene.clone(),
        show: Show::new(Tracking::Scripted(tracker), hz as f64),
        nodes: (0..nodes)
            .map(|i| {
                let role = if i % 2 == 0 {
                    Role::Face
                } else {
                    Role::Projector
                };
                (format!("node-{i}"), role)
            })
            .collect(),
        frames,
        core: MasterConfig {
            target_hz: hz,
            ..cluster_core_defaults()
        },
        renderers: state_hash_renderers(),
        restart: None,
        metrics: None,
        write_frames: None,
        keep_frames: false,
        keep_presented: false,
        illumination_lag: None,
        illumination_patch_area: None,
        maps: Vec::new(),
    })
}

/// `bench cluster`: a loopback cluster of each of `node_counts` at each of
/// `rates` Hz (the command's defaults: 2, 4 and 8 nodes at 60 and 120 Hz)
/// on the demo scene with the scripted walk; one node is killed and
/// restarted a third of the way in. `done(nodes, hz)` is called after each
/// configuration (progress display).
pub async fn bench_cluster(
    scene: &Showcase,
    frames: u64,
    node_counts: &[usize],
    rates: &[f32],
    done: &dyn Fn(usize, f32),
) -> Result<Vec<ClusterBenchRecord>> {
    let mut out = Vec::new();
    for &nodes in node_counts {
        for &hz in rates {
            let plan = LoopbackPlan {
                restart: Some((0, frames / 3)),
                keep_frames: true,
                ..walk_plan(scene, nodes, hz, frames)?
            };
            let r = run_loopback(plan).await?;
            out.push(bench_record(nodes, hz, frames, &r));
            done(nodes, hz);
        }
    }
    Ok(out)
}

/// The tracking settings a replay uses: the ones the recording kept (the
/// live show's mapping, room transform and limits), else, for recordings
/// that predate them, the built-in walk's mapping.
pub fn replay_tracking(header: &recording::Header, scene: &Showcase) -> TrackingConfig {
    match &header.tracking {
        Some(t) => TrackingConfig {
            source: TrackingSource::Recording,
            ..t.clone()
        },
        None => walk_tracking(scene, TrackingSource::Recording),
    }
}

/// What a replay produced: every node's per-frame output hashes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReplayOutcome {
    /// Frames run.
    pub frames: u64,
    /// Per node: name, frames presented, and the hashes in frame order.
    pub nodes: Vec<ReplayNode>,
}

/// One node of a replay.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReplayNode {
    /// Node name.
    pub name: String,
    /// A digest of all its per-frame hashes.
    pub digest: String,
    /// `(frame, output hash)` per presented frame.
    pub hashes: Vec<(u64, u64)>,
}

/// In a replay of a scene in global mode, each solution is first drawn
/// this many frames after the frame whose state it solves (the master
/// holds the frame clock for a late solver), so a replay is bit-exact at
/// any speed.
pub const REPLAY_ILLUMINATION_LAG: u64 = 30;

/// Replay a recorded session through a loopback cluster of the scene's
/// outputs and return each node's per-frame output hashes.
pub async fn replay(
    scene: &Showcase,
    session: &Path,
    hz: f32,
    frames: Option<u64>,
) -> Result<ReplayOutcome> {
    let recorded = recording::read_recording(session)?;
    recorded.warn_if_cut();
    let entries = recorded.entries;
    let Some(last) = entries.last() else {
        bail!("{}: the recording has no datagrams", session.display());
    };
    let frames = frames.unwrap_or(((last.t * hz as f64).floor() as u64 + 1).max(1));
    let tracker = Tracker::new(&replay_tracking(&recorded.header, scene), scene)
        .with_context(|| format!("{}: the recorded tracking settings", session.display()))?;
    let show = Show::new(
        Tracking::Replay {
            tracker,
            entries,
            next: 0,
        },
        hz as f64,
    );
    let r = run_loopback(LoopbackPlan {
        scene: scene.clone(),
        show,
        nodes: output_nodes(scene),
        frames,
        core: MasterConfig {
            target_hz: hz,
            ..cluster_core_defaults()
        },
        renderers: state_hash_renderers(),
        restart: None,
        metrics: None,
        write_frames: None,
        keep_frames: false,
        // The replay's result is every node's per-frame hashes.
        keep_presented: true,
        illumination_lag: Some(REPLAY_ILLUMINATION_LAG),
        illumination_patch_area: None,
        maps: Vec::new(),
    })
    .await?;
    let nodes = r
        .logs
        .into_iter()
        .map(|(name, log)| {
            let mut h = Fnv64::default();
            for (f, x) in &log.presented {
                h.write(&f.to_le_bytes());
                h.write(&x.to_le_bytes());
            }
            ReplayNode {
                name,
                digest: format!("{:016x}", h.finish()),
                hashes: log.presented,
            }
        })
        .collect();
    Ok(ReplayOutcome { frames, nodes })
}

/// `run --config FILE`: the live master of a cluster, until SIGINT or
/// SIGTERM, which stop it cleanly (Bye to the nodes, whole files, a
/// summary, exit 0); with `dashboard`, it serves the live dashboard too.
pub async fn run_master(
    config: &Path,
    maps: Option<&Path>,
    metrics: Option<&Path>,
    record: Option<&Path>,
    dashboard: Option<&DashboardOptions>,
) -> Result<()> {
    // Refuse a bad dashboard address before anything else starts.
    if let Some(d) = dashboard {
        d.check()?;
    }
    let text = std::fs::read_to_string(config)
        .with_context(|| format!("cannot read cluster config {}", config.display()))?;
    let label = config.display().to_string();
    let cfg = ClusterConfig::parse(&text, &label)?;
    let base = config.parent().unwrap_or(Path::new("."));
    let scene = crate::scene_file::load_any(&crate::scene_file::resolve(base, &cfg.master.scene))?;
    let names = crate::scene_file::SceneNames::of(&scene);
    if let Some(p) =
        super::check::node_problems(&cfg, Some(&names), Some(&scene), base, &label).first()
    {
        bail!("{p}");
    }
    let maps = match maps {
        Some(dir) => {
            let maps = crate::capture::cluster::captured_maps_in(dir)?;
            let named: Vec<&str> = scene
                .objects
                .iter()
                .filter_map(|o| o.material.reflectance_map.as_deref())
                .collect();
            let loaded: Vec<&str> = maps.iter().map(|m| m.name.as_str()).collect();
            eprintln!(
                "{} reflectance maps from {}: {}",
                maps.len(),
                dir.display(),
                loaded.join(", ")
            );
            for missing in named.iter().filter(|n| !loaded.contains(n)) {
                tracing::warn!(
                    map = missing,
                    "the scene names a reflectance map that {} does not hold; its object keeps the scene's albedo",
                    dir.display()
                );
            }
            maps
        }
        None => Vec::new(),
    };
    let listen = showcase_render::net::resolve(&cfg.master.listen, "master.listen")?;
    let identity = ClusterIdentity::load(&base.join(&cfg.master.certs), crate::certs::MASTER_FILE)?;
    let tracking = match &cfg.tracking {
        None => Tracking::None,
        Some(t) => {
            let tracker = Tracker::new(t, &scene)?;
            match t.source {
                TrackingSource::Dtrack => Tracking::Live(tracker),
                TrackingSource::Scripted => Tracking::Scripted(tracker),
                TrackingSource::Recording => {
                    let file = base.join(t.file.as_ref().expect("checked by the config"));
                    Tracking::Replay {
                        tracker,
                        entries: recording::read(&file)?,
                        next: 0,
                    }
                }
            }
        }
    };
    let mut show = Show::new(tracking, cfg.master.target_hz as f64);
    if let Some(path) = record {
        let f = std::fs::File::create(path)
            .with_context(|| format!("cannot create recording {}", path.display()))?;
        show.record_to(
            Box::new(std::io::BufWriter::new(f)),
            &label,
            cfg.tracking.as_ref(),
        )?;
    }
    let metrics_out: Option<Box<dyn std::io::Write + Send>> = match metrics {
        Some(p) => Some(Box::new(std::io::BufWriter::new(
            std::fs::File::create(p)
                .with_context(|| format!("cannot create metrics file {}", p.display()))?,
        ))),
        None => None,
    };
    let tracking_addr = match &cfg.tracking {
        Some(t) if t.source == TrackingSource::Dtrack => Some(std::net::SocketAddr::new(
            listen.ip(),
            t.port.unwrap_or(5000),
        )),
        _ => None,
    };
    let server = Server::bind(ServerSettings {
        listen,
        identity,
        roster: super::Roster::from_config(&cfg),
        core: MasterConfig {
            target_hz: cfg.master.target_hz,
            deadline_ns: (cfg.master.deadline_ms as f64 * 1e6) as u64,
            ..cluster_core_defaults()
        },
        frames: None,
        wait_for_nodes: cfg.nodes.len(),
        start_timeout: Duration::from_secs(30),
        tracking: tracking_addr,
        metrics: metrics_out,
        keep_frames: false,
        illumination_lag: None,
        illumination_patch_area: None,
        maps,
    })?;
    eprintln!(
        "master listening on {} for {} nodes; Ctrl-C or SIGTERM stops",
        server.local_addr(),
        cfg.nodes.len()
    );
    let stop = CancellationToken::new();
    let (server, page) = match dashboard {
        Some(d) => {
            let dash = Dashboard::bind(d)?;
            // `bench dashboard` and the tests read the address from this line.
            eprintln!("dashboard on http://{}/", dash.local_addr());
            let (publisher, snapshots) = LivePublisher::new(PUBLISH_EVERY);
            let task = dash.serve(snapshots, stop.child_token())?;
            (server.publish_to(publisher), Some(task))
        }
        None => (server, None),
    };
    showcase_render::node::cancel_on_stop_signal(stop.clone());
    let scene_is_global = scene.illumination == showcase_proto::IlluminationMode::Global;
    let run = server.run(scene, show, stop.clone()).await;
    stop.cancel();
    if let Some(task) = page {
        super::dashboard::stop(task).await;
    }
    let run = run?;
    eprintln!(
        "master stopped after {} frames ({} ticks dropped, {} evictions)",
        run.submitted, run.dropped_ticks, run.evictions
    );
    eprintln!("{}", run.stats.line());
    if scene_is_global {
        let summary = super::illumination::UpdateSummary::of(&run.illumination_updates);
        eprintln!("{}", summary.line());
        for e in &run.illumination_failures {
            eprintln!("global illumination: a solve failed: {e}");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::recording::{Recorder, parse_recording};

    /// A recording keeps the live show's tracking settings, and its replay
    /// maps and filters with them; one without falls back to the walk's.
    #[test]
    fn replays_use_the_recorded_tracking_settings() {
        let scene = Showcase {
            observers: vec![showcase_proto::Observer {
                name: "alice".into(),
                head: Default::default(),
                ipd: showcase_proto::Observer::DEFAULT_IPD,
            }],
            ..Showcase::default()
        };
        let live = TrackingConfig {
            room_translation: [0.5, 0.0, -0.25],
            predict_ms: 8.0,
            bodies: vec![BodyMapping {
                id: 7,
                target: "observer:alice".into(),
            }],
            ..walk_tracking(&scene, TrackingSource::Dtrack)
        };
        let rec = Recorder::new(Vec::new(), "live", Some(&live)).unwrap();
        let bytes = rec.into_inner();
        let read = parse_recording(&bytes[..], "s.jsonl").unwrap();
        assert_eq!(read.header.tracking.as_ref(), Some(&live));
        let used = replay_tracking(&read.header, &scene);
        assert_eq!(
            used,
            TrackingConfig {
                source: TrackingSource::Recording,
                ..live
            }
        );
        let old = parse_recording(
            &b"{\"format\":\"showcase-tracking\",\"version\":1}\n"[..],
            "old.jsonl",
        )
        .unwrap();
        assert_eq!(
            replay_tracking(&old.header, &scene),
            walk_tracking(&scene, TrackingSource::Recording)
        );
    }
}
