//! The patterns a projector shows: a white and a black reference, then
//! reflected binary Gray codes of its columns and of its rows, each bit
//! followed by its inverse so that every camera pixel gets its own
//! threshold (the bit is 1 where the pattern is brighter than its
//! inverse).
//!
//! Column `x` of a projector `width` pixels wide is coded by the Gray code
//! of `x` in [`bits_for`]`(width)` bits, most significant bit first; the
//! codes at or past `width` are never shown and decode as invalid.

use glam::Vec3;
use showcase_light::{Image, RgbImage};
use showcase_proto::capture::Pattern as SeamPattern;

/// Which projector coordinate a pattern codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// Columns: vertical stripes.
    Column,
    /// Rows: horizontal stripes.
    Row,
}

/// One image of the sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pattern {
    /// Every pixel at the level: the reference of full light.
    White,
    /// Every pixel at 0: the reference of no light (the black level and
    /// whatever else lights the scene).
    Black,
    /// Bit `bit` (0 = least significant) of the Gray code of `axis`, lit
    /// where the bit is 1, or where it is 0 when `inverted`.
    Bit {
        /// Columns or rows.
        axis: Axis,
        /// The bit, 0 = least significant.
        bit: u32,
        /// The inverse pattern.
        inverted: bool,
    },
}

/// Bits that code `n` values: `ceil(log2(n))`, at least 1.
pub fn bits_for(n: u32) -> u32 {
    (u32::BITS - n.max(2).saturating_sub(1).leading_zeros()).max(1)
}

/// The reflected binary Gray code of `v`.
pub fn gray(v: u32) -> u32 {
    v ^ (v >> 1)
}

/// The value whose Gray code is `g`.
pub fn gray_inverse(g: u32) -> u32 {
    let mut v = g;
    let mut shift = g >> 1;
    while shift != 0 {
        v ^= shift;
        shift >>= 1;
    }
    v
}

/// The pattern sequence of a `width` x `height` projector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PatternSet {
    /// Projector width in pixels.
    pub width: u32,
    /// Projector height in pixels.
    pub height: u32,
}

impl PatternSet {
    /// The sequence of a `width` x `height` projector.
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height }
    }

    /// Bits of `axis`.
    pub fn bits(&self, axis: Axis) -> u32 {
        bits_for(match axis {
            Axis::Column => self.width,
            Axis::Row => self.height,
        })
    }

    /// White, black, then per axis (columns first) each bit from the most
    /// significant down, the pattern then its inverse.
    pub fn patterns(&self) -> Vec<Pattern> {
        let mut out = vec![Pattern::White, Pattern::Black];
        for axis in [Axis::Column, Axis::Row] {
            for bit in (0..self.bits(axis)).rev() {
                for inverted in [false, true] {
                    out.push(Pattern::Bit {
                        axis,
                        bit,
                        inverted,
                    });
                }
            }
        }
        out
    }

    /// Whether projector pixel `(x, y)` is lit in `pattern`.
    pub fn lit(&self, pattern: Pattern, x: u32, y: u32) -> bool {
        match pattern {
            Pattern::White => true,
            Pattern::Black => false,
            Pattern::Bit {
                axis,
                bit,
                inverted,
            } => {
                let v = match axis {
                    Axis::Column => x,
                    Axis::Row => y,
                };
                ((gray(v) >> bit) & 1 == 1) != inverted
            }
        }
    }

    /// `pattern` as the hardware seam's pattern
    /// ([`ProjectorDevice::show_pattern`]), lit pixels at `level` in every
    /// channel: a projector behind the cluster sends it as it is, not as an
    /// image.
    ///
    /// [`ProjectorDevice::show_pattern`]: showcase_light::hardware::ProjectorDevice::show_pattern
    pub fn seam_pattern(&self, pattern: Pattern, level: f32) -> SeamPattern {
        match pattern {
            Pattern::White => SeamPattern::Full { level: [level; 3] },
            Pattern::Black => SeamPattern::Full { level: [0.0; 3] },
            Pattern::Bit {
                axis,
                bit,
                inverted,
            } => SeamPattern::GrayCode {
                columns: axis == Axis::Column,
                bit,
                inverted,
                level: [level; 3],
            },
        }
    }

    /// The image of `pattern`: lit pixels at `level` in every channel, the
    /// others 0.
    pub fn image(&self, pattern: Pattern, level: f32) -> RgbImage {
        Image::from_fn(self.width, self.height, |x, y| {
            if self.lit(pattern, x, y) {
                Vec3::splat(level)
            } else {
                Vec3::ZERO
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gray_codes_round_trip_and_differ_by_one_bit() {
        for v in 0..5000u32 {
            assert_eq!(gray_inverse(gray(v)), v);
            assert_eq!((gray(v) ^ gray(v + 1)).count_ones(), 1);
        }
    }

    #[test]
    fn the_seam_shows_the_same_images() {
        let set = PatternSet::new(37, 23);
        for p in set.patterns() {
            let seam = showcase_light::hardware::pattern_image(&set.seam_pattern(p, 0.8), 37, 23);
            assert_eq!(seam, set.image(p, 0.8), "{p:?}");
        }
    }

    #[test]
    fn bits_cover_the_size() {
        for (n, bits) in [
            (1, 1),
            (2, 1),
            (3, 2),
            (600, 10),
            (800, 10),
            (1024, 10),
            (1025, 11),
        ] {
            assert_eq!(bits_for(n), bits, "{n}");
        }
    }

    #[test]
    fn every_column_and_row_reads_back_from_its_patterns() {
        let set = PatternSet::new(800, 600);
        let patterns = set.patterns();
        assert_eq!(patterns.len(), 2 + 2 * (10 + 10));
        for (axis, n) in [(Axis::Column, 800), (Axis::Row, 600)] {
            for v in 0..n {
                let (x, y) = match axis {
                    Axis::Column => (v, 0),
                    Axis::Row => (0, v),
                };
                let mut code = 0;
                for p in &patterns {
                    if let Pattern::Bit {
                        axis: a,
                        bit,
                        inverted: false,
                    } = *p
                    {
                        let inverse = Pattern::Bit {
                            axis: a,
                            bit,
                            inverted: true,
                        };
                        assert_ne!(set.lit(*p, x, y), set.lit(inverse, x, y));
                        if a == axis && set.lit(*p, x, y) {
                            code |= 1 << bit;
                        }
                    }
                }
                assert_eq!(gray_inverse(code), v, "{axis:?} {v}");
            }
        }
    }
}
