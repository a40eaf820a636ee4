//! Direct checks of the master's and the node's rules, message by message.

use super::{MS, config};
use crate::PROTOCOL_VERSION;
use crate::message::{Capabilities, Hello, Message, Ready, Role, Swap};
use crate::session::testing::{EPOCH_NS, test_frame, test_scene};
use crate::session::*;

fn hello(name: &str, version: u32) -> Message {
    Message::Hello(Hello {
        protocol_version: version,
        node: name.into(),
        role: Role::Projector,
        capabilities: Capabilities::default(),
    })
}

fn drain(m: &mut MasterCore) -> Vec<MasterOutput> {
    std::iter::from_fn(|| m.poll()).take(10_000).collect()
}

fn closes(out: &[MasterOutput]) -> Vec<(ConnId, String)> {
    out.iter()
        .filter_map(|o| match o {
            MasterOutput::Close { conn, reason } => Some((*conn, reason.to_string())),
            _ => None,
        })
        .collect()
}

fn master() -> MasterCore {
    MasterCore::new(config(50), test_scene()).unwrap()
}

#[test]
fn messages_out_of_state_close_the_connection_with_a_reason() {
    #[track_caller]
    fn check(first: Message, second: Option<Message>, want: &str) {
        let mut m = master();
        let (a, b) = (ConnId(1), ConnId(2));
        m.handle_connect(EPOCH_NS, a);
        m.handle_connect(EPOCH_NS, b);
        m.handle_message(EPOCH_NS, b, hello("bystander", PROTOCOL_VERSION));
        m.handle_message(EPOCH_NS, a, first);
        if let Some(second) = second {
            m.handle_message(EPOCH_NS, a, second);
        }
        let out = drain(&mut m);
        let c = closes(&out);
        assert_eq!(c.len(), 1, "{c:?}");
        assert_eq!(c[0].0, a);
        assert!(c[0].1.contains(want), "{} does not say {want:?}", c[0].1);
        assert!(m.node(b).is_some(), "the bystander stays");
    }
    let ready = Message::Ready(Ready {
        frame: 0,
        output_hash: 0,
    });
    check(ready.clone(), None, "Ready before Hello");
    check(Message::Swap(Swap { frame: 0 }), None, "Swap before Hello");
    check(
        hello("a", PROTOCOL_VERSION + 1),
        None,
        &format!("speaks protocol version {}", PROTOCOL_VERSION + 1),
    );
    check(
        hello("a", PROTOCOL_VERSION),
        Some(hello("a", 1)),
        "Hello twice",
    );
    check(
        hello("a", PROTOCOL_VERSION),
        Some(ready),
        "Ready for frame 0 (frames sent none",
    );
}

#[test]
fn a_second_connection_with_a_live_name_replaces_the_first() {
    let mut m = master();
    let (a, b) = (ConnId(1), ConnId(2));
    m.handle_connect(EPOCH_NS, a);
    m.handle_message(EPOCH_NS, a, hello("face-left", PROTOCOL_VERSION));
    m.handle_connect(EPOCH_NS + 1, b);
    m.handle_message(EPOCH_NS + 1, b, hello("face-left", PROTOCOL_VERSION));
    let c = closes(&drain(&mut m));
    assert_eq!(c.len(), 1);
    assert_eq!(c[0].0, a);
    assert!(c[0].1.contains("connected again on conn#2"), "{}", c[0].1);
    assert_eq!(m.node_by_name("face-left").map(|n| n.conn), Some(b));
}

#[test]
fn a_silent_connection_times_out() {
    let mut m = master();
    m.handle_connect(EPOCH_NS, ConnId(7));
    let t = m.poll_timeout().unwrap();
    assert_eq!(t, EPOCH_NS + MasterConfig::default().handshake_timeout_ns);
    m.handle_timeout(t - 1);
    assert!(closes(&drain(&mut m)).is_empty());
    m.handle_timeout(t);
    let c = closes(&drain(&mut m));
    assert_eq!(c.len(), 1);
    assert!(
        c[0].1.contains("conn#7 sent no Hello within 5000.0 ms"),
        "{}",
        c[0].1
    );
}

#[test]
fn frames_are_refused_out_of_order_beyond_the_pipeline_and_for_another_scene() {
    let mut m = master();
    m.submit_frame(0, test_frame(5, 1, 0)).unwrap();
    // No node: frame 5 swaps at once, so the pipeline is empty again.
    assert_eq!(m.swapped_upto(), Some(5));
    assert!(matches!(
        m.submit_frame(1, test_frame(7, 1, 0)),
        Err(SubmitError::OutOfOrder {
            frame: 7,
            expected: 6
        })
    ));
    assert!(matches!(
        m.submit_frame(1, test_frame(6, 2, 0)),
        Err(SubmitError::WrongSceneVersion { .. })
    ));
    let mut bad = test_frame(6, 1, 0);
    bad.heads.clear();
    assert!(matches!(
        m.submit_frame(1, bad),
        Err(SubmitError::Invalid(_))
    ));
    // With a node that never answers, two frames fill the pipeline.
    m.handle_connect(1, ConnId(1));
    m.handle_message(1, ConnId(1), hello("n", PROTOCOL_VERSION));
    m.submit_frame(2, test_frame(6, 1, 0)).unwrap();
    m.submit_frame(3, test_frame(7, 1, 0)).unwrap();
    assert!(!m.can_submit());
    assert!(matches!(
        m.submit_frame(4, test_frame(8, 1, 0)),
        Err(SubmitError::PipelineFull { oldest: 6, .. })
    ));
}

#[test]
fn settings_out_of_range_are_refused() {
    #[track_caller]
    fn check(config: MasterConfig, field: &str) {
        match MasterCore::new(config, test_scene()) {
            Err(MasterError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
            other => panic!("expected an error for {field}, got {other:?}"),
        }
    }
    let base = MasterConfig::default;
    check(
        MasterConfig {
            target_hz: 0.0,
            ..base()
        },
        "target_hz",
    );
    check(
        MasterConfig {
            target_hz: f32::NAN,
            ..base()
        },
        "target_hz",
    );
    check(
        MasterConfig {
            deadline_ns: 0,
            ..base()
        },
        "deadline_ns",
    );
    check(
        MasterConfig {
            clock_probe_interval_ns: 0,
            ..base()
        },
        "clock_probe_interval_ns",
    );
    check(
        MasterConfig {
            clock_window: 0,
            ..base()
        },
        "clock_window",
    );
    assert!(MasterCore::new(base(), test_scene()).is_ok());
}

#[test]
fn invalid_node_stats_close_the_node() {
    let mut m = master();
    m.handle_connect(EPOCH_NS, ConnId(1));
    m.handle_message(EPOCH_NS, ConnId(1), hello("n", PROTOCOL_VERSION));
    let stats = crate::message::NodeStats {
        frame: 0,
        render_ms: f32::NAN,
        barrier_wait_ms: 0.0,
        present_time_ns: 0,
    };
    m.handle_message(EPOCH_NS, ConnId(1), Message::NodeStats(stats));
    let c = closes(&drain(&mut m));
    assert_eq!(c.len(), 1);
    assert!(
        c[0].1.contains("invalid NodeStats") && c[0].1.contains("render_ms"),
        "{}",
        c[0].1
    );
}

// Direct checks of the node's side.

fn live_node() -> NodeCore {
    let mut node = NodeCore::new(NodeConfig::new("face-left", Role::Face));
    assert_eq!(node.poll(), Some(NodeOutput::Dial));
    node.connect(0);
    node.handle_message(
        1,
        Message::Welcome(crate::message::Welcome {
            protocol_version: PROTOCOL_VERSION,
            target_hz: 120.0,
            deadline_ms: 50.0,
        }),
    );
    node.handle_message(
        2,
        Message::SceneSnapshot(Box::new(crate::message::SceneSnapshot {
            version: 1,
            showcase: test_scene(),
            current: Some(test_frame(10, 1, 0)),
            maps: Vec::new(),
        })),
    );
    assert!(node.is_live());
    node
}

fn node_outputs(node: &mut NodeCore) -> Vec<NodeOutput> {
    std::iter::from_fn(|| node.poll()).take(10_000).collect()
}

fn node_close_reason(out: &[NodeOutput]) -> Option<String> {
    out.iter().find_map(|o| match o {
        NodeOutput::Close { reason } => Some(reason.clone()),
        _ => None,
    })
}

#[test]
fn a_node_renders_its_snapshot_frame_then_presents_on_swap() {
    let mut node = live_node();
    let out = node_outputs(&mut node);
    let kinds: Vec<&str> = out
        .iter()
        .map(|o| match o {
            NodeOutput::Transmit(m) => m.kind(),
            NodeOutput::Event(NodeEvent::Connected { .. }) => "Connected",
            NodeOutput::Event(NodeEvent::SceneChanged { .. }) => "SceneChanged",
            NodeOutput::Event(NodeEvent::Render { .. }) => "Render",
            other => panic!("unexpected {other:?}"),
        })
        .collect();
    assert_eq!(kinds, ["Hello", "Connected", "SceneChanged", "Render"]);
    // Swap before the render finished: present as soon as it is done.
    node.handle_message(3, Message::Swap(Swap { frame: 10 }));
    assert!(node_outputs(&mut node).is_empty());
    node.rendered(5, 10, 0xabc, 3).unwrap();
    let out = node_outputs(&mut node);
    assert_eq!(
        out,
        [
            NodeOutput::Transmit(Message::Ready(Ready {
                frame: 10,
                output_hash: 0xabc
            })),
            NodeOutput::Event(NodeEvent::Present { frame: 10 }),
        ]
    );
    node.presented(6, 10).unwrap();
    match node_outputs(&mut node).as_slice() {
        [NodeOutput::Transmit(Message::NodeStats(s))] => {
            assert_eq!(
                (s.frame, s.present_time_ns, s.barrier_wait_ms),
                (10, 6, 0.0)
            );
        }
        other => panic!("{other:?}"),
    }
    // Frame 11: Ready at 20, Swap at 27 -> 7 ns of barrier wait.
    node.handle_message(15, Message::FrameState(Box::new(test_frame(11, 1, 0))));
    node.rendered(20, 11, 1, 5).unwrap();
    node.handle_message(27, Message::Swap(Swap { frame: 11 }));
    node.presented(28, 11).unwrap();
    let stats = node_outputs(&mut node).into_iter().find_map(|o| match o {
        NodeOutput::Transmit(Message::NodeStats(s)) => Some(s),
        _ => None,
    });
    assert_eq!(stats.unwrap().barrier_wait_ms, 7e-6);
}

#[test]
fn a_master_out_of_protocol_makes_the_node_close_and_back_off() {
    #[track_caller]
    fn check(message: Message, want: &str) {
        let mut node = live_node();
        node_outputs(&mut node);
        node.handle_message(100, message);
        let out = node_outputs(&mut node);
        let reason = node_close_reason(&out).expect("the node closes");
        assert!(reason.contains(want), "{reason} does not say {want:?}");
        assert!(matches!(
            out.first(),
            Some(NodeOutput::Transmit(Message::Bye(_)))
        ));
        assert_eq!(node.poll_timeout(), Some(100 + Backoff::default().delay(0)));
        node.handle_timeout(100 + Backoff::default().delay(0));
        assert_eq!(node.poll(), Some(NodeOutput::Dial));
    }
    check(
        Message::Swap(Swap { frame: 11 }),
        "Swap for frame 11, the next frame to swap is 10",
    );
    check(
        Message::FrameState(Box::new(test_frame(10, 1, 0))),
        "frame 10 after frame 10",
    );
    check(
        Message::FrameState(Box::new(test_frame(11, 9, 0))),
        "refers to scene version 9",
    );
    let mut no_heads = test_frame(11, 1, 0);
    no_heads.heads.clear();
    check(Message::FrameState(Box::new(no_heads)), "1 observers");
    check(hello("x", PROTOCOL_VERSION), "unexpected Hello");
    check(
        Message::Ready(Ready {
            frame: 10,
            output_hash: 0,
        }),
        "unexpected Ready",
    );
}

#[test]
fn a_node_gives_up_a_handshake_that_does_not_finish() {
    let mut node = NodeCore::new(NodeConfig::new("n", Role::Camera));
    node_outputs(&mut node);
    node.connect(1_000);
    node_outputs(&mut node);
    let t = node.poll_timeout().unwrap();
    assert_eq!(t, 1_000 + 5_000 * MS);
    node.handle_timeout(t);
    let reason = node_close_reason(&node_outputs(&mut node)).unwrap();
    assert!(reason.contains("no snapshot within 5000.0 ms"), "{reason}");
    // A master that speaks another version is refused too.
    node.handle_timeout(node.poll_timeout().unwrap());
    assert_eq!(node.poll(), Some(NodeOutput::Dial));
    node.connect(t + 1);
    node.handle_message(
        t + 2,
        Message::Welcome(crate::message::Welcome {
            protocol_version: PROTOCOL_VERSION + 1,
            target_hz: 60.0,
            deadline_ms: 50.0,
        }),
    );
    let reason = node_close_reason(&node_outputs(&mut node)).unwrap();
    let want = format!("master speaks protocol version {}", PROTOCOL_VERSION + 1);
    assert!(reason.contains(&want), "{reason}");
    assert_eq!(node.failures(), 2);
}
