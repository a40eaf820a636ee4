//! Per-connection handling: handshake, clock probes, protocol violations and removal.

use super::*;

impl MasterCore {
    pub(super) fn violation(&mut self, conn: ConnId, detail: String) {
        if let Some(peer) = self.peers.get(&conn) {
            let peer = peer_label(conn, peer);
            tracing::warn!(%conn, %peer, %detail, "protocol violation");
            self.remove(conn, CloseReason::Violation { peer, detail }, true);
        }
    }

    /// Forget `conn`; with `close`, queue a Bye and a Close for the driver.
    pub(super) fn remove(&mut self, conn: ConnId, reason: CloseReason, close: bool) {
        let Some(peer) = self.peers.remove(&conn) else {
            return;
        };
        let name = match peer {
            Peer::Live(n) => {
                if self.names.get(&n.name) == Some(&conn) {
                    self.names.remove(&n.name);
                }
                Some(n.name)
            }
            Peer::AwaitHello { .. } => None,
        };
        self.barrier.remove(conn);
        for p in &mut self.presents {
            p.awaiting.remove(&conn);
        }
        // The version the cluster waited on this node for may now be held
        // by every node left.
        self.advance_illumination(None);
        if close {
            let bye = Bye {
                reason: truncate(reason.to_string(), 4096),
            };
            self.transmit(conn, Message::Bye(bye));
            self.out.push_back(MasterOutput::Close {
                conn,
                reason: reason.clone(),
            });
        }
        self.event(MasterEvent::NodeClosed {
            conn,
            node: name,
            reason,
        });
        // Frames this frees are released by the caller's `advance`.
    }

    pub(super) fn hello(&mut self, now: u64, conn: ConnId, hello: Hello) {
        if hello.protocol_version != PROTOCOL_VERSION {
            let reason = CloseReason::VersionMismatch {
                node: hello.node,
                theirs: hello.protocol_version,
                ours: PROTOCOL_VERSION,
            };
            self.remove(conn, reason, true);
            return;
        }
        if let Some(&old) = self.names.get(&hello.node) {
            let reason = CloseReason::Replaced {
                node: hello.node.clone(),
                by: conn,
            };
            self.remove(old, reason, true);
        }
        // The newest frame of the current scene is this node's first frame.
        let current = self
            .latest
            .as_ref()
            .filter(|f| f.scene_version == self.scene_version)
            .cloned();
        let current_frame = current.as_ref().map(|f| f.frame);
        let swapped = current_frame.is_some_and(|f| self.swapped_upto.is_some_and(|s| s >= f));
        let node = LiveNode {
            name: hello.node.clone(),
            role: hello.role,
            capabilities: hello.capabilities,
            joined_at_ns: now,
            first_frame: current_frame,
            newest_sent: current_frame,
            last_ready: None,
            last_swapped: if swapped { current_frame } else { None },
            last_stats: None,
            clock: ClockEstimator::new(self.config.clock_window),
            next_probe_id: 0,
            next_probe_at_ns: now,
            outstanding_probes: VecDeque::new(),
            illumination_ready: None,
        };
        self.peers.insert(conn, Peer::Live(Box::new(node)));
        self.names.insert(hello.node.clone(), conn);
        self.transmit(
            conn,
            Message::Welcome(Welcome {
                protocol_version: PROTOCOL_VERSION,
                target_hz: self.config.target_hz,
                deadline_ms: ms(self.config.deadline_ns) as f32,
            }),
        );
        // The solutions its first frames name come first, so the
        // snapshot's current frame finds them.
        for m in self.illumination_for_joiner(current.as_ref()) {
            self.transmit(conn, m);
        }
        self.transmit(
            conn,
            Message::SceneSnapshot(Box::new(SceneSnapshot {
                version: self.scene_version,
                showcase: (*self.scene).clone(),
                current,
                maps: (*self.maps).clone(),
            })),
        );
        if let (true, Some(frame)) = (swapped, current_frame) {
            self.transmit(conn, Message::Swap(Swap { frame }));
        }
        self.event(MasterEvent::NodeJoined {
            conn,
            node: hello.node,
            role: hello.role,
            current_frame,
        });
        self.probe(now, conn);
    }

    pub(super) fn probe(&mut self, now: u64, conn: ConnId) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        let id = node.next_probe_id;
        node.next_probe_id += 1;
        node.next_probe_at_ns = now.saturating_add(self.config.clock_probe_interval_ns.max(1));
        if node.outstanding_probes.len() == MAX_OUTSTANDING_PROBES {
            node.outstanding_probes.pop_front();
        }
        node.outstanding_probes.push_back((id, now));
        self.transmit(
            conn,
            Message::ClockProbe(ClockProbe {
                id,
                master_send_ns: now,
            }),
        );
    }

    pub(super) fn clock_reply(&mut self, now: u64, conn: ConnId, r: ClockReply) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        if r.id >= node.next_probe_id {
            let detail = format!("ClockReply for probe {} never sent", r.id);
            self.violation(conn, detail);
            return;
        }
        let Some(i) = node.outstanding_probes.iter().position(|p| p.0 == r.id) else {
            return; // Answered already or forgotten: stale, harmless.
        };
        let (_, sent) = node.outstanding_probes.remove(i).unwrap_or_default();
        if sent != r.master_send_ns {
            let detail = format!(
                "ClockReply {} echoes send time {} ns, the probe was sent at {sent} ns",
                r.id, r.master_send_ns
            );
            self.violation(conn, detail);
            return;
        }
        match clock_sample(&r, now) {
            Ok(s) => node.clock.push(s),
            Err(e) => self.violation(conn, e.to_string()),
        }
    }
}
