//! A capture or a structured-light calibration through a whole cluster on
//! one machine ([`LoopbackCluster`]): the master and projector nodes and a
//! camera node, each holding its sim device, as tasks talking real QUIC
//! with mutual TLS over loopback; the sim's light goes from the projector
//! nodes to the camera node through an in-memory [`LightBus`] (the room),
//! never through the master. Used by the tests, `bench capture-cluster`
//! and `bench calibration`.

use super::capture_link::CaptureLink;
use super::server::{Server, ServerSettings};
use super::show::{Show, Tracking};
use crate::calibrate::structured_light::{
    StructuredLightOptions, StructuredLightSummary, Targets, ThroughNodes,
    run_structured_light_on_nodes,
};
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

/// A node task of a [`LoopbackCluster`].
pub type NodeTask =
    tokio::task::JoinHandle<std::result::Result<NodeLog, showcase_render::node::NodeRunError>>;

/// A master and its nodes as tasks of this process talking QUIC with
/// mutual TLS over 127.0.0.1, the master's capture requests on
/// [`Self::link`], the sim's light on one in-memory [`LightBus`]. The
/// start-up and shutdown every loopback capture job shares (the capture,
/// the structured-light calibration).
pub struct LoopbackCluster {
    /// The running master's capture requests.
    pub link: CaptureLink,
    /// The room's light.
    pub bus: LightBus,
    addr: std::net::SocketAddr,
    certs: certs::ClusterCerts,
    stop: CancellationToken,
    master: tokio::task::JoinHandle<std::result::Result<super::ClusterRun, super::ServerError>>,
    nodes: Vec<(NodeTask, CancellationToken)>,
}

impl LoopbackCluster {
    /// Start the master of `scene` (inside a tokio runtime), its roster
    /// `nodes` (each gets a certificate; the frame clock waits at most 1 s
    /// for all but [`LATE_JOINER`], then is held); each
    /// request of the link bounded by `request_timeout`.
    pub fn start(
        scene: &Showcase,
        nodes: &[(String, Role)],
        request_timeout: Duration,
    ) -> Result<Self> {
        let names: Vec<String> = nodes.iter().map(|(n, _)| n.clone()).collect();
        let certs = certs::generate(&names)?;
        let (link, commands) = CaptureLink::new(request_timeout);
        let server = Server::bind(ServerSettings::capture(
            "127.0.0.1:0".parse().expect("valid address"),
            identity(&certs, MASTER_FILE)?,
            super::Roster::new(nodes.iter().cloned()),
            // Every node but a late joiner.
            nodes.iter().filter(|(n, _)| n != LATE_JOINER).count(),
        ))?
        .capture_from(commands);
        let addr = server.local_addr();
        let stop = CancellationToken::new();
        let show = Show::new(Tracking::None, MasterConfig::default().target_hz as f64);
        let master = tokio::spawn(server.run(scene.clone(), show, stop.clone()));
        Ok(Self {
            link,
            bus: LightBus::memory(),
            addr,
            certs,
            stop,
            master,
            nodes: Vec::new(),
        })
    }

    /// Start node `name` of `role` with `devices`; its task and its stop
    /// token (the caller joins it; [`Self::start_node`] keeps it instead).
    pub fn spawn_node(
        &self,
        name: &str,
        role: Role,
        devices: Option<CaptureHost>,
    ) -> Result<(NodeTask, CancellationToken)> {
        let rt = NodeRuntime {
            name: name.into(),
            role,
            master: self.addr,
            identity: identity(&self.certs, name)?,
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
    }

    /// Start node `name` and keep it until [`Self::stop`]; its stop token.
    pub fn start_node(
        &mut self,
        name: &str,
        role: Role,
        devices: Option<CaptureHost>,
    ) -> Result<CancellationToken> {
        let (task, token) = self.spawn_node(name, role, devices)?;
        self.nodes.push((task, token.clone()));
        Ok(token)
    }

    /// Stop the master and every kept node (each bounded to 10 s).
    pub async fn stop(self) -> Result<()> {
        self.stop.cancel();
        for (task, token) in self.nodes {
            token.cancel();
            let _ = join(task).await;
        }
        match tokio::time::timeout(Duration::from_secs(10), self.master).await {
            Ok(Ok(r)) => r.map(|_| ()).map_err(Into::into),
            Ok(Err(e)) => anyhow::bail!("master task: {e}"),
            Err(_) => anyhow::bail!("the master did not stop"),
        }
    }
}

fn identity(c: &certs::ClusterCerts, name: &str) -> Result<ClusterIdentity> {
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
}

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
    let mut cluster = LoopbackCluster::start(&plan.scene, &nodes, plan.request_timeout)?;
    let shown = Arc::new(AtomicU64::new(0));
    let projector_token = if plan.projector {
        let devices = CaptureHost::new(Counted {
            inner: SimProjectorNode::new(&pname, cluster.bus.clone()),
            shown: shown.clone(),
        });
        Some(cluster.start_node(&pname, Role::Projector, Some(devices))?)
    } else {
        None
    };
    let camera = CaptureHost::new(SimCameraNode::new(
        &cname,
        cluster.bus.clone(),
        plan.sim.clone(),
    ));
    cluster.start_node(&cname, Role::Camera, Some(camera))?;
    // The projector node leaves after its n-th pattern (between the
    // captures: the master's next pattern finds it gone).
    let watcher = match (projector_token, plan.projector_leaves_after) {
        (Some(token), Some(n)) => {
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
        let link = cluster.link.clone();
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
        let (task, token) = cluster.spawn_node(LATE_JOINER, Role::Face, None)?;
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
    cluster.stop().await?;
    Ok(CaptureLoopbackResult {
        summary,
        late_joiner,
        seconds,
    })
}

async fn join(task: NodeTask) -> Result<NodeLog> {
    match tokio::time::timeout(Duration::from_secs(10), task).await {
        Ok(Ok(Ok(log))) => Ok(log),
        Ok(Ok(Err(e))) => anyhow::bail!("node: {e}"),
        Ok(Err(e)) => anyhow::bail!("node task: {e}"),
        Err(_) => anyhow::bail!("a node did not stop"),
    }
}

/// A structured-light calibration through a loopback cluster: one sim
/// projector node per projector of the scene, a sim camera node for its
/// first camera, every node named after its device.
#[derive(Clone, Debug)]
pub struct StructuredLightLoopback {
    /// The scene.
    pub scene: Showcase,
    /// The camera node's sim.
    pub sim: SimConfig,
    /// The method's settings.
    pub options: StructuredLightOptions,
    /// Where the calibrations go.
    pub out: PathBuf,
    /// Longest wait for the nodes to join.
    pub wait: Duration,
    /// Longest wait for one request's answer.
    pub request_timeout: Duration,
    /// A node of the roster left unstarted (the job finds it missing).
    pub absent: Option<String>,
}

/// What a [`StructuredLightLoopback`] did.
#[derive(Debug)]
pub struct StructuredLightLoopbackResult {
    /// The job's summary, or its error (with the chain, as the CLI prints
    /// it).
    pub summary: std::result::Result<StructuredLightSummary, String>,
    /// Patterns the projector nodes showed.
    pub patterns_shown: u64,
    /// Wall-clock seconds of the job (without the cluster's start).
    pub seconds: f64,
}

/// Run the structured-light plan through a loopback cluster (bounded:
/// every request by `request_timeout`, the nodes' join by `wait`).
pub async fn loopback_structured_light(
    plan: StructuredLightLoopback,
) -> Result<StructuredLightLoopbackResult> {
    let targets = Targets::of_scene(&plan.scene)?;
    let mut nodes: Vec<(String, Role)> = targets
        .projectors
        .iter()
        .map(|p| (p.device.clone(), Role::Projector))
        .collect();
    nodes.push((targets.camera.device.clone(), Role::Camera));
    let mut cluster = LoopbackCluster::start(&plan.scene, &nodes, plan.request_timeout)?;
    let shown = Arc::new(AtomicU64::new(0));
    for p in &targets.projectors {
        if plan.absent.as_ref() == Some(&p.device) {
            continue;
        }
        let devices = CaptureHost::new(Counted {
            inner: SimProjectorNode::new(&p.device, cluster.bus.clone()),
            shown: shown.clone(),
        });
        cluster.start_node(&p.device, Role::Projector, Some(devices))?;
    }
    let camera = &targets.camera.device;
    if plan.absent.as_ref() != Some(camera) {
        let devices = CaptureHost::new(SimCameraNode::new(camera, cluster.bus.clone(), plan.sim));
        cluster.start_node(camera, Role::Camera, Some(devices))?;
    }
    let t0 = Instant::now();
    let job = {
        let link = cluster.link.clone();
        let (options, out) = (plan.options, plan.out);
        let nodes = ThroughNodes {
            wait: plan.wait,
            sim: true,
        };
        tokio::task::spawn_blocking(move || {
            run_structured_light_on_nodes(
                &link,
                &targets,
                &out,
                &options,
                &nodes,
                &|s| tracing::info!("structured light: {s}"),
                &|name, done, total, what| {
                    tracing::debug!("structured light: {name}: {done}/{total} ({what})")
                },
            )
            .map_err(|e| format!("{e:#}"))
        })
    };
    let summary = job.await.context("the structured-light job panicked")?;
    let seconds = t0.elapsed().as_secs_f64();
    cluster.stop().await?;
    Ok(StructuredLightLoopbackResult {
        summary,
        patterns_shown: shown.load(Ordering::SeqCst),
        seconds,
    })
}
