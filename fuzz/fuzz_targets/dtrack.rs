//! Fuzz the DTrack parser and the pose filter behind it, as the master
//! uses them: any bytes must parse to `Ok` or `Err` without panicking, and
//! every tracked body offered to a pose filter must leave it finite, a unit
//! rotation and inside the tracking volume. Run from the repository root:
//! `cargo +nightly fuzz run dtrack fuzz/corpus/dtrack fuzz/seeds/dtrack`.
#![no_main]

use glam::DQuat;
use libfuzzer_sys::fuzz_target;
use showcase_proto::tracking::dtrack::MAX_BODIES;
use showcase_proto::tracking::{FilterConfig, PoseFilter, parse_datagram};
use std::collections::BTreeMap;

fuzz_target!(|data: &[u8]| {
    // The master drops datagrams that are not UTF-8; lossy text still
    // reaches the parser with every byte pattern it can see.
    let text = String::from_utf8_lossy(data);
    let Ok(frame) = parse_datagram(&text) else {
        return;
    };
    assert!(frame.bodies.len() <= MAX_BODIES);
    let config = FilterConfig {
        predict_s: 0.05,
        ..FilterConfig::default()
    };
    let mut filters: BTreeMap<u32, PoseFilter> = BTreeMap::new();
    // The same datagram three times, 10 ms apart, so that bodies can be
    // acquired, as a tracker would offer them.
    for round in 0..3 {
        let t = f64::from(round) * 0.01;
        for b in &frame.bodies {
            assert!(b.position.is_finite() && b.quality.is_finite());
            if !b.is_tracked() {
                continue;
            }
            let f = filters
                .entry(b.id)
                .or_insert_with(|| PoseFilter::new(config.clone()));
            let _ = f.offer(t, b.position, DQuat::from_mat3(&b.rotation));
            for now in [t, t + 0.02, f64::NAN] {
                if let Some((p, q)) = f.pose(now) {
                    assert!(p.is_finite() && config.in_volume(p), "{p}");
                    assert!(p.as_vec3().is_finite(), "{p} overflows f32");
                    assert!((q.length() - 1.0).abs() < 1e-6, "{q}");
                }
            }
        }
    }
});
