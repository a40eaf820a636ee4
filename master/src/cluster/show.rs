//! Where each frame's state comes from: the scene's initial state plus
//! tracking (live DTrack datagrams, a recorded session, or the built-in
//! scripted walk). Scripted and replayed shows use show time
//! (`frame / target_hz`) for every sample, so two runs of the same
//! recording produce bit-identical frame states.

use crate::tracking::recording::{Entry, Recorder};
use crate::tracking::scripted::walk_datagram;
use crate::tracking::{Tracker, initial_frame};
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
        }
    }

    /// Record every datagram (live, scripted or replayed) to `out`.
    pub fn record_to(&mut self, out: Box<dyn Write + Send>, note: &str) -> std::io::Result<()> {
        self.recorder = Some(Recorder::new(out, note)?);
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

    fn ingest(tracker: &mut Tracker, bad: &mut u64, t: f64, datagram: &str) {
        match tracker.ingest(t, datagram) {
            Ok(r) => {
                for (id, why) in r.rejected {
                    warn!(body = id, %why, "tracking sample rejected");
                }
            }
            Err(e) => {
                *bad += 1;
                warn!(error = %e, "bad tracking datagram");
            }
        }
    }

    fn record(&mut self, t: f64, datagram: &str) {
        if let Some(r) = self.recorder.as_mut()
            && let Err(e) = r.record(t, datagram)
        {
            warn!(error = %e, "recording failed; recording stops");
            self.recorder = None;
        }
    }

    /// A datagram arrived from DTrack at show time `now_s`.
    pub fn ingest_live(&mut self, now_s: f64, datagram: &str) {
        if let Tracking::Live(tracker) = &mut self.tracking {
            Self::ingest(tracker, &mut self.bad_datagrams, now_s, datagram);
            self.record(now_s, datagram);
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
                let d = walk_datagram(frame, t);
                Self::ingest(tracker, &mut self.bad_datagrams, t, &d);
                to_record.push((t, d));
                tracker.apply(t, scene, &mut state);
                tracker.last_sample_s()
            }
            Tracking::Replay {
                tracker,
                entries,
                next,
            } => {
                while let Some(e) = entries.get(*next).filter(|e| e.t <= t) {
                    Self::ingest(tracker, &mut self.bad_datagrams, e.t, &e.datagram);
                    to_record.push((e.t, e.datagram.clone()));
                    *next += 1;
                }
                tracker.apply(t, scene, &mut state);
                tracker.last_sample_s()
            }
        };
        for (t, d) in to_record {
            self.record(t, &d);
        }
        (state, sample)
    }
}
