//! Arbitrary message sequences against both cores: nothing panics, and a
//! message from one connection closes at most that connection (or, for a
//! Hello, the older connection of the same name).

use super::config;
use crate::PROTOCOL_VERSION;
use crate::message::{
    Bye, Capabilities, ClockProbe, ClockReply, Hello, Message, NodeStats, Ready, Role,
    SceneSnapshot, Swap, Welcome,
};
use crate::session::testing::{test_frame, test_scene};
use crate::session::*;
use proptest::prelude::*;

fn message() -> impl Strategy<Value = Message> {
    let n = 0u64..6;
    prop_oneof![
        (0u32..3, 0usize..3).prop_map(|(v, name)| Message::Hello(Hello {
            protocol_version: PROTOCOL_VERSION + v.saturating_sub(1),
            node: format!("n{name}"),
            role: Role::Face,
            capabilities: Capabilities::default(),
        })),
        Just(Message::Welcome(Welcome {
            protocol_version: PROTOCOL_VERSION,
            target_hz: 60.0,
            deadline_ms: 50.0,
        })),
        (n.clone(), 1u64..3).prop_map(|(f, v)| Message::SceneSnapshot(Box::new(SceneSnapshot {
            version: v,
            showcase: test_scene(),
            current: Some(test_frame(f, v, 0)),
            maps: Vec::new(),
        }))),
        (n.clone(), 1u64..3).prop_map(|(f, v)| Message::FrameState(Box::new(test_frame(f, v, 0)))),
        n.clone().prop_map(|frame| Message::Ready(Ready {
            frame,
            output_hash: 0
        })),
        n.clone().prop_map(|frame| Message::Swap(Swap { frame })),
        (n.clone(), 0u64..1_000_000_000).prop_map(|(frame, t)| Message::NodeStats(NodeStats {
            frame,
            render_ms: 1.0,
            barrier_wait_ms: 0.5,
            present_time_ns: t,
        })),
        n.clone().prop_map(|id| Message::ClockProbe(ClockProbe {
            id,
            master_send_ns: 5
        })),
        (n, 0u64..2_000, 0u64..2_000).prop_map(|(id, a, b)| Message::ClockReply(ClockReply {
            id,
            master_send_ns: a,
            node_recv_ns: b,
            node_send_ns: b + 3,
        })),
        Just(Message::Bye(Bye {
            reason: "fuzz".into()
        })),
    ]
}

#[derive(Clone, Debug)]
enum Input {
    Connect(u64),
    Message(u64, Message),
    Disconnect(u64),
    Submit,
    Wait(u64),
}

fn input() -> impl Strategy<Value = Input> {
    let conn = 1u64..4;
    prop_oneof![
        1 => conn.clone().prop_map(Input::Connect),
        4 => (conn.clone(), message()).prop_map(|(c, m)| Input::Message(c, m)),
        1 => conn.prop_map(Input::Disconnect),
        2 => Just(Input::Submit),
        1 => (0u64..80_000_000).prop_map(Input::Wait),
    ]
}

proptest! {
    #[test]
    fn the_master_survives_any_sequence_and_closes_only_the_sender(
        inputs in prop::collection::vec(input(), 1..60)
    ) {
        let mut m = MasterCore::new(config(50), test_scene()).unwrap();
        let mut now = 1_000_000_000u64;
        let mut frame = 0;
        for inp in inputs {
            let sender = match &inp {
                Input::Message(c, _) => Some(ConnId(*c)),
                _ => None,
            };
            let timers = matches!(inp, Input::Wait(_) | Input::Submit);
            match inp {
                Input::Connect(c) => m.handle_connect(now, ConnId(c)),
                Input::Message(c, msg) => m.handle_message(now, ConnId(c), msg),
                Input::Disconnect(c) => m.handle_disconnect(now, ConnId(c)),
                Input::Submit => {
                    if m.can_submit() {
                        m.submit_frame(now, test_frame(frame, 1, now)).unwrap();
                        frame += 1;
                    }
                }
                Input::Wait(dt) => {
                    now += dt;
                    m.handle_timeout(now);
                }
            }
            let mut replaced = 0;
            for out in std::iter::from_fn(|| m.poll()).take(10_000) {
                if let MasterOutput::Close { conn, reason } = out {
                    match reason {
                        CloseReason::Replaced { by, .. } => {
                            prop_assert_eq!(Some(by), sender);
                            replaced += 1;
                        }
                        CloseReason::MissedDeadline { .. } | CloseReason::HandshakeTimeout { .. } => {
                            prop_assert!(timers, "{:?} closed {:?} outside a timer", reason, conn);
                        }
                        _ => prop_assert_eq!(Some(conn), sender, "{}", reason),
                    }
                }
            }
            prop_assert!(replaced <= 1);
            prop_assert!(m.frames_in_flight() <= MAX_FRAMES_IN_FLIGHT);
        }
    }

    /// Mostly a well-behaved master (`None`: the next valid message) with
    /// arbitrary messages mixed in (1 in 20), so the node gets deep into its states.
    #[test]
    fn a_node_survives_any_sequence_from_the_master(
        steps in prop::collection::vec(
            (prop::option::weighted(0.05, message()), 0u64..200_000_000),
            1..120,
        )
    ) {
        let mut node = NodeCore::new(NodeConfig::new("n", Role::Projector));
        let mut now = 1_000u64;
        let mut hash = 0;
        // The well-behaved master's view: 0 await Welcome, 1 await snapshot, 2 live.
        let mut stage = 0;
        let mut next_frame = 0u64;
        let mut unswapped = std::collections::VecDeque::new();
        for (random, dt) in steps {
            now += dt;
            if node.poll_timeout().is_some_and(|t| t <= now) {
                node.handle_timeout(now);
            }
            let msg = random.unwrap_or_else(|| match stage {
                0 => Message::Welcome(Welcome {
                    protocol_version: PROTOCOL_VERSION,
                    target_hz: 60.0,
                    deadline_ms: 50.0,
                }),
                1 => {
                    unswapped.push_back(next_frame);
                    next_frame += 1;
                    Message::SceneSnapshot(Box::new(SceneSnapshot {
                        version: 1,
                        showcase: test_scene(),
                        current: Some(test_frame(next_frame - 1, 1, 0)),
                        maps: Vec::new(),
                    }))
                }
                _ => match unswapped.front() {
                    Some(&f) if unswapped.len() >= 2 || dt % 2 == 0 => {
                        unswapped.pop_front();
                        Message::Swap(Swap { frame: f })
                    }
                    _ => {
                        unswapped.push_back(next_frame);
                        next_frame += 1;
                        Message::FrameState(Box::new(test_frame(next_frame - 1, 1, 0)))
                    }
                },
            });
            node.handle_message(now, msg);
            for out in std::iter::from_fn(|| node.poll()).take(10_000).collect::<Vec<_>>() {
                match out {
                    NodeOutput::Dial => node.connect(now),
                    NodeOutput::Event(NodeEvent::Render { frame, .. }) => {
                        hash += 1;
                        node.rendered(now, frame.frame, hash, 1).unwrap();
                    }
                    NodeOutput::Event(NodeEvent::Present { frame }) => {
                        node.presented(now, frame).unwrap();
                    }
                    NodeOutput::Event(NodeEvent::Connected { .. }) => {
                        stage = 1;
                        unswapped.clear();
                    }
                    NodeOutput::Event(NodeEvent::SceneChanged { .. }) => stage = 2,
                    NodeOutput::Event(NodeEvent::Disconnected { .. }) => stage = 0,
                    _ => {}
                }
            }
        }
    }
}
