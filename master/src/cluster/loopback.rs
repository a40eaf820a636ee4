//! A whole cluster on one machine: the master and its nodes as tasks of
//! one runtime, talking real QUIC with mutual TLS over loopback, with
//! certificates made in memory. Used by `replay`, `bench cluster` and the
//! demo; ARCHITECTURE.md says why tasks rather than processes.

use super::server::{ClusterRun, Server, ServerError, ServerSettings};
use super::show::Show;
use crate::certs::{self, CertError, ClusterCerts, MASTER_FILE};
use showcase_proto::session::MasterConfig;
use showcase_proto::{FrameState, Role, Showcase};
use showcase_render::net::ClusterIdentity;
use showcase_render::node::{
    NodeLog, NodeRunError, NodeRuntime, RenderError, RenderOutput, Renderer, run_node,
};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tokio_util::sync::CancellationToken;

/// Makes the renderer of a node from its name and role.
pub type RendererFactory = Arc<dyn Fn(&str, Role) -> Box<dyn Renderer> + Send + Sync>;

/// What to run.
pub struct LoopbackPlan {
    /// The scene.
    pub scene: Showcase,
    /// Where frame states come from.
    pub show: Show,
    /// `(name, role)` of each node.
    pub nodes: Vec<(String, Role)>,
    /// Frames to run.
    pub frames: u64,
    /// The master's core settings (rate, deadline).
    pub core: MasterConfig,
    /// Renderers.
    pub renderers: RendererFactory,
    /// Kill this node (by index) at this frame and restart it at once.
    pub restart: Option<(usize, u64)>,
    /// Per-frame metrics sink.
    pub metrics: Option<Box<dyn std::io::Write + Send>>,
    /// Write node images of these frames into this folder.
    pub write_frames: Option<(PathBuf, Vec<u64>)>,
    /// Keep every frame's metrics in the result (see `ServerSettings`).
    pub keep_frames: bool,
    /// Keep every node's per-frame `(frame, hash)` in its log (see
    /// `NodeRuntime::keep_presented`).
    pub keep_presented: bool,
    /// See `ServerSettings::illumination_lag`.
    pub illumination_lag: Option<u64>,
    /// See `ServerSettings::illumination_patch_area`.
    pub illumination_patch_area: Option<f64>,
    /// See `ServerSettings::maps`.
    pub maps: Vec<showcase_proto::capture::CapturedMap>,
}

/// What happened.
#[derive(Debug)]
pub struct LoopbackResult {
    /// The master's record.
    pub run: ClusterRun,
    /// Each node's log, by name; a restarted node has two.
    pub logs: Vec<(String, NodeLog)>,
    /// From restarting the killed node to its first rendered frame.
    pub rejoin: Option<Duration>,
}

/// Why a loopback run failed.
#[derive(Debug, thiserror::Error)]
pub enum LoopbackError {
    /// Certificates could not be made.
    #[error(transparent)]
    Certs(#[from] CertError),
    /// TLS material was unusable.
    #[error(transparent)]
    Tls(#[from] showcase_render::net::TlsError),
    /// The master failed.
    #[error("master: {0}")]
    Master(#[from] ServerError),
    /// A node failed.
    #[error("node {name}: {error}")]
    Node {
        /// The node.
        name: String,
        /// Why.
        error: NodeRunError,
    },
    /// A task panicked or the run exceeded its time limit.
    #[error("{0}")]
    Runtime(String),
}

/// Counts rendered frames, so the harness can see a node come back.
struct Counting {
    inner: Box<dyn Renderer>,
    rendered: Arc<AtomicU64>,
}

impl Renderer for Counting {
    fn set_scene(&mut self, v: u64, s: Arc<Showcase>) -> Result<(), RenderError> {
        self.inner.set_scene(v, s)
    }
    fn render(&mut self, f: &FrameState, s: &Showcase) -> Result<RenderOutput, RenderError> {
        self.rendered.fetch_add(1, Ordering::Relaxed);
        self.inner.render(f, s)
    }
    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        self.inner.present(frame)
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
}

type NodeTask = (
    tokio::task::JoinHandle<Result<NodeLog, NodeRunError>>,
    CancellationToken,
    Arc<AtomicU64>,
);

fn identity(c: &ClusterCerts, name: &str) -> Result<ClusterIdentity, LoopbackError> {
    let p = c
        .peers
        .iter()
        .find(|p| p.name == name)
        .ok_or_else(|| LoopbackError::Runtime(format!("no certificate for {name}")))?;
    Ok(ClusterIdentity::from_pem(
        &c.ca_pem,
        &p.cert_pem,
        &p.key_pem,
    )?)
}

/// Run the plan to completion (bounded: frames at the target rate plus
/// generous slack).
pub async fn run_loopback(plan: LoopbackPlan) -> Result<LoopbackResult, LoopbackError> {
    let names: Vec<String> = plan.nodes.iter().map(|(n, _)| n.clone()).collect();
    let c = certs::generate(&names)?;
    let server = Server::bind(ServerSettings {
        listen: "127.0.0.1:0".parse().expect("valid address"),
        identity: identity(&c, MASTER_FILE)?,
        roster: super::Roster::new(plan.nodes.iter().cloned()),
        core: plan.core.clone(),
        frames: Some(plan.frames),
        wait_for_nodes: plan.nodes.len(),
        start_timeout: Duration::from_secs(10),
        tracking: None,
        metrics: plan.metrics,
        keep_frames: plan.keep_frames,
        illumination_lag: plan.illumination_lag,
        illumination_patch_area: plan.illumination_patch_area,
        maps: plan.maps,
    })?;
    let addr = server.local_addr();
    let stop = CancellationToken::new();
    let master = tokio::spawn(server.run(plan.scene, plan.show, stop.clone()));

    let start_node = |i: usize| -> Result<NodeTask, LoopbackError> {
        let (name, role) = &plan.nodes[i];
        let rt = NodeRuntime {
            name: name.clone(),
            role: *role,
            master: addr,
            identity: identity(&c, name)?,
            bind: "127.0.0.1:0".parse().expect("valid address"),
            capabilities: Default::default(),
            write_frames: plan.write_frames.clone(),
            keep_presented: plan.keep_presented,
        };
        let rendered = Arc::new(AtomicU64::new(0));
        let mut r = Counting {
            inner: (plan.renderers)(name, *role),
            rendered: rendered.clone(),
        };
        let token = CancellationToken::new();
        let t = token.clone();
        Ok((
            tokio::spawn(async move { run_node(rt, &mut r, t).await }),
            token,
            rendered,
        ))
    };
    let mut tasks: Vec<(String, NodeTask)> = Vec::new();
    for i in 0..plan.nodes.len() {
        tasks.push((plan.nodes[i].0.clone(), start_node(i)?));
    }
    let mut logs = Vec::new();
    let mut rejoin = None;
    let limit =
        Duration::from_secs_f64(plan.frames as f64 / plan.core.target_hz as f64 * 3.0 + 20.0);
    let started = Instant::now();
    if let Some((victim, at_frame)) = plan.restart {
        let watch = tasks[(victim + 1) % tasks.len()].1.2.clone();
        while watch.load(Ordering::Relaxed) < at_frame {
            if started.elapsed() > limit || master.is_finished() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
        let (name, (h, token, _)) = tasks.remove(victim);
        token.cancel();
        logs.push((name.clone(), join_node(&name, h).await?));
        let restarted_at = Instant::now();
        let task = start_node(victim)?;
        let count = task.2.clone();
        tasks.push((name, task));
        while count.load(Ordering::Relaxed) == 0 && restarted_at.elapsed() < Duration::from_secs(10)
        {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        if count.load(Ordering::Relaxed) > 0 {
            rejoin = Some(restarted_at.elapsed());
        }
    }
    let remaining = limit.saturating_sub(started.elapsed());
    let run = match tokio::time::timeout(remaining, master).await {
        Ok(Ok(r)) => r?,
        Ok(Err(e)) => return Err(LoopbackError::Runtime(format!("master task: {e}"))),
        Err(_) => {
            stop.cancel();
            return Err(LoopbackError::Runtime(format!(
                "the loopback cluster did not finish {} frames in {limit:?}",
                plan.frames
            )));
        }
    };
    for (name, (h, token, _)) in tasks {
        token.cancel();
        logs.push((name.clone(), join_node(&name, h).await?));
    }
    Ok(LoopbackResult { run, logs, rejoin })
}

async fn join_node(
    name: &str,
    h: tokio::task::JoinHandle<Result<NodeLog, NodeRunError>>,
) -> Result<NodeLog, LoopbackError> {
    match tokio::time::timeout(Duration::from_secs(10), h).await {
        Ok(Ok(Ok(log))) => Ok(log),
        Ok(Ok(Err(error))) => Err(LoopbackError::Node {
            name: name.to_owned(),
            error,
        }),
        Ok(Err(e)) => Err(LoopbackError::Runtime(format!("node {name} task: {e}"))),
        Err(_) => Err(LoopbackError::Runtime(format!("node {name} did not stop"))),
    }
}
