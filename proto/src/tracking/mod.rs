//! Tracking input without IO: the A.R.T. DTrack ASCII parser and the pose
//! filter that decides which raw body poses can be trusted. Both are pure
//! (time is an argument), so the master, its replays and the fuzzer run
//! the very same code.

pub mod dtrack;
pub mod filter;
#[cfg(test)]
mod properties;
#[cfg(any(test, feature = "testing"))]
pub mod strategies;

pub use dtrack::{Body6d, DtrackError, DtrackFrame, parse_datagram};
pub use filter::{ACQUIRE_SAMPLES, FilterConfig, Offered, PoseFilter, Rejection};
