//! Head, light and object tracking on the master: recordings, the
//! scripted walk, and bodies mapped onto the scene. The DTrack parser and
//! the pose filter are pure and live in `showcase_proto::tracking`; they
//! are re-exported here so that `crate::tracking::dtrack` still names them.

pub use showcase_proto::tracking::{dtrack, filter};
pub mod recording;
pub mod scripted;
pub mod tracker;

pub use dtrack::{Body6d, DtrackError, DtrackFrame, parse_datagram};
pub use filter::{FilterConfig, Offered, PoseFilter, Rejection};
pub use tracker::{Target, Tracker, TrackerError, initial_frame, resolve_target};
