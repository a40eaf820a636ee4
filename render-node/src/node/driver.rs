//! The node's driver: a tokio task around the sans-IO `NodeCore`. It dials
//! the master over QUIC (mutual TLS), feeds what arrives into the core,
//! sleeps until `poll_timeout`, renders and presents through the
//! [`Renderer`], and redials with the core's backoff when the master goes
//! away. Shutdown is a cancellation token, so tests can stop it.

use super::capture::CaptureHost;
use super::renderer::{RenderError, Renderer};
use crate::net::{ClusterIdentity, MASTER_SERVER_NAME, MessageStream, TlsError, client_config};
use showcase_proto::Message;
use showcase_proto::capture;
use showcase_proto::session::{NodeConfig, NodeCore, NodeEvent, NodeOutput};
use showcase_proto::{Capabilities, Role};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tokio_util::sync::CancellationToken;
use tracing::{Instrument, debug, info, info_span, warn};

/// How a node runs.
#[derive(Clone, Debug)]
pub struct NodeRuntime {
    /// The node's name (its certificate name).
    pub name: String,
    /// What it drives.
    pub role: Role,
    /// Where the master listens.
    pub master: SocketAddr,
    /// Its certificate, key and the cluster CA.
    pub identity: ClusterIdentity,
    /// Local address to bind (port 0: any).
    pub bind: SocketAddr,
    /// What it can do, sent in Hello.
    pub capabilities: Capabilities,
    /// Write the images of these frames as PNG into this folder.
    pub write_frames: Option<(PathBuf, Vec<u64>)>,
    /// Keep every presented frame's `(frame, hash)` in
    /// [`NodeLog::presented`], for replay checks and tests. A live node
    /// keeps only the count and the last one, so that its memory stays
    /// flat over an exhibition day.
    pub keep_presented: bool,
}

/// What a node did, returned when it stops.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeLog {
    /// `(frame, output hash)` of every presented frame, in order, when
    /// [`NodeRuntime::keep_presented`] was set; else empty.
    pub presented: Vec<(u64, u64)>,
    /// Frames presented, kept or not.
    pub presented_count: u64,
    /// `(frame, output hash)` of the last presented frame.
    pub last_presented: Option<(u64, u64)>,
    /// Times the node (re)joined the master.
    pub joins: u32,
    /// Why each connection to the master ended, in order.
    pub disconnects: Vec<String>,
    /// Frame images written.
    pub written: Vec<PathBuf>,
    /// `(scene version, captured reflectance maps)` of every scene
    /// received, in order (a late joiner's first is its snapshot's).
    pub scenes: Vec<(u64, usize)>,
    /// Capture requests answered (patterns shown, captures sent, failed).
    pub captures: u64,
    /// Rendered frames waiting for their swap.
    pending: Vec<(u64, u64)>,
}

/// Why a node stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum NodeRunError {
    /// TLS material could not be used.
    #[error(transparent)]
    Tls(#[from] TlsError),
    /// The local UDP socket could not be bound.
    #[error("cannot bind {addr}: {error}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The IO error.
        error: std::io::Error,
    },
    /// The renderer failed.
    #[error("renderer: {0}")]
    Render(#[from] RenderError),
    /// The master refused this node's Hello: its name, certificate and the
    /// master's configuration disagree, which no retry can change.
    #[error(
        "the master refused this node: {reason}. Fix the master's [[node]] entries, or this node's --name or certificate, and start it again"
    )]
    Refused {
        /// The master's reason: the claimed name, the certificate's names
        /// and the configuration's entry.
        reason: String,
    },
    /// A frame image could not be written.
    #[error("writing frame image {path}: {problem}")]
    WriteFrame {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
}

struct Link {
    conn: quinn::Connection,
    stream: MessageStream,
}

async fn dial(ep: &quinn::Endpoint, addr: SocketAddr) -> Result<Link, String> {
    let connecting = ep
        .connect(addr, MASTER_SERVER_NAME)
        .map_err(|e| format!("connect to {addr}: {e}"))?;
    let conn = tokio::time::timeout(Duration::from_secs(3), connecting)
        .await
        .map_err(|_| format!("connect to {addr}: timed out"))?
        .map_err(|e| format!("connect to {addr}: {e}"))?;
    let (send, recv) = conn.open_bi().await.map_err(|e| e.to_string())?;
    Ok(Link {
        conn,
        stream: MessageStream::new(send, recv),
    })
}

/// Run a node until `shutdown` is cancelled.
pub async fn run_node<R: Renderer + ?Sized>(
    rt: NodeRuntime,
    renderer: &mut R,
    shutdown: CancellationToken,
) -> Result<NodeLog, NodeRunError> {
    run_node_with_devices(rt, renderer, None, shutdown).await
}

/// [`run_node`] with capture devices: the master's `ShowPattern` and
/// `CaptureFrames` go to `devices` (on a blocking thread; the node answers
/// nothing else meanwhile, so a capture runs while the frame clock is
/// held). A node without devices answers them with `CaptureFailed`.
pub async fn run_node_with_devices<R: Renderer + ?Sized>(
    rt: NodeRuntime,
    renderer: &mut R,
    devices: Option<CaptureHost>,
    shutdown: CancellationToken,
) -> Result<NodeLog, NodeRunError> {
    let span = info_span!("node", node = %rt.name);
    run_inner(rt, renderer, devices, shutdown)
        .instrument(span)
        .await
}

async fn run_inner<R: Renderer + ?Sized>(
    rt: NodeRuntime,
    renderer: &mut R,
    devices: Option<CaptureHost>,
    shutdown: CancellationToken,
) -> Result<NodeLog, NodeRunError> {
    // A folder the node will write into is made now, so a bad path stops
    // the node before it joins, not the whole show at the first frame.
    if let Some((dir, _)) = &rt.write_frames {
        std::fs::create_dir_all(dir).map_err(|e| NodeRunError::WriteFrame {
            path: dir.clone(),
            problem: format!("cannot create the frames folder: {e}"),
        })?;
    }
    let socket = std::net::UdpSocket::bind(rt.bind).map_err(|error| NodeRunError::Bind {
        addr: rt.bind,
        error,
    })?;
    let mut ep = quinn::Endpoint::new(
        quinn::EndpointConfig::default(),
        None,
        socket,
        std::sync::Arc::new(quinn::TokioRuntime),
    )
    .map_err(|error| NodeRunError::Bind {
        addr: rt.bind,
        error,
    })?;
    ep.set_default_client_config(client_config(&rt.identity)?);

    let start = Instant::now();
    let now = || start.elapsed().as_nanos() as u64;
    let mut config = NodeConfig::new(rt.name.clone(), rt.role);
    config.capabilities = rt.capabilities.clone();
    let mut core = NodeCore::new(config);
    let mut link: Option<Link> = None;
    let mut log = NodeLog::default();
    let mut refused = None;

    'run: loop {
        while let Some(out) = core.poll() {
            match out {
                NodeOutput::Dial => {
                    let dialled = tokio::select! {
                        _ = shutdown.cancelled() => break 'run,
                        d = dial(&ep, rt.master) => d,
                    };
                    match dialled {
                        Ok(l) => {
                            link = Some(l);
                            core.connect(now());
                        }
                        Err(e) => {
                            debug!(error = %e, "dial failed");
                            core.handle_disconnect(now(), &e);
                        }
                    }
                }
                NodeOutput::Transmit(msg) => {
                    if let Some(l) = link.as_mut()
                        && let Err(e) = l.stream.send(&msg).await
                    {
                        if let Some(reason) = e.refusal() {
                            refused = Some(reason);
                            break 'run;
                        }
                        link = None;
                        core.handle_disconnect(now(), &e.to_string());
                    }
                }
                NodeOutput::Close { reason } => {
                    if let Some(l) = link.take() {
                        let (mut writer, _) = l.stream.split();
                        writer.finish();
                        l.conn.close(0u32.into(), reason.as_bytes());
                    }
                }
                NodeOutput::Event(NodeEvent::Capture(request)) => {
                    let answers = tokio::select! {
                        _ = shutdown.cancelled() => break 'run,
                        a = answer_capture(&rt, devices.as_ref(), *request) => a,
                    };
                    log.captures += 1;
                    for a in answers {
                        core.answer_capture(a);
                    }
                }
                NodeOutput::Event(ev) => {
                    if let (NodeEvent::SceneChanged { scene, .. }, Some(d)) =
                        (&ev, devices.as_ref())
                    {
                        d.0.lock()
                            .unwrap_or_else(|e| e.into_inner())
                            .set_scene(scene.clone());
                    }
                    handle_event(ev, &rt, renderer, &mut core, &mut log, now)?
                }
            }
        }
        let deadline = core.poll_timeout();
        let sleep = async {
            match deadline {
                Some(t) => tokio::time::sleep(Duration::from_nanos(t.saturating_sub(now()))).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            _ = shutdown.cancelled() => break 'run,
            got = async {
                match link.as_mut() {
                    Some(l) => l.stream.recv().await,
                    None => std::future::pending().await,
                }
            } => match got {
                Ok(msg) => core.handle_message(now(), msg),
                Err(e) => {
                    if let Some(reason) = e.refusal() {
                        refused = Some(reason);
                        break 'run;
                    }
                    link = None;
                    core.handle_disconnect(now(), &e.to_string());
                }
            },
            _ = sleep => core.handle_timeout(now()),
        }
    }
    if let Some(l) = link.take() {
        l.conn.close(0u32.into(), b"node shutting down");
    }
    let _ = tokio::time::timeout(Duration::from_secs(1), ep.wait_idle()).await;
    match refused {
        Some(reason) => Err(NodeRunError::Refused { reason }),
        None => Ok(log),
    }
}

/// Run one capture request on the node's devices (on a blocking thread)
/// and make its answers: `PatternShown`, the frames' chunks, or
/// `CaptureFailed` with why.
async fn answer_capture(
    rt: &NodeRuntime,
    devices: Option<&CaptureHost>,
    request: Message,
) -> Vec<Message> {
    let id = match &request {
        Message::ShowPattern(p) => p.id,
        Message::CaptureFrames(c) => c.id,
        _ => return Vec::new(),
    };
    let failed = |reason: String| {
        let mut reason = format!("node {}: {reason}", rt.name);
        reason.truncate(capture::MAX_REASON_LEN);
        vec![Message::CaptureFailed(capture::CaptureFailed {
            id,
            reason,
        })]
    };
    let Some(host) = devices.cloned() else {
        return failed(format!(
            "this {} node has no capture device (start it with a camera or projector attached, or in sim mode)",
            rt.role
        ));
    };
    let work = tokio::task::spawn_blocking(move || {
        let mut d = host.0.lock().unwrap_or_else(|e| e.into_inner());
        match request {
            Message::ShowPattern(p) => d
                .show(&p.pattern)
                .map(|()| vec![Message::PatternShown(capture::PatternShown { id })]),
            Message::CaptureFrames(c) => d.capture(&c).map(|frames| {
                let n = frames.len() as u32;
                frames
                    .iter()
                    .enumerate()
                    .flat_map(|(k, f)| {
                        let codes = capture::FrameCodes {
                            width: f.codes.width,
                            height: f.codes.height,
                            bits: f.bits,
                            codes: f.codes.data.clone(),
                        };
                        capture::split_frame(id, k as u32, n, &codes, capture::MAX_CHUNK_BYTES)
                    })
                    .map(|c| Message::FrameChunk(Box::new(c)))
                    .collect()
            }),
            _ => Ok(Vec::new()),
        }
    });
    match work.await {
        Ok(Ok(answers)) => answers,
        Ok(Err(reason)) => failed(reason),
        Err(e) => failed(format!("the capture device failed: {e}")),
    }
}

fn handle_event<R: Renderer + ?Sized>(
    ev: NodeEvent,
    rt: &NodeRuntime,
    renderer: &mut R,
    core: &mut NodeCore,
    log: &mut NodeLog,
    now: impl Fn() -> u64,
) -> Result<(), NodeRunError> {
    match ev {
        NodeEvent::Connected { target_hz, .. } => {
            log.joins += 1;
            info!(target_hz, "joined the master");
        }
        NodeEvent::SceneChanged {
            version,
            scene,
            maps,
        } => {
            log.scenes.push((version, maps.len()));
            renderer.set_scene(version, scene)?
        }
        NodeEvent::Capture(_) => {}
        NodeEvent::Illumination(solution) => renderer.prepare_illumination(&solution),
        NodeEvent::Render {
            frame,
            scene,
            illumination,
        } => {
            let t0 = Instant::now();
            renderer.set_illumination(illumination.as_ref())?;
            let out = renderer.render(&frame, &scene)?;
            let render_ns = t0.elapsed().as_nanos() as u64;
            if let (Some((dir, frames)), Some(img)) = (&rt.write_frames, &out.image)
                && frames.contains(&frame.frame)
            {
                let path = dir.join(format!("{}-{:05}.png", rt.name, frame.frame));
                crate::node::png_out::write_png(&path, img).map_err(|problem| {
                    NodeRunError::WriteFrame {
                        path: path.clone(),
                        problem,
                    }
                })?;
                log.written.push(path);
            }
            log.pending.push((frame.frame, out.hash));
            if let Err(e) = core.rendered(now(), frame.frame, out.hash, render_ns) {
                warn!(error = %e, "core refused a rendered frame");
            }
        }
        NodeEvent::Present { frame } => {
            renderer.present(frame)?;
            if let Some(i) = log.pending.iter().position(|(f, _)| *f == frame) {
                let done = log.pending.remove(i);
                log.presented_count += 1;
                log.last_presented = Some(done);
                if rt.keep_presented {
                    log.presented.push(done);
                }
            }
            // Frames present in order: one rendered before this one and
            // not presented never will be (its swap was skipped).
            log.pending.retain(|(f, _)| *f > frame);
            if let Err(e) = core.presented(now(), frame) {
                warn!(error = %e, "core refused a presented frame");
            }
        }
        NodeEvent::Disconnected { reason, .. } => {
            // Frames rendered but not presented are dropped by the core.
            log.pending.clear();
            info!(%reason, "left the master");
            log.disconnects.push(reason);
        }
    }
    Ok(())
}
