//! A capture through a whole cluster on one machine: the master and a
//! projector node and a camera node, each holding its sim device, as tasks
//! talking real QUIC with mutual TLS over loopback; the sim's light goes
//! from the projector node to the camera node through an in-memory
//! [`LightBus`] (the room), never through the master. Used by the tests
//! and `bench capture-cluster`.

use super::capture_link::CaptureLink;
use super::server::{Server, ServerSettings};
use super::show::{Show, Tracking};
use crate::capture::cluster::{ClusterCaptureOptions, ClusterCaptureSummary, run_cluster_capture};
use crate::certs::{self, MASTER_FILE};
use anyhow::{Context, Result};
use showcase_light::hardware::CameraFrame;
use showcase_light::sim::SimConfig;
use showcase_proto::capture::{CaptureFrames, Pattern};
use showcase_proto::session::MasterConfig;
use showcase_proto::{Role, Showcase};
use showcase_render::net::ClusterIdentity;
use showcase_render::node::{
    CaptureDevices, CaptureHost, LightBus, NodeLog, NodeRuntime, SimCameraNode, SimProjectorNode,
    StateHashRenderer, run_node_with_devices,
};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tokio_util::sync::CancellationToken;

/// What to run.
#[derive(Clone, Debug)]
pub struct CaptureLoopback {
    /// The scene (its projector 0 and camera 0 capture; the nodes are
    /// named after them).
    pub scene: Showcase,
    /// The camera node's sim.
    pub sim: SimConfig,
    /// The capture job's settings.
    pub options: ClusterCaptureOptions,
    /// Where the maps go.
    pub out: PathBuf,
    /// Start the projector node (false: the job finds it missing).
    pub projector: bool,
    /// The projector node leaves after showing this many patterns.
    pub projector_leaves_after: Option<u64>,
    /// A node that joins after the capture, to see the maps in its
    /// snapshot.
    pub late_joiner: bool,
    /// Longest wait for one request's answer.
    pub request_timeout: Duration,
}

/// What happened.
#[derive(Debug)]
pub struct CaptureLoopbackResult {
    /// The job's summary, or its error (with the chain, as the CLI prints
    /// it).
    pub summary: std::result::Result<ClusterCaptureSummary, String>,
    /// The late joiner's log (its scenes: version and map count).
    pub late_joiner: Option<NodeLog>,
    /// Wall-clock seconds of the job (without the cluster's start).
    pub seconds: f64,
}

/// Counts the patterns a projector node shows.
struct Counted {
    inner: SimProjectorNode,
    shown: Arc<AtomicU64>,
}

impl CaptureDevices for Counted {
    fn set_scene(&mut self, scene: Arc<Showcase>) {
        self.inner.set_scene(scene)
    }
    fn show(&mut self, pattern: &Pattern) -> std::result::Result<(), String> {
        self.inner.show(pattern)?;
        self.shown.fetch_add(1, Ordering::SeqCst);
        Ok(())
    }
    fn capture(&mut self, r: &CaptureFrames) -> std::result::Result<Vec<CameraFrame>, String> {
        self.inner.capture(r)
    }
}

/// The name of the late joiner.
pub const LATE_JOINER: &str = "late-joiner";

/// Run the plan (bounded: every request by `request_timeout`, the nodes'
/// join by the options' `wait`).
pub async fn loopback_capture(plan: CaptureLoopback) -> Result<CaptureLoopbackResult> {
    let pname = plan
        .scene
        .projectors
        .first()
        .context("the scene has no projector")?
        .name
        .clone();
    let cname = plan
        .scene
        .cameras
        .first()
        .context("the scene has no camera")?
        .name
        .clone();
    let nodes = [
        (pname.clone(), Role::Projector),
        (cname.clone(), Role::Camera),
        (LATE_JOINER.to_string(), Role::Face),
    ];
    let names: Vec<String> = nodes.iter().map(|(n, _)| n.clone()).collect();
    let c = certs::generate(&names)?;
    let identity = |name: &str| -> Result<ClusterIdentity> {
        let p = c
            .peers
            .iter()
            .find(|p| p.name == name)
            .with_context(|| format!("no certificate for {name}"))?;
        Ok(ClusterIdentity::from_pem(
            &c.ca_pem,
            &p.cert_pem,
            &p.key_pem,
        )?)
    };
    let (link, commands) = CaptureLink::new(plan.request_timeout);
    let server = Server::bind(ServerSettings {
        listen: "127.0.0.1:0".parse().expect("valid address"),
        identity: identity(MASTER_FILE)?,
        roster: super::Roster::new(nodes.iter().cloned()),
        core: super::cluster_core_defaults(),
        frames: Some(0),
        wait_for_nodes: 2,
        start_timeout: Duration::from_secs(1),
        tracking: None,
        metrics: None,
        keep_frames: false,
        illumination_lag: None,
        illumination_patch_area: None,
    })?
    .capture_from(commands);
    let addr = server.local_addr();
    let stop = CancellationToken::new();
    let show = Show::new(Tracking::None, MasterConfig::default().target_hz as f64);
    let master = tokio::spawn(server.run(plan.scene.clone(), show, stop.clone()));
    let bus = LightBus::memory();
    let start_node = |name: &str, role: Role, devices: Option<CaptureHost>| -> Result<_> {
        let rt = NodeRuntime {
            name: name.into(),
            role,
            master: addr,
            identity: identity(name)?,
            bind: "127.0.0.1:0".parse().expect("valid address"),
            capabilities: Default::default(),
            write_frames: None,
            keep_presented: false,
        };
        let token = CancellationToken::new();
        let t = token.clone();
        let role_name = name.to_string();
        let task = tokio::spawn(async move {
            let mut r = StateHashRenderer::new(&role_name, role);
            run_node_with_devices(rt, &mut r, devices, t).await
        });
        Ok((task, token))
    };
    let shown = Arc::new(AtomicU64::new(0));
    let mut tasks = Vec::new();
    if plan.projector {
        let devices = CaptureHost::new(Counted {
            inner: SimProjectorNode::new(&pname, bus.clone()),
            shown: shown.clone(),
        });
        tasks.push(start_node(&pname, Role::Projector, Some(devices))?);
    }
    let camera = CaptureHost::new(SimCameraNode::new(&cname, bus.clone(), plan.sim.clone()));
    tasks.push(start_node(&cname, Role::Camera, Some(camera))?);
    // The projector node leaves after its n-th pattern (between the
    // captures: the master's next pattern finds it gone).
    let watcher = match (plan.projector, plan.projector_leaves_after) {
        (true, Some(n)) => {
            let token = tasks[0].1.clone();
            let shown = shown.clone();
            let limit = plan.request_timeout * 4;
            Some(tokio::spawn(async move {
                let t = Instant::now();
                while shown.load(Ordering::SeqCst) < n && t.elapsed() < limit {
                    tokio::time::sleep(Duration::from_millis(1)).await;
                }
                token.cancel();
            }))
        }
        _ => None,
    };
    let t0 = Instant::now();
    let job = {
        let (scene, options, out) = (plan.scene.clone(), plan.options.clone(), plan.out.clone());
        let (pname, cname) = (pname.clone(), cname.clone());
        tokio::task::spawn_blocking(move || {
            run_cluster_capture(&scene, &link, &pname, &cname, &out, &options, &|s| {
                tracing::info!("capture: {s}");
            })
            .map_err(|e| format!("{e:#}"))
        })
    };
    let summary = job.await.context("the capture job panicked")?;
    let seconds = t0.elapsed().as_secs_f64();
    let late_joiner = if plan.late_joiner {
        let (task, token) = start_node(LATE_JOINER, Role::Face, None)?;
        // Time to join and get its snapshot (a loopback join takes a few
        // milliseconds).
        tokio::time::sleep(Duration::from_millis(800)).await;
        token.cancel();
        Some(join(task).await?)
    } else {
        None
    };
    if let Some(w) = watcher {
        w.abort();
    }
    stop.cancel();
    for (task, token) in tasks {
        token.cancel();
        let _ = join(task).await;
    }
    match tokio::time::timeout(Duration::from_secs(10), master).await {
        Ok(Ok(r)) => {
            r?;
        }
        Ok(Err(e)) => anyhow::bail!("master task: {e}"),
        Err(_) => anyhow::bail!("the master did not stop"),
    }
    Ok(CaptureLoopbackResult {
        summary,
        late_joiner,
        seconds,
    })
}

async fn join(
    task: tokio::task::JoinHandle<
        std::result::Result<NodeLog, showcase_render::node::NodeRunError>,
    >,
) -> Result<NodeLog> {
    match tokio::time::timeout(Duration::from_secs(10), task).await {
        Ok(Ok(Ok(log))) => Ok(log),
        Ok(Ok(Err(e))) => anyhow::bail!("node: {e}"),
        Ok(Err(e)) => anyhow::bail!("node task: {e}"),
        Err(_) => anyhow::bail!("a node did not stop"),
    }
}
