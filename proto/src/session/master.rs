//! The master's side: one session per connection (handshake, snapshot,
//! frame stream, clock probes), the swap barrier across all live nodes, and
//! per-frame reports for metrics.
//!
//! Policies, decided here:
//! - The first message must be a [`Hello`] with [`PROTOCOL_VERSION`] within
//!   [`MasterConfig::handshake_timeout_ns`]. A Hello with a name that is
//!   already live **replaces** the older connection (the newest wins): a
//!   restarted node must not wait for its dead predecessor to time out, and
//!   mutual TLS already ties names to certificates.
//! - A joiner gets `Welcome`, then a `SceneSnapshot` whose `current` is the
//!   newest submitted frame (if it belongs to the current scene version), so
//!   it renders the right state at any frame. If that frame has already
//!   swapped, `Swap` follows at once; if it is still in flight the joiner
//!   watches it (gets its Swap, is not waited for). From the next submitted
//!   frame on it is a full member of the barrier.
//! - Anything out of order closes only that peer, with a reason.

use super::barrier::{ReadyMark, Release, SwapBarrier};
use super::clock::{ClockEstimator, ClockSample, clock_sample};
use super::{ConnId, NS_PER_MS, ms};
use crate::PROTOCOL_VERSION;
use crate::message::{
    Bye, Capabilities, ClockProbe, ClockReply, Hello, Message, NodeStats, Ready, Role,
    SceneSnapshot, Swap, Welcome,
};
use crate::scene::{FrameState, Showcase};
use crate::validate::{Validate, ValidationError};
use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::Arc;

/// Clock probes a node may have unanswered before the oldest is forgotten.
const MAX_OUTSTANDING_PROBES: usize = 8;

/// Settings of a [`MasterCore`].
#[derive(Clone, Debug, PartialEq)]
pub struct MasterConfig {
    /// Target frame rate, announced in `Welcome` (the driver's frame clock uses it).
    pub target_hz: f32,
    /// Swap deadline after a frame is sent (ns); default 50 ms.
    pub deadline_ns: u64,
    /// Time a connection has to send its Hello (ns); default 5 s.
    pub handshake_timeout_ns: u64,
    /// Interval between clock probes to each node (ns); default 200 ms.
    pub clock_probe_interval_ns: u64,
    /// Recent clock samples among which the minimum-delay one is kept; default 16.
    pub clock_window: usize,
    /// A frame's [`PresentReport`] is emitted once every node reported its
    /// stats, or at the latest when the frame this many frames later swaps; default 4.
    pub present_report_lag: u64,
}

impl Default for MasterConfig {
    fn default() -> Self {
        Self {
            target_hz: 60.0,
            deadline_ns: 50 * NS_PER_MS,
            handshake_timeout_ns: 5_000 * NS_PER_MS,
            clock_probe_interval_ns: 200 * NS_PER_MS,
            clock_window: 16,
            present_report_lag: 4,
        }
    }
}

impl MasterConfig {
    /// Check every setting is in range (what `Welcome` can carry).
    pub fn check(&self) -> Result<(), MasterError> {
        let bad = |field, value: String, problem| {
            Err(MasterError::InvalidConfig {
                field,
                value,
                problem,
            })
        };
        if !(self.target_hz.is_finite() && self.target_hz > 0.0) {
            return bad("target_hz", self.target_hz.to_string(), "must be positive");
        }
        if !(NS_PER_MS / 1_000..=3_600_000 * NS_PER_MS).contains(&self.deadline_ns) {
            let problem = "must be between 1 us and 1 hour";
            return bad("deadline_ns", self.deadline_ns.to_string(), problem);
        }
        if self.clock_probe_interval_ns == 0 {
            let value = self.clock_probe_interval_ns.to_string();
            return bad("clock_probe_interval_ns", value, "must be positive");
        }
        if self.clock_window == 0 {
            return bad("clock_window", "0".into(), "must be at least 1");
        }
        Ok(())
    }
}

/// Why the master closes (or lost) a connection.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CloseReason {
    /// The peer broke the protocol.
    #[error("protocol violation by {peer}: {detail}")]
    Violation {
        /// The node (`node 'name'`), or the connection if it has not said Hello.
        peer: String,
        /// What it did.
        detail: String,
    },
    /// The peer speaks another protocol version.
    #[error("node '{node}' speaks protocol version {theirs}, the master speaks {ours}")]
    VersionMismatch {
        /// The node's name.
        node: String,
        /// Its version.
        theirs: u32,
        /// Ours.
        ours: u32,
    },
    /// No Hello arrived in time.
    #[error("{peer} sent no Hello within {waited_ms:.1} ms")]
    HandshakeTimeout {
        /// The connection.
        peer: String,
        /// How long the master waited.
        waited_ms: f64,
    },
    /// A node missed the swap deadline and is evicted; it may rejoin.
    #[error(
        "node '{node}' missed the swap deadline of frame {frame}: no Ready {waited_ms:.1} ms after the frame was sent (deadline {deadline_ms:.1} ms)"
    )]
    MissedDeadline {
        /// The node's name.
        node: String,
        /// The frame it did not answer.
        frame: u64,
        /// Time from sending the frame to the eviction (ms).
        waited_ms: f64,
        /// The configured deadline (ms).
        deadline_ms: f64,
    },
    /// A newer connection said Hello with the same name.
    #[error("node '{node}' connected again on {by}; this older connection is replaced")]
    Replaced {
        /// The node's name.
        node: String,
        /// The newer connection.
        by: ConnId,
    },
    /// The node said Bye.
    #[error("{peer} left: {reason}")]
    Left {
        /// The node (`node 'name'`) or the connection.
        peer: String,
        /// Its reason.
        reason: String,
    },
    /// The transport reported the connection lost.
    #[error("connection to {peer} lost")]
    Disconnected {
        /// The node (`node 'name'`) or the connection.
        peer: String,
    },
    /// The master is shutting down.
    #[error("master shutting down: {reason}")]
    Shutdown {
        /// Why.
        reason: String,
    },
}

/// What the driver must do, in order.
#[derive(Clone, Debug, PartialEq)]
pub enum MasterOutput {
    /// Send this message on this connection.
    Transmit {
        /// The connection.
        conn: ConnId,
        /// The message (encode with [`crate::encode_frame`]).
        message: Message,
    },
    /// Close this connection after flushing what was transmitted on it (a
    /// `Bye` with the reason was queued just before). The master has
    /// forgotten it: do not report its disconnect or messages any more.
    Close {
        /// The connection.
        conn: ConnId,
        /// Why.
        reason: CloseReason,
    },
    /// Something for logs and metrics.
    Event(MasterEvent),
}

/// Things that happened, for logs and metrics.
#[derive(Clone, Debug, PartialEq)]
pub enum MasterEvent {
    /// A node completed its handshake and got a snapshot.
    NodeJoined {
        /// Its connection.
        conn: ConnId,
        /// Its name.
        node: String,
        /// Its role.
        role: Role,
        /// The frame in its snapshot (`SceneSnapshot::current`), if any.
        current_frame: Option<u64>,
    },
    /// A connection is gone (closed by the master or lost).
    NodeClosed {
        /// Its connection.
        conn: ConnId,
        /// Its name, if it had said Hello.
        node: Option<String>,
        /// Why.
        reason: CloseReason,
    },
    /// A frame swapped.
    FrameSwapped(SwapReport),
    /// The nodes' present times of a frame are in (or the wait for them ended).
    FramePresented(PresentReport),
}

/// A node that was ready when a frame swapped.
#[derive(Clone, Debug, PartialEq)]
pub struct ReadyNode {
    /// Its connection.
    pub conn: ConnId,
    /// Its name.
    pub node: String,
    /// When its Ready arrived (master clock, ns).
    pub ready_at_ns: u64,
    /// Time its Ready waited at the barrier: swap time minus arrival (ns).
    pub barrier_wait_ns: u64,
    /// The output hash it reported.
    pub output_hash: u64,
}

/// One swapped frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SwapReport {
    /// The frame.
    pub frame: u64,
    /// When it was sent (master clock, ns).
    pub sent_at_ns: u64,
    /// When Swap was sent (master clock, ns).
    pub swap_at_ns: u64,
    /// `FrameState::tracking_time_ns` of the frame, for tracking-to-swap latency.
    pub tracking_time_ns: Option<u64>,
    /// The nodes that were ready, in connection order.
    pub ready: Vec<ReadyNode>,
    /// Names of the nodes evicted for missing this frame's deadline.
    pub evicted: Vec<String>,
    /// The deadline released it (some node was not ready).
    pub by_deadline: bool,
}

/// One node's presentation of a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct NodePresent {
    /// Its connection.
    pub conn: ConnId,
    /// Its name.
    pub node: String,
    /// Its render time (ms).
    pub render_ms: f32,
    /// Time between its Ready and its Swap, as the node measured it (ms).
    pub barrier_wait_ms: f32,
    /// Present time on the node's clock (ns).
    pub present_node_ns: u64,
    /// Present time mapped to the master's clock, once its offset is estimated.
    pub present_master_ns: Option<u64>,
    /// `present_master_ns` minus the swap time (ns).
    pub present_offset_ns: Option<i64>,
}

/// The presentation of one frame across nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct PresentReport {
    /// The frame.
    pub frame: u64,
    /// When Swap was sent (master clock, ns).
    pub swap_at_ns: u64,
    /// The nodes that reported, in connection order.
    pub nodes: Vec<NodePresent>,
    /// Names of nodes that were sent Swap but did not report in time.
    pub missing: Vec<String>,
    /// Spread (max minus min) of the mapped present times; `None` when no
    /// reporting node has a clock estimate yet.
    pub swap_skew_ns: Option<u64>,
}

/// What the master knows about a live node.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeInfo {
    /// Its connection.
    pub conn: ConnId,
    /// Its name.
    pub node: String,
    /// Its role.
    pub role: Role,
    /// Its capabilities.
    pub capabilities: Capabilities,
    /// When it joined (master clock, ns).
    pub joined_at_ns: u64,
    /// The current clock-offset estimate (node minus master).
    pub clock: Option<ClockSample>,
    /// Its last stats.
    pub last_stats: Option<NodeStats>,
}

/// Why a [`MasterCore`] could not be created or a scene was refused.
#[derive(Debug, thiserror::Error)]
pub enum MasterError {
    /// The scene breaks an invariant.
    #[error("scene is invalid: {0}")]
    InvalidScene(#[from] ValidationError),
    /// A setting is out of range.
    #[error("master setting {field} = {value} is out of range: {problem}")]
    InvalidConfig {
        /// The setting.
        field: &'static str,
        /// Its value, as text.
        value: String,
        /// The rule it breaks.
        problem: &'static str,
    },
}

/// Why a frame was refused by [`MasterCore::submit_frame`].
#[derive(Debug, thiserror::Error)]
pub enum SubmitError {
    /// One frame already waits ahead of the one being swapped.
    #[error("frame {frame} refused: {in_flight} frames are in flight, the oldest is {oldest}")]
    PipelineFull {
        /// The refused frame.
        frame: u64,
        /// Frames in flight.
        in_flight: usize,
        /// The oldest unswapped frame.
        oldest: u64,
    },
    /// Frames must be numbered consecutively.
    #[error("frame {frame} is out of order: the next frame is {expected}")]
    OutOfOrder {
        /// The refused frame.
        frame: u64,
        /// The frame expected.
        expected: u64,
    },
    /// The frame refers to another scene version.
    #[error("frame {frame} refers to scene version {version}, the current one is {current}")]
    WrongSceneVersion {
        /// The refused frame.
        frame: u64,
        /// Its scene version.
        version: u64,
        /// The current scene version.
        current: u64,
    },
    /// The frame breaks an invariant against the scene.
    #[error("frame is invalid: {0}")]
    Invalid(#[from] ValidationError),
}

#[derive(Debug)]
struct LiveNode {
    name: String,
    role: Role,
    capabilities: Capabilities,
    joined_at_ns: u64,
    /// First frame sent to this connection (in its snapshot or a FrameState).
    first_frame: Option<u64>,
    newest_sent: Option<u64>,
    last_ready: Option<u64>,
    last_swapped: Option<u64>,
    last_stats: Option<NodeStats>,
    clock: ClockEstimator,
    next_probe_id: u64,
    next_probe_at_ns: u64,
    outstanding_probes: VecDeque<(u64, u64)>,
}

#[derive(Debug)]
enum Peer {
    AwaitHello { connected_at_ns: u64 },
    Live(Box<LiveNode>),
}

#[derive(Debug)]
struct PresentWait {
    frame: u64,
    swap_at_ns: u64,
    awaiting: BTreeSet<ConnId>,
    nodes: Vec<NodePresent>,
}

/// The master's sans-IO core. See the module documentation for the policies.
#[derive(Debug)]
pub struct MasterCore {
    config: MasterConfig,
    scene: Arc<Showcase>,
    scene_version: u64,
    peers: BTreeMap<ConnId, Peer>,
    names: HashMap<String, ConnId>,
    barrier: SwapBarrier,
    /// The newest submitted frame.
    latest: Option<FrameState>,
    next_frame: Option<u64>,
    swapped_upto: Option<u64>,
    presents: VecDeque<PresentWait>,
    out: VecDeque<MasterOutput>,
}

impl MasterCore {
    /// A master serving `scene` as version 1.
    pub fn new(config: MasterConfig, scene: Showcase) -> Result<Self, MasterError> {
        config.check()?;
        scene.validate()?;
        Ok(Self {
            barrier: SwapBarrier::new(config.deadline_ns),
            config,
            scene: Arc::new(scene),
            scene_version: 1,
            peers: BTreeMap::new(),
            names: HashMap::new(),
            latest: None,
            next_frame: None,
            swapped_upto: None,
            presents: VecDeque::new(),
            out: VecDeque::new(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &MasterConfig {
        &self.config
    }

    /// The current scene version (frames must carry it).
    pub fn scene_version(&self) -> u64 {
        self.scene_version
    }

    /// The current scene.
    pub fn scene(&self) -> &Arc<Showcase> {
        &self.scene
    }

    /// The number the next submitted frame must carry, once one was submitted.
    pub fn next_frame(&self) -> Option<u64> {
        self.next_frame
    }

    /// The newest swapped frame.
    pub fn swapped_upto(&self) -> Option<u64> {
        self.swapped_upto
    }

    /// Whether [`Self::submit_frame`] would accept a frame now (fewer than
    /// [`MAX_FRAMES_IN_FLIGHT`](super::MAX_FRAMES_IN_FLIGHT) frames unswapped).
    pub fn can_submit(&self) -> bool {
        self.barrier.can_submit()
    }

    /// Frames sent and not yet swapped.
    pub fn frames_in_flight(&self) -> usize {
        self.barrier.len()
    }

    /// The live (handshaken) nodes, in connection order.
    pub fn nodes(&self) -> impl Iterator<Item = NodeInfo> + '_ {
        self.peers.iter().filter_map(|(conn, p)| match p {
            Peer::Live(n) => Some(info(*conn, n)),
            Peer::AwaitHello { .. } => None,
        })
    }

    /// The live node on `conn`.
    pub fn node(&self, conn: ConnId) -> Option<NodeInfo> {
        match self.peers.get(&conn)? {
            Peer::Live(n) => Some(info(conn, n)),
            Peer::AwaitHello { .. } => None,
        }
    }

    /// The live node named `name`.
    pub fn node_by_name(&self, name: &str) -> Option<NodeInfo> {
        self.node(*self.names.get(name)?)
    }

    /// A transport connection was accepted. A handle already in use is ignored.
    pub fn handle_connect(&mut self, now: u64, conn: ConnId) {
        if self.peers.contains_key(&conn) {
            tracing::warn!(%conn, "connection handle reused; ignored");
            return;
        }
        self.peers.insert(
            conn,
            Peer::AwaitHello {
                connected_at_ns: now,
            },
        );
    }

    /// The transport lost `conn` (or the peer closed it).
    pub fn handle_disconnect(&mut self, now: u64, conn: ConnId) {
        if let Some(peer) = self.peers.get(&conn) {
            let peer = peer_label(conn, peer);
            self.remove(now, conn, CloseReason::Disconnected { peer }, false);
            self.advance(now);
        }
    }

    /// A message from `conn` could not be decoded; closes only that peer.
    pub fn handle_decode_error(&mut self, now: u64, conn: ConnId, error: &crate::CodecError) {
        self.violation(now, conn, error.to_string());
        self.advance(now);
    }

    /// A decoded message from `conn`.
    pub fn handle_message(&mut self, now: u64, conn: ConnId, message: Message) {
        if !self.peers.contains_key(&conn) {
            return; // Already closed; late data is dropped.
        }
        if let Err(e) = message.validate() {
            self.violation(now, conn, format!("invalid {}: {e}", message.kind()));
            self.advance(now);
            return;
        }
        let Some(peer) = self.peers.get_mut(&conn) else {
            return;
        };
        match (peer, message) {
            (Peer::AwaitHello { .. }, Message::Hello(hello)) => self.hello(now, conn, hello),
            (_, Message::Bye(Bye { reason })) => {
                let peer = peer_label(conn, &self.peers[&conn]);
                self.remove(now, conn, CloseReason::Left { peer, reason }, true);
            }
            (Peer::Live(_), Message::Ready(r)) => self.ready(now, conn, r),
            (Peer::Live(_), Message::NodeStats(s)) => self.stats(now, conn, s),
            (Peer::Live(_), Message::ClockReply(r)) => self.clock_reply(now, conn, r),
            (Peer::Live(_), Message::Hello(_)) => self.violation(now, conn, "Hello twice".into()),
            (Peer::AwaitHello { .. }, m) => {
                self.violation(now, conn, format!("{} before Hello", m.kind()))
            }
            (Peer::Live(_), m) => self.violation(
                now,
                conn,
                format!("{} is a master-to-node message", m.kind()),
            ),
        }
        self.advance(now);
    }

    /// Replace the scene: bumps the version and sends a fresh snapshot (with
    /// no `current`; frames in flight keep their version) to every live
    /// node. Returns the new version.
    pub fn set_scene(&mut self, _now: u64, scene: Showcase) -> Result<u64, MasterError> {
        scene.validate()?;
        self.scene = Arc::new(scene);
        self.scene_version += 1;
        let snapshot = Message::SceneSnapshot(Box::new(SceneSnapshot {
            version: self.scene_version,
            showcase: (*self.scene).clone(),
            current: None,
        }));
        let live: Vec<ConnId> = self.live_conns().collect();
        for conn in live {
            self.transmit(conn, snapshot.clone());
        }
        Ok(self.scene_version)
    }

    /// Send a frame to every live node and start its swap barrier.
    pub fn submit_frame(&mut self, now: u64, frame: FrameState) -> Result<(), SubmitError> {
        if let Some(expected) = self.next_frame
            && frame.frame != expected
        {
            return Err(SubmitError::OutOfOrder {
                frame: frame.frame,
                expected,
            });
        }
        if let Some(oldest) = self.barrier.oldest()
            && !self.barrier.can_submit()
        {
            return Err(SubmitError::PipelineFull {
                frame: frame.frame,
                in_flight: self.barrier.len(),
                oldest,
            });
        }
        if frame.scene_version != self.scene_version {
            return Err(SubmitError::WrongSceneVersion {
                frame: frame.frame,
                version: frame.scene_version,
                current: self.scene_version,
            });
        }
        frame.validate_against(&self.scene)?;
        let n = frame.frame;
        let live: Vec<ConnId> = self.live_conns().collect();
        let message = Message::FrameState(Box::new(frame.clone()));
        for &conn in &live {
            if let Some(Peer::Live(node)) = self.peers.get_mut(&conn) {
                node.first_frame.get_or_insert(n);
                node.newest_sent = Some(n);
            }
            self.transmit(conn, message.clone());
        }
        self.barrier.push(now, n, frame.tracking_time_ns, live);
        self.next_frame = n.checked_add(1);
        self.latest = Some(frame);
        self.advance(now);
        Ok(())
    }

    /// Close every connection (each gets a Bye) and forget them.
    pub fn shutdown(&mut self, now: u64, reason: &str) {
        let conns: Vec<ConnId> = self.peers.keys().copied().collect();
        for conn in conns {
            let reason = CloseReason::Shutdown {
                reason: reason.to_string(),
            };
            self.remove(now, conn, reason, true);
        }
        self.advance(now);
    }

    /// When [`Self::handle_timeout`] must be called next.
    pub fn poll_timeout(&self) -> Option<u64> {
        let peers = self.peers.values().map(|p| match p {
            Peer::AwaitHello { connected_at_ns } => {
                connected_at_ns.saturating_add(self.config.handshake_timeout_ns)
            }
            Peer::Live(n) => n.next_probe_at_ns,
        });
        peers.chain(self.barrier.next_deadline()).min()
    }

    /// Time has reached `now`: deadlines, handshake timeouts, clock probes.
    pub fn handle_timeout(&mut self, now: u64) {
        let timeout = self.config.handshake_timeout_ns;
        let stale: Vec<(ConnId, u64)> = self
            .peers
            .iter()
            .filter_map(|(c, p)| match p {
                Peer::AwaitHello { connected_at_ns }
                    if now >= connected_at_ns.saturating_add(timeout) =>
                {
                    Some((*c, *connected_at_ns))
                }
                _ => None,
            })
            .collect();
        for (conn, since) in stale {
            let reason = CloseReason::HandshakeTimeout {
                peer: conn.to_string(),
                waited_ms: ms(now - since),
            };
            self.remove(now, conn, reason, true);
        }
        let due: Vec<ConnId> = self
            .peers
            .iter()
            .filter_map(|(c, p)| match p {
                Peer::Live(n) if now >= n.next_probe_at_ns => Some(*c),
                _ => None,
            })
            .collect();
        for conn in due {
            self.probe(now, conn);
        }
        self.advance(now);
    }

    /// The next output, in order.
    pub fn poll(&mut self) -> Option<MasterOutput> {
        self.out.pop_front()
    }

    fn live_conns(&self) -> impl Iterator<Item = ConnId> + '_ {
        self.peers
            .iter()
            .filter(|(_, p)| matches!(p, Peer::Live(_)))
            .map(|(c, _)| *c)
    }

    fn transmit(&mut self, conn: ConnId, message: Message) {
        self.out.push_back(MasterOutput::Transmit { conn, message });
    }

    fn event(&mut self, event: MasterEvent) {
        self.out.push_back(MasterOutput::Event(event));
    }

    fn violation(&mut self, now: u64, conn: ConnId, detail: String) {
        if let Some(peer) = self.peers.get(&conn) {
            let peer = peer_label(conn, peer);
            tracing::warn!(%conn, %peer, %detail, "protocol violation");
            self.remove(now, conn, CloseReason::Violation { peer, detail }, true);
        }
    }

    /// Forget `conn`; with `close`, queue a Bye and a Close for the driver.
    fn remove(&mut self, now: u64, conn: ConnId, reason: CloseReason, close: bool) {
        let Some(peer) = self.peers.remove(&conn) else {
            return;
        };
        let name = match peer {
            Peer::Live(n) => {
                if self.names.get(&n.name) == Some(&conn) {
                    self.names.remove(&n.name);
                }
                Some(n.name)
            }
            Peer::AwaitHello { .. } => None,
        };
        self.barrier.remove(conn);
        for p in &mut self.presents {
            p.awaiting.remove(&conn);
        }
        if close {
            let bye = Bye {
                reason: truncate(reason.to_string(), 4096),
            };
            self.transmit(conn, Message::Bye(bye));
            self.out.push_back(MasterOutput::Close {
                conn,
                reason: reason.clone(),
            });
        }
        self.event(MasterEvent::NodeClosed {
            conn,
            node: name,
            reason,
        });
        // Releases are driven by the caller's `advance`.
        let _ = now;
    }

    fn hello(&mut self, now: u64, conn: ConnId, hello: Hello) {
        if hello.protocol_version != PROTOCOL_VERSION {
            let reason = CloseReason::VersionMismatch {
                node: hello.node,
                theirs: hello.protocol_version,
                ours: PROTOCOL_VERSION,
            };
            self.remove(now, conn, reason, true);
            return;
        }
        if let Some(&old) = self.names.get(&hello.node) {
            let reason = CloseReason::Replaced {
                node: hello.node.clone(),
                by: conn,
            };
            self.remove(now, old, reason, true);
        }
        // The newest frame of the current scene is this node's first frame.
        let current = self
            .latest
            .as_ref()
            .filter(|f| f.scene_version == self.scene_version)
            .cloned();
        let current_frame = current.as_ref().map(|f| f.frame);
        let swapped = current_frame.is_some_and(|f| self.swapped_upto.is_some_and(|s| s >= f));
        let node = LiveNode {
            name: hello.node.clone(),
            role: hello.role,
            capabilities: hello.capabilities,
            joined_at_ns: now,
            first_frame: current_frame,
            newest_sent: current_frame,
            last_ready: None,
            last_swapped: if swapped { current_frame } else { None },
            last_stats: None,
            clock: ClockEstimator::new(self.config.clock_window),
            next_probe_id: 0,
            next_probe_at_ns: now,
            outstanding_probes: VecDeque::new(),
        };
        self.peers.insert(conn, Peer::Live(Box::new(node)));
        self.names.insert(hello.node.clone(), conn);
        self.transmit(
            conn,
            Message::Welcome(Welcome {
                protocol_version: PROTOCOL_VERSION,
                target_hz: self.config.target_hz,
                deadline_ms: ms(self.config.deadline_ns) as f32,
            }),
        );
        self.transmit(
            conn,
            Message::SceneSnapshot(Box::new(SceneSnapshot {
                version: self.scene_version,
                showcase: (*self.scene).clone(),
                current,
            })),
        );
        if let (true, Some(frame)) = (swapped, current_frame) {
            self.transmit(conn, Message::Swap(Swap { frame }));
        }
        self.event(MasterEvent::NodeJoined {
            conn,
            node: hello.node,
            role: hello.role,
            current_frame,
        });
        self.probe(now, conn);
    }

    fn ready(&mut self, now: u64, conn: ConnId, r: Ready) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        let legal = node.first_frame.is_some_and(|f| r.frame >= f)
            && node.newest_sent.is_some_and(|n| r.frame <= n)
            && node.last_ready.is_none_or(|l| r.frame > l);
        if !legal {
            let detail = format!(
                "Ready for frame {} (frames sent {}, last Ready {})",
                r.frame,
                range_text(node.first_frame, node.newest_sent),
                opt_text(node.last_ready)
            );
            self.violation(now, conn, detail);
            return;
        }
        node.last_ready = Some(r.frame);
        let mark = ReadyMark {
            at_ns: now,
            output_hash: r.output_hash,
        };
        // False for a joiner watching its first frame: accepted, not waited for.
        self.barrier.ready(conn, r.frame, mark);
    }

    fn stats(&mut self, now: u64, conn: ConnId, s: NodeStats) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        let legal = node.first_frame.is_some_and(|f| s.frame >= f)
            && node.last_swapped.is_some_and(|l| s.frame <= l)
            && node.last_stats.is_none_or(|l| s.frame > l.frame);
        if !legal {
            let detail = format!(
                "NodeStats for frame {} (frames swapped {}, last stats {})",
                s.frame,
                range_text(node.first_frame, node.last_swapped),
                opt_text(node.last_stats.map(|l| l.frame))
            );
            self.violation(now, conn, detail);
            return;
        }
        node.last_stats = Some(s);
        let present_master_ns = node
            .clock
            .estimate()
            .map(|c| c.to_master(s.present_time_ns));
        let name = node.name.clone();
        if let Some(p) = self
            .presents
            .iter_mut()
            .find(|p| p.frame == s.frame && p.awaiting.contains(&conn))
        {
            p.awaiting.remove(&conn);
            p.nodes.push(NodePresent {
                conn,
                node: name,
                render_ms: s.render_ms,
                barrier_wait_ms: s.barrier_wait_ms,
                present_node_ns: s.present_time_ns,
                present_master_ns,
                present_offset_ns: present_master_ns
                    .map(|t| (t as i128 - p.swap_at_ns as i128) as i64),
            });
        }
    }

    fn clock_reply(&mut self, now: u64, conn: ConnId, r: ClockReply) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        if r.id >= node.next_probe_id {
            let detail = format!("ClockReply for probe {} never sent", r.id);
            self.violation(now, conn, detail);
            return;
        }
        let Some(i) = node.outstanding_probes.iter().position(|p| p.0 == r.id) else {
            return; // Answered already or forgotten: stale, harmless.
        };
        let (_, sent) = node.outstanding_probes.remove(i).unwrap_or_default();
        if sent != r.master_send_ns {
            let detail = format!(
                "ClockReply {} echoes send time {} ns, the probe was sent at {sent} ns",
                r.id, r.master_send_ns
            );
            self.violation(now, conn, detail);
            return;
        }
        match clock_sample(&r, now) {
            Ok(s) => node.clock.push(s),
            Err(e) => self.violation(now, conn, e.to_string()),
        }
    }

    fn probe(&mut self, now: u64, conn: ConnId) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        let id = node.next_probe_id;
        node.next_probe_id += 1;
        node.next_probe_at_ns = now.saturating_add(self.config.clock_probe_interval_ns.max(1));
        if node.outstanding_probes.len() == MAX_OUTSTANDING_PROBES {
            node.outstanding_probes.pop_front();
        }
        node.outstanding_probes.push_back((id, now));
        self.transmit(
            conn,
            Message::ClockProbe(ClockProbe {
                id,
                master_send_ns: now,
            }),
        );
    }

    /// Release every frame that can swap, then emit finished present reports.
    fn advance(&mut self, now: u64) {
        while let Some(release) = self.barrier.poll_release(now) {
            self.swap(now, release);
        }
        self.flush_presents(false);
    }

    fn swap(&mut self, now: u64, release: Release) {
        let mut evicted = Vec::new();
        for conn in &release.late {
            let Some(Peer::Live(node)) = self.peers.get(conn) else {
                continue;
            };
            let node = node.name.clone();
            tracing::warn!(%node, frame = release.frame, "missed swap deadline");
            evicted.push(node.clone());
            let reason = CloseReason::MissedDeadline {
                node,
                frame: release.frame,
                waited_ms: ms(now.saturating_sub(release.sent_at_ns)),
                deadline_ms: ms(release.deadline_ns - release.sent_at_ns),
            };
            self.remove(now, *conn, reason, true);
        }
        let frame = release.frame;
        let mut swapped_to = BTreeSet::new();
        for (conn, peer) in &mut self.peers {
            if let Peer::Live(node) = peer
                && node.first_frame.is_some_and(|f| f <= frame)
                && node.newest_sent.is_some_and(|n| n >= frame)
                && node.last_swapped.is_none_or(|l| l < frame)
            {
                node.last_swapped = Some(frame);
                swapped_to.insert(*conn);
            }
        }
        for &conn in &swapped_to {
            self.transmit(conn, Message::Swap(Swap { frame }));
        }
        self.swapped_upto = Some(frame);
        let ready = release
            .ready
            .iter()
            .filter_map(|(conn, mark)| {
                let Some(Peer::Live(node)) = self.peers.get(conn) else {
                    return None;
                };
                Some(ReadyNode {
                    conn: *conn,
                    node: node.name.clone(),
                    ready_at_ns: mark.at_ns,
                    barrier_wait_ns: now.saturating_sub(mark.at_ns),
                    output_hash: mark.output_hash,
                })
            })
            .collect();
        self.event(MasterEvent::FrameSwapped(SwapReport {
            frame,
            sent_at_ns: release.sent_at_ns,
            swap_at_ns: now,
            tracking_time_ns: release.tracking_time_ns,
            ready,
            by_deadline: !release.late.is_empty(),
            evicted,
        }));
        self.presents.push_back(PresentWait {
            frame,
            swap_at_ns: now,
            awaiting: swapped_to,
            nodes: Vec::new(),
        });
        // Frames old enough are reported even if incomplete.
        let lag = self.config.present_report_lag;
        while self
            .presents
            .front()
            .is_some_and(|p| p.frame.saturating_add(lag) <= frame && p.frame != frame)
        {
            self.flush_presents(true);
        }
    }

    /// Emit the oldest present reports that are complete (or, with `force`, the oldest one).
    fn flush_presents(&mut self, force: bool) {
        let mut force = force;
        while let Some(p) = self.presents.front() {
            if !p.awaiting.is_empty() && !force {
                break;
            }
            force = false;
            let Some(mut p) = self.presents.pop_front() else {
                break;
            };
            p.nodes.sort_by_key(|n| n.conn);
            let missing = p
                .awaiting
                .iter()
                .filter_map(|c| match self.peers.get(c) {
                    Some(Peer::Live(n)) => Some(n.name.clone()),
                    _ => None,
                })
                .collect();
            let mapped = p.nodes.iter().filter_map(|n| n.present_master_ns);
            let swap_skew_ns = mapped
                .clone()
                .max()
                .zip(mapped.min())
                .map(|(hi, lo)| hi - lo);
            self.event(MasterEvent::FramePresented(PresentReport {
                frame: p.frame,
                swap_at_ns: p.swap_at_ns,
                nodes: p.nodes,
                missing,
                swap_skew_ns,
            }));
        }
    }
}

fn info(conn: ConnId, n: &LiveNode) -> NodeInfo {
    NodeInfo {
        conn,
        node: n.name.clone(),
        role: n.role,
        capabilities: n.capabilities.clone(),
        joined_at_ns: n.joined_at_ns,
        clock: n.clock.estimate(),
        last_stats: n.last_stats,
    }
}

fn peer_label(conn: ConnId, peer: &Peer) -> String {
    match peer {
        Peer::Live(n) => format!("node '{}'", n.name),
        Peer::AwaitHello { .. } => conn.to_string(),
    }
}

fn opt_text(v: Option<u64>) -> String {
    v.map_or_else(|| "none".into(), |v| v.to_string())
}

fn range_text(lo: Option<u64>, hi: Option<u64>) -> String {
    match (lo, hi) {
        (Some(lo), Some(hi)) => format!("{lo}..={hi}"),
        _ => "none".into(),
    }
}

fn truncate(mut s: String, max: usize) -> String {
    if s.len() > max {
        let mut cut = max;
        while !s.is_char_boundary(cut) {
            cut -= 1;
        }
        s.truncate(cut);
    }
    s
}
