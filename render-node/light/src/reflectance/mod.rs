//! Diffuse reflectance maps (paper sections 3.4 and 3.5), pure code with
//! no IO: extracting `I_ref = I_rad / I_int` with a floor and the phi_max
//! cut ([`extract`]), blend weights and re-rendering stored maps by
//! projective texturing with merging ([`map`]), Brent's minimiser and the
//! projector intensity fit ([`brent`], [`eta`]), and the interreflection
//! correction beyond the paper ([`correct`]).
//!
//! # Units
//! `I_rad` is the captured radiance times pi (the exitance a Lambertian
//! surface would have), and `I_int` the irradiance of equation 3.1, so
//! their ratio is the albedo.
#![forbid(unsafe_code)]
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod brent;
pub mod correct;
pub mod eta;
pub mod extract;
pub mod map;

pub use brent::{BrentError, bracket, brent_minimize, minimize};
pub use correct::{CorrectionParams, WholeCapture, indirect_irradiance};
pub use eta::{CalibrationLevel, ProjectorFit, estimate_projector};
pub use extract::{ExtractParams, blend_weights, extract_reflectance, intensity_floor};
pub use map::{ReflectanceMap, render_maps};

/// Why reflectance math refused its input.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ReflectanceError {
    /// Images of different sizes.
    #[error("image sizes differ: {what} is {got:?}, expected {expected:?}")]
    SizeMismatch {
        /// Which input.
        what: &'static str,
        /// Its `(width, height)`.
        got: (u32, u32),
        /// The expected `(width, height)`.
        expected: (u32, u32),
    },
    /// No pixel can take part in a fit.
    #[error("no valid pixels for {0}")]
    NoValidPixels(&'static str),
    /// A parameter that must be finite and positive is not.
    #[error("{what}: value {value} is not finite and positive")]
    BadParameter {
        /// The parameter.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// The minimiser failed.
    #[error("minimiser: {0}")]
    Brent(#[from] BrentError),
}

pub(crate) fn check_size<A, B>(
    what: &'static str,
    a: &crate::Image<A>,
    b: &crate::Image<B>,
) -> Result<(), ReflectanceError> {
    if a.same_size(b) {
        Ok(())
    } else {
        Err(ReflectanceError::SizeMismatch {
            what,
            got: (a.width, a.height),
            expected: (b.width, b.height),
        })
    }
}
