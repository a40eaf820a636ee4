//! The master's capture requests through the running cluster: a
//! synchronous [`CaptureLink`] (for the capture pipeline's thread) sends
//! [`CaptureCommand`]s into the server loop, which sends them to the nodes
//! through the core and answers each when its node does ([`Requests`]):
//! a pattern shown, a capture's frames put together from their chunks
//! ([`FrameAssembler`]), or the node's failure, disconnection or a bad
//! chunk, in words that say what to change.

use showcase_proto::capture::{
    CaptureFrames, CapturedMap, FrameAssembler, FrameCodes, Pattern, ShowPattern,
};
use showcase_proto::session::{ConnId, MasterCore};
use showcase_proto::{Message, Role, Showcase};
use std::collections::HashMap;
use std::sync::mpsc as sync_mpsc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

type Reply<T> = sync_mpsc::Sender<Result<T, String>>;

/// What the capture job asks of the server loop.
pub enum CaptureCommand {
    /// The live nodes.
    Nodes(Reply<Vec<(String, Role)>>),
    /// Show a pattern on a projector node.
    Show {
        /// The node.
        node: String,
        /// The pattern.
        pattern: Pattern,
        /// Answered when the node shows it.
        reply: Reply<()>,
    },
    /// Capture frames on a camera node.
    Capture {
        /// The node.
        node: String,
        /// The request (its id is set by the loop).
        request: CaptureFrames,
        /// The camera's `(width, height)` as the master knows it.
        size: (u32, u32),
        /// Answered with every frame.
        reply: Reply<Vec<FrameCodes>>,
    },
    /// Replace the scene (version bump, snapshots to the nodes).
    SetScene {
        /// The scene.
        scene: Box<Showcase>,
        /// The new version.
        reply: Reply<u64>,
    },
    /// Publish captured maps (version bump, snapshots with them).
    PublishMaps {
        /// The maps.
        maps: Vec<CapturedMap>,
        /// The new version.
        reply: Reply<u64>,
    },
}

enum Pending {
    Show(Reply<()>),
    Capture(Box<FrameAssembler>, Reply<Vec<FrameCodes>>),
}

/// The server loop's outstanding requests, by id.
#[derive(Default)]
pub struct Requests {
    next_id: u64,
    pending: HashMap<u64, (ConnId, String, Pending)>,
}

impl Requests {
    /// Run a command on `core`.
    pub fn command(&mut self, core: &mut MasterCore, now: u64, command: CaptureCommand) {
        match command {
            CaptureCommand::Nodes(reply) => {
                let _ = reply.send(Ok(core.nodes().map(|n| (n.node, n.role)).collect()));
            }
            CaptureCommand::Show {
                node,
                pattern,
                reply,
            } => {
                let id = self.id();
                let m = Message::ShowPattern(Box::new(ShowPattern { id, pattern }));
                match core.send_capture(&node, m) {
                    Ok(conn) => {
                        self.pending.insert(id, (conn, node, Pending::Show(reply)));
                    }
                    Err(e) => {
                        let _ = reply.send(Err(e.to_string()));
                    }
                }
            }
            CaptureCommand::Capture {
                node,
                mut request,
                size,
                reply,
            } => {
                let id = self.id();
                request.id = id;
                match core.send_capture(&node, Message::CaptureFrames(request)) {
                    Ok(conn) => {
                        let a = FrameAssembler::new(id, request.count, Some(size));
                        self.pending
                            .insert(id, (conn, node, Pending::Capture(Box::new(a), reply)));
                    }
                    Err(e) => {
                        let _ = reply.send(Err(e.to_string()));
                    }
                }
            }
            CaptureCommand::SetScene { scene, reply } => {
                let _ = reply.send(core.set_scene(now, *scene).map_err(|e| e.to_string()));
            }
            CaptureCommand::PublishMaps { maps, reply } => {
                let _ = reply.send(core.set_maps(now, maps).map_err(|e| e.to_string()));
            }
        }
    }

    fn id(&mut self) -> u64 {
        self.next_id += 1;
        self.next_id
    }

    /// A node answered.
    pub fn answer(&mut self, conn: ConnId, node: &str, message: Message) {
        let id = match &message {
            Message::PatternShown(p) => p.id,
            Message::FrameChunk(c) => c.id,
            Message::CaptureFailed(f) => f.id,
            _ => return,
        };
        let Some((c, _, _)) = self.pending.get(&id) else {
            tracing::warn!(
                node,
                id,
                kind = message.kind(),
                "answer to no pending capture request"
            );
            return;
        };
        if *c != conn {
            tracing::warn!(node, id, "capture answer from another connection");
            return;
        }
        let (conn, name, pending) = self.pending.remove(&id).expect("looked up above");
        match (pending, message) {
            (Pending::Show(reply), Message::PatternShown(_)) => {
                let _ = reply.send(Ok(()));
            }
            (Pending::Show(reply), Message::CaptureFailed(f)) => {
                let _ = reply.send(Err(f.reason));
            }
            (Pending::Capture(_, reply), Message::CaptureFailed(f)) => {
                let _ = reply.send(Err(f.reason));
            }
            (Pending::Capture(mut a, reply), Message::FrameChunk(chunk)) => match a.push(&chunk) {
                Ok(()) if a.is_complete() => {
                    let _ = reply.send(Ok(a.take()));
                }
                Ok(()) => {
                    self.pending
                        .insert(id, (conn, name, Pending::Capture(a, reply)));
                }
                Err(e) => {
                    let _ = reply.send(Err(format!("node {name}: {e}")));
                }
            },
            (Pending::Show(reply), m) => {
                let _ = reply.send(Err(format!(
                    "node {name} answered a pattern with {}",
                    m.kind()
                )));
            }
            (Pending::Capture(_, reply), m) => {
                let _ = reply.send(Err(format!(
                    "node {name} answered a capture with {}",
                    m.kind()
                )));
            }
        }
    }

    /// `conn` closed: its requests fail.
    pub fn closed(&mut self, conn: ConnId, node: Option<&str>, reason: &str) {
        let ids: Vec<u64> = self
            .pending
            .iter()
            .filter(|(_, (c, _, _))| *c == conn)
            .map(|(id, _)| *id)
            .collect();
        for id in ids {
            let (_, name, p) = self.pending.remove(&id).expect("listed above");
            let why = format!(
                "node {} went away during the request ({reason}): restart it (showcase-node --config CLUSTER.toml --name {name}) and run the capture again",
                node.unwrap_or(&name)
            );
            match p {
                Pending::Show(r) => {
                    let _ = r.send(Err(why));
                }
                Pending::Capture(_, r) => {
                    let _ = r.send(Err(why));
                }
            }
        }
    }
}

/// The capture job's handle on the running cluster: blocking calls,
/// each bounded by `timeout`. Not for the server loop's own thread.
#[derive(Clone)]
pub struct CaptureLink {
    tx: mpsc::UnboundedSender<CaptureCommand>,
    /// Longest wait for one request's answer.
    pub timeout: Duration,
}

impl CaptureLink {
    /// A link and the receiver to give the server
    /// ([`super::Server::capture_from`]).
    pub fn new(timeout: Duration) -> (Self, mpsc::UnboundedReceiver<CaptureCommand>) {
        let (tx, rx) = mpsc::unbounded_channel();
        (Self { tx, timeout }, rx)
    }

    fn ask<T>(
        &self,
        what: &str,
        make: impl FnOnce(Reply<T>) -> CaptureCommand,
    ) -> anyhow::Result<T> {
        let (reply, answer) = sync_mpsc::channel();
        self.tx
            .send(make(reply))
            .map_err(|_| anyhow::anyhow!("{what}: the master's cluster loop has stopped"))?;
        match answer.recv_timeout(self.timeout) {
            Ok(r) => r.map_err(|e| anyhow::anyhow!("{what}: {e}")),
            Err(sync_mpsc::RecvTimeoutError::Timeout) => anyhow::bail!(
                "{what}: no answer in {:?}; check that the node is running and not stuck",
                self.timeout
            ),
            Err(sync_mpsc::RecvTimeoutError::Disconnected) => {
                anyhow::bail!("{what}: the master's cluster loop has stopped")
            }
        }
    }

    /// The live nodes.
    pub fn nodes(&self) -> anyhow::Result<Vec<(String, Role)>> {
        self.ask("listing the nodes", CaptureCommand::Nodes)
    }

    /// Wait until every `(name, role)` has joined, at most `timeout`.
    pub fn wait_for(&self, needed: &[(String, Role)], timeout: Duration) -> anyhow::Result<()> {
        let start = Instant::now();
        loop {
            let live = self.nodes()?;
            let missing: Vec<&(String, Role)> =
                needed.iter().filter(|n| !live.contains(n)).collect();
            let Some((name, role)) = missing.first() else {
                return Ok(());
            };
            if start.elapsed() >= timeout {
                anyhow::bail!(
                    "{role} node {name:?} is not connected after {:.0} s: start it (showcase-node --config CLUSTER.toml --name {name}) and check that it reaches the master",
                    timeout.as_secs_f64()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Projector node `node` shows `pattern`.
    pub fn show(&self, node: &str, pattern: Pattern) -> anyhow::Result<()> {
        let what = format!("showing {} on projector node {node:?}", pattern.describe());
        self.ask(&what, |reply| CaptureCommand::Show {
            node: node.into(),
            pattern,
            reply,
        })
    }

    /// Camera node `node` captures `request`'s frames at `size`.
    pub fn capture(
        &self,
        node: &str,
        request: CaptureFrames,
        size: (u32, u32),
    ) -> anyhow::Result<Vec<FrameCodes>> {
        let what = format!("capturing {} frames on camera node {node:?}", request.count);
        self.ask(&what, |reply| CaptureCommand::Capture {
            node: node.into(),
            request,
            size,
            reply,
        })
    }

    /// Replace the cluster's scene.
    pub fn set_scene(&self, scene: Showcase) -> anyhow::Result<u64> {
        self.ask("changing the scene", |reply| CaptureCommand::SetScene {
            scene: Box::new(scene),
            reply,
        })
    }

    /// Publish maps to the running cluster.
    pub fn publish_maps(&self, maps: Vec<CapturedMap>) -> anyhow::Result<u64> {
        self.ask("publishing the maps", |reply| CaptureCommand::PublishMaps {
            maps,
            reply,
        })
    }
}
