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
use super::clock::{ClockEstimator, clock_sample};
use super::{ConnId, ms};
use crate::PROTOCOL_VERSION;
use crate::capture::CapturedMap;
use crate::message::{
    Bye, Capabilities, ClockProbe, ClockReply, Hello, Message, NodeStats, Ready, Role,
    SceneSnapshot, Swap, Welcome,
};
use crate::scene::{FrameState, Showcase};
use crate::validate::Validate;
use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::Arc;

mod config;
mod frames;
mod illumination;
mod peers;
mod report;

use illumination::IlluminationState;

pub use config::{CaptureSendError, MasterConfig, MasterError, SubmitError};
pub use report::{
    CloseReason, MasterEvent, MasterOutput, NodeInfo, NodePresent, PresentReport, ReadyNode,
    SwapReport,
};

/// Clock probes a node may have unanswered before the oldest is forgotten.
const MAX_OUTSTANDING_PROBES: usize = 8;

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
    /// The newest global-illumination version it said it holds.
    illumination_ready: Option<u64>,
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
    /// The captured reflectance maps, sent in every snapshot.
    maps: Arc<Vec<CapturedMap>>,
    peers: BTreeMap<ConnId, Peer>,
    names: HashMap<String, ConnId>,
    barrier: SwapBarrier,
    /// The newest submitted frame.
    latest: Option<FrameState>,
    next_frame: Option<u64>,
    swapped_upto: Option<u64>,
    presents: VecDeque<PresentWait>,
    /// The global-illumination solution's versions.
    illumination: IlluminationState,
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
            maps: Arc::new(Vec::new()),
            peers: BTreeMap::new(),
            names: HashMap::new(),
            latest: None,
            next_frame: None,
            swapped_upto: None,
            presents: VecDeque::new(),
            illumination: IlluminationState::default(),
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
            self.remove(conn, CloseReason::Disconnected { peer }, false);
            self.advance(now);
        }
    }

    /// A message from `conn` could not be decoded; closes only that peer.
    pub fn handle_decode_error(&mut self, now: u64, conn: ConnId, error: &crate::CodecError) {
        self.violation(conn, error.to_string());
        self.advance(now);
    }

    /// A decoded message from `conn`.
    pub fn handle_message(&mut self, now: u64, conn: ConnId, message: Message) {
        if !self.peers.contains_key(&conn) {
            return; // Already closed; late data is dropped.
        }
        if let Err(e) = message.validate() {
            self.violation(conn, format!("invalid {}: {e}", message.kind()));
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
                self.remove(conn, CloseReason::Left { peer, reason }, true);
            }
            (Peer::Live(_), Message::Ready(r)) => self.ready(now, conn, r),
            (Peer::Live(_), Message::NodeStats(s)) => self.stats(conn, s),
            (Peer::Live(_), Message::ClockReply(r)) => self.clock_reply(now, conn, r),
            (Peer::Live(_), Message::IlluminationResync(r)) => self.illumination_resync(conn, r),
            (Peer::Live(_), Message::IlluminationReady(r)) => self.illumination_ready(conn, r),
            (
                Peer::Live(n),
                m @ (Message::PatternShown(_) | Message::FrameChunk(_) | Message::CaptureFailed(_)),
            ) => {
                let node = n.name.clone();
                self.event(MasterEvent::Capture {
                    conn,
                    node,
                    message: Box::new(m),
                });
            }
            (Peer::Live(_), Message::Hello(_)) => self.violation(conn, "Hello twice".into()),
            (Peer::AwaitHello { .. }, m) => {
                self.violation(conn, format!("{} before Hello", m.kind()))
            }
            (Peer::Live(_), m) => {
                self.violation(conn, format!("{} is a master-to-node message", m.kind()))
            }
        }
        self.advance(now);
    }

    /// The captured reflectance maps the snapshots carry.
    pub fn maps(&self) -> &Arc<Vec<CapturedMap>> {
        &self.maps
    }

    /// New captured reflectance maps (replacing those of the same name):
    /// bumps the scene version and sends every live node a fresh snapshot
    /// with them; a later joiner gets them in its snapshot. Returns the new
    /// version.
    pub fn set_maps(&mut self, now: u64, maps: Vec<CapturedMap>) -> Result<u64, MasterError> {
        let mut all: Vec<CapturedMap> = (*self.maps)
            .iter()
            .filter(|m| !maps.iter().any(|n| n.name == m.name))
            .cloned()
            .collect();
        all.extend(maps);
        let check = Message::SceneSnapshot(Box::new(SceneSnapshot {
            version: self.scene_version + 1,
            showcase: Showcase::default(),
            current: None,
            maps: all,
        }));
        check.validate()?;
        let Message::SceneSnapshot(s) = check else {
            unreachable!("built above")
        };
        self.maps = Arc::new(s.maps);
        let scene = (*self.scene).clone();
        self.set_scene(now, scene)
    }

    /// Send a capture request (`ShowPattern` to a projector node,
    /// `CaptureFrames` to a camera node) to the live node `node`; its
    /// answers come back as [`MasterEvent::Capture`].
    pub fn send_capture(
        &mut self,
        node: &str,
        message: Message,
    ) -> Result<ConnId, CaptureSendError> {
        let want = match &message {
            Message::ShowPattern(_) => Role::Projector,
            Message::CaptureFrames(_) => Role::Camera,
            m => return Err(CaptureSendError::NotARequest(m.kind())),
        };
        message
            .validate()
            .map_err(|e| CaptureSendError::Invalid(e.to_string()))?;
        let conn = *self
            .names
            .get(node)
            .ok_or_else(|| CaptureSendError::NotConnected(node.to_string()))?;
        let Some(Peer::Live(n)) = self.peers.get(&conn) else {
            return Err(CaptureSendError::NotConnected(node.to_string()));
        };
        if n.role != want {
            return Err(CaptureSendError::WrongRole {
                node: node.to_string(),
                role: n.role,
                want,
            });
        }
        self.transmit(conn, message);
        Ok(conn)
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
            maps: (*self.maps).clone(),
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
        if frame.illumination_version.is_some()
            && frame.illumination_version != self.illumination_version()
        {
            return Err(SubmitError::WrongIllumination {
                frame: frame.frame,
                version: frame.illumination_version,
                current: self.illumination_version(),
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
        let version = frame.illumination_version;
        self.latest = Some(frame);
        self.frame_names_illumination(n, version);
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
            self.remove(conn, reason, true);
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
        peers
            .chain(self.barrier.next_deadline())
            .chain(self.illumination_due())
            .min()
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
            self.remove(conn, reason, true);
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
        self.advance_illumination(Some(now));
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
