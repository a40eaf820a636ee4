//! The global-illumination solution through the cluster, on virtual time:
//! every node presents each frame with the version it names, a late
//! joiner gets the current solution, a lost delta is recovered with full
//! copies, and a hostile solution closes only its node's connection.

use crate::message::{ElementChange, ElementLight, Illumination, IlluminationBody, Message};
use crate::session::testing::{Cluster, NodeSpec, values_digest};
use std::collections::BTreeMap;

use super::{MS, PERIOD, config};

const ELEMENTS: usize = 1000;

/// Publish `solution(k)` and remember its digest.
fn publish(c: &mut Cluster, published: &mut BTreeMap<u64, u64>, k: u32) -> u64 {
    let values = solution(k);
    let digest = values_digest(&values);
    let v = c.set_illumination(values).unwrap();
    published.insert(v, digest);
    v
}

fn specs(k: usize) -> Vec<NodeSpec> {
    (0..k)
        .map(|i| NodeSpec::new(&format!("node-{i}")))
        .collect()
}

/// A solution that differs from `solution(k - 1)` in ten elements.
fn solution(k: u32) -> Vec<ElementLight> {
    (0..ELEMENTS as u32)
        .map(|e| {
            let changed = (0..=k).filter(|j| e % 100 == (j * 7) % 100).count() as f32;
            ElementLight {
                add: [e as f32 * 1e-3, changed, -0.5 * changed],
                cabinet: [changed, 0.0, e as f32 * 1e-4],
            }
        })
        .collect()
}

/// Every frame a node rendered names the version the master submitted it
/// with, and was drawn with that version's values (`published`: version to
/// the values' digest), so every node drew it with the same light; and
/// each version's arrival was announced before any frame that names it,
/// so the renderer prepared it off that frame's path.
#[track_caller]
fn check_versions(c: &Cluster, published: &BTreeMap<u64, u64>) {
    for n in &c.nodes {
        assert!(
            n.log.unprepared.is_empty(),
            "{} drew frames {:?} with a solution whose arrival it was not told of",
            n.spec.config.name,
            n.log.unprepared
        );

        for f in &n.log.rendered {
            let submitted = &c.log.submitted[&f.frame];
            assert_eq!(
                f.illumination_version, submitted.illumination_version,
                "{} frame {}",
                n.spec.config.name, f.frame
            );
        }
        for &(frame, version, digest) in &n.log.illuminated {
            assert_eq!(
                c.log.submitted[&frame].illumination_version,
                Some(version),
                "{} frame {frame}",
                n.spec.config.name
            );
            assert_eq!(
                published.get(&version),
                Some(&digest),
                "{} drew frame {frame} with other values than version {version}'s",
                n.spec.config.name
            );
        }
    }
}

/// Stop the frame clock, let every frame in flight finish, and check that
/// no connection closed and every frame was drawn with its version.
#[track_caller]
fn drain_and_check(c: &mut Cluster, published: &BTreeMap<u64, u64>) {
    c.frame_period_ns = None;
    c.run_for(500 * MS).unwrap();
    assert!(c.log.closed.is_empty(), "{:?}", c.log.closed);
    check_versions(c, published);
}

/// The versions a node drew frames with.
fn drawn_versions(n: &crate::session::testing::SimNode) -> std::collections::BTreeSet<u64> {
    n.log.illuminated.iter().map(|i| i.1).collect()
}

#[test]
fn every_node_presents_each_frame_with_the_version_it_names() {
    let mut c = Cluster::new(config(50), specs(3), PERIOD);
    let mut p = BTreeMap::new();
    let first = publish(&mut c, &mut p, 0);
    // Later versions travel as deltas (ten elements each), so the nodes
    // apply them; none asks for a copy.
    c.run_for(20 * PERIOD).unwrap();
    let mut versions = vec![first];
    for k in 1..=5 {
        versions.push(publish(&mut c, &mut p, k));
        c.run_for(7 * PERIOD).unwrap();
    }
    drain_and_check(&mut c, &p);
    for n in &c.nodes {
        let drawn = drawn_versions(n);
        assert_eq!(
            drawn,
            versions.iter().copied().collect(),
            "{} drew every version",
            n.spec.config.name
        );
        assert_eq!(n.log.illuminated.len(), n.log.rendered.len());
        assert!(n.presented_frames().len() > 40);
    }
    assert!(c.nodes.iter().all(|n| n.log.resyncs.is_empty()));
    // The master holds only what frames in flight name, not the history.
    assert!(c.master.as_ref().unwrap().illumination_versions_held() <= 2);
}

#[test]
fn a_late_joiner_gets_the_current_solution() {
    let mut nodes = specs(2);
    nodes[1].config.backoff.initial_ns = 1;
    let mut c = Cluster::new(config(50), nodes, PERIOD);
    let mut p = BTreeMap::new();
    c.crash_node(1, true);
    publish(&mut c, &mut p, 0);
    c.run_for(10 * PERIOD).unwrap();
    let current = publish(&mut c, &mut p, 1);
    c.run_for(10 * PERIOD).unwrap();
    c.restart_node(1);
    c.run_for(20 * PERIOD).unwrap();
    drain_and_check(&mut c, &p);
    let late = &c.nodes[1];
    assert!(late.presented_frames().len() >= 15, "{late:?}");
    assert!(late.log.illuminated.iter().all(|i| i.1 == current));
    assert_eq!(late.log.illuminated.len(), late.log.rendered.len());
    // It had the solution with its snapshot: it never had to ask.
    assert!(late.log.resyncs.is_empty(), "{:?}", late.log.resyncs);
}

#[test]
fn a_lost_delta_is_recovered_with_full_copies() {
    let mut c = Cluster::new(config(50), specs(2), PERIOD);
    let mut p = BTreeMap::new();
    publish(&mut c, &mut p, 0);
    c.run_for(10 * PERIOD).unwrap();
    // Node 0 never gets version 2's delta, so never says it holds it;
    // frames name it a swap deadline (50 ms) later all the same.
    c.drop_next_to_node(0, "Illumination");
    let lost = publish(&mut c, &mut p, 1);
    c.run_for(10 * PERIOD).unwrap();
    let later = publish(&mut c, &mut p, 2);
    c.run_for(20 * PERIOD).unwrap();
    drain_and_check(&mut c, &p);
    let n = &c.nodes[0];
    for v in [lost, later] {
        assert!(
            n.log.illuminated.iter().any(|i| i.1 == v),
            "node 0 drew version {v}: {:?}",
            n.log.illuminated
        );
    }
    assert_eq!(n.log.resyncs, [lost], "one resync, for the lost version");
    assert!(c.nodes[1].log.resyncs.is_empty());
    // No frame was skipped: the node waited for the copy, within the deadline.
    let presented = n.presented_frames();
    let first = presented[0];
    assert_eq!(
        presented,
        (first..first + presented.len() as u64).collect::<Vec<_>>()
    );
    assert!(n.log.disconnects.is_empty(), "{:?}", n.log.disconnects);
}

/// A new version is named by frames only once every live node said it
/// holds it, so no frame waits for a solution in transit or being
/// prepared; a node that never says so holds the cluster back one swap
/// deadline at most.
#[test]
fn frames_name_a_version_once_every_node_holds_it() {
    let mut nodes = specs(3);
    // A slow link: its solution arrives, and its word comes back, last.
    nodes[2].down_ns = 3 * MS;
    nodes[2].up_ns = 3 * MS;
    let mut c = Cluster::new(config(50), nodes, PERIOD);
    let mut p = BTreeMap::new();
    let first = publish(&mut c, &mut p, 0);
    c.run_for(10 * PERIOD).unwrap();
    let master = |c: &Cluster| c.master.as_ref().unwrap().illumination_version();
    assert_eq!(master(&c), Some(first));

    let second = publish(&mut c, &mut p, 1);
    assert_eq!(master(&c), Some(first), "named before any node holds it");
    c.run_for(4 * MS).unwrap();
    assert_eq!(
        master(&c),
        Some(first),
        "named before the slow node holds it"
    );
    c.run_for(3 * MS).unwrap();
    assert_eq!(master(&c), Some(second));

    // Node 1 never says it holds anything more: the next version is named
    // one swap deadline (50 ms) after it was published, and node 1 still
    // draws it.
    c.mute_to_master(1, "IlluminationReady");
    let third = publish(&mut c, &mut p, 2);
    c.run_for(45 * MS).unwrap();
    assert_eq!(master(&c), Some(second));
    c.run_for(10 * MS).unwrap();
    assert_eq!(master(&c), Some(third));
    c.run_for(10 * PERIOD).unwrap();
    drain_and_check(&mut c, &p);
    for n in &c.nodes {
        let drawn = drawn_versions(n);
        assert!(drawn.contains(&third), "{}", n.spec.config.name);
        assert!(
            n.log.resyncs.is_empty(),
            "{} {:?} {:?}",
            n.spec.config.name,
            n.log.resyncs,
            n.log.arrived
        );
    }
}

/// A node may only say it holds a version that was published.
#[test]
fn ready_for_an_unpublished_version_closes_only_its_node() {
    let mut c = Cluster::new(config(50), specs(2), PERIOD);
    let mut p = BTreeMap::new();
    let v = publish(&mut c, &mut p, 0);
    c.run_for(10 * PERIOD).unwrap();
    let bytes = crate::codec::encode_frame(
        &Message::IlluminationReady(crate::message::IlluminationReady { version: v + 1 }),
        crate::MAX_FRAME_LEN,
    )
    .unwrap();
    c.inject_bytes_to_master(0, bytes);
    c.run_for(10 * PERIOD).unwrap();
    assert_eq!(c.log.closed.len(), 1, "{:?}", c.log.closed);
    assert!(
        format!("{:?}", c.log.closed[0]).contains("IlluminationReady for version"),
        "{:?}",
        c.log.closed
    );
    assert!(c.nodes[1].presented_frames().len() >= 15);
}

fn hostile(c: &Cluster, body: IlluminationBody) -> Message {
    let m = c.master.as_ref().unwrap();
    Message::Illumination(Box::new(Illumination {
        version: m.illumination_version().unwrap() + 1,
        scene_version: m.scene_version(),
        body,
    }))
}

#[test]
fn a_hostile_solution_closes_only_its_connection() {
    let nan = |c: &Cluster| {
        let mut values = solution(0);
        values[3].add[1] = f32::NAN;
        hostile(
            c,
            IlluminationBody::Full {
                mesh: crate::message::IlluminationMesh {
                    max_patch_area: 0.01,
                    element_depth: 1,
                    min_element_area: 0.0,
                },
                values,
            },
        )
    };
    let out_of_range = |c: &Cluster| {
        let base = c.master.as_ref().unwrap().illumination_version().unwrap();
        hostile(
            c,
            IlluminationBody::Delta {
                base,
                changes: vec![ElementChange {
                    element: ELEMENTS as u32,
                    value: ElementLight {
                        add: [1.0; 3],
                        cabinet: [1.0; 3],
                    },
                }],
            },
        )
    };
    for (what, make) in [
        ("NaN", &nan as &dyn Fn(&Cluster) -> Message),
        ("out-of-range element", &out_of_range),
    ] {
        let mut c = Cluster::new(config(50), specs(2), PERIOD);
        let mut p = BTreeMap::new();
        publish(&mut c, &mut p, 0);
        c.run_for(10 * PERIOD).unwrap();
        let m = make(&c);
        c.inject_message_to_node(0, &m);
        c.run_for(30 * PERIOD).unwrap();
        c.frame_period_ns = None;
        c.run_for(500 * MS).unwrap();
        let (hit, other) = (&c.nodes[0], &c.nodes[1]);
        assert_eq!(
            hit.log.disconnects.len(),
            1,
            "{what}: {:?}",
            hit.log.disconnects
        );
        assert!(
            other.log.disconnects.is_empty(),
            "{what}: {:?}",
            other.log.disconnects
        );
        assert_eq!(hit.log.connected.len(), 2, "{what}: the node came back");
        // The node that came back draws the master's solution again.
        let last = *hit.presented_frames().last().unwrap();
        assert!(last >= 30, "{what}: presented up to {last}");
        check_versions(&c, &p);
    }
    // Oversize: a length prefix beyond the frame limit.
    let mut c = Cluster::new(config(50), specs(2), PERIOD);
    c.set_illumination(solution(0)).unwrap();
    c.run_for(10 * PERIOD).unwrap();
    let mut bytes = ((crate::codec::MAX_FRAME_LEN + 1) as u32)
        .to_le_bytes()
        .to_vec();
    bytes.extend([0u8; 16]);
    c.inject_bytes_to_node(0, bytes);
    c.run_for(30 * PERIOD).unwrap();
    assert_eq!(c.nodes[0].log.disconnects.len(), 1);
    assert!(c.nodes[1].log.disconnects.is_empty());
}

#[test]
fn a_frame_naming_an_unpublished_version_is_refused() {
    let mut c = Cluster::new(config(50), specs(1), PERIOD);
    let v = c.set_illumination(solution(0)).unwrap();
    let m = c.master.as_mut().unwrap();
    let n = m.next_frame().unwrap_or(0);
    let mut f = crate::session::testing::test_frame(n, m.scene_version(), 0);
    f.illumination_version = Some(v + 1);
    assert!(matches!(
        m.submit_frame(0, f),
        Err(crate::session::SubmitError::WrongIllumination { .. })
    ));
}

#[test]
fn bad_solutions_are_refused_naming_the_field() {
    use crate::message::IlluminationMesh;
    use crate::validate::Validate;
    let mesh = IlluminationMesh {
        max_patch_area: 0.01,
        element_depth: 1,
        min_element_area: 0.0,
    };
    let field = |body: IlluminationBody| {
        Message::Illumination(Box::new(Illumination {
            version: 2,
            scene_version: 1,
            body,
        }))
        .validate()
        .unwrap_err()
        .field
    };
    let mut nan = solution(0);
    nan[7].cabinet[2] = f32::INFINITY;
    assert_eq!(
        field(IlluminationBody::Full { mesh, values: nan }),
        "Illumination.body.values[7]"
    );
    let mut huge = solution(0);
    huge[8].add[0] = 2e6;
    assert_eq!(
        field(IlluminationBody::Full { mesh, values: huge }),
        "Illumination.body.values[8]"
    );
    let deep = IlluminationMesh {
        element_depth: 7,
        ..mesh
    };
    assert_eq!(
        field(IlluminationBody::Full {
            mesh: deep,
            values: Vec::new()
        }),
        "Illumination.body.mesh.element_depth"
    );
    let change = |element| ElementChange {
        element,
        value: ElementLight::default(),
    };
    assert_eq!(
        field(IlluminationBody::Delta {
            base: 1,
            changes: vec![change(5), change(5)]
        }),
        "Illumination.body.changes[1].element"
    );
    let oversize = vec![change(0); crate::message::MAX_ILLUMINATION_ELEMENTS + 1];
    assert_eq!(
        field(IlluminationBody::Delta {
            base: 1,
            changes: oversize
        }),
        "Illumination.body.changes"
    );
}
