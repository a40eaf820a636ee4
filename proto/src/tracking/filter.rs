//! Pose filtering for tracked bodies: decide which raw poses can be
//! trusted, hold the last trusted pose of an untracked body, and optionally
//! predict ahead with constant velocity to cover pipeline latency. Time is
//! an input (seconds), so this is deterministic.
//!
//! A sample is refused outright when it is not finite, lies outside the
//! tracking volume, or is older than the newest sample seen. Otherwise:
//!
//! - While the held pose is fresh (accepted less than `reacquire_s` ago), a
//!   sample the body could have reached from it within `max_speed` and
//!   `max_angular_speed_deg` continues the track and becomes the held
//!   pose; any other is rejected as a jump or a turn.
//! - With no held pose, or an expired one, nothing vouches for a sample,
//!   so one sample is never enough: samples that each lie within the same
//!   limits of the one before form a candidate track, and
//!   `acquire_samples` of them in a row become the held pose.
//!
//! Rejected jumps feed the candidate too. So a single wild sample is never
//! accepted (it is refused against a fresh pose, or starts a candidate that
//! the next good sample breaks), and nothing locks good samples out for
//! longer than `reacquire_s` plus `acquire_samples` samples: the held pose
//! they contradict gets no new samples and expires. Every pose that leaves
//! the filter is finite and inside the volume (a prediction is clamped to
//! it), so it converts to f32 without overflow.

use crate::config::TrackingLimits;
use glam::{DQuat, DVec3};

/// Consistent samples in a row that (re-)acquire a body by default.
pub const ACQUIRE_SAMPLES: u32 = 3;

/// Limits and prediction settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterConfig {
    /// Fastest plausible linear speed (m/s); faster jumps are rejected.
    pub max_speed: f64,
    /// Fastest plausible angular speed (degrees/s).
    pub max_angular_speed_deg: f64,
    /// Predict this far ahead (s); 0 disables prediction.
    pub predict_s: f64,
    /// Lowest corner of the tracking volume (metres).
    pub volume_min: DVec3,
    /// Highest corner of the tracking volume (metres).
    pub volume_max: DVec3,
    /// A held pose with no accepted sample for this long (s) has expired:
    /// the body is re-acquired from a candidate track.
    pub reacquire_s: f64,
    /// Consistent samples in a row that make a candidate the held pose
    /// (0 counts as 1).
    pub acquire_samples: u32,
}

impl FilterConfig {
    /// The filter for these configured limits, predicting `predict_s` ahead.
    pub fn new(limits: &TrackingLimits, predict_s: f64) -> Self {
        Self {
            max_speed: limits.max_speed,
            max_angular_speed_deg: limits.max_angular_speed_deg,
            predict_s,
            volume_min: DVec3::from(limits.volume_min),
            volume_max: DVec3::from(limits.volume_max),
            reacquire_s: limits.reacquire_ms / 1000.0,
            acquire_samples: ACQUIRE_SAMPLES,
        }
    }

    /// True when `p` lies inside the tracking volume (never for NaN).
    pub fn in_volume(&self, p: DVec3) -> bool {
        p.cmpge(self.volume_min).all() && p.cmple(self.volume_max).all()
    }
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self::new(&TrackingLimits::default(), 0.0)
    }
}

/// A point for a message: millimetre precision, exponents for wild values.
fn coords(p: &DVec3) -> String {
    let c = |v: f64| {
        if v.abs() < 1e6 {
            format!("{v:.3}")
        } else {
            format!("{v:.3e}")
        }
    };
    format!("({}, {}, {})", c(p.x), c(p.y), c(p.z))
}

/// Why a sample was not accepted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Rejection {
    /// A coordinate was NaN or infinite, or the rotation was degenerate.
    #[error("pose is not finite or its rotation is degenerate")]
    NonFinite,
    /// The position is outside the tracking volume.
    #[error(
        "position {} m is outside the tracking volume {} to {} m; a reflection or a mis-assigned body, or tracking.limits.volume_min/volume_max are too tight",
        coords(.position),
        coords(.min),
        coords(.max)
    )]
    OutsideVolume {
        /// The position (world metres).
        position: DVec3,
        /// The volume's lowest corner.
        min: DVec3,
        /// The volume's highest corner.
        max: DVec3,
    },
    /// The body would have moved faster than `max_speed`.
    #[error("jump of {distance:.3} m in {dt:.4} s exceeds {max} m/s")]
    Jump {
        /// Distance moved.
        distance: f64,
        /// Time elapsed.
        dt: f64,
        /// The limit.
        max: f64,
    },
    /// The body would have turned faster than `max_angular_speed_deg`.
    #[error("turn of {degrees:.1} degrees in {dt:.4} s exceeds {max} deg/s")]
    Turn {
        /// Angle turned.
        degrees: f64,
        /// Time elapsed.
        dt: f64,
        /// The limit.
        max: f64,
    },
    /// The sample is older than the newest one seen.
    #[error("sample at {t} s is older than the newest one offered")]
    Stale {
        /// The sample's time.
        t: f64,
    },
}

/// What became of a sample that was not rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Offered {
    /// It continues the held track and is the held pose now.
    Accepted,
    /// It completes a candidate track, which is the held pose now.
    Acquired,
    /// It is sample `count` of a candidate track that needs `needed`; the
    /// held pose (if any) stays.
    Candidate {
        /// Consistent samples in a row so far.
        count: u32,
        /// Samples that acquire the body.
        needed: u32,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Sample {
    t: f64,
    position: DVec3,
    rotation: DQuat,
}

/// A run of mutually consistent samples not (yet) vouched for.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    last: Sample,
    velocity: DVec3,
    count: u32,
}

/// Filter state of one body.
#[derive(Clone, Debug, Default)]
pub struct PoseFilter {
    config: FilterConfig,
    last: Option<Sample>,
    velocity: DVec3,
    candidate: Option<Candidate>,
    rejected: u64,
}

impl PoseFilter {
    /// A filter with these limits.
    pub fn new(config: FilterConfig) -> Self {
        Self {
            config,
            ..Self::default()
        }
    }

    /// Offer a tracked sample at time `t`. It becomes the held pose when it
    /// continues a fresh track or completes a candidate one; see the module
    /// documentation. Rejected samples leave the held pose unchanged.
    pub fn offer(
        &mut self,
        t: f64,
        position: DVec3,
        rotation: DQuat,
    ) -> Result<Offered, Rejection> {
        let r = self.classify(t, position, rotation);
        if r.is_err() {
            self.rejected += 1;
        }
        r
    }

    fn classify(&mut self, t: f64, position: DVec3, rotation: DQuat) -> Result<Offered, Rejection> {
        // A rotation so long that its length overflows would normalise to
        // zero: degenerate, like one too short to normalise.
        let length = rotation.length();
        if !(t.is_finite() && position.is_finite() && length.is_finite() && length >= 1e-6) {
            return Err(Rejection::NonFinite);
        }
        if !self.config.in_volume(position) {
            return Err(Rejection::OutsideVolume {
                position,
                min: self.config.volume_min,
                max: self.config.volume_max,
            });
        }
        let newest = [self.last, self.candidate.map(|c| c.last)]
            .into_iter()
            .flatten()
            .map(|s| s.t)
            .fold(f64::NEG_INFINITY, f64::max);
        if t < newest {
            return Err(Rejection::Stale { t });
        }
        let sample = Sample {
            t,
            position,
            rotation: rotation.normalize(),
        };
        let fresh = self.last.filter(|l| t - l.t < self.config.reacquire_s);
        if let Some(last) = fresh {
            match self.reachable(&last, &sample) {
                Ok(()) => {
                    self.velocity = self.velocity_between(&last, &sample, self.velocity);
                    self.last = Some(sample);
                    self.candidate = None;
                    return Ok(Offered::Accepted);
                }
                Err(e) => {
                    // Evidence against a held pose that may be the wrong one.
                    self.extend_candidate(sample);
                    return Err(e);
                }
            }
        }
        let c = self.extend_candidate(sample);
        let needed = self.config.acquire_samples.max(1);
        if c.count < needed {
            return Ok(Offered::Candidate {
                count: c.count,
                needed,
            });
        }
        self.last = Some(c.last);
        self.velocity = c.velocity;
        self.candidate = None;
        Ok(Offered::Acquired)
    }

    /// Add `s` to the candidate track, or start a new one with it when it
    /// does not follow the candidate's last sample.
    fn extend_candidate(&mut self, s: Sample) -> Candidate {
        let c = match self.candidate {
            Some(c) if self.reachable(&c.last, &s).is_ok() => Candidate {
                last: s,
                velocity: self.velocity_between(&c.last, &s, c.velocity),
                count: c.count.saturating_add(1),
            },
            _ => Candidate {
                last: s,
                velocity: DVec3::ZERO,
                count: 1,
            },
        };
        self.candidate = Some(c);
        c
    }

    /// Whether the body could move from `a` to `b` within the limits.
    fn reachable(&self, a: &Sample, b: &Sample) -> Result<(), Rejection> {
        let dt = b.t - a.t;
        // Allow at least 1 ms worth of motion so equal timestamps still pass
        // tiny corrections.
        let dt_eff = dt.max(1e-3);
        let distance = b.position.distance(a.position);
        // Written so that a NaN limit rejects rather than passes.
        let within_speed = distance <= self.config.max_speed * dt_eff;
        if !within_speed {
            return Err(Rejection::Jump {
                distance,
                dt,
                max: self.config.max_speed,
            });
        }
        let degrees = a.rotation.angle_between(b.rotation).to_degrees();
        let within_turn = degrees <= self.config.max_angular_speed_deg * dt_eff;
        if !within_turn {
            return Err(Rejection::Turn {
                degrees,
                dt,
                max: self.config.max_angular_speed_deg,
            });
        }
        Ok(())
    }

    /// The velocity from `a` to `b`, at most `max_speed`; `keep` when they
    /// are too close in time to tell.
    fn velocity_between(&self, a: &Sample, b: &Sample, keep: DVec3) -> DVec3 {
        let dt = b.t - a.t;
        if dt > 1e-6 {
            ((b.position - a.position) / dt.max(1e-3)).clamp_length_max(self.config.max_speed)
        } else {
            keep
        }
    }

    /// The pose to use at time `now`: the held pose, advanced by constant
    /// velocity for at most `predict_s` when prediction is on, and kept
    /// inside the tracking volume. `None` until a body has been acquired.
    /// An untracked body simply gets no new samples, so it holds its pose.
    pub fn pose(&self, now: f64) -> Option<(DVec3, DQuat)> {
        let last = self.last?;
        // max/min, not clamp: they neither panic nor pass on a NaN.
        let ahead = (now - last.t).max(0.0).min(self.config.predict_s.max(0.0));
        let p = (last.position + self.velocity * ahead)
            .max(self.config.volume_min)
            .min(self.config.volume_max);
        Some((p, last.rotation))
    }

    /// Samples rejected so far.
    pub fn rejected(&self) -> u64 {
        self.rejected
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Acquire a body standing at `p` at time `t`.
    #[track_caller]
    fn acquire(f: &mut PoseFilter, t: f64, p: DVec3) {
        for _ in 1..ACQUIRE_SAMPLES {
            assert!(matches!(
                f.offer(t, p, DQuat::IDENTITY),
                Ok(Offered::Candidate { .. })
            ));
        }
        assert_eq!(f.offer(t, p, DQuat::IDENTITY), Ok(Offered::Acquired));
    }

    #[test]
    fn rejects_non_finite_jumps_turns_and_stale_samples() {
        let mut f = PoseFilter::new(FilterConfig::default());
        acquire(&mut f, 0.0, DVec3::ZERO);
        assert_eq!(
            f.offer(0.01, DVec3::NAN, DQuat::IDENTITY),
            Err(Rejection::NonFinite)
        );
        // 1 m in 10 ms is 100 m/s.
        assert!(matches!(
            f.offer(0.01, DVec3::X, DQuat::IDENTITY),
            Err(Rejection::Jump { .. })
        ));
        assert!(matches!(
            f.offer(0.01, DVec3::ZERO, DQuat::from_rotation_y(1.0)),
            Err(Rejection::Turn { .. })
        ));
        f.offer(0.01, DVec3::new(0.01, 0.0, 0.0), DQuat::IDENTITY)
            .unwrap();
        assert!(matches!(
            f.offer(0.005, DVec3::ZERO, DQuat::IDENTITY),
            Err(Rejection::Stale { .. })
        ));
        assert_eq!(f.rejected(), 4);
        // The held pose is the last accepted one.
        assert_eq!(f.pose(1.0).unwrap().0, DVec3::new(0.01, 0.0, 0.0));
    }

    /// A walk at 1 m/s along x, sampled at 100 Hz.
    fn walk(i: u32) -> (f64, DVec3) {
        let t = 1.0 + f64::from(i) * 0.01;
        (t, DVec3::new(t - 1.0, 0.4, 0.5))
    }

    /// A first sample 1e43 mm away (inf once it is an f32) has nothing to
    /// jump from; it must still be refused, and must not lock out the good
    /// samples that follow.
    #[test]
    fn a_wild_first_sample_is_refused_and_good_samples_take_over() {
        let mut f = PoseFilter::new(FilterConfig::default());
        let wild = DVec3::new(1e40, 0.0, 0.0);
        let e = f.offer(0.99, wild, DQuat::IDENTITY).unwrap_err();
        assert!(matches!(e, Rejection::OutsideVolume { position, .. } if position == wild));
        assert_eq!(
            e.to_string(),
            "position (1.000e40, 0.000, 0.000) m is outside the tracking volume \
             (-4.000, -1.500, -4.000) to (4.000, 2.500, 4.000) m; a reflection or a \
             mis-assigned body, or tracking.limits.volume_min/volume_max are too tight"
        );
        assert_eq!(f.pose(0.99), None);
        let mut got = Vec::new();
        for i in 0..10 {
            let (t, p) = walk(i);
            got.push(f.offer(t, p, DQuat::IDENTITY).unwrap());
        }
        let candidate = |count| Offered::Candidate { count, needed: 3 };
        assert_eq!(
            got[..4],
            [
                candidate(1),
                candidate(2),
                Offered::Acquired,
                Offered::Accepted
            ]
        );
        assert_eq!(f.pose(1.09), Some((walk(9).1, DQuat::IDENTITY)));
    }

    /// A ghost consistent for a few samples was acquired; the real body,
    /// 3.5 m and more away, is rejected as a jump until the ghost's pose expires, then
    /// re-acquired: locked out for at most `reacquire_s` and a few samples.
    #[test]
    fn good_samples_reacquire_after_a_ghost_track() {
        let mut f = PoseFilter::new(FilterConfig::default());
        let ghost = DVec3::new(-3.5, 0.4, 0.5);
        acquire(&mut f, 0.99, ghost);
        let mut first_good = None;
        for i in 0..100 {
            let (t, p) = walk(i);
            match f.offer(t, p, DQuat::IDENTITY) {
                Err(Rejection::Jump { .. }) => assert!(t - 0.99 < 0.5, "{t}"),
                Ok(Offered::Acquired) => first_good = first_good.or(Some(t)),
                Ok(Offered::Accepted) => assert!(first_good.is_some()),
                other => panic!("at {t}: {other:?}"),
            }
        }
        // The ghost's pose expires 0.5 s after 0.99 s, give or take rounding.
        let first_good = first_good.unwrap();
        assert!((1.49..1.505).contains(&first_good), "{first_good}");
        assert_eq!(f.pose(2.0).unwrap().0, walk(99).1);
    }

    /// After the held pose expired, a lone sample is never taken, even one
    /// the speed limit would allow after so long; nor is a lone wild sample
    /// among good ones while the pose is fresh.
    #[test]
    fn a_single_wild_sample_is_never_accepted() {
        let mut f = PoseFilter::new(FilterConfig::default());
        acquire(&mut f, 0.0, DVec3::ZERO);
        let far = DVec3::new(3.0, 0.0, 0.0);
        assert_eq!(
            f.offer(2.0, far, DQuat::IDENTITY),
            Ok(Offered::Candidate {
                count: 1,
                needed: 3
            })
        );
        assert_eq!(f.pose(2.0).unwrap().0, DVec3::ZERO);
        for i in 0..30 {
            let (t, p) = walk(i);
            let t = t + 1.5;
            if i == 10 {
                assert!(f.offer(t, far, DQuat::IDENTITY).is_err());
            } else {
                f.offer(t, p, DQuat::IDENTITY).unwrap();
            }
            let held = f.pose(t).unwrap().0;
            assert!(
                held == DVec3::ZERO || held.distance(p) < 0.02,
                "{t}: {held}"
            );
        }
    }

    /// Found by a property: a rotation whose length overflows normalised
    /// to the zero quaternion and was held.
    #[test]
    fn an_overflowing_rotation_is_degenerate() {
        let mut f = PoseFilter::new(FilterConfig::default());
        let huge = DQuat::from_xyzw(0.0, 0.0, 0.0, 1e308);
        for t in [0.0, 0.01, 0.02] {
            assert_eq!(f.offer(t, DVec3::ZERO, huge), Err(Rejection::NonFinite));
        }
        assert_eq!(f.pose(0.02), None);
    }

    /// Prediction never carries a pose out of the volume, and a huge
    /// velocity from nearly equal timestamps is capped at `max_speed`.
    #[test]
    fn predictions_stay_in_the_volume() {
        let mut f = PoseFilter::new(FilterConfig {
            predict_s: 0.2,
            ..FilterConfig::default()
        });
        let edge = DVec3::new(3.999, 0.0, 0.0);
        acquire(&mut f, 0.0, edge - DVec3::X * 0.004);
        f.offer(2e-6, edge, DQuat::IDENTITY).unwrap();
        let (p, _) = f.pose(0.2).unwrap();
        assert_eq!(p.x, 4.0);
        assert!(f.pose(f64::NAN).unwrap().0.is_finite());
    }

    #[test]
    fn predicts_with_constant_velocity_up_to_the_limit() {
        let mut f = PoseFilter::new(FilterConfig {
            predict_s: 0.02,
            ..FilterConfig::default()
        });
        assert!(f.pose(0.0).is_none());
        acquire(&mut f, 0.0, DVec3::ZERO);
        f.offer(0.1, DVec3::new(0.1, 0.0, 0.0), DQuat::IDENTITY)
            .unwrap();
        let (p, _) = f.pose(0.11).unwrap();
        assert!((p.x - 0.11).abs() < 1e-12, "{p}");
        // Never extrapolates beyond predict_s, however stale the sample.
        let (p, _) = f.pose(5.0).unwrap();
        assert!((p.x - 0.12).abs() < 1e-12, "{p}");
    }
}
