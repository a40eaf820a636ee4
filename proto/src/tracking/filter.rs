//! Pose filtering for tracked bodies: reject non-finite poses and jumps
//! beyond physical limits, hold the last good pose of an untracked body,
//! and optionally predict ahead with constant velocity to cover pipeline
//! latency. Time is an input (seconds), so this is deterministic.

use glam::{DQuat, DVec3};

/// Limits and prediction settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterConfig {
    /// Fastest plausible linear speed (m/s); faster jumps are rejected.
    pub max_speed: f64,
    /// Fastest plausible angular speed (degrees/s).
    pub max_angular_speed_deg: f64,
    /// Predict this far ahead (s); 0 disables prediction.
    pub predict_s: f64,
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            // A walking head moves well under 3 m/s and turns under 720 deg/s.
            max_speed: 5.0,
            max_angular_speed_deg: 1000.0,
            predict_s: 0.0,
        }
    }
}

/// Why a sample was not accepted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Rejection {
    /// A coordinate was NaN or infinite.
    #[error("pose is not finite")]
    NonFinite,
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
    /// The sample is older than the last accepted one.
    #[error("sample at {t} s is older than the last accepted one")]
    Stale {
        /// The sample's time.
        t: f64,
    },
}

#[derive(Clone, Copy, Debug)]
struct Sample {
    t: f64,
    position: DVec3,
    rotation: DQuat,
}

/// Filter state of one body.
#[derive(Clone, Debug, Default)]
pub struct PoseFilter {
    config: FilterConfig,
    last: Option<Sample>,
    velocity: DVec3,
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

    /// Offer a tracked sample at time `t`. Accepted samples become the held
    /// pose; rejected ones leave it unchanged.
    pub fn offer(&mut self, t: f64, position: DVec3, rotation: DQuat) -> Result<(), Rejection> {
        let r = self.check(t, position, rotation);
        match r {
            Ok(()) => {
                if let Some(last) = self.last {
                    let dt = t - last.t;
                    if dt > 1e-6 {
                        self.velocity = (position - last.position) / dt;
                    }
                }
                self.last = Some(Sample {
                    t,
                    position,
                    rotation: rotation.normalize(),
                });
            }
            Err(_) => self.rejected += 1,
        }
        r
    }

    fn check(&self, t: f64, position: DVec3, rotation: DQuat) -> Result<(), Rejection> {
        if !(t.is_finite() && position.is_finite() && rotation.is_finite())
            || rotation.length() < 1e-6
        {
            return Err(Rejection::NonFinite);
        }
        let Some(last) = self.last else {
            return Ok(());
        };
        let dt = t - last.t;
        if dt < 0.0 {
            return Err(Rejection::Stale { t });
        }
        // Allow at least 1 ms worth of motion so equal timestamps still pass
        // tiny corrections.
        let dt_eff = dt.max(1e-3);
        let distance = position.distance(last.position);
        if distance > self.config.max_speed * dt_eff {
            return Err(Rejection::Jump {
                distance,
                dt,
                max: self.config.max_speed,
            });
        }
        let degrees = last
            .rotation
            .angle_between(rotation.normalize())
            .to_degrees();
        if degrees > self.config.max_angular_speed_deg * dt_eff {
            return Err(Rejection::Turn {
                degrees,
                dt,
                max: self.config.max_angular_speed_deg,
            });
        }
        Ok(())
    }

    /// The pose to use at time `now`: the last accepted pose, advanced by
    /// constant velocity for at most `predict_s` when prediction is on.
    /// `None` until a sample has been accepted. An untracked body simply
    /// gets no new samples, so it holds its last pose.
    pub fn pose(&self, now: f64) -> Option<(DVec3, DQuat)> {
        let last = self.last?;
        let ahead = (now - last.t).clamp(0.0, self.config.predict_s);
        Some((last.position + self.velocity * ahead, last.rotation))
    }

    /// Samples rejected so far.
    pub fn rejected(&self) -> u64 {
        self.rejected
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_non_finite_jumps_turns_and_stale_samples() {
        let mut f = PoseFilter::new(FilterConfig::default());
        f.offer(0.0, DVec3::ZERO, DQuat::IDENTITY).unwrap();
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

    #[test]
    fn predicts_with_constant_velocity_up_to_the_limit() {
        let mut f = PoseFilter::new(FilterConfig {
            predict_s: 0.02,
            ..FilterConfig::default()
        });
        assert!(f.pose(0.0).is_none());
        f.offer(0.0, DVec3::ZERO, DQuat::IDENTITY).unwrap();
        f.offer(0.1, DVec3::new(0.1, 0.0, 0.0), DQuat::IDENTITY)
            .unwrap();
        let (p, _) = f.pose(0.11).unwrap();
        assert!((p.x - 0.11).abs() < 1e-12, "{p}");
        // Never extrapolates beyond predict_s, however stale the sample.
        let (p, _) = f.pose(5.0).unwrap();
        assert!((p.x - 0.12).abs() < 1e-12, "{p}");
    }
}
