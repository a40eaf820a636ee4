//! Properties of the DTrack parser and the pose filter over hostile input:
//! nothing panics, nothing non-finite or outside the tracking volume ever
//! leaves the filter (the first sample included), a lone wild sample is
//! never used, and good samples always win back a body after garbage.

use super::dtrack::{MAX_BODIES, parse_datagram};
use super::filter::{FilterConfig, Offered, PoseFilter};
use super::strategies::{datagram, sample};
use glam::{DQuat, DVec3};
use proptest::collection::vec;
use proptest::prelude::*;

/// The pose at `now` is absent, or finite, inside the volume and a unit
/// rotation.
fn check_pose(f: &PoseFilter, cfg: &FilterConfig, now: f64) -> Result<(), TestCaseError> {
    if let Some((p, q)) = f.pose(now) {
        prop_assert!(p.is_finite() && cfg.in_volume(p), "{p} at {now}");
        prop_assert!(q.is_finite() && (q.length() - 1.0).abs() < 1e-9, "{q}");
        // And so as f32, where 1e43 would have become inf.
        prop_assert!(p.as_vec3().is_finite() && q.as_quat().is_finite());
    }
    Ok(())
}

/// A smooth walk inside the volume: at most 2 m/s and 100 deg/s.
fn good(t: f64, phase: f64) -> (DVec3, DQuat) {
    let p = DVec3::new(
        1.5 * (0.5 * t + phase).sin(),
        0.4 + 0.1 * (t + phase).cos(),
        1.0 + 0.5 * (0.7 * t).sin(),
    );
    (p, DQuat::from_rotation_y(0.8 * (t + phase).sin()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn dtrack_like_datagrams_never_panic(text in datagram()) {
        if let Ok(f) = parse_datagram(&text) {
            prop_assert!(f.bodies.len() <= MAX_BODIES);
            for b in &f.bodies {
                prop_assert!(b.position.is_finite() && b.quality.is_finite());
                if b.is_tracked() {
                    let r = b.rotation;
                    prop_assert!(r.is_finite() && (r.determinant() - 1.0).abs() < 1e-2, "{r}");
                }
            }
        }
    }

    #[test]
    fn arbitrary_bytes_as_text_never_panic(bytes in vec(any::<u8>(), 0..400)) {
        let _ = parse_datagram(&String::from_utf8_lossy(&bytes));
    }

    /// Whatever is offered, from the very first sample on.
    #[test]
    fn nothing_unsafe_leaves_the_filter(
        samples in vec(sample(), 1..60),
        predict_ms in 0.0f64..200.0,
    ) {
        let cfg = FilterConfig { predict_s: predict_ms / 1000.0, ..FilterConfig::default() };
        let mut f = PoseFilter::new(cfg.clone());
        let mut t = 0.0;
        for (i, (dt, p, q)) in samples.into_iter().enumerate() {
            t += dt;
            let r = f.offer(t, p, q);
            if !(p.is_finite() && cfg.in_volume(p)) {
                prop_assert!(r.is_err(), "sample {i} at {p} was taken: {r:?}");
            }
            if i + 1 < cfg.acquire_samples as usize {
                prop_assert!(f.pose(t).is_none(), "acquired from {} samples", i + 1);
            }
            for now in [t, t + 0.01, t + 10.0, f64::NAN, f64::INFINITY] {
                check_pose(&f, &cfg, now)?;
            }
        }
    }

    /// After any garbage, a good walk is tracked again within
    /// `reacquire_s` plus `acquire_samples` samples.
    #[test]
    fn good_samples_win_back_the_body_after_garbage(
        garbage in vec(sample(), 0..40),
        gap in 0.0f64..1.0,
        phase in 0.0f64..6.0,
    ) {
        let cfg = FilterConfig::default();
        let mut f = PoseFilter::new(cfg.clone());
        let mut t = 0.0f64;
        for (dt, p, q) in garbage {
            // Garbage only before the walk: its times stay in [0, 2].
            t = (t + dt).clamp(0.0, 2.0);
            let _ = f.offer(t, p, q);
        }
        let start = 2.0 + gap;
        let step = 0.01;
        let needed = ((cfg.reacquire_s / step).ceil() as usize) + cfg.acquire_samples as usize + 1;
        let mut last = None;
        for i in 0..needed {
            let t = start + i as f64 * step;
            let (p, q) = good(t, phase);
            let _ = f.offer(t, p, q);
            last = Some((t, p));
        }
        let (t, p) = last.unwrap();
        let (held, _) = f.pose(t).expect("the walk was acquired");
        prop_assert!(held.distance(p) < 1e-12, "held {held}, walk at {p}");
    }

    /// A tracked walk with one wild sample: the wild one is never used,
    /// and the walk is never lost.
    #[test]
    fn a_lone_wild_sample_is_never_used(
        at in 5usize..60,
        wild in (-4.0f64..4.0, -1.5f64..2.5, -4.0f64..4.0),
        phase in 0.0f64..6.0,
    ) {
        let wild = DVec3::new(wild.0, wild.1, wild.2);
        let mut f = PoseFilter::new(FilterConfig::default());
        for i in 0..80 {
            let t = i as f64 * 0.01;
            let (p, q) = good(t, phase);
            let offered = if i == at { wild } else { p };
            let r = f.offer(t, offered, q);
            if i == at && wild.distance(p) > 0.1 {
                prop_assert!(r.is_err(), "{r:?}");
            }
            if i >= 2 && i != at {
                prop_assert!(matches!(r, Ok(Offered::Accepted | Offered::Acquired)), "{i}: {r:?}");
            }
            if let Some((held, _)) = f.pose(t) {
                prop_assert!(held.distance(p) < 0.1, "{i}: held {held}, walk at {p}");
            }
        }
    }
}
