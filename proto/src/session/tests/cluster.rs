//! Cluster scenarios on virtual time through the in-memory harness.

use crate::PROTOCOL_VERSION;
use crate::message::{Capabilities, Hello, Message, Ready, Role, Swap};
use crate::session::testing::{Cluster, NodeSpec, test_scene};
use crate::session::*;

use super::{MS, PERIOD, config};

fn specs(k: usize) -> Vec<NodeSpec> {
    (0..k)
        .map(|i| NodeSpec::new(&format!("node-{i}")))
        .collect()
}

/// Stop the frame clock and let the frames in flight finish.
fn settle(c: &mut Cluster) {
    c.frame_period_ns = None;
    c.run_for(500 * MS).unwrap();
}

/// Node `i` presented consecutive frames from `first` on, each once, and
/// rendered exactly the states the master submitted.
#[track_caller]
fn check_presents_consecutively(c: &Cluster, i: usize, first: u64, last: u64) {
    let node = &c.nodes[i];
    let got = node.presented_frames();
    let want: Vec<u64> = (first..=last).collect();
    assert_eq!(got, want, "frames presented by {}", node.spec.config.name);
    for f in &node.log.rendered {
        assert_eq!(
            Some(f),
            c.log.submitted.get(&f.frame),
            "state of frame {}",
            f.frame
        );
    }
}

fn last_swapped(c: &Cluster) -> u64 {
    c.log.swaps.last().map(|s| s.frame).unwrap()
}

#[test]
fn sixteen_nodes_present_a_thousand_frames_in_order_with_measured_skew() {
    // Different link delays and clocks per node; symmetric links, so the
    // offset estimate is exact and the master's skew must equal the true one.
    let nodes: Vec<NodeSpec> = (0..16)
        .map(|i| NodeSpec {
            up_ns: 50_000 + 20_000 * i as u64,
            down_ns: 50_000 + 20_000 * i as u64,
            clock_offset_ns: (i as i64 - 8) * 123_456_789,
            ..NodeSpec::new(&format!("node-{i}"))
        })
        .collect();
    let mut c = Cluster::new(config(50), nodes, PERIOD);
    assert!(c.run_until_swapped(1000, 2000 * PERIOD).unwrap());
    settle(&mut c);
    let last = last_swapped(&c);
    assert!(c.log.closed.is_empty(), "{:?}", c.log.closed);
    assert_eq!(c.log.dropped_ticks, 0);
    assert!(c.log.swaps.iter().all(|s| !s.by_deadline));
    for i in 0..16 {
        let first = c.nodes[i].presented_frames()[0];
        assert_eq!(first, 0, "every node joined during frame 0");
        check_presents_consecutively(&c, i, 0, last);
    }
    // Swap reports are consecutive and every node was ready for every frame from 1 on.
    for (n, s) in c.log.swaps.iter().enumerate() {
        assert_eq!(s.frame, n as u64);
        if s.frame >= 1 {
            assert_eq!(s.ready.len(), 16, "frame {}", s.frame);
        }
    }
    // Skew: the true spread of present times (virtual clock) against the
    // master's estimate from node clocks.
    let mut checked = 0;
    for r in c.log.presents.iter().filter(|r| r.frame >= 10) {
        let times: Vec<u64> = c
            .nodes
            .iter()
            .filter_map(|n| n.log.presented.iter().find(|p| p.0 == r.frame).map(|p| p.1))
            .collect();
        let truth = times.iter().max().unwrap() - times.iter().min().unwrap();
        assert_eq!(r.nodes.len(), 16);
        assert!(r.missing.is_empty());
        let est = r.swap_skew_ns.unwrap();
        assert!(
            est.abs_diff(truth) <= 1,
            "frame {}: {est} vs {truth}",
            r.frame
        );
        assert_eq!(truth, 15 * 20_000);
        checked += 1;
    }
    assert!(checked > 900);
}

#[test]
fn a_dropped_node_stalls_the_others_at_most_the_deadline() {
    for tell_master in [true, false] {
        // node-2's loss reaches the master 5 ms after the crash, after the
        // other nodes' Ready for the frame in flight.
        let mut nodes = specs(4);
        nodes[2].up_ns = 5 * MS;
        let mut c = Cluster::new(config(50), nodes, PERIOD);
        assert!(c.run_until_swapped(100, 400 * PERIOD).unwrap());
        let in_flight = c.log.swaps.last().unwrap().sent_at_ns + PERIOD;
        c.run_until(in_flight + MS).unwrap();
        c.crash_node(2, tell_master);
        let crash_at = c.now;
        assert!(c.run_until_swapped(300, 400 * PERIOD).unwrap());
        settle(&mut c);
        let last = last_swapped(&c);
        for i in [0, 1, 3] {
            check_presents_consecutively(&c, i, 0, last);
        }
        for s in &c.log.swaps {
            assert!(
                s.swap_at_ns - s.sent_at_ns <= 50 * MS,
                "frame {} stalled",
                s.frame
            );
        }
        let evicted: Vec<&SwapReport> = c
            .log
            .swaps
            .iter()
            .filter(|s| !s.evicted.is_empty())
            .collect();
        if tell_master {
            // The loss releases the frame in flight the moment it arrives.
            let s = c.log.swaps.iter().find(|s| s.sent_at_ns == in_flight);
            assert_eq!(s.unwrap().swap_at_ns, crash_at + 5 * MS);
            assert_eq!(s.unwrap().ready.len(), 3);
            assert!(evicted.is_empty());
            assert!(matches!(
                &c.log.closed[..],
                [(Some(n), CloseReason::Disconnected { .. })] if n == "node-2"
            ));
        } else {
            // Exactly one frame waited for the full deadline, then went on without node-2.
            assert_eq!(evicted.len(), 1);
            let s = evicted[0];
            assert_eq!(s.evicted, ["node-2"]);
            assert_eq!(s.swap_at_ns - s.sent_at_ns, 50 * MS);
            assert_eq!(s.sent_at_ns, in_flight);
            let reason = c.log.closed[0].1.to_string();
            assert!(
                reason.contains("node-2") && reason.contains("50.0 ms"),
                "{reason}"
            );
        }
    }
}

#[test]
fn a_slow_node_is_evicted_at_the_deadline_and_the_others_swap_then() {
    let mut nodes = specs(4);
    nodes[3].render_ns = 80 * MS;
    let mut c = Cluster::new(config(50), nodes, PERIOD);
    assert!(c.run_until_swapped(200, 1000 * PERIOD).unwrap());
    settle(&mut c);
    let last = last_swapped(&c);
    for i in 0..3 {
        check_presents_consecutively(&c, i, 0, last);
    }
    let late: Vec<&SwapReport> = c.log.swaps.iter().filter(|s| s.by_deadline).collect();
    assert!(!late.is_empty());
    for s in &late {
        assert_eq!(s.evicted, ["node-3"], "frame {}", s.frame);
        assert_eq!(s.swap_at_ns - s.sent_at_ns, 50 * MS);
        assert_eq!(s.ready.len(), 3);
    }
    // It keeps rejoining (with backoff) and is evicted again each time.
    assert_eq!(c.log.closed.len(), late.len());
    assert!(
        c.log
            .closed
            .iter()
            .all(|(n, r)| n.as_deref() == Some("node-3")
                && matches!(r, CloseReason::MissedDeadline { .. }))
    );
    assert!(c.nodes[3].log.connected.len() >= 2);
}

#[test]
fn a_node_that_comes_back_rejoins_with_the_current_state() {
    let mut c = Cluster::new(config(50), specs(3), PERIOD);
    assert!(c.run_until_swapped(50, 200 * PERIOD).unwrap());
    c.crash_node(1, false);
    c.run_for(500 * MS).unwrap();
    let presented_before = c.nodes[1].presented_frames();
    c.nodes[1].log = Default::default();
    c.restart_node(1);
    c.run_for(300 * MS).unwrap();
    settle(&mut c);
    let last = last_swapped(&c);
    let (name, current, _) = c.log.joined.last().unwrap().clone();
    assert_eq!(name, "node-1");
    let current = current.unwrap();
    assert!(current > *presented_before.last().unwrap() + 10);
    // Its first render after the rejoin is the snapshot's current frame.
    assert_eq!(c.nodes[1].log.rendered[0].frame, current);
    assert_eq!(c.nodes[1].log.scenes, [1]);
    check_presents_consecutively(&c, 1, current, last);
    for i in [0, 2] {
        check_presents_consecutively(&c, i, 0, last);
    }
}

#[test]
fn late_join_at_any_point_of_a_frame_renders_the_right_state() {
    // Join at offsets that fall while the frame is in flight and after it swapped.
    for offset_us in [0, 500, 1_000, 2_300, 5_000, 8_000] {
        let mut nodes = specs(3);
        nodes[2].up_ns = 700_000;
        let mut c = Cluster::new(config(50), nodes, PERIOD);
        c.crash_node(2, false);
        assert!(c.run_until_swapped(137, 400 * PERIOD).unwrap());
        let frame_sent = c.log.swaps.last().unwrap().sent_at_ns;
        c.run_until(frame_sent + offset_us * 1_000).unwrap();
        c.restart_node(2);
        c.run_for(200 * MS).unwrap();
        settle(&mut c);
        let last = last_swapped(&c);
        let (name, current, _) = c.log.joined.last().unwrap().clone();
        assert_eq!(name, "node-2");
        let current = current.unwrap();
        assert!(
            (137..=140).contains(&current),
            "offset {offset_us} us: {current}"
        );
        check_presents_consecutively(&c, 2, current, last);
        assert!(
            c.log.closed.is_empty(),
            "offset {offset_us} us: {:?}",
            c.log.closed
        );
    }
}

#[test]
fn master_restart_nodes_reconnect_with_backoff_and_a_fresh_snapshot() {
    let mut c = Cluster::new(config(50), specs(3), PERIOD);
    assert!(c.run_until_swapped(200, 400 * PERIOD).unwrap());
    c.stop_master();
    let stopped = c.now;
    c.run_for(1_600 * MS).unwrap();
    c.start_master();
    // The fifth redial (after 100 + 200 + 400 + 800 + 1600 ms) reaches the new master.
    c.run_for(2_000 * MS).unwrap();
    let swapped = c
        .master
        .as_ref()
        .and_then(MasterCore::swapped_upto)
        .unwrap();
    assert!(c.run_until_swapped(swapped + 100, 200 * PERIOD).unwrap());
    settle(&mut c);
    let last = last_swapped(&c);
    let backoff = Backoff::default();
    for (i, node) in c.nodes.iter().enumerate() {
        // Dials after the loss: delays of 100, 200, 400, 800... ms after each failure.
        let redials: Vec<u64> = node
            .log
            .dials
            .iter()
            .copied()
            .filter(|&d| d > stopped)
            .collect();
        assert_eq!(redials.len(), 5, "{redials:?}");
        let lost_at = stopped + node.spec.down_ns;
        let rtt = node.spec.up_ns + node.spec.down_ns;
        let mut expect = lost_at + backoff.delay(0);
        for (k, &d) in redials.iter().enumerate() {
            assert_eq!(d, expect, "node {i} redial {k}");
            expect = d + rtt + backoff.delay(k as u32 + 1);
        }
        assert_eq!(node.core.failures(), 0, "backoff resets on Welcome");
        assert_eq!(
            node.log.scenes,
            [1, 1],
            "a fresh snapshot from the new master"
        );
        let rejoined = *node.log.connected.last().unwrap();
        assert!(rejoined > stopped);
        let restart_frames: Vec<u64> = node
            .log
            .presented
            .iter()
            .filter(|p| p.1 > rejoined)
            .map(|p| p.0)
            .collect();
        let first = restart_frames[0];
        assert_eq!(restart_frames, (first..=last).collect::<Vec<_>>());
    }
}

/// A message from one node that breaks the protocol closes only that node.
#[test]
fn a_protocol_violation_closes_only_that_peer() {
    let hello = Message::Hello(Hello {
        protocol_version: PROTOCOL_VERSION,
        node: "node-1".into(),
        role: Role::Face,
        capabilities: Capabilities::default(),
    });
    type Inject = Box<dyn Fn(&mut Cluster)>;
    let cases: Vec<(&str, Inject, &str)> = vec![
        (
            "swap from a node",
            Box::new(|c| c.inject_message_to_master(1, &Message::Swap(Swap { frame: 3 }))),
            "Swap is a master-to-node message",
        ),
        (
            "ready for a future frame",
            Box::new(|c| {
                let r = Ready {
                    frame: 1_000_000,
                    output_hash: 0,
                };
                c.inject_message_to_master(1, &Message::Ready(r))
            }),
            "Ready for frame 1000000",
        ),
        (
            "ready for an old frame",
            Box::new(|c| {
                let r = Ready {
                    frame: 2,
                    output_hash: 0,
                };
                c.inject_message_to_master(1, &Message::Ready(r))
            }),
            "Ready for frame 2",
        ),
        (
            "hello twice",
            Box::new(move |c| c.inject_message_to_master(1, &hello)),
            "Hello twice",
        ),
        (
            "garbage bytes",
            Box::new(|c| c.inject_bytes_to_master(1, vec![3, 0, 0, 0, 0xff, 0xff, 0xff])),
            "malformed message",
        ),
        (
            "oversized frame",
            Box::new(|c| c.inject_bytes_to_master(1, vec![0xff, 0xff, 0xff, 0x7f])),
            "exceeds the limit",
        ),
    ];
    for (name, inject, want) in cases {
        let mut c = Cluster::new(config(50), specs(4), PERIOD);
        assert!(c.run_until_swapped(60, 200 * PERIOD).unwrap());
        inject(&mut c);
        assert!(c.run_until_swapped(150, 200 * PERIOD).unwrap());
        settle(&mut c);
        let last = last_swapped(&c);
        assert_eq!(c.log.closed.len(), 1, "{name}: {:?}", c.log.closed);
        let (node, reason) = &c.log.closed[0];
        assert_eq!(node.as_deref(), Some("node-1"), "{name}");
        let text = reason.to_string();
        assert!(
            text.contains("node-1") && text.contains(want),
            "{name}: {text}"
        );
        assert!(c.log.swaps.iter().all(|s| !s.by_deadline), "{name}");
        for i in [0, 2, 3] {
            check_presents_consecutively(&c, i, 0, last);
        }
        // The offender learns why, then rejoins.
        assert!(c.nodes[1].log.disconnects[0].contains(want), "{name}");
        assert_eq!(c.nodes[1].log.connected.len(), 2, "{name}");
    }
}

#[test]
fn clock_offsets_are_recovered_within_the_link_asymmetry() {
    // (clock offset, up delay, down delay)
    let cases = [
        (3_700_000_000i64, 200_000u64, 200_000u64),
        (-1_200_000_000, 300_000, 100_000),
        (42, 50_000, 900_000),
        (-987_654_321, 1_000_000, 1_000_000),
    ];
    let nodes = cases
        .iter()
        .enumerate()
        .map(|(i, &(offset, up, down))| NodeSpec {
            clock_offset_ns: offset,
            up_ns: up,
            down_ns: down,
            ..NodeSpec::new(&format!("node-{i}"))
        })
        .collect();
    let mut c = Cluster::new(config(50), nodes, PERIOD);
    c.run_for(1_000 * MS).unwrap();
    let master = c.master.as_ref().unwrap();
    for (i, &(offset, up, down)) in cases.iter().enumerate() {
        let est = master
            .node_by_name(&format!("node-{i}"))
            .unwrap()
            .clock
            .unwrap();
        let err = est.offset_ns - offset;
        assert_eq!(est.delay_ns, up + down);
        // The error of a sample is half the asymmetry of the one-way delays.
        let expect = (down as i64 - up as i64) / 2;
        assert!(
            (err - expect).abs() <= 1,
            "node {i}: error {err}, expected {expect}"
        );
        assert!(err.unsigned_abs() <= est.error_bound_ns());
    }
}

#[test]
fn the_deadline_is_configurable() {
    for deadline_ms in [10, 20, 50, 100] {
        let mut c = Cluster::new(config(deadline_ms), specs(3), PERIOD);
        assert!(c.run_until_swapped(30, 100 * PERIOD).unwrap());
        c.crash_node(0, false);
        assert!(c.run_until_swapped(80, 200 * PERIOD).unwrap());
        let late: Vec<&SwapReport> = c.log.swaps.iter().filter(|s| s.by_deadline).collect();
        assert_eq!(late.len(), 1, "deadline {deadline_ms} ms");
        assert_eq!(late[0].swap_at_ns - late[0].sent_at_ns, deadline_ms * MS);
        let longest = c
            .log
            .swaps
            .iter()
            .map(|s| s.swap_at_ns - s.sent_at_ns)
            .max();
        assert_eq!(longest, Some(deadline_ms * MS));
    }
}

#[test]
fn a_scene_change_reaches_every_node_and_frames_follow_it() {
    let mut c = Cluster::new(config(50), specs(3), PERIOD);
    assert!(c.run_until_swapped(40, 200 * PERIOD).unwrap());
    let mut scene = test_scene();
    scene.name = "second".into();
    assert_eq!(c.set_scene(scene), Some(2));
    assert!(c.run_until_swapped(80, 200 * PERIOD).unwrap());
    settle(&mut c);
    let last = last_swapped(&c);
    for i in 0..3 {
        assert_eq!(c.nodes[i].log.scenes, [1, 2]);
        let versions: Vec<u64> = c.nodes[i]
            .log
            .rendered
            .iter()
            .map(|f| f.scene_version)
            .collect();
        assert!(versions.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(versions.last(), Some(&2));
        check_presents_consecutively(&c, i, 0, last);
    }
}

/// Random clusters under random faults (seeded): crashes told and untold,
/// restarts, protocol violations and scene changes. Whatever happens, the
/// master swaps consecutive frames within the deadline, every node presents
/// consecutive frames within each connection with exactly the submitted
/// states, and after the faults stop every node is back and presents the
/// newest frames.
#[test]
fn random_faults_keep_the_frame_lock_invariants() {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    for seed in 0..12u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = rng.random_range(2..8);
        let nodes = (0..k)
            .map(|i| NodeSpec {
                up_ns: rng.random_range(50_000..3_000_000),
                down_ns: rng.random_range(50_000..3_000_000),
                render_ns: rng.random_range(500_000..6_000_000),
                clock_offset_ns: rng.random_range(-5_000_000_000..5_000_000_000),
                ..NodeSpec::new(&format!("node-{i}"))
            })
            .collect();
        let mut c = Cluster::new(config(50), nodes, PERIOD);
        let mut version = 1;
        for _ in 0..40 {
            c.run_for(rng.random_range(1..60) * MS).unwrap();
            let i = rng.random_range(0..k);
            match rng.random_range(0..6) {
                0 => c.crash_node(i, true),
                1 => c.crash_node(i, false),
                2 | 3 => {
                    if !c.nodes[i].alive {
                        c.restart_node(i);
                    }
                }
                4 => c.inject_message_to_master(i, &Message::Swap(Swap { frame: 1 })),
                _ => {
                    let mut scene = test_scene();
                    scene.name = format!("scene {version}");
                    version += 1;
                    assert_eq!(c.set_scene(scene), Some(version));
                }
            }
        }
        for i in 0..k {
            if !c.nodes[i].alive {
                c.restart_node(i);
            }
        }
        // Quiet time: 2 s covers the largest backoff reached (1.6 s) plus a rejoin.
        c.run_for(3_000 * MS).unwrap();
        let newest = last_swapped(&c);
        settle(&mut c);
        let last = last_swapped(&c);

        for (n, s) in c.log.swaps.iter().enumerate() {
            assert_eq!(s.frame, n as u64, "seed {seed}");
            assert!(s.swap_at_ns - s.sent_at_ns <= 50 * MS, "seed {seed}");
        }
        for node in &c.nodes {
            let name = &node.spec.config.name;
            for f in &node.log.rendered {
                assert_eq!(Some(f), c.log.submitted.get(&f.frame), "seed {seed} {name}");
            }
            // Split presents by connection: consecutive frames within each.
            let mut joins = node.log.connected.clone();
            joins.push(u64::MAX);
            for w in joins.windows(2) {
                let frames: Vec<u64> = node
                    .log
                    .presented
                    .iter()
                    .filter(|p| (w[0]..w[1]).contains(&p.1))
                    .map(|p| p.0)
                    .collect();
                assert!(
                    frames.windows(2).all(|f| f[1] == f[0] + 1),
                    "seed {seed} {name}: {frames:?}"
                );
            }
            let presented = node.presented_frames();
            assert!(
                presented.windows(2).all(|f| f[0] < f[1]),
                "seed {seed} {name}"
            );
            assert!(
                presented.contains(&newest),
                "seed {seed} {name} missed {newest}"
            );
            assert_eq!(presented.last(), Some(&last), "seed {seed} {name}");
        }
    }
}
