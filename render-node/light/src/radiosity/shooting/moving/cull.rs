//! Which static form-factor entries an object move may change: the
//! object's old and new place (boxes and triangles), a per-shooter
//! penumbra test that rejects most receivers with a few dot products, and
//! the exact-with-margin crossing test of single visibility rays.

use crate::finite::finite_or_zero;
use crate::radiosity::mesh::RadiosityMesh;
use glam::DVec3;

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

/// The 12 edges of a box, as pairs of [`Bounds::corners`] indices.
const BOX_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Where a segment stands against an object's triangles, with a margin
/// far above round-off and the ray offsets of
/// [`SceneGeometry::visible`](crate::SceneGeometry::visible).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Crossing {
    /// It certainly passes through a triangle's interior.
    Hit,
    /// It certainly misses every triangle.
    Miss,
    /// Too close to an edge, an end or a plane to tell.
    Unsure,
}

/// Relative margin of [`crossing`] (in barycentric and segment units).
const CROSSING_MARGIN: f64 = 1e-6;

/// A triangle prepared for [`crossing`]: its plane, first corner, the
/// dual basis that gives a point's barycentric coordinates, and its box.
#[derive(Clone, Copy, Debug)]
pub(super) struct PreparedTriangle {
    /// Unit normal of the plane (zero when degenerate).
    normal: DVec3,
    v0: DVec3,
    /// `(p - v0) . u_axis` and `(p - v0) . v_axis` are the barycentric
    /// coordinates of a point `p` of the plane along the two edges.
    u_axis: DVec3,
    v_axis: DVec3,
    /// Length of the edges' cross product over the product of their
    /// lengths (the sine of the corner angle).
    sine: f64,
    lo: DVec3,
    hi: DVec3,
}

impl PreparedTriangle {
    /// `[v0, v1, v2]` prepared.
    pub(super) fn new([v0, v1, v2]: [DVec3; 3]) -> Self {
        let (e1, e2) = (v1 - v0, v2 - v0);
        let n = e1.cross(e2);
        let n2 = n.length_squared();
        let (u_axis, v_axis) = if n2 > 0.0 && n2.is_finite() {
            (e2.cross(n) / n2, n.cross(e1) / n2)
        } else {
            (DVec3::ZERO, DVec3::ZERO)
        };
        let sine = n.length() / (e1.length() * e2.length());
        Self {
            normal: n.normalize_or_zero(),
            v0,
            u_axis,
            v_axis,
            sine: finite_or_zero(sine),
            lo: v0.min(v1).min(v2),
            hi: v0.max(v1).max(v2),
        }
    }
}

/// How the segment `a`-`b` meets `triangles` (Moller-Trumbore with a
/// margin on both sides).
#[cfg(test)]
fn crossing(triangles: &[PreparedTriangle], a: DVec3, b: DVec3) -> Crossing {
    crossing_from(triangles, a, b, &mut 0)
}

/// [`crossing`], trying the triangles from index `first` on (wrapping
/// round) and leaving there the one hit: neighbouring rays tend to hit the
/// same triangle, and any triangle hit decides, so the order changes only
/// the time.
pub(super) fn crossing_from(
    triangles: &[PreparedTriangle],
    a: DVec3,
    b: DVec3,
    first: &mut usize,
) -> Crossing {
    let d = b - a;
    let d_length = d.length();
    let m = CROSSING_MARGIN;
    let mut all_miss = true;
    // A segment that stays this far on one side of a triangle's plane
    // certainly misses it (its ends are farther than the margin in
    // segment units, and far beyond the ray offsets).
    let off_plane = m * (1.0 + d_length);
    let start = if *first < triangles.len() { *first } else { 0 };
    let (tail, head) = triangles.split_at(start);
    for (k, t) in head.iter().chain(tail).enumerate() {
        let (da, db) = (t.normal.dot(a - t.v0), t.normal.dot(b - t.v0));
        if t.normal != DVec3::ZERO
            && ((da > off_plane && db > off_plane) || (da < -off_plane && db < -off_plane))
        {
            continue;
        }
        // Where the line crosses the plane, as a fraction of the segment.
        let across = da - db;
        if !(across.abs() > 1e-9 * t.sine * d_length) {
            // Parallel to the plane (or degenerate): only sure when the
            // segment is far from the triangle's box.
            let pad = m * (1.0 + (t.hi - t.lo).max_element());
            let bounds = Bounds::aligned(t.lo, t.hi).grown(pad);
            if bounds.meets_segment(a, b) {
                all_miss = false;
            }
            continue;
        }
        let tt = da / across;
        let q = a + tt * d - t.v0;
        let (u, v) = (q.dot(t.u_axis), q.dot(t.v_axis));
        if u > m && v > m && u + v < 1.0 - m && tt > m && tt < 1.0 - m {
            *first = (start + k) % triangles.len();
            return Crossing::Hit;
        }
        let miss = u < -m || v < -m || u + v > 1.0 + m || tt < -m || tt > 1.0 + m;
        if !miss {
            all_miss = false;
        }
    }
    if all_miss {
        Crossing::Miss
    } else {
        Crossing::Unsure
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

/// Relative round-off within which [`penumbra_planes`] takes touching
/// extents as separate.
const TOUCH: f64 = 1e-12;

/// Planes that bound the region a segment from the triangle `shooter`
/// through the box `b` can reach: `(n, c)` with unit `n` such that every
/// point `x` with a segment from a point of `shooter` to `x` that meets
/// `b` has `n . x >= c`. They are the planes through an edge of one and a
/// corner of the other (and the axis planes and the triangle's plane)
/// that have the triangle on their negative and the box on their
/// positive side: for `y` on the triangle, `b` in the box and
/// `x = y + s (b - y)` with `s >= 1`, `n . x >= n . b >= c`. Empty when
/// no plane separates them (the triangle touches or enters the box).
pub(super) fn penumbra_planes(shooter: &[DVec3; 3], b: &Bounds) -> Vec<(DVec3, f64)> {
    let corners = b.corners();
    let (center, half) = b.centre_and_half();
    let mut candidates = [DVec3::ZERO; 64];
    candidates[..4].copy_from_slice(&[
        b.axes[0],
        b.axes[1],
        b.axes[2],
        (shooter[1] - shooter[0]).cross(shooter[2] - shooter[0]),
    ]);
    let mut k = 4;
    for e in 0..3 {
        let (a, c) = (shooter[e], shooter[(e + 1) % 3]);
        for v in corners {
            candidates[k] = (c - a).cross(v - a);
            k += 1;
        }
    }
    for (i, j) in BOX_EDGES {
        let (a, c) = (corners[i], corners[j]);
        for y in shooter {
            candidates[k] = (c - a).cross(*y - a);
            k += 1;
        }
    }
    let mut planes: Vec<(DVec3, f64)> = Vec::new();
    let mut push = |n: DVec3, c: f64| {
        let duplicate = planes
            .iter()
            .any(|(m, d)| m.dot(n) > 1.0 - 1e-12 && (d - c).abs() < 1e-12);
        if !duplicate {
            planes.push((n, c));
        }
    };
    for n in candidates {
        // The shooter's and the box's extent along n (the box's from its
        // support function): a plane with normal n or -n separates them
        // when the extents do not overlap. Both scale with n, so only the
        // separating candidates are normalised. A plane through an edge of
        // one and a corner of the other touches both, so the extents meet
        // to round-off: they count as separate within `touch`, which
        // moves a far receiver's side of the plane by far less than the
        // tolerance of the tests (see `outside_penumbra`).
        let y = shooter.map(|y| n.dot(y));
        let (y_lo, y_hi) = (y[0].min(y[1]).min(y[2]), y[0].max(y[1]).max(y[2]));
        let reach = b.local(n).abs().dot(half);
        let mid = n.dot(center);
        let (b_lo, b_hi) = (mid - reach, mid + reach);
        let touch = TOUCH * (y_lo.abs().max(y_hi.abs()) + mid.abs() + reach);
        let (below, above) = (y_hi <= b_lo + touch, b_hi <= y_lo + touch);
        if !(below || above) {
            continue;
        }
        let length = n.length();
        if !(length > 0.0 && length.is_finite()) {
            continue;
        }
        if below {
            push(n / length, b_lo / length);
        }
        if above {
            push(-n / length, -b_hi / length);
        }
    }
    planes
}

/// True when no segment from the shooter of `planes` (see
/// [`penumbra_planes`]) to a point of the triangle `receiver` can meet the
/// box: the receiver lies below one of the planes by more than `tolerance`.
pub(super) fn outside_penumbra(
    planes: &[(DVec3, f64)],
    receiver: &[DVec3; 3],
    tolerance: f64,
) -> bool {
    planes
        .iter()
        .any(|(n, c)| receiver.iter().all(|x| n.dot(*x) < c - tolerance))
}

/// [`outside_penumbra`] for a receiver inside the ball `(center, radius)`:
/// one dot product per plane, a little less strict. The plane that
/// rejects moves to the front of `planes`, where the next receiver (the
/// scan's neighbour, often rejected by the same plane) tries it first.
pub(super) fn ball_outside_penumbra(
    planes: &mut [(DVec3, f64)],
    center: DVec3,
    radius: f64,
    tolerance: f64,
) -> bool {
    match planes
        .iter()
        .position(|(n, c)| n.dot(center) + radius < c - tolerance)
    {
        Some(k) => {
            planes.swap(0, k);
            true
        }
        None => false,
    }
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

    #[test]
    fn crossing_is_sure_only_away_from_edges_and_ends() {
        let tri = [PreparedTriangle::new([DVec3::ZERO, DVec3::X, DVec3::Y])];
        let down = |x: f64, y: f64| crossing(&tri, DVec3::new(x, y, 1.0), DVec3::new(x, y, -1.0));
        assert_eq!(down(0.2, 0.2), Crossing::Hit);
        assert_eq!(down(0.7, 0.7), Crossing::Miss);
        assert_eq!(down(-0.1, 0.2), Crossing::Miss);
        assert_eq!(down(0.5, 0.5), Crossing::Unsure);
        assert_eq!(down(0.0, 0.3), Crossing::Unsure);
        // Ending on the plane, short of it, and in the plane.
        let at = |z: f64| crossing(&tri, DVec3::new(0.2, 0.2, 1.0), DVec3::new(0.2, 0.2, z));
        assert_eq!(at(0.0), Crossing::Unsure);
        assert_eq!(at(0.5), Crossing::Miss);
        assert_eq!(
            crossing(&tri, DVec3::new(-1.0, 0.2, 0.0), DVec3::new(2.0, 0.2, 0.0)),
            Crossing::Unsure
        );
        assert_eq!(
            crossing(&tri, DVec3::new(-1.0, 0.2, 0.5), DVec3::new(2.0, 0.2, 0.5)),
            Crossing::Miss
        );
    }

    /// A sure answer agrees with a plain Moller-Trumbore test (no
    /// margins) on random segments and triangles, and most answers are
    /// sure.
    #[test]
    fn crossing_agrees_with_plain_moller_trumbore() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        let mut p = || DVec3::new(rng.random(), rng.random(), rng.random());
        let plain = |[v0, v1, v2]: [DVec3; 3], a: DVec3, b: DVec3| -> bool {
            let (e1, e2, d) = (v1 - v0, v2 - v0, b - a);
            let h = d.cross(e2);
            let det = e1.dot(h);
            let s = a - v0;
            let (u, q) = (s.dot(h) / det, s.cross(e1));
            let (v, t) = (d.dot(q) / det, e2.dot(q) / det);
            u > 0.0 && v > 0.0 && u + v < 1.0 && t > 0.0 && t < 1.0
        };
        let (mut hits, mut misses, mut unsure) = (0, 0, 0);
        for _ in 0..20_000 {
            let tri = [p(), p(), p()];
            // Half the segments through a point of the triangle's plane
            // near the triangle, half anywhere.
            let (a, b) = if hits + misses + unsure < 10_000 {
                let w = p();
                let (u, v) = (1.4 * w.x - 0.2, 1.4 * w.y - 0.2);
                let on = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
                let dir = p() - 0.5 * DVec3::ONE;
                (on + dir, on - w.z * dir)
            } else {
                (3.0 * p() - DVec3::ONE, 3.0 * p() - DVec3::ONE)
            };
            match crossing(&[PreparedTriangle::new(tri)], a, b) {
                Crossing::Hit => {
                    hits += 1;
                    assert!(plain(tri, a, b), "{tri:?} {a} {b}");
                }
                Crossing::Miss => {
                    misses += 1;
                    assert!(!plain(tri, a, b), "{tri:?} {a} {b}");
                }
                Crossing::Unsure => unsure += 1,
            }
        }
        assert!(
            hits > 1000 && misses > 10_000 && unsure < 50,
            "{hits} {misses} {unsure}"
        );
    }

    /// The answer does not depend on the triangle tried first.
    #[test]
    fn crossing_does_not_depend_on_the_first_triangle() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut p = || DVec3::new(rng.random(), rng.random(), rng.random());
        let tris: Vec<PreparedTriangle> = (0..6)
            .map(|_| PreparedTriangle::new([p(), p(), p()]))
            .collect();
        for _ in 0..500 {
            let (a, b) = (2.0 * p() - DVec3::ONE, 2.0 * p());
            let expected = crossing(&tris, a, b);
            for start in 0..tris.len() + 1 {
                let mut first = start;
                assert_eq!(crossing_from(&tris, a, b, &mut first), expected);
                assert!(first < tris.len() || expected != Crossing::Hit);
            }
        }
    }

    /// The penumbra test never rejects a receiver that a segment from the
    /// shooter through the box reaches (random segments through random
    /// boxes), and it does reject receivers beside the shooter and off to
    /// the side of the box.
    #[test]
    fn penumbra_planes_never_reject_a_receiver_a_segment_reaches() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let point = |rng: &mut rand_chacha::ChaCha8Rng, s: f64| {
            DVec3::new(
                rng.random_range(-s..s),
                rng.random_range(-s..s),
                rng.random_range(-s..s),
            )
        };
        let mut rejected = 0;
        for k in 0..2000 {
            let lo = point(&mut rng, 0.3);
            // Every other box turned to a random frame.
            let axes = if k % 2 == 0 {
                WORLD
            } else {
                let q = glam::DQuat::from_euler(
                    glam::EulerRot::XYZ,
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                );
                [q * DVec3::X, q * DVec3::Y, q * DVec3::Z]
            };
            let b = Bounds {
                axes,
                lo,
                hi: lo + point(&mut rng, 0.2).abs() + DVec3::splat(0.01),
            };
            let shooter = [0, 1, 2].map(|_| DVec3::new(0.0, 0.0, -1.5) + point(&mut rng, 0.4));
            let mut planes = penumbra_planes(&shooter, &b);
            // A segment from a shooter point through a box point reaches a
            // receiver around its far end: never rejected.
            let w = [
                rng.random::<f64>(),
                rng.random::<f64>(),
                rng.random::<f64>(),
            ];
            let sum: f64 = w.iter().sum();
            let y = (w[0] * shooter[0] + w[1] * shooter[1] + w[2] * shooter[2]) / sum;
            let inside =
                b.lo + (b.hi - b.lo) * DVec3::new(rng.random(), rng.random(), rng.random());
            let through = axes[0] * inside.x + axes[1] * inside.y + axes[2] * inside.z;
            let x = y + rng.random_range(1.0..4.0) * (through - y);
            let receiver = [x, x + point(&mut rng, 0.05), x + point(&mut rng, 0.05)];
            assert!(
                !outside_penumbra(&planes, &receiver, 1e-9),
                "{shooter:?} through {b:?} reaches {x}"
            );
            assert!(!ball_outside_penumbra(&mut planes, x, 0.0, 1e-9));
            // A receiver on the shooter's side, far to the side.
            let beside = [0, 1, 2].map(|k| shooter[k] + DVec3::new(3.0, 0.0, -0.5));
            if outside_penumbra(&planes, &beside, 1e-9) {
                rejected += 1;
            }
        }
        assert!(rejected > 1000, "only {rejected} of 2000 rejected");
    }
}
