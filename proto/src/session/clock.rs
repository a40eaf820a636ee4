//! NTP-style clock-offset estimation between the master's clock and a node's
//! clock, from [`ClockProbe`](crate::ClockProbe) / [`ClockReply`] exchanges.
//!
//! With `t0` the master's send time, `t1` the node's receive time, `t2` the
//! node's send time and `t3` the master's receive time:
//! `offset = ((t1 - t0) + (t2 - t3)) / 2` (node clock minus master clock) and
//! `delay = (t3 - t0) - (t2 - t1)` (the round trip spent on the links). The
//! error of one sample's offset is at most `delay / 2` (it is exactly half the
//! difference of the two one-way delays), so the estimator keeps the sample
//! with the smallest delay among the recent ones.

use crate::message::ClockReply;
use std::collections::VecDeque;

/// One offset measurement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockSample {
    /// Node clock minus master clock (ns).
    pub offset_ns: i64,
    /// Round-trip time spent on the links (ns); the offset's error is at most half of it.
    pub delay_ns: u64,
    /// Master clock when the reply arrived (ns).
    pub at_ns: u64,
}

impl ClockSample {
    /// Map a time on the node's clock to the master's clock.
    pub fn to_master(&self, node_ns: u64) -> u64 {
        clamp_u64(node_ns as i128 - self.offset_ns as i128)
    }

    /// Map a time on the master's clock to the node's clock.
    pub fn to_node(&self, master_ns: u64) -> u64 {
        clamp_u64(master_ns as i128 + self.offset_ns as i128)
    }

    /// Upper bound of this sample's offset error (ns): half the delay.
    pub fn error_bound_ns(&self) -> u64 {
        self.delay_ns.div_ceil(2)
    }
}

fn clamp_u64(v: i128) -> u64 {
    v.clamp(0, u64::MAX as i128) as u64
}

fn clamp_i64(v: i128) -> i64 {
    v.clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// Why a [`ClockReply`] cannot be turned into a sample.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ClockError {
    /// The reply arrived (on the master's clock) before its probe was sent.
    #[error(
        "clock reply {id} arrives at {master_recv_ns} ns, before its probe was sent at {master_send_ns} ns"
    )]
    ReplyBeforeProbe {
        /// The probe.
        id: u64,
        /// Master send time (ns).
        master_send_ns: u64,
        /// Master receive time (ns).
        master_recv_ns: u64,
    },
    /// The node claims to have sent its reply before it received the probe.
    #[error(
        "clock reply {id} was sent at {node_send_ns} ns, before the probe arrived at {node_recv_ns} ns"
    )]
    SentBeforeReceived {
        /// The probe.
        id: u64,
        /// Node receive time (ns).
        node_recv_ns: u64,
        /// Node send time (ns).
        node_send_ns: u64,
    },
    /// The node held the probe longer than the whole round trip took.
    #[error(
        "clock reply {id} claims {held_ns} ns at the node, longer than the round trip of {round_trip_ns} ns"
    )]
    HeldLongerThanRoundTrip {
        /// The probe.
        id: u64,
        /// `t2 - t1`.
        held_ns: u64,
        /// `t3 - t0`.
        round_trip_ns: u64,
    },
}

/// Turn a reply that arrived at `master_recv_ns` into a sample.
pub fn clock_sample(reply: &ClockReply, master_recv_ns: u64) -> Result<ClockSample, ClockError> {
    let (t0, t1, t2, t3) = (
        reply.master_send_ns,
        reply.node_recv_ns,
        reply.node_send_ns,
        master_recv_ns,
    );
    if t3 < t0 {
        return Err(ClockError::ReplyBeforeProbe {
            id: reply.id,
            master_send_ns: t0,
            master_recv_ns: t3,
        });
    }
    if t2 < t1 {
        return Err(ClockError::SentBeforeReceived {
            id: reply.id,
            node_recv_ns: t1,
            node_send_ns: t2,
        });
    }
    let (round_trip, held) = (t3 - t0, t2 - t1);
    if held > round_trip {
        return Err(ClockError::HeldLongerThanRoundTrip {
            id: reply.id,
            held_ns: held,
            round_trip_ns: round_trip,
        });
    }
    let (t0, t1, t2, t3) = (t0 as i128, t1 as i128, t2 as i128, t3 as i128);
    // Sum first, then halve: floor division keeps the rounding error below 1 ns.
    let offset = ((t1 - t0) + (t2 - t3)).div_euclid(2);
    Ok(ClockSample {
        offset_ns: clamp_i64(offset),
        delay_ns: round_trip - held,
        at_ns: master_recv_ns,
    })
}

/// Keeps the last `window` samples and estimates from the one with the smallest delay.
#[derive(Clone, Debug)]
pub struct ClockEstimator {
    window: usize,
    samples: VecDeque<ClockSample>,
}

impl ClockEstimator {
    /// An estimator over the last `window` samples (at least 1).
    pub fn new(window: usize) -> Self {
        Self {
            window: window.max(1),
            samples: VecDeque::new(),
        }
    }

    /// Add a sample, forgetting the oldest beyond the window.
    pub fn push(&mut self, sample: ClockSample) {
        if self.samples.len() == self.window {
            self.samples.pop_front();
        }
        self.samples.push_back(sample);
    }

    /// The minimum-delay sample of the window (the newest among equals).
    pub fn estimate(&self) -> Option<ClockSample> {
        self.samples
            .iter()
            .rev()
            .min_by_key(|s| s.delay_ns)
            .copied()
    }

    /// Samples in the window.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// No sample yet.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A probe exchange over links with one-way delays `down` (master to
    /// node) and `up`, a node holding the probe for `held`, and a node clock
    /// `offset` ahead of the master's.
    fn exchange(t0: u64, offset: i64, down: u64, held: u64, up: u64) -> (ClockReply, u64) {
        let t1 = (t0 as i128 + down as i128 + offset as i128) as u64;
        let t2 = t1 + held;
        let t3 = t0 + down + held + up;
        let reply = ClockReply {
            id: 7,
            master_send_ns: t0,
            node_recv_ns: t1,
            node_send_ns: t2,
        };
        (reply, t3)
    }

    #[test]
    fn symmetric_links_give_the_exact_offset() {
        for offset in [0i64, 1, -1, 123_456_789, -987_654_321_000] {
            let (reply, t3) = exchange(10_000_000_000_000, offset, 300_000, 20_000, 300_000);
            let s = clock_sample(&reply, t3).unwrap();
            assert_eq!(s.offset_ns, offset);
            assert_eq!(s.delay_ns, 600_000);
        }
    }

    #[test]
    fn bad_replies_are_refused() {
        let (reply, t3) = exchange(1_000_000, 5, 10, 10, 10);
        assert!(matches!(
            clock_sample(&reply, reply.master_send_ns - 1),
            Err(ClockError::ReplyBeforeProbe { .. })
        ));
        let swapped = ClockReply {
            node_recv_ns: reply.node_send_ns,
            node_send_ns: reply.node_recv_ns - 1,
            ..reply
        };
        assert!(matches!(
            clock_sample(&swapped, t3),
            Err(ClockError::SentBeforeReceived { .. })
        ));
        let held = ClockReply {
            node_send_ns: reply.node_recv_ns + 1_000,
            ..reply
        };
        assert!(matches!(
            clock_sample(&held, t3),
            Err(ClockError::HeldLongerThanRoundTrip { .. })
        ));
    }

    #[test]
    fn estimator_keeps_the_minimum_delay_sample_of_the_window() {
        let mut est = ClockEstimator::new(3);
        assert_eq!(est.estimate(), None);
        let s = |offset_ns, delay_ns, at_ns| ClockSample {
            offset_ns,
            delay_ns,
            at_ns,
        };
        est.push(s(10, 100, 1));
        est.push(s(20, 50, 2));
        est.push(s(30, 80, 3));
        assert_eq!(est.estimate().unwrap().offset_ns, 20);
        est.push(s(40, 90, 4));
        assert_eq!(est.estimate().unwrap().offset_ns, 20);
        // The 50 ns sample leaves the window.
        est.push(s(50, 95, 5));
        assert_eq!(est.len(), 3);
        assert_eq!(est.estimate().unwrap().offset_ns, 30);
    }

    #[test]
    fn mapping_between_clocks_round_trips_and_saturates() {
        let s = ClockSample {
            offset_ns: -5_000,
            delay_ns: 0,
            at_ns: 0,
        };
        assert_eq!(s.to_master(1_000), 6_000);
        assert_eq!(s.to_node(6_000), 1_000);
        assert_eq!(s.to_node(1_000), 0);
        let ahead = ClockSample { offset_ns: 10, ..s };
        assert_eq!(ahead.to_node(u64::MAX), u64::MAX);
    }

    proptest! {
        #[test]
        fn offset_error_is_half_the_delay_asymmetry(
            t0 in 1u64 << 40..1u64 << 50,
            offset in -(1i64 << 39)..(1i64 << 39),
            down in 0u64..50_000_000,
            held in 0u64..10_000_000,
            up in 0u64..50_000_000,
        ) {
            let (reply, t3) = exchange(t0, offset, down, held, up);
            let s = clock_sample(&reply, t3).unwrap();
            prop_assert_eq!(s.delay_ns, down + up);
            let err = s.offset_ns as i128 - offset as i128;
            let expect = (down as i128 - up as i128) as f64 / 2.0;
            prop_assert!((err as f64 - expect).abs() <= 0.5, "err {} expect {}", err, expect);
            prop_assert!(err.unsigned_abs() as u64 <= s.error_bound_ns());
        }
    }
}
