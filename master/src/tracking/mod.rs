//! Head, light and object tracking: the A.R.T. DTrack ASCII protocol, and
//! the filter that turns raw body poses into trustworthy ones (rejecting
//! non-finite values and impossible jumps, holding untracked bodies, and
//! optional constant-velocity prediction).

pub mod dtrack;
pub mod filter;
pub mod recording;
pub mod scripted;
pub mod tracker;

pub use dtrack::{Body6d, DtrackError, DtrackFrame, parse_datagram};
pub use filter::{FilterConfig, PoseFilter, Rejection};
pub use tracker::{Target, Tracker, TrackerError, initial_frame};
