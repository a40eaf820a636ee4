//! The master's driver: a tokio loop around the sans-IO `MasterCore`. It
//! accepts QUIC connections (mutual TLS), admits a Hello only when its
//! name, its certificate and the configuration's roster agree, moves messages between the
//! connections and the core, runs the frame clock at the target rate,
//! feeds DTrack datagrams to the show, and writes per-frame metrics.
//! Every task it spawns lives in a `JoinSet` that ends with the run.

use super::identity::Roster;
use super::live::{LivePublisher, LiveStats, LiveSummary};
use super::metrics::{FrameMetrics, frame_metrics};
use super::show::Show;
use super::timer::DeadlineTimer;
use showcase_proto::capture::CapturedMap;
use showcase_proto::session::{
    ConnId, MasterConfig, MasterCore, MasterError, MasterEvent, MasterOutput, SwapReport,
};
use showcase_proto::{CodecError, FrameState, Message, Showcase};
use showcase_render::net::{
    ClusterIdentity, MessageReader, MessageStream, MessageWriter, REFUSED, StreamError, TlsError,
    peer_is, peer_names, server_config, server_endpoint_config,
};
use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio_util::sync::CancellationToken;
use tracing::{Instrument, debug, info, info_span, warn};

/// How the master runs.
pub struct ServerSettings {
    /// QUIC listen address.
    pub listen: SocketAddr,
    /// The master's certificate and the cluster CA.
    pub identity: ClusterIdentity,
    /// The nodes it admits (the configuration's `[[node]]` entries).
    pub roster: Roster,
    /// Frame rate, deadline and the rest of the core's settings.
    pub core: MasterConfig,
    /// Stop after this many frames (run forever if `None`).
    pub frames: Option<u64>,
    /// Start the frame clock once this many nodes have joined and hold
    /// the scene (or after `start_timeout`).
    pub wait_for_nodes: usize,
    /// Longest wait for `wait_for_nodes`.
    pub start_timeout: Duration,
    /// UDP address for DTrack datagrams.
    pub tracking: Option<SocketAddr>,
    /// Where to write one JSON line per frame.
    pub metrics: Option<Box<dyn Write + Send>>,
    /// Keep every frame's metrics in the returned [`ClusterRun`] (benches,
    /// the demo, tests). A live show leaves it off, so its memory does not
    /// grow with the length of the day.
    pub keep_frames: bool,
    /// Global mode only: publish each update exactly this many frames
    /// after the frame it solves, waiting for the solver when it is late,
    /// so the same frames get the same solutions at any machine speed
    /// (`replay`); `None`: publish as soon as a solve lands (live).
    pub illumination_lag: Option<u64>,
    /// Global mode only: the largest radiosity patch of the solution (m^2;
    /// `None`: the scene's `patch_area`, else the radiosity job's
    /// default), which sets how many elements
    /// it has (`bench gi`'s records at about 20,000).
    pub illumination_patch_area: Option<f64>,
    /// Captured reflectance maps the cluster starts with (`run --maps`):
    /// every snapshot carries them, and global mode solves with them.
    pub maps: Vec<CapturedMap>,
}

impl ServerSettings {
    /// A master that serves a capture job ([`Server::capture_from`]): the
    /// frame clock held (`frames` 0), the cluster defaults, starting once
    /// `wait_for_nodes` nodes joined or after a second; no tracking,
    /// metrics or global illumination.
    pub fn capture(
        listen: SocketAddr,
        identity: ClusterIdentity,
        roster: Roster,
        wait_for_nodes: usize,
    ) -> Self {
        Self {
            listen,
            identity,
            roster,
            core: super::cluster_core_defaults(),
            frames: Some(0),
            wait_for_nodes,
            start_timeout: Duration::from_secs(1),
            tracking: None,
            metrics: None,
            keep_frames: false,
            illumination_lag: None,
            illumination_patch_area: None,
            maps: Vec::new(),
        }
    }
}

/// Why the master could not run.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// TLS material could not be used.
    #[error(transparent)]
    Tls(#[from] TlsError),
    /// A socket could not be bound (e.g. the port is taken).
    #[error("cannot listen on {addr} ({what})")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// QUIC or tracking.
        what: &'static str,
        /// The IO error.
        source: std::io::Error,
    },
    /// The core refused its settings or the scene.
    #[error(transparent)]
    Core(#[from] MasterError),
    /// The deadline timer's thread could not start.
    #[error("cannot start the deadline timer thread: {0}")]
    Timer(std::io::Error),
    /// Metrics could not be written.
    #[error("writing metrics: {0}")]
    Metrics(std::io::Error),
    /// The scene is in global-illumination mode and its solver could not
    /// start (its first solution failed, or its thread).
    #[error("global illumination: {0}")]
    Illumination(String),
}

/// What a run did.
#[derive(Debug, Default)]
pub struct ClusterRun {
    /// One entry per presented frame, when `keep_frames` was set.
    pub frames: Vec<FrameMetrics>,
    /// Frames presented.
    pub presented: u64,
    /// Frames submitted.
    pub submitted: u64,
    /// Frame-clock ticks at which no frame could be submitted (pipeline
    /// full because a node was late).
    pub dropped_ticks: u64,
    /// Nodes evicted for missing a deadline.
    pub evictions: u64,
    /// `(node, master-clock ns)` of every join.
    pub joins: Vec<(String, u64)>,
    /// Hellos refused because name, certificate and roster disagreed, with why.
    pub refusals: Vec<String>,
    /// `(node, master-clock ns)` of every connection closed, with why.
    pub closes: Vec<(Option<String>, u64, String)>,
    /// Bytes of FrameState messages written to the nodes, in total.
    pub frame_bytes: u64,
    /// FrameState messages sent.
    pub frame_messages: u64,
    /// Master-clock ns when the frame clock started.
    pub started_ns: u64,
    /// Master-clock ns when the run loop ended.
    pub finished_ns: u64,
    /// Swap skew and latency over the run, from the live histograms
    /// (constant memory; kept whether or not `keep_frames` is set).
    pub stats: LiveSummary,
    /// Global-illumination updates published during the run (the first
    /// solution, before frame 0, is not one), at most
    /// [`MAX_KEPT_UPDATES`].
    pub illumination_updates: Vec<super::illumination::Update>,
    /// Solves that failed, with why (the frames keep the last solution).
    pub illumination_failures: Vec<String>,
    /// Lockstep (`illumination_lag`): frame-clock ticks skipped waiting for
    /// a late solve.
    pub illumination_waits: u64,
}

/// Updates a run keeps (a live show's memory must not grow with the day).
pub const MAX_KEPT_UPDATES: usize = 100_000;

enum Inbound {
    Connected(ConnId, mpsc::UnboundedSender<Outbound>),
    Message(ConnId, Message),
    DecodeError(ConnId, CodecError),
    Lost(ConnId, String),
    Refused(ConnId, String),
}

enum Outbound {
    Send(Message),
    Close(String),
}

/// A bound master, ready to run.
pub struct Server {
    endpoint: quinn::Endpoint,
    udp: Option<tokio::net::UdpSocket>,
    settings: ServerSettings,
    live: Option<LivePublisher>,
    capture: Option<mpsc::UnboundedReceiver<super::capture_link::CaptureCommand>>,
}

impl Server {
    /// Bind the QUIC endpoint and the tracking socket. Must be called
    /// inside a tokio runtime.
    pub fn bind(settings: ServerSettings) -> Result<Self, ServerError> {
        settings.core.check()?;
        let cfg = server_config(&settings.identity)?;
        let bind = |source| ServerError::Bind {
            addr: settings.listen,
            what: "QUIC",
            source,
        };
        let socket = std::net::UdpSocket::bind(settings.listen).map_err(bind)?;
        let endpoint = quinn::Endpoint::new(
            server_endpoint_config(&settings.identity),
            Some(cfg),
            socket,
            Arc::new(quinn::TokioRuntime),
        )
        .map_err(bind)?;
        let udp = match settings.tracking {
            Some(addr) => {
                let bind = |source| ServerError::Bind {
                    addr,
                    what: "DTrack tracking",
                    source,
                };
                let s = std::net::UdpSocket::bind(addr).map_err(bind)?;
                s.set_nonblocking(true).map_err(bind)?;
                Some(tokio::net::UdpSocket::from_std(s).map_err(bind)?)
            }
            None => None,
        };
        Ok(Self {
            endpoint,
            udp,
            settings,
            live: None,
            capture: None,
        })
    }

    /// The QUIC address nodes connect to.
    pub fn local_addr(&self) -> SocketAddr {
        self.endpoint
            .local_addr()
            .expect("a bound endpoint has an address")
    }

    /// Publish live snapshots (for the dashboard) through `publisher`.
    pub fn publish_to(mut self, publisher: LivePublisher) -> Self {
        self.live = Some(publisher);
        self
    }

    /// Take capture commands (`capture --config`) from `link`'s sender.
    pub fn capture_from(
        mut self,
        commands: mpsc::UnboundedReceiver<super::capture_link::CaptureCommand>,
    ) -> Self {
        self.capture = Some(commands);
        self
    }

    /// The UDP address DTrack sends to.
    pub fn tracking_addr(&self) -> Option<SocketAddr> {
        self.udp.as_ref().and_then(|u| u.local_addr().ok())
    }

    /// Run the show until `frames` are done or `shutdown` is cancelled.
    pub async fn run(
        self,
        scene: Showcase,
        mut show: Show,
        shutdown: CancellationToken,
    ) -> Result<ClusterRun, ServerError> {
        let Server {
            endpoint,
            udp,
            mut settings,
            live: mut publisher,
            capture: mut capture_rx,
        } = self;
        let mut captures = super::capture_link::Requests::default();
        let start = Instant::now();
        let origin_unix_ms = super::metrics::unix_ms();
        let now = || start.elapsed().as_nanos() as u64;
        let hz = settings.core.target_hz as f64;
        let mut core = MasterCore::new(settings.core.clone(), scene)?;
        if !settings.maps.is_empty() {
            core.set_maps(0, std::mem::take(&mut settings.maps))?;
        }
        let (tx, mut rx) = mpsc::unbounded_channel::<Inbound>();
        let mut tasks = JoinSet::new();
        let mut conns: HashMap<ConnId, mpsc::UnboundedSender<Outbound>> = HashMap::new();
        let mut next_conn = 0u64;
        let mut run = ClusterRun::default();
        let mut states: BTreeMap<u64, FrameState> = BTreeMap::new();
        let mut swaps: BTreeMap<u64, SwapReport> = BTreeMap::new();
        let mut ticker = tokio::time::interval(Duration::from_secs_f64(1.0 / hz));
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        let mut started = false;
        let mut next_frame = 0u64;
        let mut last_swap_at: Option<Instant> = None;
        let mut udp_buf = vec![0u8; 64 * 1024];
        let traffic = Arc::new(FrameTraffic::default());
        let roster = Arc::new(std::mem::take(&mut settings.roster));
        let mut live = LiveStats::new(&roster, settings.core.target_hz, origin_unix_ms);
        let mut timer = DeadlineTimer::start().map_err(ServerError::Timer)?;
        // Why the run stopped early (the first global-illumination solve
        // failed); returned after the connections are closed.
        let mut failed = None;
        let mut gi = GlobalIllumination::start(
            &core,
            settings.illumination_lag,
            settings.illumination_patch_area,
        )?;

        'run: loop {
            while let Some(out) = core.poll() {
                match out {
                    MasterOutput::Transmit { conn, message } => {
                        if let Some(c) = conns.get(&conn) {
                            let _ = c.send(Outbound::Send(message));
                        }
                    }
                    MasterOutput::Close { conn, reason } => {
                        if let Some(c) = conns.remove(&conn) {
                            let _ = c.send(Outbound::Close(reason.to_string()));
                        }
                    }
                    MasterOutput::Event(ev) => match ev {
                        MasterEvent::Capture {
                            conn,
                            node,
                            message,
                        } => captures.answer(conn, &node, *message),
                        MasterEvent::NodeJoined {
                            conn,
                            node,
                            role,
                            current_frame,
                        } => {
                            info!(%node, %role, ?current_frame, "node joined");
                            live.joined(&node, role, conn);
                            run.joins.push((node, now()));
                        }
                        MasterEvent::NodeClosed { conn, node, reason } => {
                            info!(node = node.as_deref().unwrap_or("?"), %reason, "node closed");
                            captures.closed(conn, node.as_deref(), &reason.to_string());
                            live.closed(node.as_deref(), conn, &reason);
                            if matches!(
                                reason,
                                showcase_proto::session::CloseReason::MissedDeadline { .. }
                            ) {
                                run.evictions += 1;
                            }
                            run.closes.push((node, now(), reason.to_string()));
                        }
                        MasterEvent::FrameSwapped(s) => {
                            last_swap_at = Some(Instant::now());
                            swaps.insert(s.frame, s);
                        }
                        MasterEvent::FramePresented(p) => {
                            if let Some(g) = gi.as_mut() {
                                g.after_present(&mut core, now(), &mut run);
                            }
                            let (Some(state), Some(swap)) =
                                (states.remove(&p.frame), swaps.remove(&p.frame))
                            else {
                                continue;
                            };
                            // A frame's record is built only for a file or
                            // a run that keeps it: a live show without
                            // `--metrics` spends nothing on it.
                            if settings.metrics.is_some() || settings.keep_frames {
                                let m = frame_metrics(&state, &swap, &p, origin_unix_ms);
                                if let Some(w) = settings.metrics.as_mut() {
                                    serde_json::to_writer(&mut *w, &m)
                                        .map_err(|e| ServerError::Metrics(e.into()))?;
                                    // Whole lines, at once: the file is read
                                    // live (`tail -f`, the fault bench).
                                    w.write_all(b"\n").map_err(ServerError::Metrics)?;
                                    w.flush().map_err(ServerError::Metrics)?;
                                }
                                if settings.keep_frames {
                                    run.frames.push(m);
                                }
                            }
                            run.presented += 1;
                            live.presented(&swap, &p, state);
                        }
                    },
                }
            }
            if let Some(p) = publisher.as_mut()
                && p.due()
            {
                p.publish_with(|| live.snapshot(&run, core.scene(), core.scene_version(), now()));
            }
            if let Some(limit) = settings.frames {
                let all_swapped = core.swapped_upto().is_some_and(|f| f + 1 >= limit);
                let reports_in = states.is_empty()
                    || last_swap_at.is_some_and(|t| t.elapsed() > Duration::from_millis(500));
                if next_frame >= limit && all_swapped && reports_in {
                    break 'run;
                }
            }
            timer.set(core.poll_timeout().map(|t| start + Duration::from_nanos(t)));
            let datagram = async {
                match udp.as_ref() {
                    Some(u) => u.recv_from(&mut udp_buf).await.map(|(n, _)| n),
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                _ = shutdown.cancelled() => break 'run,
                Some(incoming) = endpoint.accept() => {
                    let id = ConnId(next_conn);
                    next_conn += 1;
                    let tx = tx.clone();
                    let span = info_span!("connection", conn = %id, peer = %incoming.remote_address());
                    tasks.spawn(connection(incoming, id, tx, traffic.clone(), roster.clone()).instrument(span));
                }
                Some(ev) = rx.recv() => match ev {
                    Inbound::Connected(id, out) => {
                        conns.insert(id, out);
                        core.handle_connect(now(), id);
                    }
                    Inbound::Message(id, m) => if conns.contains_key(&id) { core.handle_message(now(), id, m) },
                    Inbound::DecodeError(id, e) => if conns.contains_key(&id) { core.handle_decode_error(now(), id, &e) },
                    Inbound::Refused(id, why) => {
                        run.refusals.push(why);
                        if conns.remove(&id).is_some() {
                            core.handle_disconnect(now(), id);
                        }
                    }
                    Inbound::Lost(id, why) => if conns.remove(&id).is_some() {
                        debug!(conn = %id, %why, "connection lost");
                        core.handle_disconnect(now(), id);
                    },
                },
                n = datagram => match n {
                    // DTrack sends ASCII. Other bytes become U+FFFD and reach
                    // the parser (which refuses them) and the recording as
                    // text, so a replay sees exactly what the show saw.
                    Ok(n) => show.ingest_live(now() as f64 / 1e9, &String::from_utf8_lossy(&udp_buf[..n])),
                    Err(e) => warn!(error = %e, "tracking socket"),
                },
                tick_at = ticker.tick() => {
                    if !started {
                        // Global mode: frames start with the first solution
                        // named (every node that joined holds it), whatever
                        // the start timeout; the nodes join meanwhile.
                        if gi.is_some() && core.illumination_version().is_none() {
                            continue 'run;
                        }
                        // A node that answered a clock probe (queued after its
                        // snapshot) has the scene; starting earlier would put
                        // frame 0 behind a snapshot still in flight.
                        // Also wait for a clock estimate good to 1 ms, or the
                        // first frames' skew figures would measure the
                        // estimate's error rather than the cluster's.
                        let joined = core
                            .nodes()
                            .filter(|n| n.clock.is_some_and(|c| c.error_bound_ns() < 1_000_000))
                            .count();
                        if joined >= settings.wait_for_nodes || start.elapsed() >= settings.start_timeout {
                            started = true;
                            live.started();
                            run.started_ns = now();
                            info!(nodes = joined, "frame clock started");
                        } else {
                            continue 'run;
                        }
                    }
                    if settings.frames.is_some_and(|l| next_frame >= l) {
                        continue 'run;
                    }
                    if !core.can_submit() {
                        run.dropped_ticks += 1;
                        continue 'run;
                    }
                    let t = now();
                    // The frame's deadline runs from its tick, not from when
                    // tokio's whole-millisecond timer got round to it: else a
                    // 17 ms tick gap adds to the stall behind a dead node.
                    let tick_ns = (tick_at.into_std().saturating_duration_since(start).as_nanos() as u64).min(t);
                    if let Some(g) = gi.as_mut()
                        && !g.due(&mut core, next_frame, now(), &mut run)
                    {
                        // A replay's solution is late: this frame waits.
                        run.illumination_waits += 1;
                        continue 'run;
                    }
                    let (mut state, sample) = show.frame_state(next_frame, t as f64 / 1e9, core.scene(), core.scene_version());
                    state.tracking_time_ns = sample.map(|s| (s * 1e9) as u64);
                    state.illumination_version = core.illumination_version();
                    if let Some(g) = gi.as_mut() {
                        g.frame(&core, &state, &mut run);
                    }
                    if show.is_live() || state.tracking_time_ns.is_none() {
                        // Live samples are already on the master clock.
                    } else {
                        // Scripted and replayed samples are in show time:
                        // their sample "arrives" as the frame is built.
                        state.tracking_time_ns = Some(t);
                    }
                    states.insert(next_frame, state.clone());
                    match core.submit_frame(tick_ns, state) {
                        Ok(()) => {
                            run.submitted += 1;
                            next_frame += 1;
                        }
                        Err(e) => {
                            states.remove(&next_frame);
                            warn!(error = %e, "frame refused");
                            run.dropped_ticks += 1;
                        }
                    }
                }
                _ = timer.fired() => core.handle_timeout(now()),
                Some(command) = async {
                    match capture_rx.as_mut() {
                        Some(r) => r.recv().await,
                        None => std::future::pending().await,
                    }
                } => captures.command(&mut core, now(), command),
                Some(solved) = async {
                    match gi.as_mut() {
                        Some(g) => match g.results.recv().await {
                            None if g.first => Some(Err("the solver stopped".to_owned())),
                            r => r,
                        },
                        None => std::future::pending().await,
                    }
                } => {
                    if let Some(g) = gi.as_mut() {
                        if g.first {
                            if let Err(e) = g.first_landed(&mut core, now(), solved) {
                                failed = Some(e);
                                break 'run;
                            }
                            continue 'run;
                        }
                        // Frames flow when one swapped within the last
                        // few periods; else nothing is in flight to wait for.
                        let flowing = last_swap_at.is_some_and(|t| t.elapsed() < Duration::from_millis(100));
                        g.landed(&mut core, now(), solved, flowing, &mut run);
                    }
                }
            }
        }
        drop(gi);
        run.finished_ns = now();
        run.stats = live.summary();
        if let Some(p) = publisher.as_mut() {
            p.publish_with(|| live.snapshot(&run, core.scene(), core.scene_version(), now()));
        }
        run.frame_bytes = traffic.bytes.load(Ordering::Relaxed);
        run.frame_messages = traffic.messages.load(Ordering::Relaxed);
        core.shutdown(now(), "the master is shutting down");
        while let Some(out) = core.poll() {
            if let MasterOutput::Transmit { conn, message } = out {
                if let Some(c) = conns.get(&conn) {
                    let _ = c.send(Outbound::Send(message));
                }
            } else if let MasterOutput::Close { conn, reason } = out
                && let Some(c) = conns.remove(&conn)
            {
                let _ = c.send(Outbound::Close(reason.to_string()));
            }
        }
        drop(conns);
        let _ = tokio::time::timeout(Duration::from_secs(2), async {
            while tasks.join_next().await.is_some() {}
        })
        .await;
        tasks.abort_all();
        endpoint.close(0u32.into(), b"master shutting down");
        let _ = tokio::time::timeout(Duration::from_secs(1), endpoint.wait_idle()).await;
        match failed {
            Some(e) => Err(e),
            None => Ok(run),
        }
    }
}

/// The master's global illumination while a run lasts: the solver
/// thread, its results, and the update being timed.
struct GlobalIllumination {
    solver: super::illumination::Solver,
    results: mpsc::UnboundedReceiver<Result<super::illumination::Solved, String>>,
    /// The first solution has not landed yet: the frame clock waits, the
    /// nodes join meanwhile.
    first: bool,
    /// The state last asked for.
    asked: Option<FrameState>,
    /// Lockstep ([`ServerSettings::illumination_lag`]): the lag, the frame
    /// whose solve is awaited, and a solve that landed before its frame.
    lag: Option<u64>,
    outstanding: Option<u64>,
    early: Option<Result<super::illumination::Solved, String>>,
    /// Lockstep: a version published for its frame that the nodes do not
    /// all hold yet; that frame waits for it.
    naming: Option<u64>,
    /// Live: a solve that landed while a frame was in flight, published
    /// once it is presented.
    waiting: Option<Result<super::illumination::Solved, String>>,
    /// A published update not yet named by a frame: the frame it solved,
    /// its version, request-to-publish and solve times (ms).
    published: Option<(u64, u64, f64, f64)>,
}

impl GlobalIllumination {
    /// For a scene in global mode: start the solver thread on the scene's
    /// first state. The frame clock waits for that solution
    /// ([`Self::first_landed`]); the loop keeps taking nodes meanwhile, so
    /// their handshakes do not wait on the solve (they timed out behind
    /// the demo cabinet's 3 s first solve).
    fn start(
        core: &MasterCore,
        lag: Option<u64>,
        patch_area: Option<f64>,
    ) -> Result<Option<Self>, ServerError> {
        use super::illumination::{Request, Solver, initial_state};
        if core.scene().illumination != showcase_proto::IlluminationMode::Global {
            return Ok(None);
        }
        let options = crate::radiosity_job::RadiosityOptions {
            max_patch_area: patch_area,
            ..Default::default()
        }
        .for_scene(core.scene());
        let scene = core.scene().clone();
        let state = initial_state(&scene, core.scene_version());
        // The solver thread solves the first state itself, so that the
        // live solution it keeps starts there.
        let first = Request::of(&scene, &state).with_maps(core.maps());
        let (solver, results) = Solver::start(options, Some(first)).map_err(|e| {
            ServerError::Illumination(format!("cannot start the solver thread: {e}"))
        })?;
        Ok(Some(Self {
            solver,
            results,
            first: true,
            asked: None,
            lag,
            outstanding: None,
            early: None,
            naming: None,
            waiting: None,
            published: None,
        }))
    }

    /// The first solution landed: publish it to the nodes that joined (and
    /// with the snapshot of those that join later). A failed first solve
    /// stops the run: there is nothing to draw global mode with.
    fn first_landed(
        &mut self,
        core: &mut MasterCore,
        now: u64,
        solved: Result<super::illumination::Solved, String>,
    ) -> Result<(), ServerError> {
        let first =
            solved.map_err(|e| ServerError::Illumination(format!("the first solution: {e}")))?;
        info!(
            elements = first.values.len(),
            solve_s = first.solve_s,
            "global illumination: first solution"
        );
        core.set_illumination(now, first.mesh, first.values)?;
        self.first = false;
        Ok(())
    }

    /// Lockstep only: before frame `frame` is built, publish the solve due
    /// at it. False while that solve has not landed, or the nodes do not
    /// all hold it yet: the frame must wait (the loop skips the tick and
    /// stays responsive, so no node misses a deadline while the solver is
    /// late), so a replay draws each frame with the same version.
    fn due(&mut self, core: &mut MasterCore, frame: u64, now: u64, run: &mut ClusterRun) -> bool {
        if let Some(v) = self.naming {
            if core.illumination_version() != Some(v) {
                return false;
            }
            self.naming = None;
        }
        let (Some(lag), Some(asked)) = (self.lag, self.outstanding) else {
            return true;
        };
        if frame < asked.saturating_add(lag) {
            return true;
        }
        let Some(solved) = self.early.take() else {
            return false;
        };
        self.outstanding = None;
        let published = self.publish_now(core, now, solved, run);
        if published.is_some() && core.illumination_version() != published {
            self.naming = published;
            return false;
        }
        true
    }

    /// `state` is about to be submitted: time the update it is the first
    /// frame of, and ask for a new solution when its inputs moved.
    fn frame(&mut self, core: &MasterCore, state: &FrameState, run: &mut ClusterRun) {
        use super::illumination::{Request, Update, inputs_differ};
        if let Some((solved_frame, version, latency_ms, solve_ms)) = self.published
            && state.illumination_version == Some(version)
        {
            self.published = None;
            if run.illumination_updates.len() < MAX_KEPT_UPDATES {
                run.illumination_updates.push(Update {
                    solved_frame,
                    first_frame: state.frame,
                    latency_ms,
                    solve_ms,
                });
            }
        }
        // In lockstep one solve at a time, each published at its frame.
        if self.lag.is_some() && self.outstanding.is_some() {
            return;
        }
        if self.asked.as_ref().is_none_or(|a| inputs_differ(a, state)) {
            self.solver
                .ask(Request::of(core.scene(), state).with_maps(core.maps()));
            self.outstanding = Some(state.frame);
            self.asked = Some(state.clone());
        }
    }

    /// A solve finished: keep it for its frame (lockstep); live, publish
    /// it once the next frame is presented (`flowing`: frames are being
    /// swapped), else now. Then no frame is in flight, so the solution
    /// crosses the network and the nodes prepare it in the gap before the
    /// next frame. Published at once, it landed on a frame in flight one
    /// time in five (`bench gi`, demo cabinet: that frame's
    /// tracking-to-swap up to 12 ms); published at the swap, its sending
    /// delayed the other nodes' Swap (skew p99 2 ms against 0.09).
    fn landed(
        &mut self,
        core: &mut MasterCore,
        now: u64,
        solved: Result<super::illumination::Solved, String>,
        flowing: bool,
        run: &mut ClusterRun,
    ) {
        if self.lag.is_some() {
            self.early = Some(solved);
        } else if flowing && solved.is_ok() {
            // A newer solve replaces one still waiting.
            self.waiting = Some(solved);
        } else {
            let _ = self.publish_now(core, now, solved, run);
        }
    }

    /// A frame was presented: publish the solve waiting for it.
    fn after_present(&mut self, core: &mut MasterCore, now: u64, run: &mut ClusterRun) {
        if let Some(solved) = self.waiting.take() {
            let _ = self.publish_now(core, now, solved, run);
        }
    }

    /// Publish a finished solve (or record why it failed); its version.
    fn publish_now(
        &mut self,
        core: &mut MasterCore,
        now: u64,
        solved: Result<super::illumination::Solved, String>,
        run: &mut ClusterRun,
    ) -> Option<u64> {
        let s = match solved {
            Ok(s) => s,
            Err(e) => {
                warn!(error = %e, "illumination solve failed; frames keep the last solution");
                if run.illumination_failures.len() < MAX_KEPT_UPDATES {
                    run.illumination_failures.push(e);
                }
                return None;
            }
        };
        let latency_ms = s.asked_at.elapsed().as_secs_f64() * 1e3;
        match core.set_illumination(now, s.mesh, s.values) {
            Ok(version) => {
                self.published = Some((s.frame, version, latency_ms, s.solve_s * 1e3));
                Some(version)
            }
            Err(e) => {
                warn!(error = %e, "illumination solution refused");
                None
            }
        }
    }
}

/// One node connection: TLS handshake, the name check, then a reader that
/// forwards messages and a writer that sends what the core transmits.
/// FrameState bytes the writers actually sent, over all connections.
#[derive(Debug, Default)]
struct FrameTraffic {
    bytes: AtomicU64,
    messages: AtomicU64,
}

async fn connection(
    incoming: quinn::Incoming,
    id: ConnId,
    tx: mpsc::UnboundedSender<Inbound>,
    traffic: Arc<FrameTraffic>,
    roster: Arc<Roster>,
) {
    let conn = match incoming.await {
        Ok(c) => c,
        Err(e) => {
            warn!(error = %e, "handshake refused");
            return;
        }
    };
    let (send, recv) = match tokio::time::timeout(Duration::from_secs(5), conn.accept_bi()).await {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => {
            debug!(error = %e, "no stream");
            return;
        }
        Err(_) => {
            conn.close(2u32.into(), b"no stream opened in 5 s");
            return;
        }
    };
    let (mut writer, mut reader): (MessageWriter, MessageReader) =
        MessageStream::new(send, recv).split();
    let (out_tx, mut out_rx) = mpsc::unbounded_channel();
    if tx.send(Inbound::Connected(id, out_tx)).is_err() {
        return;
    }
    let write_conn = conn.clone();
    let writer_task = async move {
        while let Some(o) = out_rx.recv().await {
            match o {
                Outbound::Send(m) => match writer.send(&m).await {
                    Ok(n) => {
                        if let Message::FrameState(_) = m {
                            traffic.bytes.fetch_add(n as u64, Ordering::Relaxed);
                            traffic.messages.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    Err(_) => break,
                },
                Outbound::Close(reason) => {
                    writer.finish();
                    // Give the Bye a moment to leave before the close frame.
                    tokio::time::sleep(Duration::from_millis(20)).await;
                    let mut r = reason.into_bytes();
                    r.truncate(1000);
                    write_conn.close(1u32.into(), &r);
                    break;
                }
            }
        }
    };
    let reader_task = async {
        loop {
            match reader.recv().await {
                Ok(Message::Hello(h)) => {
                    let names = peer_names(&conn);
                    if let Err(refusal) =
                        roster.admit(&h.node, h.role, &names, peer_is(&conn, &h.node))
                    {
                        warn!(
                            hello = %h.node,
                            certificate = ?names,
                            config = ?refusal.entry,
                            "{refusal}"
                        );
                        let mut why = refusal.to_string().into_bytes();
                        why.truncate(1000);
                        conn.close(REFUSED.into(), &why);
                        let _ = tx.send(Inbound::Refused(id, refusal.to_string()));
                        return false;
                    }
                    if tx.send(Inbound::Message(id, Message::Hello(h))).is_err() {
                        return false;
                    }
                }
                Ok(m) => {
                    if tx.send(Inbound::Message(id, m)).is_err() {
                        return false;
                    }
                }
                Err(StreamError::Codec(e)) => {
                    // The core answers with Bye + Close: let the writer send them.
                    let _ = tx.send(Inbound::DecodeError(id, e));
                    return true;
                }
                Err(e) => {
                    let _ = tx.send(Inbound::Lost(id, e.to_string()));
                    return false;
                }
            }
        }
    };
    let mut writer_task = std::pin::pin!(writer_task);
    tokio::select! {
        _ = &mut writer_task => {}
        wait_for_writer = reader_task => if wait_for_writer {
            let _ = tokio::time::timeout(Duration::from_secs(1), &mut writer_task).await;
        }
    }
    // Whatever ended first, make sure the core hears the connection is gone.
    let _ = tx.send(Inbound::Lost(id, "connection ended".into()));
}
