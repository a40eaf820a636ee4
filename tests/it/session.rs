//! Integration tests: session. The sans-IO master and node cores of
//! `showcase_proto::session` in the in-memory cluster on virtual time, with
//! every message through the wire codec: the loopback scenario
//! (a master and 4 nodes for 600 frames, a node killed and restarted)
//! without sockets, so it is exact and fast.

use anyhow::{Context, Result, ensure};
use showcase_proto::session::testing::{Cluster, NodeSpec};
use showcase_proto::session::{CloseReason, MasterConfig, MasterCore};

const MS: u64 = 1_000_000;
const PERIOD_120HZ: u64 = 8_333_333;

fn cluster(nodes: usize, links_us: &[u64]) -> Cluster {
    let specs = (0..nodes)
        .map(|i| {
            let link = links_us[i % links_us.len()] * 1_000;
            NodeSpec {
                up_ns: link,
                down_ns: link,
                ..NodeSpec::new(&format!("node-{i}"))
            }
        })
        .collect();
    let config = MasterConfig {
        target_hz: 120.0,
        ..MasterConfig::default()
    };
    Cluster::new(config, specs, PERIOD_120HZ)
}

fn swapped(c: &Cluster) -> Result<u64> {
    c.master
        .as_ref()
        .and_then(MasterCore::swapped_upto)
        .context("the master swapped nothing")
}

#[test]
fn four_nodes_six_hundred_frames_with_a_node_killed_and_restarted() -> Result<()> {
    let mut c = cluster(4, &[80, 120, 200, 350]);
    ensure!(c.run_until_swapped(200, 400 * PERIOD_120HZ)?);
    // Kill node-2 without telling anyone: the barrier deadline finds out.
    c.crash_node(2, false);
    ensure!(c.run_until_swapped(300, 400 * PERIOD_120HZ)?);
    c.nodes[2].log = Default::default();
    c.restart_node(2);
    let restarted = c.now;
    ensure!(c.run_until_swapped(600, 600 * PERIOD_120HZ)?);
    c.frame_period_ns = None;
    c.run_for(200 * MS)?;
    let last = swapped(&c)?;

    // The others present every frame, in order, with the submitted state.
    for i in [0, 1, 3] {
        let got = c.nodes[i].presented_frames();
        ensure!(
            got == (0..=last).collect::<Vec<_>>(),
            "node-{i} presented {got:?}"
        );
    }
    // One eviction, naming the node; no frame waited longer than the deadline.
    let deadline = MasterConfig::default().deadline_ns;
    ensure!(
        c.log
            .swaps
            .iter()
            .all(|s| s.swap_at_ns - s.sent_at_ns <= deadline)
    );
    let evicted: Vec<_> = c.log.swaps.iter().flat_map(|s| s.evicted.clone()).collect();
    ensure!(evicted == ["node-2"], "evicted {evicted:?}");
    ensure!(matches!(
        &c.log.closed[..],
        [(Some(n), CloseReason::MissedDeadline { .. })] if n == "node-2"
    ));
    // The restarted node rejoins with the full state and presents from its
    // snapshot's frame on.
    let node = &c.nodes[2];
    let first = node
        .log
        .rendered
        .first()
        .context("node-2 rendered nothing")?;
    ensure!(c.log.submitted.get(&first.frame) == Some(first));
    let got = node.presented_frames();
    ensure!(
        got == (first.frame..=last).collect::<Vec<_>>(),
        "node-2 presented {got:?}"
    );
    let rejoin_ns = node.log.presented[0].1 - restarted;
    ensure!(rejoin_ns <= 1_000 * MS, "rejoin took {} ms", rejoin_ns / MS);
    for n in &c.nodes {
        for f in &n.log.rendered {
            ensure!(
                c.log.submitted.get(&f.frame) == Some(f),
                "frame {}",
                f.frame
            );
        }
    }
    // Only the one stall drops frame-clock ticks: those that fall within
    // the deadline while two frames are in flight.
    let dropped = c.log.dropped_ticks;
    ensure!(
        dropped > 0 && dropped <= deadline / PERIOD_120HZ,
        "{dropped} ticks dropped"
    );
    Ok(())
}

#[test]
fn swap_skew_from_estimated_clocks_matches_the_true_spread() -> Result<()> {
    // Nodes at different link delays present at different true times; the
    // master only sees node clocks, mapped through its offset estimates.
    let mut c = cluster(8, &[50, 90, 130, 400]);
    for (i, n) in c.nodes.iter_mut().enumerate() {
        n.spec.clock_offset_ns = 1_000_000_007 * (i as i64 - 3);
    }
    ensure!(c.run_until_swapped(300, 600 * PERIOD_120HZ)?);
    let mut checked = 0;
    for r in c.log.presents.iter().filter(|r| r.frame >= 5) {
        let times: Vec<u64> = c
            .nodes
            .iter()
            .filter_map(|n| n.log.presented.iter().find(|p| p.0 == r.frame))
            .map(|p| p.1)
            .collect();
        ensure!(times.len() == 8);
        let truth = times.iter().max().unwrap_or(&0) - times.iter().min().unwrap_or(&0);
        let est = r.swap_skew_ns.context("no skew estimate")?;
        ensure!(
            est.abs_diff(truth) <= 1,
            "frame {}: {est} vs {truth}",
            r.frame
        );
        checked += 1;
    }
    ensure!(checked >= 290, "{checked} frames checked");
    Ok(())
}
