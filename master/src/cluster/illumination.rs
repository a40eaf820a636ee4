//! Global illumination in the live cluster (a scene with
//! `illumination = "global"`): the master solves the global-illumination
//! field ([`crate::radiosity_job::indirect_values`]) on its own
//! thread, off the frame loop, for the newest state the loop asked for;
//! the loop publishes each solution ([`MasterCore::set_illumination`]) as
//! it lands, and frames name the version they are drawn with. The frame
//! clock never waits for the solver, except once at start: frame 0 is
//! drawn with a solution.
//!
//! [`MasterCore::set_illumination`]: showcase_proto::session::MasterCore::set_illumination

use crate::radiosity_job::{RadiosityOptions, indirect_values};
use showcase_light::render::FrameScene;
use showcase_proto::message::{ElementLight, IlluminationMesh};
use showcase_proto::{FrameState, Showcase};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;
use tokio::sync::mpsc;

/// What the solver is asked to solve: the scene as a frame left it. The
/// frame loop only shares the scene and copies the (small) state; the
/// solver resolves them on its own thread.
#[derive(Debug)]
pub struct Request {
    /// When the loop asked.
    pub asked_at: Instant,
    /// The scene the frame refers to.
    pub scene: Arc<Showcase>,
    /// The frame's state: its lights, transforms and heads.
    pub state: FrameState,
}

impl Request {
    /// The request for `state` of `scene`, asked now.
    pub fn of(scene: &Arc<Showcase>, state: &FrameState) -> Self {
        Self {
            asked_at: Instant::now(),
            scene: scene.clone(),
            state: state.clone(),
        }
    }
}

/// A solution, ready to publish.
#[derive(Debug)]
pub struct Solved {
    /// The frame whose state it was solved for.
    pub frame: u64,
    /// When the loop asked for it.
    pub asked_at: Instant,
    /// How the scene was meshed.
    pub mesh: IlluminationMesh,
    /// Per element.
    pub values: Vec<ElementLight>,
    /// The solve's own time (s).
    pub solve_s: f64,
}

/// Solve `request` (the scene meshed by `options`' hierarchical mesh).
pub fn solve(request: Request, options: &RadiosityOptions) -> anyhow::Result<Solved> {
    let t = Instant::now();
    let resolved = FrameScene::resolve(&request.scene, &request.state)?;
    let (_, values) = indirect_values(&resolved.showcase, &resolved.eyes, options)?;
    let m = options.hierarchical_mesh();
    Ok(Solved {
        frame: request.state.frame,
        asked_at: request.asked_at,
        mesh: IlluminationMesh {
            max_patch_area: m.max_patch_area,
            element_depth: m.element_depth,
            min_element_area: m.min_element_area,
        },
        values: values
            .iter()
            .map(|v| ElementLight {
                add: v.add.as_vec3().to_array(),
                cabinet: v.cabinet.as_vec3().to_array(),
            })
            .collect(),
        solve_s: t.elapsed().as_secs_f64(),
    })
}

#[derive(Debug, Default)]
struct Slot {
    /// The newest request not yet taken (older ones are replaced).
    request: Option<Request>,
    stop: bool,
}

/// The solver thread: takes the newest request, solves, sends the result;
/// stops (after the solve in hand) when dropped.
#[derive(Debug)]
pub struct Solver {
    slot: Arc<(Mutex<Slot>, Condvar)>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Solver {
    /// Start the thread; results (or why a solve failed) arrive on the
    /// returned receiver. The solves run on their own pool of one thread
    /// fewer than the machine has (at least one), so the frame loop and
    /// the connections keep a core.
    pub fn start(
        options: RadiosityOptions,
    ) -> std::io::Result<(Self, mpsc::UnboundedReceiver<Result<Solved, String>>)> {
        let slot = Arc::new((Mutex::new(Slot::default()), Condvar::new()));
        let (tx, rx) = mpsc::unbounded_channel();
        let shared = slot.clone();
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(cores.saturating_sub(1).max(1))
            .thread_name(|i| format!("illumination-{i}"))
            .build()
            .map_err(std::io::Error::other)?;
        let thread = std::thread::Builder::new()
            .name("illumination".into())
            .spawn(move || {
                loop {
                    let request = {
                        let (lock, ready) = &*shared;
                        let Ok(mut s) = lock.lock() else { return };
                        loop {
                            if s.stop {
                                return;
                            }
                            if let Some(r) = s.request.take() {
                                break r;
                            }
                            let Ok(next) = ready.wait(s) else { return };
                            s = next;
                        }
                    };
                    let result = pool
                        .install(|| solve(request, &options))
                        .map_err(|e| format!("{e:#}"));
                    if tx.send(result).is_err() {
                        return;
                    }
                }
            })?;
        Ok((
            Self {
                slot,
                thread: Some(thread),
            },
            rx,
        ))
    }

    /// Ask for `request`, replacing any request not yet taken.
    pub fn ask(&self, request: Request) {
        let (lock, ready) = &*self.slot;
        if let Ok(mut s) = lock.lock() {
            s.request = Some(request);
            ready.notify_one();
        }
    }
}

impl Drop for Solver {
    fn drop(&mut self) {
        let (lock, ready) = &*self.slot;
        if let Ok(mut s) = lock.lock() {
            s.stop = true;
            ready.notify_one();
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// What moved between two frames, as the solution sees it: the lights,
/// the object transforms and the heads (the eyes' occlusion shadows).
pub fn inputs_differ(a: &FrameState, b: &FrameState) -> bool {
    a.lights != b.lights || a.object_transforms != b.object_transforms || a.heads != b.heads
}

/// One published update: the frame it was solved for, the first frame
/// drawn with it, and the time from the loop's request to publishing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Update {
    /// The frame whose state was solved.
    pub solved_frame: u64,
    /// The first frame that names the update.
    pub first_frame: u64,
    /// Request to publish (ms).
    pub latency_ms: f64,
    /// The solve alone (ms).
    pub solve_ms: f64,
}

impl Update {
    /// Frames from the state this update solves to the first frame drawn
    /// with it: 1 when the very next frame has it.
    pub fn frames_stale(&self) -> u64 {
        self.first_frame.saturating_sub(self.solved_frame)
    }
}

/// What a run's updates amount to.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UpdateSummary {
    /// Updates published.
    pub updates: usize,
    /// Request to publish (ms), p50 (nearest rank).
    pub latency_ms_p50: Option<f64>,
    /// The same, p99.
    pub latency_ms_p99: Option<f64>,
    /// [`Update::frames_stale`], at most.
    pub frames_stale_max: Option<u64>,
}

impl UpdateSummary {
    /// The summary of `updates`.
    pub fn of(updates: &[Update]) -> Self {
        let latency: Vec<f64> = updates.iter().map(|u| u.latency_ms).collect();
        Self {
            updates: updates.len(),
            latency_ms_p50: showcase_light::metrics::percentile(&latency, 50.0),
            latency_ms_p99: showcase_light::metrics::percentile(&latency, 99.0),
            frames_stale_max: updates.iter().map(Update::frames_stale).max(),
        }
    }

    /// One line for the end of a run.
    pub fn line(&self) -> String {
        match (
            self.latency_ms_p50,
            self.latency_ms_p99,
            self.frames_stale_max,
        ) {
            (Some(a), Some(b), Some(s)) => format!(
                "global illumination: {} updates, request to publish p50 {a:.0} / p99 {b:.0} ms, at most {s} frames stale",
                self.updates
            ),
            _ => "global illumination: no update after the first solution".to_owned(),
        }
    }
}

/// The first frame's state of `scene`: its observers' initial heads and
/// its own lights, what the solution is solved for before frame 0.
pub fn initial_state(scene: &Showcase, scene_version: u64) -> FrameState {
    FrameState {
        frame: 0,
        time_s: 0.0,
        scene_version,
        heads: scene.observers.iter().map(|o| o.head).collect(),
        lights: scene.lights.clone(),
        object_transforms: Vec::new(),
        tracking_time_ns: None,
        illumination_version: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn updates_summarise_to_latency_quantiles_and_the_worst_staleness() {
        let u = |solved_frame, first_frame, latency_ms| Update {
            solved_frame,
            first_frame,
            latency_ms,
            solve_ms: latency_ms / 2.0,
        };
        // The very next frame drawn with it: 1 frame stale.
        assert_eq!(u(10, 11, 5.0).frames_stale(), 1);
        let s = UpdateSummary::of(&[u(0, 3, 30.0), u(5, 30, 400.0), u(40, 42, 20.0)]);
        assert_eq!(s.updates, 3);
        assert_eq!(s.latency_ms_p50, Some(30.0));
        assert_eq!(s.latency_ms_p99, Some(400.0));
        assert_eq!(s.frames_stale_max, Some(25));
        assert!(s.line().contains("3 updates"), "{}", s.line());
        let none = UpdateSummary::of(&[]);
        assert_eq!(none.frames_stale_max, None);
        assert!(none.line().contains("no update"));
    }

    #[test]
    fn only_lights_transforms_and_heads_ask_for_a_solve() {
        let scene = Showcase {
            observers: vec![showcase_proto::Observer {
                name: "o".into(),
                head: Default::default(),
                ipd: 0.064,
            }],
            ..Showcase::default()
        };
        let a = initial_state(&scene, 1);
        let mut b = a.clone();
        b.frame = 7;
        b.time_s = 1.0;
        b.tracking_time_ns = Some(3);
        assert!(!inputs_differ(&a, &b), "time alone moves nothing");
        b.heads[0].position.x += 0.01;
        assert!(inputs_differ(&a, &b));
    }
}
