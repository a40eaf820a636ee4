//! The cluster's event loop: the delivery queue in virtual time, the
//! frame clock's ticks, and what the master's and nodes' cores output,
//! turned into deliveries.

use super::*;

impl Cluster {
    pub(super) fn schedule(&mut self, at: u64, d: Delivery) {
        self.queue.insert((at, self.seq), d);
        self.seq += 1;
    }

    pub(super) fn next_time(&self) -> Option<u64> {
        let queue = self.queue.keys().next().map(|k| k.0);
        let master = self.master.as_ref().and_then(MasterCore::poll_timeout);
        let tick = self
            .frame_period_ns
            .filter(|_| self.master.is_some())
            .map(|_| self.next_tick);
        let nodes = self
            .nodes
            .iter()
            .filter(|n| n.alive)
            .filter_map(|n| n.core.poll_timeout().map(|t| n.virtual_time(t)));
        [queue, master, tick]
            .into_iter()
            .flatten()
            .chain(nodes)
            .min()
    }

    pub(super) fn step(&mut self) {
        let now = self.now;
        while let Some(entry) = self.queue.first_entry() {
            if entry.key().0 > now {
                break;
            }
            let d = entry.remove();
            self.deliver(d);
        }
        if let Some(period) = self.frame_period_ns
            && self.master.is_some()
            && self.next_tick <= now
        {
            self.next_tick = now + period.max(1);
            self.tick();
        }
        if let Some(m) = self.master.as_mut()
            && m.poll_timeout().is_some_and(|t| t <= now)
        {
            m.handle_timeout(now);
        }
        for node in self.nodes.iter_mut().filter(|n| n.alive) {
            let local = node.clock(now);
            if node.core.poll_timeout().is_some_and(|t| t <= local) {
                node.core.handle_timeout(local);
            }
        }
    }

    pub(super) fn tick(&mut self) {
        let now = self.now;
        let Some(m) = self.master.as_mut() else {
            return;
        };
        if !m.can_submit() {
            self.log.dropped_ticks += 1;
            return;
        }
        let n = m.next_frame().unwrap_or(0);
        let mut frame = test_frame(n, m.scene_version(), now);
        frame.illumination_version = m.illumination_version();
        if m.submit_frame(now, frame.clone()).is_ok() {
            self.log.submitted.insert(n, frame);
        }
    }

    pub(super) fn deliver(&mut self, d: Delivery) {
        let now = self.now;
        match d {
            Delivery::ToMaster { conn, bytes } => {
                let Some(m) = self.master.as_mut() else {
                    return;
                };
                match decode_frame(&bytes, MAX_FRAME_LEN) {
                    Ok(Some((msg, used))) if used == bytes.len() => {
                        m.handle_message(now, conn, msg)
                    }
                    Ok(_) => {
                        let e = crate::CodecError::Malformed(format!(
                            "{} bytes are not exactly one frame",
                            bytes.len()
                        ));
                        m.handle_decode_error(now, conn, &e);
                    }
                    Err(e) => m.handle_decode_error(now, conn, &e),
                }
            }
            Delivery::MasterLost { conn } => {
                if let Some(m) = self.master.as_mut() {
                    m.handle_disconnect(now, conn);
                }
            }
            Delivery::ToNode { node, conn, bytes } => {
                let n = &mut self.nodes[node];
                if !n.alive || n.conn != Some(conn) {
                    return;
                }
                let local = n.clock(now);
                match decode_frame(&bytes, MAX_FRAME_LEN) {
                    Ok(Some((msg, _))) => n.core.handle_message(local, msg),
                    _ => n.core.handle_disconnect(local, "undecodable message"),
                }
            }
            Delivery::NodeLost { node, conn, reason } => {
                let n = &mut self.nodes[node];
                if n.alive && n.conn == Some(conn) {
                    n.conn = None;
                    let local = n.clock(now);
                    n.core.handle_disconnect(local, &reason);
                }
            }
            Delivery::DialFailed { node, dial } => {
                let n = &mut self.nodes[node];
                if n.alive && n.log.dials.len() as u64 == dial {
                    let local = n.clock(now);
                    n.core.handle_disconnect(local, "connection refused");
                }
            }
            Delivery::Rendered {
                node,
                conn,
                frame,
                hash,
            } => {
                let n = &mut self.nodes[node];
                if n.alive && n.conn == Some(conn) {
                    let local = n.clock(now);
                    // An error means the frame was dropped by a reconnect.
                    let _ = n.core.rendered(local, frame, hash, n.spec.render_ns);
                }
            }
        }
    }

    /// Move every output until nothing is left.
    pub(super) fn pump(&mut self, steps: usize) -> Result<(), StepLimit> {
        for _ in 0..MAX_STEPS {
            let mut moved = false;
            while let Some(out) = self.master.as_mut().and_then(MasterCore::poll) {
                moved = true;
                self.master_output(out);
            }
            for i in 0..self.nodes.len() {
                while let Some(out) = self.nodes[i].core.poll() {
                    moved = true;
                    if self.nodes[i].alive {
                        self.node_output(i, out);
                    }
                }
            }
            if !moved {
                return Ok(());
            }
        }
        Err(StepLimit {
            steps,
            now_ns: self.now,
        })
    }

    pub(super) fn master_output(&mut self, out: MasterOutput) {
        let now = self.now;
        match out {
            MasterOutput::Transmit { conn, message } => {
                let Some(&node) = self.conn_owner.get(&conn) else {
                    return;
                };
                if let Some(k) = self.drops.iter().position(|d| *d == (node, message.kind())) {
                    self.drops.remove(k);
                    return;
                }
                if let Ok(bytes) = encode_frame(&message, MAX_FRAME_LEN) {
                    let at = now + self.nodes[node].spec.down_ns;
                    self.schedule(at, Delivery::ToNode { node, conn, bytes });
                }
            }
            MasterOutput::Close { conn, reason } => {
                if let Some(&node) = self.conn_owner.get(&conn) {
                    let at = now + self.nodes[node].spec.down_ns;
                    let reason = reason.to_string();
                    self.schedule(at, Delivery::NodeLost { node, conn, reason });
                }
            }
            MasterOutput::Event(e) => match e {
                MasterEvent::FrameSwapped(r) => self.log.swaps.push(r),
                MasterEvent::FramePresented(r) => self.log.presents.push(r),
                MasterEvent::NodeClosed { node, reason, .. } => {
                    self.log.closed.push((node, reason))
                }
                MasterEvent::NodeJoined {
                    node,
                    current_frame,
                    ..
                } => self.log.joined.push((node, current_frame, now)),
                MasterEvent::Capture { .. } => {}
            },
        }
    }

    pub(super) fn node_output(&mut self, i: usize, out: NodeOutput) {
        let now = self.now;
        let n = &mut self.nodes[i];
        match out {
            NodeOutput::Dial => {
                n.log.dials.push(now);
                let dial = n.log.dials.len() as u64;
                match self.master.as_mut() {
                    Some(m) => {
                        let conn = ConnId(self.next_conn);
                        self.next_conn += 1;
                        self.conn_owner.insert(conn, i);
                        m.handle_connect(now, conn);
                        n.conn = Some(conn);
                        let local = n.clock(now);
                        n.core.connect(local);
                    }
                    None => {
                        let at = now + n.spec.up_ns + n.spec.down_ns;
                        self.schedule(at, Delivery::DialFailed { node: i, dial });
                    }
                }
            }
            NodeOutput::Transmit(message) => {
                let Some(conn) = n.conn else {
                    return;
                };
                if let Message::IlluminationResync(r) = &message {
                    n.log.resyncs.push(r.version);
                }
                if self.muted.contains(&(i, message.kind())) {
                    return;
                }
                if let Ok(bytes) = encode_frame(&message, MAX_FRAME_LEN) {
                    let at = now + n.spec.up_ns;
                    self.schedule(at, Delivery::ToMaster { conn, bytes });
                }
            }
            NodeOutput::Close { .. } => {
                if let Some(conn) = n.conn.take() {
                    let at = now + n.spec.up_ns;
                    self.schedule(at, Delivery::MasterLost { conn });
                }
            }
            NodeOutput::Event(e) => match e {
                NodeEvent::Connected { .. } => n.log.connected.push(now),
                NodeEvent::SceneChanged { version, .. } => n.log.scenes.push(version),
                NodeEvent::Capture(_) => {}
                NodeEvent::Illumination(s) => n.log.arrived.push(s.version),
                NodeEvent::Render {
                    frame,
                    illumination,
                    ..
                } => {
                    if let Some(s) = illumination {
                        if !n.log.arrived.contains(&s.version) {
                            n.log.unprepared.push(frame.frame);
                        }
                        let digest = values_digest(&s.values);
                        n.log.illuminated.push((frame.frame, s.version, digest));
                    }
                    let done = now.max(n.busy_until) + n.spec.render_ns;
                    n.busy_until = done;
                    let hash = frame_hash(&frame);
                    let (conn, f) = (n.conn.unwrap_or(ConnId(0)), frame.frame);
                    n.log.rendered.push(*frame);
                    self.schedule(
                        done,
                        Delivery::Rendered {
                            node: i,
                            conn,
                            frame: f,
                            hash,
                        },
                    );
                }
                NodeEvent::Present { frame } => {
                    n.log.presented.push((frame, now));
                    let local = n.clock(now);
                    let _ = n.core.presented(local, frame);
                }
                NodeEvent::Disconnected { reason, .. } => {
                    n.conn = None;
                    n.busy_until = 0;
                    n.log.disconnects.push(reason);
                }
            },
        }
    }
}
