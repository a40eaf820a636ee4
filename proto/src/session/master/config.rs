//! The master's settings and the errors of its inputs.

use crate::session::NS_PER_MS;
use crate::validate::ValidationError;

/// Settings of a [`MasterCore`](super::MasterCore).
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
    /// A frame's [`PresentReport`](super::PresentReport) is emitted once every node reported its
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

/// Why a [`MasterCore`](super::MasterCore) could not be created or a scene was refused.
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

/// Why a capture request could not be sent
/// ([`MasterCore::send_capture`](super::MasterCore::send_capture)).
#[derive(Debug, thiserror::Error)]
pub enum CaptureSendError {
    /// No live node of that name.
    #[error(
        "node {0:?} is not connected: start it (showcase-node --config CLUSTER.toml --name {0}) and check that it can reach the master"
    )]
    NotConnected(String),
    /// The node drives something else.
    #[error(
        "node {node:?} is a {role} node; this request needs a {want} node (check the [[node]] role in the cluster config)"
    )]
    WrongRole {
        /// The node.
        node: String,
        /// Its role.
        role: crate::message::Role,
        /// The role the request needs.
        want: crate::message::Role,
    },
    /// The message is no capture request.
    #[error("{0} is not a capture request")]
    NotARequest(&'static str),
    /// The request breaks a rule.
    #[error("invalid capture request: {0}")]
    Invalid(String),
}

/// Why a frame was refused by [`MasterCore::submit_frame`](super::MasterCore::submit_frame).
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
    /// The frame names a global-illumination version other than the
    /// current one.
    #[error("frame {frame} names illumination version {version:?}, the current one is {current:?}")]
    WrongIllumination {
        /// The refused frame.
        frame: u64,
        /// The version it names.
        version: Option<u64>,
        /// The current version.
        current: Option<u64>,
    },
    /// The frame breaks an invariant against the scene.
    #[error("frame is invalid: {0}")]
    Invalid(#[from] ValidationError),
}
