//! Sans-IO session and frame-lock state machines (master side and node side), driven by `now` inputs.
//!
//! Shaped like quinn-proto: no sockets, no clock, no tasks. A driver feeds
//! inputs through `handle_*(now, ...)` and drains outputs through `poll()`,
//! sleeping until `poll_timeout()` and then calling `handle_timeout(now)`.
//! `now` is nanoseconds on the caller's monotonic clock; the master's and a
//! node's clocks are unrelated (see [`clock`]).
//!
//! - [`MasterCore`]: the per-node sessions (handshake, snapshot, frame
//!   stream), the two-phase [swap barrier](barrier) with deadline and
//!   eviction, clock probes, and per-frame reports for metrics.
//! - [`NodeCore`]: one node's side, with reconnect backoff.
//! - [`testing`]: an in-memory cluster on virtual time that drives both
//!   through the wire codec.
//!
//! A master driver is a loop like this (a node driver is the same with
//! [`NodeCore`] and [`NodeOutput`], plus dialing on [`NodeOutput::Dial`]):
//!
//! ```text
//! loop {
//!     while let Some(out) = core.poll() {
//!         match out {
//!             MasterOutput::Transmit { conn, message } => send(conn, encode_frame(&message)),
//!             MasterOutput::Close { conn, reason } => flush_and_close(conn, reason),
//!             MasterOutput::Event(e) => metrics(e),
//!         }
//!     }
//!     select! {
//!         accepted(conn) => core.handle_connect(now(), conn),
//!         received(conn, Ok(msg)) => core.handle_message(now(), conn, msg),
//!         received(conn, Err(e)) => core.handle_decode_error(now(), conn, &e),
//!         lost(conn) => core.handle_disconnect(now(), conn),
//!         frame_tick => if core.can_submit() { core.submit_frame(now(), next_state())? },
//!         sleep_until(core.poll_timeout()) => core.handle_timeout(now()),
//!     }
//! }
//! ```

pub mod barrier;
pub mod clock;
mod master;
mod node;
pub mod testing;

#[cfg(test)]
mod tests;

pub use barrier::MAX_FRAMES_IN_FLIGHT;
pub use clock::{ClockError, ClockEstimator, ClockSample, clock_sample};
pub use master::{
    CaptureSendError, CloseReason, MasterConfig, MasterCore, MasterError, MasterEvent,
    MasterOutput, NodeInfo, NodePresent, PresentReport, ReadyNode, SubmitError, SwapReport,
};
pub use node::{Backoff, NodeConfig, NodeCore, NodeError, NodeEvent, NodeOutput, Solution};

/// A connection handle chosen by the driver, unique among the master's
/// connections for the master's lifetime (never reuse one).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ConnId(pub u64);

impl std::fmt::Display for ConnId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "conn#{}", self.0)
    }
}

/// Nanoseconds per millisecond.
pub(crate) const NS_PER_MS: u64 = 1_000_000;

/// Nanoseconds as milliseconds, for reasons, reports and `Welcome`.
pub(crate) fn ms(ns: u64) -> f64 {
    ns as f64 / NS_PER_MS as f64
}
