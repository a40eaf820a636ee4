//! Non-finite values (NaN, infinities) replaced by a fallback, zero unless
//! said otherwise: the crate's one definition of how bad numbers end as
//! black, dark or "no contribution" instead of spreading.

use glam::{DVec3, Vec3};

/// A number or vector that can be tested for finiteness as a whole.
pub trait Finite: Copy {
    /// Zero of the type (every component `+0.0`).
    const ZERO: Self;
    /// True when every component is finite.
    fn all_finite(self) -> bool;
}

impl Finite for f32 {
    const ZERO: Self = 0.0;
    fn all_finite(self) -> bool {
        self.is_finite()
    }
}

impl Finite for f64 {
    const ZERO: Self = 0.0;
    fn all_finite(self) -> bool {
        self.is_finite()
    }
}

impl Finite for Vec3 {
    const ZERO: Self = Vec3::ZERO;
    fn all_finite(self) -> bool {
        self.is_finite()
    }
}

impl Finite for DVec3 {
    const ZERO: Self = DVec3::ZERO;
    fn all_finite(self) -> bool {
        self.is_finite()
    }
}

/// `v` if it is finite (every component), else `fallback`.
pub fn finite_or<T: Finite>(v: T, fallback: T) -> T {
    if v.all_finite() { v } else { fallback }
}

/// `v` if it is finite (every component), else zero: a vector with one
/// bad component becomes zero as a whole.
pub fn finite_or_zero<T: Finite>(v: T) -> T {
    finite_or(v, T::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_become_the_fallback_and_good_ones_stay() {
        assert_eq!(finite_or_zero(-2.5f64), -2.5);
        assert_eq!(finite_or_zero(f64::NAN), 0.0);
        assert_eq!(finite_or_zero(f32::NEG_INFINITY), 0.0);
        assert_eq!(finite_or_zero(-0.0f64).to_bits(), (-0.0f64).to_bits());
        assert_eq!(finite_or_zero(f64::NAN).to_bits(), 0);
        assert_eq!(
            finite_or_zero(DVec3::new(1.0, f64::INFINITY, 2.0)),
            DVec3::ZERO
        );
        assert_eq!(
            finite_or_zero(Vec3::new(1.0, -2.0, 3.0)),
            Vec3::new(1.0, -2.0, 3.0)
        );
        assert_eq!(finite_or(DVec3::NAN, DVec3::ONE), DVec3::ONE);
        assert_eq!(finite_or(f32::INFINITY, 7.0), 7.0);
    }
}
