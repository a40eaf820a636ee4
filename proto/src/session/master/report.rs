//! What the master hands its driver: outputs, events, close reasons and the per-frame reports for metrics.

use crate::message::{Capabilities, Message, NodeStats, Role};
use crate::session::{ClockSample, ConnId};

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
    /// A node answered a capture request (`PatternShown`, `FrameChunk`,
    /// `CaptureFailed`).
    Capture {
        /// Its connection.
        conn: ConnId,
        /// Its name.
        node: String,
        /// The answer.
        message: Box<crate::message::Message>,
    },
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
