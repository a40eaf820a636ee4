//! Tracking end to end: hostile DTrack datagrams recorded by a live show
//! replay through a loopback cluster to bit-identical output, whole or cut
//! short by a crash; and nothing any datagram says makes `Tracker::apply`
//! write a non-finite or out-of-volume pose into a frame.

use showcase_master::cluster::commands::{replay, walk_tracking};
use showcase_master::cluster::{Show, Tracking};
use showcase_master::tracking::{Tracker, initial_frame};
use showcase_proto::config::{TrackingConfig, TrackingSource};
use showcase_proto::tracking::FilterConfig;
use showcase_proto::tracking::strategies::datagram;
use showcase_proto::{Light, Showcase, Validate};
use std::sync::OnceLock;
use std::time::Duration;
use tokio::time::timeout;

fn scene() -> &'static Showcase {
    static SCENE: OnceLock<Showcase> = OnceLock::new();
    SCENE.get_or_init(|| {
        showcase_master::scene_file::load_scene(&showcase_master::demo::default_scene()).unwrap()
    })
}

/// One second of the walk at 50 Hz with the red team's datagrams: a first
/// sample 1e43 mm away, a body count that wraps `3 * count`, a cut-off
/// line, a teleport, a NaN, and a body at -1e43 mm.
fn hostile_session() -> Vec<(f64, String)> {
    const ROT: &str = "[1 0 0 0 1 0 0 0 1]";
    let mut v = vec![(
        0.0,
        format!("fr 0\r\n6d 1 [0 1.000][1e43 0 0 0 0 0]{ROT}\r\n"),
    )];
    for i in 1..50u64 {
        let t = i as f64 * 0.02;
        v.push((t, showcase_master::tracking::scripted::walk_datagram(i, t)));
        let hostile = match i {
            10 => "6d 12297829382473034411 [0 1.000]".to_owned(),
            20 => "fr 20\r\n6d 1 [1 1.000][0 0 0 0 0 0] [1 0 0".to_owned(),
            25 => format!("6d 1 [0 1.000][3000 400 0 0 0 0]{ROT}"),
            30 => format!("6d 1 [0 1.000][nan 0 0 0 0 0]{ROT}"),
            40 => format!("6d 1 [2 1.000][-1e43 0 0 0 0 0]{ROT}"),
            _ => continue,
        };
        v.push((t, hostile));
    }
    v
}

/// The live show records every datagram; `replay` (the `showcase-master
/// replay` command) plays the file through a loopback cluster twice with
/// identical per-frame output hashes on every node, and a copy whose last
/// line a crash cut off replays like the whole file without that line.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_recordings_replay_bit_identically() {
    let scene = scene();
    let config = walk_tracking(scene, TrackingSource::Dtrack);
    let tracker = Tracker::new(&config, scene).unwrap();
    let mut live = Show::new(Tracking::Live(tracker), 50.0);
    let dir = std::env::temp_dir().join(format!("showcase-tracking-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let session = dir.join("hostile.jsonl");
    live.record_to(
        Box::new(std::fs::File::create(&session).unwrap()),
        "hostile",
        Some(&config),
    )
    .unwrap();
    for (t, d) in hostile_session() {
        live.ingest_live(t, &d);
    }
    assert_eq!(live.bad_datagrams, 3);
    drop(live);
    let whole = std::fs::read(&session).unwrap();
    let cut = dir.join("cut.jsonl");
    let mut bytes = whole.clone();
    bytes.extend_from_slice(b"{\"t\":0.99,\"datagram\":\"fr 50\\r\\n6d 3 [0 1.0");
    std::fs::write(&cut, &bytes).unwrap();

    let run = |path: std::path::PathBuf| async move {
        timeout(Duration::from_secs(60), replay(scene, &path, 60.0, None))
            .await
            .unwrap()
            .unwrap()
    };
    let a = run(session.clone()).await;
    let b = run(session.clone()).await;
    let c = run(cut.clone()).await;
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(a.frames, 59, "the recording's 0.98 s at 60 Hz");
    assert_eq!(a.nodes.len(), scene.faces.len() + scene.projectors.len());
    for ((x, y), z) in a.nodes.iter().zip(&b.nodes).zip(&c.nodes) {
        assert_eq!(x.hashes.len() as u64, a.frames, "{} missed frames", x.name);
        assert_eq!(x.hashes, y.hashes, "{} differs between replays", x.name);
        assert_eq!(x.hashes, z.hashes, "{} differs when cut short", x.name);
    }
}

/// Whatever the datagrams say, every pose `Tracker::apply` writes is
/// finite, and heads and tracked objects stay in the tracking volume.
#[test]
fn nothing_unsafe_leaves_tracker_apply() {
    use proptest::prelude::*;
    let scene = scene();
    let mut config: TrackingConfig = walk_tracking(scene, TrackingSource::Dtrack);
    config.bodies.push(showcase_proto::config::BodyMapping {
        id: 3,
        target: format!("object:{}", scene.objects[1].name),
    });
    config.room_translation = [0.2, -0.9, 0.1];
    config.room_rotation_deg = [0.0, 30.0, 0.0];
    config.predict_ms = 50.0;
    let volume = FilterConfig::new(&config.limits, 0.0);
    let inside = |p: glam::Vec3| volume.in_volume(p.as_dvec3());
    proptest!(ProptestConfig::with_cases(256), |(datagrams in proptest::collection::vec(datagram(), 1..12), dt in 0.0f64..0.1)| {
        let mut tracker = Tracker::new(&config, scene).unwrap();
        for (i, d) in datagrams.iter().enumerate() {
            let now = i as f64 * dt;
            let _ = tracker.ingest(now, d);
            let mut frame = initial_frame(scene, i as u64, now, 1);
            tracker.apply(now + 0.01, scene, &mut frame);
            prop_assert!(frame.validate_against(scene).is_ok(), "{:?}", frame.validate());
            for h in &frame.heads {
                prop_assert!(h.position.is_finite() && h.orientation.is_finite());
            }
            for l in &frame.lights {
                prop_assert!(l.light.position().is_finite(), "{:?}", l.light);
                if let Light::Point { position, .. } | Light::Spot { position, .. } = l.light {
                    prop_assert!(inside(position), "{position}");
                }
            }
            for o in &frame.object_transforms {
                prop_assert!(inside(o.transform.translation), "{:?}", o.transform);
            }
        }
        let heads: Vec<_> = initial_frame(scene, 0, 0.0, 1).heads;
        let mut frame = initial_frame(scene, 0, 0.0, 1);
        tracker.apply(1e9, scene, &mut frame);
        for (h, h0) in frame.heads.iter().zip(&heads) {
            prop_assert!(h == h0 || inside(h.position), "{h:?}");
        }
    });
}
