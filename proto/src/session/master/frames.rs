//! The frame stream: Ready and NodeStats from nodes, swap releases and present reports.

use super::*;

impl MasterCore {
    pub(super) fn ready(&mut self, now: u64, conn: ConnId, r: Ready) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        let legal = node.first_frame.is_some_and(|f| r.frame >= f)
            && node.newest_sent.is_some_and(|n| r.frame <= n)
            && node.last_ready.is_none_or(|l| r.frame > l);
        if !legal {
            let detail = format!(
                "Ready for frame {} (frames sent {}, last Ready {})",
                r.frame,
                range_text(node.first_frame, node.newest_sent),
                opt_text(node.last_ready)
            );
            self.violation(conn, detail);
            return;
        }
        node.last_ready = Some(r.frame);
        let mark = ReadyMark {
            at_ns: now,
            output_hash: r.output_hash,
        };
        // False for a joiner watching its first frame: accepted, not waited for.
        self.barrier.ready(conn, r.frame, mark);
    }

    pub(super) fn stats(&mut self, conn: ConnId, s: NodeStats) {
        let Some(Peer::Live(node)) = self.peers.get_mut(&conn) else {
            return;
        };
        let legal = node.first_frame.is_some_and(|f| s.frame >= f)
            && node.last_swapped.is_some_and(|l| s.frame <= l)
            && node.last_stats.is_none_or(|l| s.frame > l.frame);
        if !legal {
            let detail = format!(
                "NodeStats for frame {} (frames swapped {}, last stats {})",
                s.frame,
                range_text(node.first_frame, node.last_swapped),
                opt_text(node.last_stats.map(|l| l.frame))
            );
            self.violation(conn, detail);
            return;
        }
        node.last_stats = Some(s);
        let present_master_ns = node
            .clock
            .estimate()
            .map(|c| c.to_master(s.present_time_ns));
        let name = node.name.clone();
        if let Some(p) = self
            .presents
            .iter_mut()
            .find(|p| p.frame == s.frame && p.awaiting.contains(&conn))
        {
            p.awaiting.remove(&conn);
            p.nodes.push(NodePresent {
                conn,
                node: name,
                render_ms: s.render_ms,
                barrier_wait_ms: s.barrier_wait_ms,
                present_node_ns: s.present_time_ns,
                present_master_ns,
                present_offset_ns: present_master_ns.map(|t| {
                    (t as i128 - p.swap_at_ns as i128).clamp(i64::MIN as i128, i64::MAX as i128)
                        as i64
                }),
            });
        }
    }

    /// Release every frame that can swap, then emit finished present reports.
    pub(super) fn advance(&mut self, now: u64) {
        let mut swapped = false;
        while let Some(release) = self.barrier.poll_release(now) {
            self.swap(now, release);
            swapped = true;
        }
        if swapped {
            self.prune_illumination();
        }
        self.flush_presents(false);
    }

    pub(super) fn swap(&mut self, now: u64, release: Release) {
        let mut evicted = Vec::new();
        for conn in &release.late {
            let Some(Peer::Live(node)) = self.peers.get(conn) else {
                continue;
            };
            let node = node.name.clone();
            tracing::warn!(%node, frame = release.frame, "missed swap deadline");
            evicted.push(node.clone());
            let reason = CloseReason::MissedDeadline {
                node,
                frame: release.frame,
                waited_ms: ms(now.saturating_sub(release.sent_at_ns)),
                deadline_ms: ms(release.deadline_ns - release.sent_at_ns),
            };
            self.remove(*conn, reason, true);
        }
        let frame = release.frame;
        let mut swapped_to = BTreeSet::new();
        for (conn, peer) in &mut self.peers {
            if let Peer::Live(node) = peer
                && node.first_frame.is_some_and(|f| f <= frame)
                && node.newest_sent.is_some_and(|n| n >= frame)
                && node.last_swapped.is_none_or(|l| l < frame)
            {
                node.last_swapped = Some(frame);
                swapped_to.insert(*conn);
            }
        }
        for &conn in &swapped_to {
            self.transmit(conn, Message::Swap(Swap { frame }));
        }
        self.swapped_upto = Some(frame);
        let ready = release
            .ready
            .iter()
            .filter_map(|(conn, mark)| {
                let Some(Peer::Live(node)) = self.peers.get(conn) else {
                    return None;
                };
                Some(ReadyNode {
                    conn: *conn,
                    node: node.name.clone(),
                    ready_at_ns: mark.at_ns,
                    barrier_wait_ns: now.saturating_sub(mark.at_ns),
                    output_hash: mark.output_hash,
                })
            })
            .collect();
        self.event(MasterEvent::FrameSwapped(SwapReport {
            frame,
            sent_at_ns: release.sent_at_ns,
            swap_at_ns: now,
            tracking_time_ns: release.tracking_time_ns,
            ready,
            by_deadline: !release.late.is_empty(),
            evicted,
        }));
        self.presents.push_back(PresentWait {
            frame,
            swap_at_ns: now,
            awaiting: swapped_to,
            nodes: Vec::new(),
        });
        // Frames old enough are reported even if incomplete.
        let lag = self.config.present_report_lag;
        while self
            .presents
            .front()
            .is_some_and(|p| p.frame.saturating_add(lag) <= frame && p.frame != frame)
        {
            self.flush_presents(true);
        }
    }

    /// Emit the oldest present reports that are complete (or, with `force`, the oldest one).
    pub(super) fn flush_presents(&mut self, force: bool) {
        let mut force = force;
        while let Some(p) = self.presents.front() {
            if !p.awaiting.is_empty() && !force {
                break;
            }
            force = false;
            let Some(mut p) = self.presents.pop_front() else {
                break;
            };
            p.nodes.sort_by_key(|n| n.conn);
            let missing = p
                .awaiting
                .iter()
                .filter_map(|c| match self.peers.get(c) {
                    Some(Peer::Live(n)) => Some(n.name.clone()),
                    _ => None,
                })
                .collect();
            let mapped = p.nodes.iter().filter_map(|n| n.present_master_ns);
            let swap_skew_ns = mapped
                .clone()
                .max()
                .zip(mapped.min())
                .map(|(hi, lo)| hi - lo);
            self.event(MasterEvent::FramePresented(PresentReport {
                frame: p.frame,
                swap_at_ns: p.swap_at_ns,
                nodes: p.nodes,
                missing,
                swap_skew_ns,
            }));
        }
    }
}
