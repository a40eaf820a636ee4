//! An in-memory cluster on virtual time, like quinn-proto's `Pair::drive`:
//! one [`MasterCore`] and K [`NodeCore`]s, links with per-direction delays,
//! every message encoded with [`encode_frame`] and decoded with
//! [`decode_frame`], nodes that render in a fixed time, a frame clock, and
//! faults (node crash, master restart, raw bytes). No sockets, no sleeps:
//! time jumps to the next thing that happens, and every loop is bounded.

use super::{
    CloseReason, ConnId, MasterConfig, MasterCore, MasterEvent, MasterOutput, NodeConfig, NodeCore,
    NodeEvent, NodeOutput, PresentReport, SwapReport,
};
use crate::codec::{MAX_FRAME_LEN, decode_frame, encode_frame};
use crate::message::{ElementLight, Message, Role};
use crate::scene::{FrameState, Light, LightSource, Observer, Pose, Showcase};
use glam::{Quat, Vec3};
use std::collections::BTreeMap;

mod drive;

/// Steps one call to [`Cluster::run_until`] may take.
const MAX_STEPS: usize = 5_000_000;

/// The virtual clock starts here, so node clocks may lag it without going negative.
pub const EPOCH_NS: u64 = 1_000_000_000_000;

/// A harness loop did not settle within its bound.
#[derive(Debug, thiserror::Error)]
#[error("the simulated cluster did not settle within {steps} steps at t = {now_ns} ns")]
pub struct StepLimit {
    /// Steps taken.
    pub steps: usize,
    /// Virtual time reached.
    pub now_ns: u64,
}

/// How one simulated node behaves.
#[derive(Clone, Debug)]
pub struct NodeSpec {
    /// The node's configuration (name, role, backoff...).
    pub config: NodeConfig,
    /// One-way delay node to master (ns).
    pub up_ns: u64,
    /// One-way delay master to node (ns).
    pub down_ns: u64,
    /// Time to render one frame (ns).
    pub render_ns: u64,
    /// The node's clock minus the virtual clock (ns).
    pub clock_offset_ns: i64,
}

impl NodeSpec {
    /// A face node with 100 us links, 2 ms renders and a clock that agrees with the master's.
    pub fn new(name: &str) -> Self {
        Self {
            config: NodeConfig::new(name, Role::Face),
            up_ns: 100_000,
            down_ns: 100_000,
            render_ns: 2_000_000,
            clock_offset_ns: 0,
        }
    }
}

/// What a simulated node saw.
#[derive(Clone, Debug, Default)]
pub struct NodeLog {
    /// Frames rendered, with the scene version they were rendered against.
    pub rendered: Vec<FrameState>,
    /// Frames presented, with the virtual time.
    pub presented: Vec<(u64, u64)>,
    /// Scene versions received.
    pub scenes: Vec<u64>,
    /// Virtual times of each Dial.
    pub dials: Vec<u64>,
    /// Virtual times of each Welcome.
    pub connected: Vec<u64>,
    /// Disconnect reasons.
    pub disconnects: Vec<String>,
    /// Per rendered frame that named a global-illumination solution: the
    /// frame, the solution's version and a digest of its values.
    pub illuminated: Vec<(u64, u64, u64)>,
    /// The versions of the solutions that arrived
    /// ([`crate::session::NodeEvent::Illumination`]), in order.
    pub arrived: Vec<u64>,
    /// Frames told to render with a solution whose arrival was not
    /// announced first.
    pub unprepared: Vec<u64>,
    /// The versions of each illumination resync the node asked for.
    pub resyncs: Vec<u64>,
}

/// A simulated node process.
#[derive(Debug)]
pub struct SimNode {
    /// Its behaviour.
    pub spec: NodeSpec,
    /// Its core.
    pub core: NodeCore,
    /// The connection it holds, if any.
    pub conn: Option<ConnId>,
    /// The process runs (false after a crash).
    pub alive: bool,
    /// What it saw.
    pub log: NodeLog,
    busy_until: u64,
}

impl SimNode {
    /// Frames presented, in order.
    pub fn presented_frames(&self) -> Vec<u64> {
        self.log.presented.iter().map(|p| p.0).collect()
    }

    fn clock(&self, now: u64) -> u64 {
        (now as i128 + self.spec.clock_offset_ns as i128).max(0) as u64
    }

    fn virtual_time(&self, t: u64) -> u64 {
        (t as i128 - self.spec.clock_offset_ns as i128).max(0) as u64
    }
}

/// What the master side saw.
#[derive(Clone, Debug, Default)]
pub struct MasterLog {
    /// Every frame submitted, by number (a restarted master overwrites).
    pub submitted: BTreeMap<u64, FrameState>,
    /// Swap reports, in order.
    pub swaps: Vec<SwapReport>,
    /// Present reports, in order.
    pub presents: Vec<PresentReport>,
    /// Closed connections: node name (if any) and reason.
    pub closed: Vec<(Option<String>, CloseReason)>,
    /// Joins: node, frame in its snapshot, virtual time.
    pub joined: Vec<(String, Option<u64>, u64)>,
    /// Frame-clock ticks skipped because the pipeline was full or the master down.
    pub dropped_ticks: u64,
}

#[derive(Debug)]
enum Delivery {
    ToMaster {
        conn: ConnId,
        bytes: Vec<u8>,
    },
    MasterLost {
        conn: ConnId,
    },
    ToNode {
        node: usize,
        conn: ConnId,
        bytes: Vec<u8>,
    },
    NodeLost {
        node: usize,
        conn: ConnId,
        reason: String,
    },
    DialFailed {
        node: usize,
        dial: u64,
    },
    Rendered {
        node: usize,
        conn: ConnId,
        frame: u64,
        hash: u64,
    },
}

/// One master and K nodes on virtual time.
#[derive(Debug)]
pub struct Cluster {
    /// Virtual time (ns).
    pub now: u64,
    /// The master, `None` while it is down.
    pub master: Option<MasterCore>,
    /// Settings for (re)starting the master.
    pub master_config: MasterConfig,
    /// The scene a (re)started master serves.
    pub scene: Showcase,
    /// The nodes.
    pub nodes: Vec<SimNode>,
    /// What the master saw.
    pub log: MasterLog,
    /// Frame period of the frame clock (ns); `None` stops the clock.
    pub frame_period_ns: Option<u64>,
    next_tick: u64,
    queue: BTreeMap<(u64, u64), Delivery>,
    seq: u64,
    next_conn: u64,
    conn_owner: BTreeMap<ConnId, usize>,
    /// Per node: drop the next master-to-node message of this kind (a
    /// lost message).
    drops: Vec<(usize, &'static str)>,
    /// Per node: node-to-master messages of this kind that never arrive.
    muted: Vec<(usize, &'static str)>,
}

/// A scene with one observer, so frames carry a head pose.
pub fn test_scene() -> Showcase {
    Showcase {
        name: "session-test".into(),
        observers: vec![Observer {
            name: "viewer".into(),
            head: Pose::default(),
            ipd: Observer::DEFAULT_IPD,
        }],
        ..Showcase::default()
    }
}

/// A deterministic frame state for frame `n`: the head and a point light
/// move with the frame, so every frame differs.
pub fn test_frame(n: u64, scene_version: u64, time_ns: u64) -> FrameState {
    let t = n as f32 * 0.01;
    FrameState {
        frame: n,
        time_s: n as f64 / 60.0,
        scene_version,
        heads: vec![Pose {
            position: Vec3::new(t.sin() * 0.3, 0.4, 0.8 + t.cos() * 0.1),
            orientation: Quat::from_rotation_y(t.sin() * 0.2),
        }],
        lights: vec![LightSource {
            name: "key".into(),
            light: Light::Point {
                position: Vec3::new(t.cos(), 1.0, t.sin()),
                intensity: Vec3::splat(1.0 + (n % 7) as f32),
            },
        }],
        object_transforms: Vec::new(),
        tracking_time_ns: Some(time_ns),
        illumination_version: None,
    }
}

/// The output hash a simulated node reports: BLAKE3 of the encoded frame.
pub fn frame_hash(frame: &FrameState) -> u64 {
    let bytes = encode_frame(&Message::FrameState(Box::new(frame.clone())), MAX_FRAME_LEN)
        .unwrap_or_default();
    let h = blake3::hash(&bytes);
    u64::from_le_bytes(h.as_bytes()[..8].try_into().unwrap_or_default())
}

/// A digest of a global-illumination solution's values (BLAKE3 of their
/// bits).
pub fn values_digest(values: &[ElementLight]) -> u64 {
    let mut h = blake3::Hasher::new();
    for v in values.iter().flat_map(ElementLight::channels) {
        h.update(&v.to_le_bytes());
    }
    u64::from_le_bytes(h.finalize().as_bytes()[..8].try_into().unwrap_or_default())
}

impl Cluster {
    /// A running master (scene [`test_scene`]) and these nodes, all about
    /// to dial; the frame clock runs at `frame_period_ns` from the start.
    pub fn new(master_config: MasterConfig, nodes: Vec<NodeSpec>, frame_period_ns: u64) -> Self {
        let scene = test_scene();
        let master = MasterCore::new(master_config.clone(), scene.clone()).ok();
        let nodes = nodes
            .into_iter()
            .map(|spec| SimNode {
                core: NodeCore::new(spec.config.clone()),
                spec,
                conn: None,
                alive: true,
                log: NodeLog::default(),
                busy_until: 0,
            })
            .collect();
        Self {
            now: EPOCH_NS,
            master,
            master_config,
            scene,
            nodes,
            log: MasterLog::default(),
            frame_period_ns: Some(frame_period_ns),
            next_tick: EPOCH_NS,
            queue: BTreeMap::new(),
            seq: 0,
            next_conn: 1,
            conn_owner: BTreeMap::new(),
            drops: Vec::new(),
            muted: Vec::new(),
        }
    }

    /// Publish a global-illumination solution of `values` (on a fixed
    /// mesh) at the master; frames from the next tick name it.
    pub fn set_illumination(&mut self, values: Vec<ElementLight>) -> Option<u64> {
        let now = self.now;
        let mesh = crate::message::IlluminationMesh {
            max_patch_area: 0.01,
            element_depth: 1,
            min_element_area: 0.0,
        };
        self.master
            .as_mut()?
            .set_illumination(now, mesh, values)
            .ok()
    }

    /// Lose the next master-to-node message of kind `kind`
    /// ([`Message::kind`]) on its way to node `i`.
    pub fn drop_next_to_node(&mut self, i: usize, kind: &'static str) {
        self.drops.push((i, kind));
    }

    /// Lose every node-to-master message of kind `kind` from node `i`
    /// from now on.
    pub fn mute_to_master(&mut self, i: usize, kind: &'static str) {
        self.muted.push((i, kind));
    }

    /// Send `bytes` on node `i`'s connection from the master, bypassing the
    /// master's core.
    pub fn inject_bytes_to_node(&mut self, i: usize, bytes: Vec<u8>) {
        if let Some(conn) = self.nodes[i].conn {
            let at = self.now + self.nodes[i].spec.down_ns;
            self.schedule(
                at,
                Delivery::ToNode {
                    node: i,
                    conn,
                    bytes,
                },
            );
        }
    }

    /// Send `message` to node `i` from the master, bypassing its core.
    pub fn inject_message_to_node(&mut self, i: usize, message: &Message) {
        if let Ok(bytes) = encode_frame(message, MAX_FRAME_LEN) {
            self.inject_bytes_to_node(i, bytes);
        }
    }

    /// The index of the node named `name`.
    pub fn node_index(&self, name: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.spec.config.name == name)
    }

    /// Run until virtual time `until` (absolute ns).
    pub fn run_until(&mut self, until: u64) -> Result<(), StepLimit> {
        for steps in 0..MAX_STEPS {
            self.pump(steps)?;
            match self.next_time() {
                Some(t) if t <= until => {
                    self.now = self.now.max(t);
                    self.step();
                }
                _ => {
                    self.now = self.now.max(until);
                    return Ok(());
                }
            }
        }
        Err(StepLimit {
            steps: MAX_STEPS,
            now_ns: self.now,
        })
    }

    /// Run for `dt` ns of virtual time.
    pub fn run_for(&mut self, dt: u64) -> Result<(), StepLimit> {
        self.run_until(self.now.saturating_add(dt))
    }

    /// Run until the master has swapped `frame` (or `limit_ns` of virtual time passed).
    pub fn run_until_swapped(&mut self, frame: u64, limit_ns: u64) -> Result<bool, StepLimit> {
        let end = self.now.saturating_add(limit_ns);
        let step = self.frame_period_ns.unwrap_or(1_000_000).max(1);
        while self.now < end {
            if self.master_swapped(frame) {
                return Ok(true);
            }
            self.run_until(self.now.saturating_add(step).min(end))?;
        }
        Ok(self.master_swapped(frame))
    }

    fn master_swapped(&self, frame: u64) -> bool {
        self.master
            .as_ref()
            .and_then(MasterCore::swapped_upto)
            .is_some_and(|s| s >= frame)
    }

    /// Crash node `i`. With `tell_master`, the transport reports the loss
    /// to the master after the link delay; otherwise the master only
    /// notices through the swap deadline.
    pub fn crash_node(&mut self, i: usize, tell_master: bool) {
        let node = &mut self.nodes[i];
        node.alive = false;
        if let Some(conn) = node.conn.take() {
            let at = self.now + node.spec.up_ns;
            if tell_master {
                self.schedule(at, Delivery::MasterLost { conn });
            }
        }
    }

    /// Start node `i` again as a fresh process (it dials at once).
    pub fn restart_node(&mut self, i: usize) {
        let node = &mut self.nodes[i];
        node.core = NodeCore::new(node.spec.config.clone());
        node.alive = true;
        node.conn = None;
        node.busy_until = 0;
    }

    /// Stop the master: every node's connection drops after its link delay.
    pub fn stop_master(&mut self) {
        self.master = None;
        for (i, node) in self.nodes.iter_mut().enumerate() {
            if let Some(conn) = node.conn {
                let at = self.now + node.spec.down_ns;
                self.queue.insert(
                    (at, self.seq),
                    Delivery::NodeLost {
                        node: i,
                        conn,
                        reason: "master stopped".into(),
                    },
                );
                self.seq += 1;
            }
        }
    }

    /// Start a fresh master (scene version 1, frame numbers from 0).
    pub fn start_master(&mut self) {
        self.master = MasterCore::new(self.master_config.clone(), self.scene.clone()).ok();
        self.next_tick = self.now;
    }

    /// Give the master a new scene (and keep it for a restarted master).
    pub fn set_scene(&mut self, scene: Showcase) -> Option<u64> {
        self.scene = scene.clone();
        let now = self.now;
        self.master.as_mut()?.set_scene(now, scene).ok()
    }

    /// Send raw bytes on node `i`'s connection to the master.
    pub fn inject_bytes_to_master(&mut self, i: usize, bytes: Vec<u8>) {
        if let Some(conn) = self.nodes[i].conn {
            let at = self.now + self.nodes[i].spec.up_ns;
            self.schedule(at, Delivery::ToMaster { conn, bytes });
        }
    }

    /// Send a message on node `i`'s connection to the master, bypassing its core.
    pub fn inject_message_to_master(&mut self, i: usize, message: &Message) {
        if let Ok(bytes) = encode_frame(message, MAX_FRAME_LEN) {
            self.inject_bytes_to_master(i, bytes);
        }
    }
}
