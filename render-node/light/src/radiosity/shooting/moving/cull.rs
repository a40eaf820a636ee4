//! Which static form-factor entries an object move may change: the
//! object's old and new place (boxes and triangles), a per-shooter
//! penumbra test that rejects most receivers with a few dot products, and
//! the exact-with-margin crossing test of single visibility rays.

use crate::radiosity::mesh::RadiosityMesh;
use crossing::{PreparedTriangle, crossing_from};
use glam::DVec3;

mod crossing;
mod penumbra;

pub(super) use crossing::Crossing;
pub(super) use penumbra::{ball_outside_penumbra, outside_penumbra, penumbra_planes};

/// A box with its own orthonormal axes (`lo`, `hi` along them): an
/// object's places are boxed in the frame that fits them best, so a
/// rotated block is not boxed by its far larger axis-aligned box.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bounds {
    /// Orthonormal axes.
    pub(super) axes: [DVec3; 3],
    /// Smallest coordinates along the axes.
    pub(super) lo: DVec3,
    /// Largest coordinates along the axes.
    pub(super) hi: DVec3,
}

/// The world axes.
const WORLD: [DVec3; 3] = [DVec3::X, DVec3::Y, DVec3::Z];

/// At most this many of an object's largest triangles propose a frame in
/// [`Bounds::of_places`].
const FRAME_CANDIDATES: usize = 32;

impl Bounds {
    /// The axis-aligned box from `lo` to `hi`.
    pub(super) fn aligned(lo: DVec3, hi: DVec3) -> Self {
        Self {
            axes: WORLD,
            lo,
            hi,
        }
    }

    /// `x` in the box's axes.
    fn local(&self, x: DVec3) -> DVec3 {
        DVec3::new(
            self.axes[0].dot(x),
            self.axes[1].dot(x),
            self.axes[2].dot(x),
        )
    }

    /// The boxes of `object`'s old and new place (its elements in
    /// `old` and `new`), in one frame: the world's or one of a large
    /// triangle's (its normal and one of its edges), whichever gives the
    /// smaller total volume. `None` when the object has no elements.
    pub(super) fn of_places(
        old: &RadiosityMesh,
        new: &RadiosityMesh,
        object: u32,
    ) -> Option<[Self; 2]> {
        let points = |m: &RadiosityMesh| -> Vec<DVec3> {
            m.elements
                .iter()
                .filter(|e| e.object == object)
                .flat_map(|e| e.vertices)
                .collect()
        };
        let (p_old, p_new) = (points(old), points(new));
        if p_old.is_empty() || p_new.is_empty() {
            return None;
        }
        let mut triangles: Vec<(f64, [DVec3; 3])> = old
            .primitives
            .iter()
            .filter(|p| p.object == object)
            .map(|p| {
                let [a, b, c] = p.vertices;
                ((b - a).cross(c - a).length(), p.vertices)
            })
            .collect();
        triangles.sort_by(|x, y| y.0.total_cmp(&x.0));
        let frames = triangles
            .iter()
            .take(FRAME_CANDIDATES)
            .flat_map(|(_, [a, b, c])| {
                let n = (*b - *a).cross(*c - *a).normalize_or_zero();
                [*b - *a, *c - *b, *a - *c].map(|edge| {
                    let u = (edge - n * n.dot(edge)).normalize_or_zero();
                    [n, u, n.cross(u)]
                })
            })
            .filter(|[n, u, w]| *n != DVec3::ZERO && *u != DVec3::ZERO && w.is_finite());
        std::iter::once(WORLD)
            .chain(frames)
            .map(|axes| {
                let frame = Self {
                    axes,
                    lo: DVec3::ZERO,
                    hi: DVec3::ZERO,
                };
                let fit = |points: &[DVec3]| {
                    let (lo, hi) = points.iter().map(|p| frame.local(*p)).fold(
                        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
                        |(lo, hi), x| (lo.min(x), hi.max(x)),
                    );
                    Self { axes, lo, hi }
                };
                [fit(&p_old), fit(&p_new)]
            })
            .min_by(|x, y| {
                let volume = |b: &[Self; 2]| {
                    (b[0].hi - b[0].lo).element_product() + (b[1].hi - b[1].lo).element_product()
                };
                volume(x).total_cmp(&volume(y))
            })
    }

    /// Grown by `by` on every side.
    pub(super) fn grown(&self, by: f64) -> Self {
        Self {
            lo: self.lo - DVec3::splat(by),
            hi: self.hi + DVec3::splat(by),
            ..*self
        }
    }

    /// The smallest box in this box's frame holding both (`other` is in
    /// the same frame).
    fn union(&self, other: &Self) -> Self {
        Self {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
            ..*self
        }
    }

    /// The volume (zero when empty).
    fn volume(&self) -> f64 {
        (self.hi - self.lo).max(DVec3::ZERO).element_product()
    }

    /// The part both boxes hold (`other` is in the same frame; empty
    /// when they do not overlap).
    fn intersection(&self, other: &Self) -> Self {
        Self {
            lo: self.lo.max(other.lo),
            hi: self.hi.min(other.hi),
            ..*self
        }
    }

    /// The eight corners, in world space.
    fn corners(&self) -> [DVec3; 8] {
        let (l, h) = (self.lo, self.hi);
        let [ax, ay, az] = self.axes;
        [0, 1, 2, 3, 4, 5, 6, 7].map(|k| {
            ax * if k & 1 == 0 { l.x } else { h.x }
                + ay * if k & 2 == 0 { l.y } else { h.y }
                + az * if k & 4 == 0 { l.z } else { h.z }
        })
    }

    /// The box's centre (world space) and half extents along its axes.
    fn centre_and_half(&self) -> (DVec3, DVec3) {
        let m = 0.5 * (self.lo + self.hi);
        let centre = self.axes[0] * m.x + self.axes[1] * m.y + self.axes[2] * m.z;
        (centre, 0.5 * (self.hi - self.lo))
    }

    /// True when the segment `a`-`b` meets the box (slab test).
    pub(super) fn meets_segment(&self, a: DVec3, b: DVec3) -> bool {
        let [a, b] = self.local_segment(a, b);
        self.meets_local_segment(a, b)
    }

    /// The segment `a`-`b` in the box's axes (as is for the world's).
    fn local_segment(&self, a: DVec3, b: DVec3) -> [DVec3; 2] {
        if self.axes == WORLD {
            [a, b]
        } else {
            [self.local(a), self.local(b)]
        }
    }

    /// [`Self::meets_segment`] for a segment already in the box's axes
    /// ([`Self::local_segment`]): the separating-axis test of a segment
    /// and a box (the box's three axes and the segment's direction
    /// crossed with each), which needs no division.
    fn meets_local_segment(&self, a: DVec3, b: DVec3) -> bool {
        let e = 0.5 * (self.hi - self.lo);
        let c = 0.5 * (a + b) - 0.5 * (self.lo + self.hi);
        let h = 0.5 * (b - a);
        let ha = h.abs();
        if c.abs().cmpgt(e + ha).any() {
            return false;
        }
        let cross = c.cross(h).abs();
        let reach = DVec3::new(
            e.y * ha.z + e.z * ha.y,
            e.x * ha.z + e.z * ha.x,
            e.x * ha.y + e.y * ha.x,
        );
        !cross.cmpgt(reach).any()
    }
}

/// The fraction of the union of the old and new box that lies in
/// neither, from which on [`Places::near_segment`] is worth its cost: a
/// receiver in the union's penumbra whose centre segment misses both
/// boxes must pass through that gap, so where the boxes fill nearly all
/// of the union (a move by a fraction of the object's size) the test
/// rejects next to nothing (none of the 7053 near pairs of the Cornell
/// box's short block moved by 3.6 cm, where the gap is 2 %).
const SEGMENT_TEST_GAP: f64 = 0.25;

/// True when at least [`SEGMENT_TEST_GAP`] of the union of `boxes` (one
/// frame) lies in neither box.
fn segment_test_pays(boxes: &[Bounds; 2]) -> bool {
    let filled = boxes[0].volume() + boxes[1].volume() - boxes[0].intersection(&boxes[1]).volume();
    filled < (1.0 - SEGMENT_TEST_GAP) * boxes[0].union(&boxes[1]).volume()
}

/// A segment's ends, in world space and in the frame of the places'
/// boxes (which share it), so that it is transformed once for both.
pub(super) struct PlacedSegment {
    ends: [DVec3; 2],
    local: [DVec3; 2],
}

/// The moved object's old and new place.
pub(super) struct Places {
    /// Bounding boxes (old, new), with a margin.
    pub(super) boxes: [Bounds; 2],
    /// Both boxes in one.
    pub(super) union: Bounds,
    /// The margin the boxes were grown by, far above the ray offsets.
    pub(super) margin: f64,
    /// Whether [`Self::near_segment`] is worth testing: the union holds
    /// a gap of at least [`SEGMENT_TEST_GAP`] outside both boxes.
    pub(super) segment_test: bool,
    /// Triangles (old, new).
    pub(super) triangles: [Vec<PreparedTriangle>; 2],
    /// The object's elements.
    pub(super) object_elements: Vec<u32>,
    /// The other active elements, packed for the per-row scan: centre,
    /// largest distance from it to a corner, element, patch.
    pub(super) receivers: Vec<(DVec3, f64, u32, u32)>,
}

impl Places {
    /// The places of `object`'s old and new `boxes` (grown here by
    /// `margin`) and `triangles`, with the elements of `mesh` (the
    /// receivers: those `active`).
    pub(super) fn new(
        boxes: [Bounds; 2],
        margin: f64,
        triangles: [Vec<[DVec3; 3]>; 2],
        mesh: &RadiosityMesh,
        object: u32,
        active: &[bool],
    ) -> Self {
        let boxes = boxes.map(|b| b.grown(margin));
        let (mut object_elements, mut receivers) = (Vec::new(), Vec::new());
        for (j, e) in mesh.elements.iter().enumerate() {
            if e.object == object {
                object_elements.push(j as u32);
            } else if active[j] {
                let r = radius(e.center, &e.vertices);
                receivers.push((e.center, r, j as u32, e.patch));
            }
        }
        Self {
            union: boxes[0].union(&boxes[1]),
            segment_test: segment_test_pays(&boxes),
            boxes,
            margin,
            triangles: triangles.map(|t| t.into_iter().map(PreparedTriangle::new).collect()),
            object_elements,
            receivers,
        }
    }

    /// True when the segment `a`-`b` comes within `by` of the old or the
    /// new box.
    pub(super) fn near_segment(&self, a: DVec3, b: DVec3, by: f64) -> bool {
        let [la, lb] = self.union.local_segment(a, b);
        self.boxes
            .iter()
            .any(|b| b.grown(by).meets_local_segment(la, lb))
    }

    /// The segment `a`-`b`, ready for [`Self::crossing`] with either
    /// place.
    pub(super) fn segment(&self, a: DVec3, b: DVec3) -> PlacedSegment {
        PlacedSegment {
            ends: [a, b],
            local: self.union.local_segment(a, b),
        }
    }

    /// How segment `s` meets place `k` (0 the old, 1 the new); `hint` is
    /// the triangle to try first (see [`crossing_from`]).
    pub(super) fn crossing(&self, k: usize, s: &PlacedSegment, hint: &mut usize) -> Crossing {
        let ([a, b], [la, lb]) = (s.ends, s.local);
        if self.boxes[k].meets_local_segment(la, lb) {
            crossing_from(&self.triangles[k], a, b, hint)
        } else {
            Crossing::Miss
        }
    }

    /// How the segment `a`-`b` meets the old and the new place. `hints`
    /// are the triangles to try first in each place (see
    /// [`crossing_from`]).
    pub(super) fn classify(&self, a: DVec3, b: DVec3, hints: &mut [usize; 2]) -> [Crossing; 2] {
        // The union and both boxes share their axes.
        let s = self.segment(a, b);
        let [la, lb] = s.local;
        if !self.union.meets_local_segment(la, lb) {
            return [Crossing::Miss; 2];
        }
        [0, 1].map(|k| self.crossing(k, &s, &mut hints[k]))
    }
}

/// True when a segment that meets the old and new place as `places`
/// says (see [`Places::classify`]) certainly sees the same before and
/// after: it passes through both, or through neither.
pub(super) fn unchanged(places: [Crossing; 2]) -> bool {
    matches!(
        places,
        [Crossing::Hit, Crossing::Hit] | [Crossing::Miss, Crossing::Miss]
    )
}

/// Largest distance from `center` to a corner.
pub(super) fn radius(center: DVec3, vertices: &[DVec3; 3]) -> f64 {
    vertices
        .iter()
        .map(|v| (*v - center).length())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The centre-segment test is taken where the two places leave a
    /// gap in their union box: not for a move by a fraction of the
    /// object's size, nor for one along an axis (the boxes fill their
    /// union up to a move by the size), but for a diagonal move that
    /// leaves two empty corners (28 % of the union) and for boxes apart.
    #[test]
    fn segment_test_is_taken_only_where_the_union_holds_a_gap() {
        let unit = Bounds::aligned(DVec3::ZERO, DVec3::ONE);
        let moved = |by: DVec3| Bounds::aligned(by, DVec3::ONE + by);
        assert!(!segment_test_pays(&[unit, unit]));
        assert!(!segment_test_pays(&[
            unit,
            moved(DVec3::new(0.2, 0.0, 0.1))
        ]));
        assert!(!segment_test_pays(&[unit, moved(DVec3::X)]));
        assert!(segment_test_pays(&[unit, moved(DVec3::new(1.0, 1.0, 0.0))]));
        assert!(segment_test_pays(&[unit, moved(DVec3::new(0.6, 0.6, 0.0))]));
        // Boxes far apart: nearly all of the union is gap.
        assert!(segment_test_pays(&[unit, moved(DVec3::splat(5.0))]));
    }

    /// The separating-axis segment-box test agrees with clipping the
    /// segment to the box's slabs, on random segments near random boxes
    /// (the few cases within round-off of touching aside).
    #[test]
    fn segment_box_test_agrees_with_slab_clipping() {
        let clipped = |b: &Bounds, a: DVec3, c: DVec3| -> Option<(f64, f64)> {
            let d = c - a;
            let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
            for k in 0..3 {
                if d[k] == 0.0 {
                    if a[k] < b.lo[k] || a[k] > b.hi[k] {
                        return None;
                    }
                    continue;
                }
                let (ta, tb) = ((b.lo[k] - a[k]) / d[k], (b.hi[k] - a[k]) / d[k]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            Some((t0, t1))
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut v = |s: f64| {
            DVec3::new(
                rng.random_range(-s..s),
                rng.random_range(-s..s),
                rng.random_range(-s..s),
            )
        };
        let (mut meets, mut misses) = (0, 0);
        for _ in 0..20000 {
            let lo = v(1.0);
            let b = Bounds::aligned(lo, lo + v(0.5).abs() + DVec3::splat(0.01));
            let centre = 0.5 * (b.lo + b.hi);
            let (a, c) = (centre + v(0.8), centre + v(0.8));
            let Some((t0, t1)) = clipped(&b, a, c) else {
                assert!(!b.meets_local_segment(a, c), "{a} {c} {b:?}");
                misses += 1;
                continue;
            };
            if (t1 - t0).abs() < 1e-9 {
                continue;
            }
            assert_eq!(b.meets_local_segment(a, c), t0 < t1, "{a} {c} {b:?}");
            if t0 < t1 {
                meets += 1;
            } else {
                misses += 1;
            }
        }
        assert!(meets > 1000 && misses > 1000, "{meets} meet, {misses} miss");
    }

    #[test]
    fn segment_box_test_matches_hand_cases() {
        let b = Bounds::aligned(DVec3::ZERO, DVec3::ONE);
        let x = DVec3::X;
        assert!(b.meets_segment(DVec3::new(-1.0, 0.5, 0.5), DVec3::new(2.0, 0.5, 0.5)));
        assert!(!b.meets_segment(DVec3::new(-1.0, 1.5, 0.5), DVec3::new(2.0, 1.5, 0.5)));
        // Stops short of the box.
        assert!(!b.meets_segment(DVec3::new(-2.0, 0.5, 0.5), DVec3::new(-0.1, 0.5, 0.5)));
        // Axis-parallel, inside the slab on the other axes.
        assert!(b.meets_segment(0.5 * DVec3::ONE, 0.5 * DVec3::ONE + x));
        // Diagonal past a corner.
        assert!(!b.meets_segment(DVec3::new(1.5, -0.5, 0.5), DVec3::new(2.5, 0.5, 0.5)));
    }
}
