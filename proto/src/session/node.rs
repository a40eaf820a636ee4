//! A render node's side: dial, Hello, Welcome, snapshot, then per frame
//! `Render` -> [`NodeCore::rendered`] (Ready) -> Swap -> `Present` ->
//! [`NodeCore::presented`] (NodeStats). Answers clock probes at once.
//! Reconnects with exponential backoff (capped) after any disconnect; the
//! backoff resets when a Welcome arrives.
//!
//! Frames are rendered, swapped and presented strictly in order. Every
//! frame carries the scene version it refers to; the core keeps each
//! version's scene until no pending frame refers to it, so `Render` always
//! hands out the scene the frame belongs to. The same holds for the
//! global-illumination solution a frame names: a frame whose version has
//! not arrived waits (and the frames behind it) until it does; a delta
//! whose base the node lacks, or a frame naming a version it was never
//! sent, makes it ask for full copies ([`IlluminationResync`]), once until
//! one arrives.

use super::{NS_PER_MS, ms};
use crate::PROTOCOL_VERSION;
use crate::message::{
    Bye, Capabilities, ClockProbe, ClockReply, ElementLight, Hello, Illumination, IlluminationBody,
    IlluminationMesh, IlluminationReady, IlluminationResync, Message, NodeStats, Ready, Role,
    SceneSnapshot, Swap, Welcome,
};
use crate::scene::{FrameState, Showcase};
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

/// Frames a node holds unswapped before it calls the master broken.
const MAX_PENDING_FRAMES: usize = 16;

/// Reconnect delays: `initial_ns * 2^failures`, at most `max_ns`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Backoff {
    /// Delay after the first failure (ns); default 100 ms.
    pub initial_ns: u64,
    /// Largest delay (ns); default 5 s.
    pub max_ns: u64,
}

impl Default for Backoff {
    fn default() -> Self {
        Self {
            initial_ns: 100 * NS_PER_MS,
            max_ns: 5_000 * NS_PER_MS,
        }
    }
}

impl Backoff {
    /// The delay before retry number `failures` (0 for the first retry).
    pub fn delay(&self, failures: u32) -> u64 {
        let factor = 1u64.checked_shl(failures.min(63)).unwrap_or(u64::MAX);
        self.initial_ns.saturating_mul(factor).min(self.max_ns)
    }
}

/// Settings of a [`NodeCore`].
#[derive(Clone, Debug, PartialEq)]
pub struct NodeConfig {
    /// The node's name (as in its certificate).
    pub name: String,
    /// What it drives.
    pub role: Role,
    /// What it can do.
    pub capabilities: Capabilities,
    /// Reconnect policy.
    pub backoff: Backoff,
    /// Time from `connect` to the snapshot before giving up (ns); default 5 s.
    pub handshake_timeout_ns: u64,
}

impl NodeConfig {
    /// Defaults for a node named `name` with role `role`.
    pub fn new(name: impl Into<String>, role: Role) -> Self {
        Self {
            name: name.into(),
            role,
            capabilities: Capabilities::default(),
            backoff: Backoff::default(),
            handshake_timeout_ns: 5_000 * NS_PER_MS,
        }
    }
}

/// What the driver must do, in order.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeOutput {
    /// Open a connection to the master, then call [`NodeCore::connect`] on
    /// success or [`NodeCore::handle_disconnect`] on failure.
    Dial,
    /// Send this message to the master.
    Transmit(Message),
    /// Close the connection after flushing (a Bye was queued just before,
    /// unless the master said Bye). Do not report its disconnect.
    Close {
        /// Why.
        reason: String,
    },
    /// Something for the renderer and logs.
    Event(NodeEvent),
}

/// What the renderer and logs need to know.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeEvent {
    /// The master accepted the node.
    Connected {
        /// The master's frame rate.
        target_hz: f32,
        /// The master's swap deadline (ms).
        deadline_ms: f32,
    },
    /// A new scene arrived (on join, rejoin or a scene change).
    SceneChanged {
        /// Its version.
        version: u64,
        /// The scene.
        scene: Arc<Showcase>,
        /// The captured reflectance maps of this version.
        maps: Arc<Vec<crate::capture::CapturedMap>>,
    },
    /// The master asks for a capture (`ShowPattern` or `CaptureFrames`):
    /// answer with [`NodeCore::answer_capture`].
    Capture(Box<Message>),
    /// A solution arrived (whole, or built from a delta), before any
    /// [`NodeEvent::Render`] that names it: do now what drawing with it
    /// needs (a field to build, a digest), so the first frame that names it
    /// does not carry that work on the frame clock's path.
    Illumination(Arc<Solution>),
    /// Render this frame, then call [`NodeCore::rendered`].
    Render {
        /// The frame state.
        frame: Box<FrameState>,
        /// The scene of `frame.scene_version`.
        scene: Arc<Showcase>,
        /// The solution of `frame.illumination_version`, if it names one.
        illumination: Option<Arc<Solution>>,
    },
    /// Present this rendered frame now, then call [`NodeCore::presented`].
    Present {
        /// The frame.
        frame: u64,
    },
    /// The connection is gone; frames not presented are dropped. A Dial
    /// follows after the backoff.
    Disconnected {
        /// Why.
        reason: String,
        /// When the next Dial is due (node clock, ns).
        retry_at_ns: u64,
    },
}

/// A call that does not fit the node's state.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NodeError {
    /// `rendered` for a frame that is not the next one to render.
    #[error("frame {frame} is not the next frame to render (that is {expected:?})")]
    UnexpectedRender {
        /// The frame given.
        frame: u64,
        /// The next frame to render, if any.
        expected: Option<u64>,
    },
    /// `presented` for a frame that is not the next one to present.
    #[error("frame {frame} is not the next frame to present (that is {expected:?})")]
    UnexpectedPresent {
        /// The frame given.
        frame: u64,
        /// The next frame to present, if any.
        expected: Option<u64>,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Link {
    /// Waiting to dial at `retry_at`.
    Idle { retry_at: u64 },
    /// Dial requested; waiting for `connect` or `handle_disconnect`.
    Dialing,
    /// Hello sent at `since`.
    AwaitWelcome { since: u64 },
    /// Welcome received; the snapshot is next.
    AwaitSnapshot { since: u64 },
    /// Snapshot received: frames flow.
    Live,
}

/// One version of the global-illumination solution, as a node holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// Its version.
    pub version: u64,
    /// The scene version it was solved for.
    pub scene_version: u64,
    /// How that scene is meshed.
    pub mesh: IlluminationMesh,
    /// Per element.
    pub values: Vec<ElementLight>,
}

#[derive(Debug)]
struct PendingFrame {
    frame: u64,
    scene_version: u64,
    illumination_version: Option<u64>,
    /// The frame and its scene until its `Render` is announced (it waits
    /// for its solution).
    unannounced: Option<(Box<FrameState>, Arc<Showcase>)>,
    ready_at: Option<u64>,
    render_ns: u64,
    swap_at: Option<u64>,
}

#[derive(Debug)]
struct Presenting {
    frame: u64,
    render_ns: u64,
    barrier_wait_ns: u64,
}

/// A node's sans-IO core.
#[derive(Debug)]
pub struct NodeCore {
    config: NodeConfig,
    link: Link,
    failures: u32,
    scenes: BTreeMap<u64, Arc<Showcase>>,
    solutions: BTreeMap<u64, Arc<Solution>>,
    /// The version asked for in an unanswered [`IlluminationResync`].
    resync: Option<u64>,
    last_frame: Option<u64>,
    /// The newest solution version a frame named. Later frames name it or
    /// any newer version the master sent (a new one is named once every
    /// node holds it), so those are kept.
    last_named: Option<u64>,
    pending: VecDeque<PendingFrame>,
    presenting: VecDeque<Presenting>,
    last_presented: Option<u64>,
    out: VecDeque<NodeOutput>,
}

impl NodeCore {
    /// A node that wants to dial at once (the first output is a Dial).
    pub fn new(config: NodeConfig) -> Self {
        Self {
            config,
            link: Link::Dialing,
            failures: 0,
            scenes: BTreeMap::new(),
            solutions: BTreeMap::new(),
            resync: None,
            last_frame: None,
            last_named: None,
            pending: VecDeque::new(),
            presenting: VecDeque::new(),
            last_presented: None,
            out: VecDeque::from([NodeOutput::Dial]),
        }
    }

    /// The settings.
    pub fn config(&self) -> &NodeConfig {
        &self.config
    }

    /// Whether the master's snapshot has arrived on the current connection.
    pub fn is_live(&self) -> bool {
        self.link == Link::Live
    }

    /// The newest presented frame (across connections).
    pub fn last_presented(&self) -> Option<u64> {
        self.last_presented
    }

    /// Failed or lost connections since the last Welcome.
    pub fn failures(&self) -> u32 {
        self.failures
    }

    /// The transport connected (after a Dial): sends Hello.
    pub fn connect(&mut self, now: u64) {
        self.reset_session();
        self.link = Link::AwaitWelcome { since: now };
        self.transmit(Message::Hello(Hello {
            protocol_version: PROTOCOL_VERSION,
            node: self.config.name.clone(),
            role: self.config.role,
            capabilities: self.config.capabilities.clone(),
        }));
    }

    /// The dial failed or the connection was lost. Ignored while already
    /// waiting to dial.
    pub fn handle_disconnect(&mut self, now: u64, reason: &str) {
        if matches!(self.link, Link::Idle { .. }) {
            return;
        }
        self.drop_link(now, reason.to_string());
    }

    /// A decoded message from the master.
    pub fn handle_message(&mut self, now: u64, message: Message) {
        match (self.link, message) {
            (Link::Idle { .. } | Link::Dialing, _) => {} // Not connected: stale data.
            (_, Message::Bye(Bye { reason })) => {
                self.out.push_back(NodeOutput::Close {
                    reason: format!("master said bye: {reason}"),
                });
                self.drop_link(now, format!("master said bye: {reason}"));
            }
            (Link::AwaitWelcome { .. }, Message::Welcome(w)) => self.welcome(now, w),
            (Link::AwaitSnapshot { .. } | Link::Live, Message::SceneSnapshot(s)) => {
                self.snapshot(now, *s)
            }
            (Link::AwaitSnapshot { .. } | Link::Live, Message::ClockProbe(p)) => {
                self.clock_probe(now, p)
            }
            (Link::AwaitSnapshot { .. } | Link::Live, Message::Illumination(i)) => {
                self.illumination(now, *i)
            }
            (Link::Live, Message::FrameState(f)) => self.frame_state(now, *f),
            (Link::Live, Message::Swap(s)) => self.swap(now, s),
            (Link::Live, m @ (Message::ShowPattern(_) | Message::CaptureFrames(_))) => {
                self.event(NodeEvent::Capture(Box::new(m)))
            }
            (link, m) => {
                let state = match link {
                    Link::AwaitWelcome { .. } => "before Welcome",
                    Link::AwaitSnapshot { .. } => "before the snapshot",
                    _ => "from the master",
                };
                self.violation(now, format!("unexpected {} {state}", m.kind()));
            }
        }
    }

    /// When [`Self::handle_timeout`] must be called next.
    pub fn poll_timeout(&self) -> Option<u64> {
        match self.link {
            Link::Idle { retry_at } => Some(retry_at),
            Link::AwaitWelcome { since } | Link::AwaitSnapshot { since } => {
                Some(since.saturating_add(self.config.handshake_timeout_ns))
            }
            Link::Dialing | Link::Live => None,
        }
    }

    /// Time has reached `now`: dial when the backoff has passed, give up a
    /// handshake that took too long.
    pub fn handle_timeout(&mut self, now: u64) {
        match self.link {
            Link::Idle { retry_at } if now >= retry_at => {
                self.link = Link::Dialing;
                self.out.push_back(NodeOutput::Dial);
            }
            Link::AwaitWelcome { since } | Link::AwaitSnapshot { since }
                if now >= since.saturating_add(self.config.handshake_timeout_ns) =>
            {
                let reason = format!("no snapshot within {:.1} ms of connecting", ms(now - since));
                self.close(now, reason);
            }
            _ => {}
        }
    }

    /// The next output, in order.
    pub fn poll(&mut self) -> Option<NodeOutput> {
        self.out.pop_front()
    }

    /// The renderer finished `frame` (the oldest one not yet rendered) in
    /// `render_ns`: sends Ready, and presents at once if its Swap already came.
    pub fn rendered(
        &mut self,
        now: u64,
        frame: u64,
        output_hash: u64,
        render_ns: u64,
    ) -> Result<(), NodeError> {
        let next = self.pending.iter_mut().find(|p| p.ready_at.is_none());
        let Some(p) = next.filter(|p| p.frame == frame && self.link == Link::Live) else {
            let expected = self.pending.iter().find(|p| p.ready_at.is_none());
            return Err(NodeError::UnexpectedRender {
                frame,
                expected: expected.map(|p| p.frame),
            });
        };
        p.ready_at = Some(now);
        p.render_ns = render_ns;
        self.transmit(Message::Ready(Ready { frame, output_hash }));
        self.present_ready();
        Ok(())
    }

    /// `frame` (the oldest one announced by `Present`) is on screen: sends NodeStats.
    pub fn presented(&mut self, now: u64, frame: u64) -> Result<(), NodeError> {
        let expected = self.presenting.front().map(|p| p.frame);
        if expected != Some(frame) {
            return Err(NodeError::UnexpectedPresent { frame, expected });
        }
        let Some(p) = self.presenting.pop_front() else {
            return Err(NodeError::UnexpectedPresent { frame, expected });
        };
        self.transmit(Message::NodeStats(NodeStats {
            frame,
            render_ms: ms(p.render_ns) as f32,
            barrier_wait_ms: ms(p.barrier_wait_ns) as f32,
            present_time_ns: now,
        }));
        Ok(())
    }

    /// Answer a capture request (`PatternShown`, `FrameChunk` or
    /// `CaptureFailed`); dropped unless the node is live (the master
    /// forgot the request with the connection).
    pub fn answer_capture(&mut self, message: Message) {
        if matches!(
            message,
            Message::PatternShown(_) | Message::FrameChunk(_) | Message::CaptureFailed(_)
        ) && self.is_live()
        {
            self.transmit(message);
        }
    }

    fn transmit(&mut self, message: Message) {
        self.out.push_back(NodeOutput::Transmit(message));
    }

    fn event(&mut self, event: NodeEvent) {
        self.out.push_back(NodeOutput::Event(event));
    }

    fn reset_session(&mut self) {
        self.scenes.clear();
        self.solutions.clear();
        self.resync = None;
        self.last_frame = None;
        self.last_named = None;
        self.pending.clear();
        self.presenting.clear();
    }

    /// Forget the connection and schedule the next dial.
    fn drop_link(&mut self, now: u64, reason: String) {
        let retry_at = now.saturating_add(self.config.backoff.delay(self.failures));
        self.failures = self.failures.saturating_add(1);
        self.link = Link::Idle { retry_at };
        self.reset_session();
        tracing::info!(node = %self.config.name, %reason, retry_at, "disconnected");
        self.event(NodeEvent::Disconnected {
            reason,
            retry_at_ns: retry_at,
        });
    }

    /// Close the connection ourselves, with a Bye.
    fn close(&mut self, now: u64, reason: String) {
        self.transmit(Message::Bye(Bye {
            reason: reason.clone(),
        }));
        self.out.push_back(NodeOutput::Close {
            reason: reason.clone(),
        });
        self.drop_link(now, reason);
    }

    fn violation(&mut self, now: u64, detail: String) {
        tracing::warn!(node = %self.config.name, %detail, "protocol violation by the master");
        self.close(now, format!("protocol violation by the master: {detail}"));
    }

    fn welcome(&mut self, now: u64, w: Welcome) {
        if w.protocol_version != PROTOCOL_VERSION {
            let reason = format!(
                "master speaks protocol version {}, node '{}' speaks {PROTOCOL_VERSION}",
                w.protocol_version, self.config.name
            );
            self.close(now, reason);
            return;
        }
        self.failures = 0;
        self.link = Link::AwaitSnapshot { since: now };
        self.event(NodeEvent::Connected {
            target_hz: w.target_hz,
            deadline_ms: w.deadline_ms,
        });
    }

    fn snapshot(&mut self, now: u64, s: SceneSnapshot) {
        if let Some((&newest, _)) = self.scenes.last_key_value()
            && s.version <= newest
        {
            let detail = format!("snapshot version {} after version {newest}", s.version);
            self.violation(now, detail);
            return;
        }
        let scene = Arc::new(s.showcase);
        self.scenes.insert(s.version, scene.clone());
        self.link = Link::Live;
        self.event(NodeEvent::SceneChanged {
            version: s.version,
            scene,
            maps: Arc::new(s.maps),
        });
        if let Some(current) = s.current {
            self.frame_state(now, current);
        }
        self.prune_scenes();
    }

    fn clock_probe(&mut self, now: u64, p: ClockProbe) {
        self.transmit(Message::ClockReply(ClockReply {
            id: p.id,
            master_send_ns: p.master_send_ns,
            node_recv_ns: now,
            node_send_ns: now,
        }));
    }

    fn frame_state(&mut self, now: u64, f: FrameState) {
        if let Some(last) = self.last_frame
            && f.frame <= last
        {
            let detail = format!("frame {} after frame {last}", f.frame);
            self.violation(now, detail);
            return;
        }
        let Some(scene) = self.scenes.get(&f.scene_version).cloned() else {
            let detail = format!(
                "frame {} refers to scene version {}, which this node was not sent",
                f.frame, f.scene_version
            );
            self.violation(now, detail);
            return;
        };
        if let Err(e) = f.validate_against(&scene) {
            self.violation(now, format!("frame {} is invalid: {e}", f.frame));
            return;
        }
        if let Some(s) = f
            .illumination_version
            .and_then(|v| self.solutions.get(&v))
            .filter(|s| s.scene_version != f.scene_version)
        {
            let detail = format!(
                "frame {} of scene version {} names illumination version {}, solved for scene version {}",
                f.frame, f.scene_version, s.version, s.scene_version
            );
            self.violation(now, detail);
            return;
        }
        if self.pending.len() >= MAX_PENDING_FRAMES {
            let detail = format!("more than {MAX_PENDING_FRAMES} frames without a Swap");
            self.violation(now, detail);
            return;
        }
        self.last_frame = Some(f.frame);
        self.last_named = self.last_named.max(f.illumination_version);
        self.pending.push_back(PendingFrame {
            frame: f.frame,
            scene_version: f.scene_version,
            illumination_version: f.illumination_version,
            unannounced: Some((Box::new(f), scene)),
            ready_at: None,
            render_ns: 0,
            swap_at: None,
        });
        self.announce();
    }

    /// Announce `Render`, in order, for every waiting frame whose solution
    /// is held; ask for full copies when the first waiting frame names a
    /// version that will not come by itself.
    fn announce(&mut self) {
        let mut renders = Vec::new();
        let mut missing = None;
        for p in self.pending.iter_mut() {
            if p.unannounced.is_none() {
                continue;
            }
            let illumination = match p.illumination_version {
                None => None,
                Some(v) => match self.solutions.get(&v) {
                    Some(s) => Some(s.clone()),
                    None => {
                        missing = Some(v);
                        break;
                    }
                },
            };
            if let Some((frame, scene)) = p.unannounced.take() {
                renders.push(NodeEvent::Render {
                    frame,
                    scene,
                    illumination,
                });
            }
        }
        for r in renders {
            self.event(r);
        }
        // The master sends a solution before any frame naming it: a frame
        // that names one not held means it was lost (or its delta could
        // not be applied).
        if let Some(v) = missing {
            self.request_resync(v);
        }
    }

    fn request_resync(&mut self, version: u64) {
        if self.resync.is_some_and(|r| r <= version) {
            return;
        }
        self.resync = Some(version);
        tracing::info!(node = %self.config.name, version, "asking for full illumination copies");
        self.transmit(Message::IlluminationResync(IlluminationResync { version }));
    }

    fn illumination(&mut self, now: u64, i: Illumination) {
        let solution = match i.body {
            IlluminationBody::Full { mesh, values } => Solution {
                version: i.version,
                scene_version: i.scene_version,
                mesh,
                values,
            },
            IlluminationBody::Delta { base, changes } => {
                if base >= i.version {
                    let detail = format!(
                        "illumination version {} is a delta on the later version {base}",
                        i.version
                    );
                    self.violation(now, detail);
                    return;
                }
                let Some(old) = self.solutions.get(&base).cloned() else {
                    // Its base never came: wait for the full copies.
                    self.request_resync(i.version);
                    return;
                };
                if old.scene_version != i.scene_version {
                    let detail = format!(
                        "illumination version {} of scene version {} is a delta on version {base} of scene version {}",
                        i.version, i.scene_version, old.scene_version
                    );
                    self.violation(now, detail);
                    return;
                }
                let mut values = old.values.clone();
                for c in &changes {
                    let Some(v) = values.get_mut(c.element as usize) else {
                        let detail = format!(
                            "illumination version {} changes element {} of {}",
                            i.version,
                            c.element,
                            old.values.len()
                        );
                        self.violation(now, detail);
                        return;
                    };
                    *v = c.value;
                }
                Solution {
                    version: i.version,
                    scene_version: i.scene_version,
                    mesh: old.mesh,
                    values,
                }
            }
        };
        if self.resync.is_some_and(|r| solution.version >= r) {
            self.resync = None;
        }
        let solution = Arc::new(solution);
        self.solutions.insert(solution.version, solution.clone());
        let version = solution.version;
        self.event(NodeEvent::Illumination(solution));
        // After the event: a driver prepares the solution before it sends
        // this, so the master names it only once it is ready here.
        self.transmit(Message::IlluminationReady(IlluminationReady { version }));
        self.announce();
        self.prune_solutions();
    }

    fn swap(&mut self, now: u64, s: Swap) {
        let next = self.pending.iter_mut().find(|p| p.swap_at.is_none());
        match next {
            Some(p) if p.frame == s.frame => p.swap_at = Some(now),
            other => {
                let expected = other.map_or_else(|| "none".to_string(), |p| p.frame.to_string());
                let detail = format!(
                    "Swap for frame {}, the next frame to swap is {expected}",
                    s.frame
                );
                self.violation(now, detail);
                return;
            }
        }
        self.present_ready();
    }

    /// Present, in order, every frame that is rendered and swapped.
    fn present_ready(&mut self) {
        while let Some(p) = self.pending.front() {
            let (Some(ready_at), Some(swap_at)) = (p.ready_at, p.swap_at) else {
                break;
            };
            let Some(p) = self.pending.pop_front() else {
                break;
            };
            self.presenting.push_back(Presenting {
                frame: p.frame,
                render_ns: p.render_ns,
                barrier_wait_ns: swap_at.saturating_sub(ready_at),
            });
            self.last_presented = Some(p.frame);
            self.event(NodeEvent::Present { frame: p.frame });
        }
        self.prune_scenes();
        self.prune_solutions();
    }

    /// Keep the solutions frames may still name: those pending frames
    /// name, the newest one a frame named and every newer one.
    fn prune_solutions(&mut self) {
        let (pending, named) = (&self.pending, self.last_named);
        self.solutions.retain(|v, _| {
            named.is_none_or(|n| *v >= n)
                || pending.iter().any(|p| p.illumination_version == Some(*v))
        });
    }

    /// Keep the newest scene and those pending frames refer to.
    fn prune_scenes(&mut self) {
        let newest = self.scenes.last_key_value().map(|(v, _)| *v);
        let pending = &self.pending;
        self.scenes
            .retain(|v, _| Some(*v) == newest || pending.iter().any(|p| p.scene_version == *v));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_and_caps() {
        let b = Backoff {
            initial_ns: 100,
            max_ns: 1_000,
        };
        let delays: Vec<u64> = (0..6).map(|i| b.delay(i)).collect();
        assert_eq!(delays, [100, 200, 400, 800, 1_000, 1_000]);
        assert_eq!(b.delay(u32::MAX), 1_000);
    }

    #[test]
    fn render_and_present_out_of_order_are_refused() {
        let mut node = NodeCore::new(NodeConfig::new("n", Role::Face));
        assert_eq!(node.poll(), Some(NodeOutput::Dial));
        node.connect(0);
        assert_eq!(
            node.rendered(1, 3, 0, 0),
            Err(NodeError::UnexpectedRender {
                frame: 3,
                expected: None
            })
        );
        assert_eq!(
            node.presented(1, 3),
            Err(NodeError::UnexpectedPresent {
                frame: 3,
                expected: None
            })
        );
    }
}
