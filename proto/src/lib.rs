//! Showcase's shared language: the scene model, the cluster messages and
//! their codec, and the sans-IO session state machines.
//!
//! Invariants: nothing here does IO (callers read files and pass text), reads a clock, or depends on tokio,
//! quinn or wgpu. Time enters as an argument (`now`, in nanoseconds of the
//! caller's monotonic clock).
#![forbid(unsafe_code)]

pub mod capture;
pub mod codec;
pub mod config;
pub mod message;
pub mod scene;
pub mod session;
#[cfg(any(test, feature = "testing"))]
pub mod testing;
pub mod tracking;
pub mod validate;

pub use codec::{CodecError, FrameDecoder, MAX_FRAME_LEN, decode_frame, encode_frame};
pub use message::{
    Bye, Capabilities, ClockProbe, ClockReply, Hello, Message, NodeStats, Ready, Role,
    SceneSnapshot, Swap, Welcome,
};
pub use scene::*;
pub use validate::{Validate, ValidationError};

/// Version of the wire protocol. A node and a master must agree exactly.
pub const PROTOCOL_VERSION: u32 = 8;
