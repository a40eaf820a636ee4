//! Where each frame's state comes from: the scene's initial state plus
//! tracking (live DTrack datagrams, a recorded session, or the built-in
//! scripted walk). Scripted and replayed shows use show time
//! (`frame / target_hz`) for every sample, so two runs of the same
//! recording produce bit-identical frame states. Every datagram is
//! recorded as received, bad ones included, with what its ingest
//! rejected; a replay rejects the same things and says when it does not.

use crate::tracking::recording::{Entry, Recorder};
use crate::tracking::scripted::{carried_object, walk_datagram_carrying};
use crate::tracking::{Tracker, initial_frame};
use showcase_proto::config::TrackingConfig;
use showcase_proto::{FrameState, Showcase};
use std::io::Write;
use tracing::warn;

/// The tracking input of a show.
#[derive(Debug)]
pub enum Tracking {
    /// No tracking: the snapshot's heads and lights.
    None,
    /// Live datagrams (fed with [`Show::ingest_live`]).
    Live(Tracker),
    /// The built-in walk, one datagram per frame.
    Scripted(Tracker),
    /// A recorded session, played by show time.
    Replay {
        /// The tracker.
        tracker: Tracker,
        /// The datagrams.
        entries: Vec<Entry>,
        /// Next entry to play.
        next: usize,
    },
}

/// Produces frame states.
pub struct Show {
    tracking: Tracking,
    recorder: Option<Recorder<Box<dyn Write + Send>>>,
    target_hz: f64,
    /// Datagrams that could not be parsed.
    pub bad_datagrams: u64,
    /// Replayed datagrams whose rejections differ from the recorded ones
    /// (another configuration or another build than the live show's).
    pub replay_divergences: u64,
}

impl std::fmt::Debug for Show {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Show")
            .field("tracking", &self.tracking)
            .field("recording", &self.recorder.is_some())
            .finish()
    }
}

impl Show {
    /// A show at `target_hz` driven by `tracking`.
    pub fn new(tracking: Tracking, target_hz: f64) -> Self {
        Self {
            tracking,
            recorder: None,
            target_hz,
            bad_datagrams: 0,
            replay_divergences: 0,
        }
    }

    /// Record every datagram (live, scripted or replayed) to `out`, with
    /// the tracking settings that map and filter them.
    pub fn record_to(
        &mut self,
        out: Box<dyn Write + Send>,
        note: &str,
        tracking: Option<&TrackingConfig>,
    ) -> std::io::Result<()> {
        self.recorder = Some(Recorder::new(out, note, tracking)?);
        Ok(())
    }

    /// Whether live datagrams are expected.
    pub fn is_live(&self) -> bool {
        matches!(self.tracking, Tracking::Live(_))
    }

    /// True once a replayed recording has played its last datagram.
    pub fn replay_finished(&self) -> bool {
        matches!(&self.tracking, Tracking::Replay { entries, next, .. } if *next >= entries.len())
    }

    /// Feed one datagram to `tracker`; returns what was rejected, as the
    /// recording keeps it: the parser's error, or `body <id>: <why>` per
    /// refused sample.
    fn ingest(tracker: &mut Tracker, bad: &mut u64, t: f64, datagram: &str) -> Vec<String> {
        match tracker.ingest(t, datagram) {
            Ok(r) => r
                .rejected
                .into_iter()
                .map(|(id, why)| {
                    warn!(body = id, %why, "tracking sample rejected");
                    format!("body {id}: {why}")
                })
                .collect(),
            Err(e) => {
                *bad += 1;
                warn!(error = %e, "bad tracking datagram");
                vec![e.to_string()]
            }
        }
    }

    fn record(&mut self, entry: Entry) {
        if let Some(r) = self.recorder.as_mut()
            && let Err(e) = r.record_entry(&entry)
        {
            warn!(error = %e, "recording failed; recording stops");
            self.recorder = None;
        }
    }

    /// A datagram arrived from DTrack at show time `now_s`. It is recorded
    /// whether or not it parses.
    pub fn ingest_live(&mut self, now_s: f64, datagram: &str) {
        if let Tracking::Live(tracker) = &mut self.tracking {
            let rejected = Self::ingest(tracker, &mut self.bad_datagrams, now_s, datagram);
            self.record(Entry {
                t: now_s,
                datagram: datagram.into(),
                rejected: Some(rejected),
            });
        }
    }

    /// The state of frame `frame`; `now_s` is the master clock in seconds
    /// (used by live tracking only). Returns the state and the show time
    /// of the newest tracking sample in it, if any.
    pub fn frame_state(
        &mut self,
        frame: u64,
        now_s: f64,
        scene: &Showcase,
        version: u64,
    ) -> (FrameState, Option<f64>) {
        let t = frame as f64 / self.target_hz;
        let mut state = initial_frame(scene, frame, t, version);
        let mut to_record = Vec::new();
        let sample = match &mut self.tracking {
            Tracking::None => None,
            Tracking::Live(tracker) => {
                tracker.apply(now_s, scene, &mut state);
                tracker.last_sample_s()
            }
            Tracking::Scripted(tracker) => {
                let carried = carried_object(scene).map(|i| &scene.objects[i].transform);
                let datagram = walk_datagram_carrying(frame, t, carried);
                let rejected = Self::ingest(tracker, &mut self.bad_datagrams, t, &datagram);
                to_record.push(Entry {
                    t,
                    datagram,
                    rejected: Some(rejected),
                });
                tracker.apply(t, scene, &mut state);
                tracker.last_sample_s()
            }
            Tracking::Replay {
                tracker,
                entries,
                next,
            } => {
                while let Some(e) = entries.get(*next).filter(|e| e.t <= t) {
                    let rejected = Self::ingest(tracker, &mut self.bad_datagrams, e.t, &e.datagram);
                    if e.rejected.as_ref().is_some_and(|then| *then != rejected) {
                        self.replay_divergences += 1;
                        if self.replay_divergences == 1 {
                            warn!(
                                t = e.t,
                                then = ?e.rejected,
                                now = ?rejected,
                                "the replay rejects other samples than the recorded show did; \
                                 is it running with the same tracking limits and room transform? \
                                 (further divergences are only counted)"
                            );
                        }
                    }
                    to_record.push(Entry {
                        t: e.t,
                        datagram: e.datagram.clone(),
                        rejected: Some(rejected),
                    });
                    *next += 1;
                }
                tracker.apply(t, scene, &mut state);
                tracker.last_sample_s()
            }
        };
        for e in to_record {
            self.record(e);
        }
        (state, sample)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::recording;
    use crate::tracking::scripted::{walk_datagram, walk_positions};
    use showcase_proto::config::{BodyMapping, TrackingConfig, TrackingSource};
    use showcase_proto::{MAX_FRAME_LEN, Message, Pose, Validate, encode_frame};
    use std::sync::{Arc, Mutex};

    const HZ: f64 = 60.0;

    fn scene() -> Showcase {
        crate::tracking::tracker::two_observers_and_a_light()
    }

    fn tracker(scene: &Showcase) -> Tracker {
        let config = TrackingConfig {
            source: TrackingSource::Dtrack,
            port: Some(5000),
            file: None,
            room_translation: [0.0; 3],
            room_rotation_deg: [0.0; 3],
            predict_ms: 0.0,
            limits: Default::default(),
            bodies: ["observer:alice", "observer:bob", "light:key"]
                .iter()
                .zip(0..)
                .map(|(t, id)| BodyMapping {
                    id,
                    target: (*t).into(),
                })
                .collect(),
        };
        Tracker::new(&config, scene).unwrap()
    }

    /// A recording sink the test can read while the show owns it.
    struct Sink(Arc<Mutex<Vec<u8>>>);
    impl Write for Sink {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// Two seconds of the walk at 100 Hz, opened by a first sample 1e43 mm
    /// away and salted with the red team's datagrams.
    fn hostile_session() -> Vec<(f64, String)> {
        const ROT: &str = "[1 0 0 0 1 0 0 0 1]";
        let mut v = vec![(
            0.0,
            format!("fr 0\r\n6d 1 [0 1.000][1e43 0 0 0 0 0]{ROT}\r\n"),
        )];
        for i in 1..200u64 {
            let t = i as f64 * 0.01;
            v.push((t, walk_datagram(i, t)));
            let hostile = match i {
                20 => "6d 12297829382473034411 [0 1.000]".to_owned(),
                40 => "fr 40\r\n6d 1 [1 1.000][0 0 0 0 0 0] [1 0 0".to_owned(),
                60 => format!("fr 60\r\n6d 1 [0 1.000][3000 400 0 0 0 0]{ROT}\r\n"),
                80 => format!("6d 1 [0 1.000][nan 0 0 0 0 0]{ROT}"),
                100 => format!("6d 1 [2 1.000][-1e43 0 0 0 0 0]{ROT}"),
                120 => String::new(),
                140 => format!("6d 1 [1 1][1.7976931348623157e308 0 0 0 0 0]{ROT}"),
                160 => "\u{0}\u{7f}\u{133}\n6d ]]][[[ \u{1F600}".to_owned(),
                _ => continue,
            };
            v.push((t, hostile));
        }
        v
    }

    /// Each frame state as its wire bytes: equal bytes are equal bits.
    fn wire(states: &[(FrameState, Option<f64>)]) -> Vec<(Vec<u8>, Option<u64>)> {
        states
            .iter()
            .map(|(s, sample)| {
                let m = Message::FrameState(Box::new(s.clone()));
                assert!(m.validate().is_ok(), "frame {} does not validate", s.frame);
                (
                    encode_frame(&m, MAX_FRAME_LEN).unwrap(),
                    sample.map(f64::to_bits),
                )
            })
            .collect()
    }

    /// A live show fed hostile datagrams records all of them, with what it
    /// rejected; the recording, read back from a file, replays twice to
    /// bit-identical frame states, identical to the live show's, and the
    /// replay rejects exactly what the live show did.
    #[test]
    fn the_scripted_walk_carries_the_demo_scenes_virtual_bunny() {
        use crate::cluster::commands::walk_tracking;
        use crate::tracking::scripted::{OBJECT_SWAY, carried_pose};
        let demo = crate::scene_file::load_any(std::path::Path::new("builtin:showcase")).unwrap();
        let bunny = demo.object_index("virtual-bunny").unwrap();
        let config = walk_tracking(&demo, TrackingSource::Scripted);
        let mut show = Show::new(
            Tracking::Scripted(Tracker::new(&config, &demo).unwrap()),
            HZ,
        );
        let mut reach = 0.0f32;
        for f in 0..400u64 {
            let (state, _) = show.frame_state(f, 0.0, &demo, 1);
            let moved: Vec<u32> = state.object_transforms.iter().map(|o| o.object).collect();
            if f < 10 {
                continue;
            }
            // Only the bunny moves, where the walk holds it.
            assert_eq!(moved, [bunny as u32], "frame {f}");
            let got = state.object_transforms[0].transform;
            let base = demo.objects[bunny].transform;
            let (want, _) = carried_pose(&base, f as f64 / HZ);
            assert!(
                (got.translation.as_dvec3() - want).length() < 1e-4,
                "frame {f}"
            );
            assert!(got.rotation.angle_between(base.rotation) < 1e-4);
            assert_eq!(got.scale, base.scale);
            reach = reach.max((got.translation - base.translation).length());
        }
        assert!(
            reach > 0.9 * OBJECT_SWAY as f32,
            "carried {reach} m at most"
        );
    }

    #[test]
    fn a_hostile_live_session_replays_exactly() {
        let s = scene();
        let session = hostile_session();
        let frames = 2 * HZ as u64;
        let out = Arc::new(Mutex::new(Vec::new()));
        let mut live = Show::new(Tracking::Live(tracker(&s)), HZ);
        live.record_to(Box::new(Sink(out.clone())), "hostile", None)
            .unwrap();
        let mut next = 0;
        let mut live_states = Vec::new();
        for f in 0..frames {
            let t = f as f64 / HZ;
            while let Some((at, d)) = session.get(next).filter(|(at, _)| *at <= t) {
                live.ingest_live(*at, d);
                next += 1;
            }
            live_states.push(live.frame_state(f, t, &s, 1));
        }
        assert_eq!(live.bad_datagrams, 4);

        let dir = std::env::temp_dir().join(format!("showcase-show-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("session.jsonl");
        std::fs::write(&path, out.lock().unwrap().as_slice()).unwrap();
        let entries = recording::read(&path).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        // Every datagram up to the last frame was kept, bad ones included.
        assert_eq!(entries.len(), next);
        let rejected: Vec<(f64, &str)> = entries
            .iter()
            .flat_map(|e| e.rejected.iter().flatten().map(move |r| (e.t, r.as_str())))
            .collect();
        assert_eq!(rejected.len(), 8, "{rejected:#?}");
        assert!(
            rejected[0].1.starts_with("body 0: position (1.000e40,"),
            "{rejected:?}"
        );
        assert!(
            rejected[1].1.contains("body count 12297829382473034411"),
            "{rejected:?}"
        );
        assert!(rejected[3].1.starts_with("body 0: jump of"), "{rejected:?}");

        let replay = || {
            let mut show = Show::new(
                Tracking::Replay {
                    tracker: tracker(&s),
                    entries: entries.clone(),
                    next: 0,
                },
                HZ,
            );
            let states: Vec<_> = (0..frames)
                .map(|f| show.frame_state(f, -1.0, &s, 1))
                .collect();
            assert_eq!((show.bad_datagrams, show.replay_divergences), (4, 0));
            states
        };
        let (a, b) = (wire(&replay()), wire(&replay()));
        assert!(a == b, "two replays differ");
        assert!(
            a == wire(&live_states),
            "the replay differs from the live show"
        );

        // The walk was tracked despite the poisoned first sample.
        let (last, _) = live_states.last().unwrap();
        let alice = walk_positions(entries.last().unwrap().t)[0].as_vec3();
        assert!(
            last.heads[0].position.distance(alice) < 1e-5,
            "{:?}",
            last.heads[0]
        );
        // Frames 0 and 1 saw the refused sample and one good one; frame 2
        // the third good one, which acquired alice.
        let untracked: Vec<bool> = live_states[..3]
            .iter()
            .map(|(st, _)| st.heads[0] == Pose::default())
            .collect();
        assert_eq!(untracked, [true, true, false]);
    }
}
