//! Photometric calibration (`calibrate --photometric`): the paper's open
//! problem of section 6, the colour seam between a real object and its CRT
//! overlay, measured and matched automatically.
//!
//! - [`response`]: a camera's response, the inverse of how its pixel codes
//!   map to light, per channel from frames of one static scene at several
//!   exposure times (Debevec & Malik 1997), so that codes turn back into
//!   linear, radiance-proportional values.
//! - [`rig`]: the seam to the devices: a camera in an observer's place
//!   looking through a face's beam splitter, with the face's CRT and the
//!   projectors showing what the calibration asks for; the simulated
//!   showcase behind it.
//! - [`face`]: a face's CRT and splitter measured in the units of the real
//!   surfaces behind the glass, as the profile its node encodes with.
//! - [`projector`]: a projector's light per device value and channel,
//!   with the camera the face's calibration recovered, as the profile its
//!   node encodes with.

pub mod face;
pub mod projector;
pub mod response;
pub mod rig;

pub use face::{FaceCalibration, PhotometricOptions, ProfileFile, calibrate_face};
pub use projector::{ProjectorCalibration, ProjectorProfileFile, calibrate_projector};
pub use response::{
    ExposureBracket, RecoveredResponse, ResponseError, ResponseOptions, recover_response,
};
pub use rig::{CrtPattern, Lamp, MirrorCamera, SimMirrorCamera, Spot};
