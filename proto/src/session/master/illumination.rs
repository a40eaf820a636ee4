//! The master's global-illumination solution: the versions it holds (the
//! newest, and every one a frame in flight or the newest frame names), how
//! a new version travels (a delta against the previous one when few
//! elements changed, else whole), what a joiner gets, and the full copies
//! a node that lost a delta asks for, and when frames start to name a new
//! version: once every live node said it holds and has prepared it
//! ([`IlluminationReady`]), or a swap deadline after it was published,
//! whichever comes first. Naming it at once put its transfer and the
//! nodes' preparation on the path of the first frame that names it.

use super::*;
use crate::message::{
    ElementChange, ElementLight, Illumination, IlluminationBody, IlluminationMesh,
    IlluminationReady, IlluminationResync,
};

/// A delta is sent only when at most this fraction of the elements
/// changed; above it the whole solution is barely larger.
const DELTA_FRACTION: usize = 4;

/// One version of the solution, as the master holds it.
#[derive(Debug)]
pub(super) struct HeldSolution {
    pub(super) version: u64,
    pub(super) scene_version: u64,
    pub(super) mesh: IlluminationMesh,
    pub(super) values: Arc<Vec<ElementLight>>,
}

impl HeldSolution {
    fn full(&self) -> Message {
        Message::Illumination(Box::new(Illumination {
            version: self.version,
            scene_version: self.scene_version,
            body: IlluminationBody::Full {
                mesh: self.mesh,
                values: (*self.values).clone(),
            },
        }))
    }
}

/// The solution's versions and which frames name them.
#[derive(Debug, Default)]
pub(super) struct IlluminationState {
    /// By version: the newest, and those frames kept below name.
    held: BTreeMap<u64, Arc<HeldSolution>>,
    /// The version each unswapped frame (and the newest frame) names.
    frames: BTreeMap<u64, u64>,
    next_version: u64,
    /// The version frames name now.
    named: Option<u64>,
    /// The newest version while some live node has not said it holds it,
    /// and when frames name it regardless (published plus one swap
    /// deadline).
    pending: Option<(u64, u64)>,
}

impl MasterCore {
    /// Publish a new version of the global-illumination solution for the
    /// current scene: per element of the scene meshed as `mesh`, its
    /// light ([`ElementLight`]). Every live node gets it before any frame
    /// that names it: as a delta against the previous version when at most
    /// a quarter of the elements changed (same scene, mesh and size), else
    /// whole. Frames name the returned version
    /// ([`Self::illumination_version`]) once every live node said it holds
    /// it, at once when no node is live, and at the latest one swap
    /// deadline from `now`.
    pub fn set_illumination(
        &mut self,
        now: u64,
        mesh: IlluminationMesh,
        values: Vec<ElementLight>,
    ) -> Result<u64, MasterError> {
        crate::validate::full_solution(&mesh, &values)?;
        self.illumination.next_version += 1;
        let version = self.illumination.next_version;
        let new = Arc::new(HeldSolution {
            version,
            scene_version: self.scene_version,
            mesh,
            values: Arc::new(values),
        });
        let previous = self.illumination.held.values().next_back().cloned();
        let message = match previous.filter(|p| {
            p.scene_version == new.scene_version
                && p.mesh == new.mesh
                && p.values.len() == new.values.len()
        }) {
            Some(p) => {
                let changes: Vec<ElementChange> = p
                    .values
                    .iter()
                    .zip(new.values.iter())
                    .enumerate()
                    .filter(|(_, (a, b))| a != b)
                    .map(|(i, (_, b))| ElementChange {
                        element: i as u32,
                        value: *b,
                    })
                    .collect();
                if changes.len() <= new.values.len() / DELTA_FRACTION {
                    Message::Illumination(Box::new(Illumination {
                        version,
                        scene_version: new.scene_version,
                        body: IlluminationBody::Delta {
                            base: p.version,
                            changes,
                        },
                    }))
                } else {
                    new.full()
                }
            }
            None => new.full(),
        };
        self.illumination.held.insert(version, new);
        let live: Vec<ConnId> = self.live_conns().collect();
        for conn in live {
            self.transmit(conn, message.clone());
        }
        let until = now.saturating_add(self.config.deadline_ns);
        self.illumination.pending = Some((version, until));
        self.advance_illumination(None);
        self.prune_illumination();
        Ok(version)
    }

    /// The version frames of the current scene must name: the newest
    /// solution every live node holds (or that waited a swap deadline), if
    /// it belongs to the current scene version.
    pub fn illumination_version(&self) -> Option<u64> {
        self.illumination
            .named
            .and_then(|v| self.illumination.held.get(&v))
            .filter(|s| s.scene_version == self.scene_version)
            .map(|s| s.version)
    }

    /// When a published version is named regardless of the nodes that
    /// have not said they hold it.
    pub(super) fn illumination_due(&self) -> Option<u64> {
        self.illumination.pending.map(|(_, until)| until)
    }

    /// Name the pending version if every live node holds it, or (given
    /// `now`) if its swap deadline has passed.
    pub(super) fn advance_illumination(&mut self, now: Option<u64>) {
        let Some((version, until)) = self.illumination.pending else {
            return;
        };
        let lacking: Vec<&str> = self
            .peers
            .values()
            .filter_map(|p| match p {
                Peer::Live(n) if n.illumination_ready.is_none_or(|r| r < version) => {
                    Some(n.name.as_str())
                }
                _ => None,
            })
            .collect();
        let overdue = now.is_some_and(|t| t >= until);
        if !lacking.is_empty() && !overdue {
            return;
        }
        if !lacking.is_empty() {
            tracing::warn!(
                version,
                nodes = ?lacking,
                "not every node said within a swap deadline that it holds the illumination solution; frames name it now"
            );
        }
        self.illumination.named = Some(version);
        self.illumination.pending = None;
    }

    /// Whether `version`, named by a node's `message`, can have been
    /// published (it is not newer than the newest held); a node naming a
    /// later one breaks the protocol and is closed.
    fn published_or_close(&mut self, conn: ConnId, message: &str, version: u64) -> bool {
        let newest = self.illumination.held.keys().next_back().copied();
        if newest.is_none_or(|n| version > n) {
            let detail = format!(
                "{message} for version {version}, the newest is {}",
                opt_text(newest)
            );
            self.violation(conn, detail);
            return false;
        }
        true
    }

    /// A node holds (and has prepared) `r.version`.
    pub(super) fn illumination_ready(&mut self, conn: ConnId, r: IlluminationReady) {
        if !self.published_or_close(conn, "IlluminationReady", r.version) {
            return;
        }
        if let Some(Peer::Live(n)) = self.peers.get_mut(&conn) {
            n.illumination_ready = n.illumination_ready.max(Some(r.version));
        }
        self.advance_illumination(None);
    }

    /// Record the version `frame` names (after it was sent).
    pub(super) fn frame_names_illumination(&mut self, frame: u64, version: Option<u64>) {
        if let Some(v) = version {
            self.illumination.frames.insert(frame, v);
        }
        self.prune_illumination();
    }

    /// Full copies, oldest first, of the version `frame` (a joiner's
    /// current frame) names, the version frames name now and the newest
    /// version of the current scene: what a node must hold before it
    /// draws anything.
    pub(super) fn illumination_for_joiner(&self, frame: Option<&FrameState>) -> Vec<Message> {
        let newest = self
            .illumination
            .held
            .values()
            .next_back()
            .filter(|s| s.scene_version == self.scene_version)
            .map(|s| s.version);
        let mut versions: Vec<u64> = frame
            .and_then(|f| f.illumination_version)
            .into_iter()
            .chain(self.illumination_version())
            .chain(newest)
            .collect();
        versions.dedup();
        versions
            .iter()
            .filter_map(|v| self.illumination.held.get(v))
            .map(|s| s.full())
            .collect()
    }

    /// A node lacks `version`: send it full copies of every held version
    /// from `version` on. A version never published closes the node.
    pub(super) fn illumination_resync(&mut self, conn: ConnId, r: IlluminationResync) {
        if !self.published_or_close(conn, "IlluminationResync", r.version) {
            return;
        }
        let copies: Vec<Message> = self
            .illumination
            .held
            .range(r.version..)
            .map(|(_, s)| s.full())
            .collect();
        tracing::info!(%conn, from = r.version, copies = copies.len(), "illumination resync");
        for m in copies {
            self.transmit(conn, m);
        }
    }

    /// Forget the versions no frame that can still be drawn or joined
    /// names, keeping the newest.
    pub(super) fn prune_illumination(&mut self) {
        let keep_from = self
            .barrier
            .oldest()
            .or(self.latest.as_ref().map(|f| f.frame));
        let state = &mut self.illumination;
        state
            .frames
            .retain(|f, _| keep_from.is_some_and(|k| *f >= k));
        let oldest = state.frames.values().min().copied();
        let newest = state.held.keys().next_back().copied();
        let named = state.named;
        state.held.retain(|v, _| {
            Some(*v) == newest || Some(*v) == named || oldest.is_some_and(|o| *v >= o)
        });
    }

    /// Versions held (for tests and reports).
    pub fn illumination_versions_held(&self) -> usize {
        self.illumination.held.len()
    }
}
