//! The two-phase swap barrier: which frames are in flight, which nodes each
//! one waits for, and when it may swap (every expected node ready, or the
//! deadline passed). Frames swap strictly in order; at most
//! [`MAX_FRAMES_IN_FLIGHT`] are unswapped at once (one frame of pipelining).

use super::ConnId;
use std::collections::{BTreeMap, VecDeque};

/// Frames sent but not yet swapped, at most: frame N waiting for its swap
/// plus frame N+1 sent ahead of it.
pub const MAX_FRAMES_IN_FLIGHT: usize = 2;

/// A node's Ready as the barrier recorded it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ReadyMark {
    pub(crate) at_ns: u64,
    pub(crate) output_hash: u64,
}

#[derive(Debug)]
struct PendingFrame {
    frame: u64,
    sent_at_ns: u64,
    deadline_ns: u64,
    tracking_time_ns: Option<u64>,
    expected: BTreeMap<ConnId, Option<ReadyMark>>,
}

/// A frame the barrier released.
#[derive(Debug)]
pub(crate) struct Release {
    pub(crate) frame: u64,
    pub(crate) sent_at_ns: u64,
    pub(crate) deadline_ns: u64,
    pub(crate) tracking_time_ns: Option<u64>,
    /// Nodes that were ready, in connection order.
    pub(crate) ready: Vec<(ConnId, ReadyMark)>,
    /// Nodes that missed the deadline (to be evicted).
    pub(crate) late: Vec<ConnId>,
}

/// The frames in flight and the Ready marks collected for them.
#[derive(Debug)]
pub(crate) struct SwapBarrier {
    deadline_ns: u64,
    in_flight: VecDeque<PendingFrame>,
}

impl SwapBarrier {
    pub(crate) fn new(deadline_ns: u64) -> Self {
        Self {
            deadline_ns,
            in_flight: VecDeque::new(),
        }
    }

    pub(crate) fn can_submit(&self) -> bool {
        self.in_flight.len() < MAX_FRAMES_IN_FLIGHT
    }

    /// The oldest unswapped frame.
    pub(crate) fn oldest(&self) -> Option<u64> {
        self.in_flight.front().map(|f| f.frame)
    }

    pub(crate) fn len(&self) -> usize {
        self.in_flight.len()
    }

    /// Start waiting for `frame`, sent now to `expected`.
    pub(crate) fn push(
        &mut self,
        now: u64,
        frame: u64,
        tracking_time_ns: Option<u64>,
        expected: impl IntoIterator<Item = ConnId>,
    ) {
        debug_assert!(self.can_submit());
        self.in_flight.push_back(PendingFrame {
            frame,
            sent_at_ns: now,
            deadline_ns: now.saturating_add(self.deadline_ns),
            tracking_time_ns,
            expected: expected.into_iter().map(|c| (c, None)).collect(),
        });
    }

    /// Record a Ready. Returns false when `conn` is not expected for `frame`
    /// (a late joiner watching a frame it was not sent, or a frame already
    /// swapped); the caller has already checked that the Ready is legal.
    pub(crate) fn ready(&mut self, conn: ConnId, frame: u64, mark: ReadyMark) -> bool {
        let Some(f) = self.in_flight.iter_mut().find(|f| f.frame == frame) else {
            return false;
        };
        match f.expected.get_mut(&conn) {
            Some(slot @ None) => {
                *slot = Some(mark);
                true
            }
            _ => false,
        }
    }

    /// Forget a node (it left or was closed): no frame waits for it any more.
    pub(crate) fn remove(&mut self, conn: ConnId) {
        for f in &mut self.in_flight {
            f.expected.remove(&conn);
        }
    }

    /// When the oldest frame's deadline passes, if any frame is in flight.
    /// Later frames were sent later, so their deadlines are no earlier.
    pub(crate) fn next_deadline(&self) -> Option<u64> {
        self.in_flight.front().map(|f| f.deadline_ns)
    }

    /// Release the oldest frame if every expected node is ready or its
    /// deadline has passed at `now`.
    pub(crate) fn poll_release(&mut self, now: u64) -> Option<Release> {
        let f = self.in_flight.front()?;
        let all_ready = f.expected.values().all(Option::is_some);
        if !all_ready && now < f.deadline_ns {
            return None;
        }
        let f = self.in_flight.pop_front()?;
        let mut ready = Vec::new();
        let mut late = Vec::new();
        for (conn, mark) in f.expected {
            match mark {
                Some(m) => ready.push((conn, m)),
                None => late.push(conn),
            }
        }
        Some(Release {
            frame: f.frame,
            sent_at_ns: f.sent_at_ns,
            deadline_ns: f.deadline_ns,
            tracking_time_ns: f.tracking_time_ns,
            ready,
            late,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    fn mark(at_ns: u64) -> ReadyMark {
        ReadyMark {
            at_ns,
            output_hash: 0,
        }
    }

    #[test]
    fn releases_when_all_ready_and_in_order() {
        let mut b = SwapBarrier::new(50 * MS);
        let (a, c) = (ConnId(1), ConnId(2));
        b.push(0, 10, None, [a, c]);
        b.push(8 * MS, 11, None, [a, c]);
        assert!(!b.can_submit());
        // Frame 11 is complete first but must wait for frame 10.
        assert!(b.ready(a, 11, mark(9 * MS)));
        assert!(b.ready(c, 11, mark(9 * MS)));
        assert!(b.ready(a, 10, mark(9 * MS)));
        assert!(b.poll_release(10 * MS).is_none());
        assert!(b.ready(c, 10, mark(10 * MS)));
        let r = b.poll_release(10 * MS).unwrap();
        assert_eq!((r.frame, r.ready.len(), r.late.len()), (10, 2, 0));
        let r = b.poll_release(10 * MS).unwrap();
        assert_eq!(r.frame, 11);
        assert!(b.poll_release(10 * MS).is_none());
    }

    #[test]
    fn deadline_releases_with_the_late_nodes() {
        let mut b = SwapBarrier::new(50 * MS);
        let (a, c) = (ConnId(1), ConnId(2));
        b.push(5 * MS, 0, None, [a, c]);
        assert_eq!(b.next_deadline(), Some(55 * MS));
        assert!(b.ready(a, 0, mark(6 * MS)));
        assert!(b.poll_release(55 * MS - 1).is_none());
        let r = b.poll_release(55 * MS).unwrap();
        assert_eq!(r.ready.iter().map(|x| x.0).collect::<Vec<_>>(), [a]);
        assert_eq!(r.late, [c]);
    }

    #[test]
    fn unexpected_and_duplicate_ready_are_not_recorded() {
        let mut b = SwapBarrier::new(50 * MS);
        b.push(0, 3, None, [ConnId(1)]);
        assert!(!b.ready(ConnId(2), 3, mark(1)));
        assert!(!b.ready(ConnId(1), 4, mark(1)));
        assert!(b.ready(ConnId(1), 3, mark(1)));
        assert!(!b.ready(ConnId(1), 3, mark(2)));
    }

    #[test]
    fn removing_the_last_waited_node_releases() {
        let mut b = SwapBarrier::new(50 * MS);
        b.push(0, 0, None, [ConnId(1), ConnId(2)]);
        assert!(b.ready(ConnId(1), 0, mark(1)));
        assert!(b.poll_release(2).is_none());
        b.remove(ConnId(2));
        let r = b.poll_release(2).unwrap();
        assert!(r.late.is_empty());
    }

    #[test]
    fn a_frame_with_no_nodes_releases_at_once() {
        let mut b = SwapBarrier::new(50 * MS);
        b.push(0, 0, None, []);
        assert_eq!(b.poll_release(0).unwrap().frame, 0);
    }
}
