//! A real loopback cluster: the master and four nodes over QUIC with
//! mutual TLS for 600 frames. Every node presents every frame in order; a
//! killed node does not stall the rest beyond the deadline and rejoins
//! with the full state; DTrack datagrams sent to the master's port move
//! the observer; a peer that sends garbage is closed and nobody else
//! notices. Every wait is bounded.

use glam::Vec3;
use showcase_master::certs::{self, ClusterCerts, MASTER_FILE, MASTER_SERVER_NAME};
use showcase_master::cluster::{Roster, Server, ServerSettings, Show, Tracking};
use showcase_master::tracking::Tracker;
use showcase_proto::config::{BodyMapping, TrackingConfig, TrackingSource};
use showcase_proto::session::MasterConfig;
use showcase_proto::{FrameState, Light, LightSource, Observer, Pose, Role, Showcase};
use showcase_render::net::{ClusterIdentity, client_config};
use showcase_render::node::{
    NodeLog, NodeRunError, NodeRuntime, RenderError, RenderOutput, Renderer, StateHashRenderer,
    run_node,
};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::time::timeout;
use tokio_util::sync::CancellationToken;

const FRAMES: u64 = 600;
const HZ: f32 = 200.0;

fn identity(c: &ClusterCerts, name: &str) -> ClusterIdentity {
    let p = c.peers.iter().find(|p| p.name == name).unwrap();
    ClusterIdentity::from_pem(&c.ca_pem, &p.cert_pem, &p.key_pem).unwrap()
}

/// A master at `HZ` on `listen` that admits `listed` as projectors and
/// starts once all of them joined; no tracking, no metrics.
fn settings(
    c: &ClusterCerts,
    listed: &[String],
    listen: std::net::SocketAddr,
    frames: Option<u64>,
) -> ServerSettings {
    ServerSettings {
        listen,
        identity: identity(c, MASTER_FILE),
        roster: Roster::new(listed.iter().map(|n| (n.clone(), Role::Projector))),
        core: MasterConfig {
            target_hz: HZ,
            ..MasterConfig::default()
        },
        frames,
        wait_for_nodes: listed.len(),
        start_timeout: Duration::from_secs(10),
        tracking: None,
        metrics: None,
        keep_frames: true,
        illumination_lag: None,
        illumination_patch_area: None,
        maps: Vec::new(),
    }
}

fn scene() -> Showcase {
    Showcase {
        name: "cluster-test".into(),
        observers: ["alice", "bob"]
            .map(|n| Observer {
                name: n.into(),
                head: Pose::default(),
                ipd: 0.064,
            })
            .to_vec(),
        lights: vec![LightSource {
            name: "key".into(),
            light: Light::Point {
                position: Vec3::Y,
                intensity: Vec3::ONE,
            },
        }],
        ..Showcase::default()
    }
}

/// Digests like the state-hash renderer and keeps every frame state it drew.
struct Recording {
    inner: StateHashRenderer,
    states: Arc<Mutex<Vec<FrameState>>>,
}

impl Renderer for Recording {
    fn set_scene(&mut self, v: u64, s: Arc<Showcase>) -> Result<(), RenderError> {
        self.inner.set_scene(v, s)
    }
    fn render(&mut self, f: &FrameState, s: &Showcase) -> Result<RenderOutput, RenderError> {
        self.states.lock().unwrap().push(f.clone());
        self.inner.render(f, s)
    }
    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        self.inner.present(frame)
    }
    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<showcase_proto::session::Solution>>,
    ) -> Result<(), RenderError> {
        self.inner.set_illumination(illumination)
    }
}

type Node = (
    tokio::task::JoinHandle<NodeLog>,
    CancellationToken,
    Arc<Mutex<Vec<FrameState>>>,
);

fn start_node(c: &ClusterCerts, name: &str, master: std::net::SocketAddr) -> Node {
    let rt = NodeRuntime {
        name: name.into(),
        role: Role::Projector,
        master,
        identity: identity(c, name),
        bind: "127.0.0.1:0".parse().unwrap(),
        capabilities: Default::default(),
        write_frames: None,
        keep_presented: true,
    };
    let states = Arc::new(Mutex::new(Vec::new()));
    let mut r = Recording {
        inner: StateHashRenderer::new(name, Role::Projector),
        states: states.clone(),
    };
    let stop = CancellationToken::new();
    let s = stop.clone();
    let h = tokio::spawn(async move { run_node(rt, &mut r, s).await.unwrap() });
    (h, stop, states)
}

fn contiguous(frames: &[u64]) -> bool {
    frames.windows(2).all(|w| w[1] == w[0] + 1)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loopback_cluster_of_four_nodes() {
    let names: Vec<String> = (0..4)
        .map(|i| format!("node-{i}"))
        .chain(["rogue".into()])
        .collect();
    let c = certs::generate(&names).unwrap();
    let scene = scene();
    let tracking = TrackingConfig {
        source: TrackingSource::Dtrack,
        port: Some(0),
        file: None,
        room_translation: [0.0; 3],
        room_rotation_deg: [0.0; 3],
        predict_ms: 0.0,
        limits: Default::default(),
        bodies: vec![BodyMapping {
            id: 0,
            target: "observer:alice".into(),
        }],
    };
    let show = Show::new(
        Tracking::Live(Tracker::new(&tracking, &scene).unwrap()),
        HZ as f64,
    );
    let metrics = Arc::new(Mutex::new(Vec::<u8>::new()));
    struct Sink(Arc<Mutex<Vec<u8>>>);
    impl std::io::Write for Sink {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let server = Server::bind(ServerSettings {
        tracking: Some("127.0.0.1:0".parse().unwrap()),
        metrics: Some(Box::new(Sink(metrics.clone()))),
        ..settings(
            &c,
            &names[..4],
            "127.0.0.1:0".parse().unwrap(),
            Some(FRAMES),
        )
    })
    .unwrap();
    let addr = server.local_addr();
    let udp_addr = server.tracking_addr().unwrap();
    let stop = CancellationToken::new();
    let master = tokio::spawn(server.run(scene, show, stop.clone()));

    let mut nodes: Vec<Node> = (0..4).map(|i| start_node(&c, &names[i], addr)).collect();
    let wait_frames = |states: &Arc<Mutex<Vec<FrameState>>>, n: usize| {
        let states = states.clone();
        async move {
            while states.lock().unwrap().len() < n {
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        }
    };
    let watch = nodes[0].2.clone();

    // Kill node-3 around frame 150 and bring it back around frame 250.
    timeout(Duration::from_secs(20), wait_frames(&watch, 150))
        .await
        .unwrap();
    let (h3, stop3, states3_first) = nodes.remove(3);
    stop3.cancel();
    let first_log = timeout(Duration::from_secs(5), h3).await.unwrap().unwrap();
    timeout(Duration::from_secs(20), wait_frames(&watch, 250))
        .await
        .unwrap();
    nodes.push(start_node(&c, "node-3", addr));

    // A peer with a valid certificate that sends garbage.
    let mut ep = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).unwrap();
    ep.set_default_client_config(client_config(&identity(&c, "rogue")).unwrap());
    let rogue = ep.connect(addr, MASTER_SERVER_NAME).unwrap().await.unwrap();
    let (mut send, _recv) = rogue.open_bi().await.unwrap();
    send.write_all(&[5, 0, 0, 0, 0xff, 0xff, 0xff, 0xff, 0xff])
        .await
        .unwrap();
    let closed = timeout(Duration::from_secs(5), rogue.closed())
        .await
        .unwrap();
    assert!(
        matches!(closed, quinn::ConnectionError::ApplicationClosed(_)),
        "rogue peer: {closed:?}"
    );

    // Move alice with DTrack datagrams (positions in mm).
    timeout(Duration::from_secs(20), wait_frames(&watch, 350))
        .await
        .unwrap();
    let udp = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let dg = "fr 1\r\n6d 1 [0 1.000][300 400 500 0 0 0][1 0 0 0 1 0 0 0 1]\r\n";
    for _ in 0..5 {
        udp.send_to(dg.as_bytes(), udp_addr).await.unwrap();
        tokio::time::sleep(Duration::from_millis(2)).await;
    }

    let run = timeout(Duration::from_secs(30), master)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    let mut logs = Vec::new();
    for (h, s, states) in nodes {
        s.cancel();
        logs.push((
            timeout(Duration::from_secs(5), h).await.unwrap().unwrap(),
            states,
        ));
    }

    // Every surviving node presented every frame, in order.
    for (log, _) in &logs[..3] {
        let frames: Vec<u64> = log.presented.iter().map(|p| p.0).collect();
        assert_eq!(frames, (0..FRAMES).collect::<Vec<_>>());
    }
    // The killed node presented a contiguous prefix; after its rejoin it
    // presented a contiguous run to the end, starting from the state the
    // others had for that frame (the full state, not a partial one).
    let before: Vec<u64> = first_log.presented.iter().map(|p| p.0).collect();
    assert!(
        before.len() >= 100 && contiguous(&before) && before[0] == 0,
        "{before:?}"
    );
    let (after_log, after_states) = &logs[3];
    let after: Vec<u64> = after_log.presented.iter().map(|p| p.0).collect();
    assert!(
        contiguous(&after) && *after.last().unwrap() == FRAMES - 1,
        "{after:?}"
    );
    assert!(after[0] > *before.last().unwrap());
    let reference = logs[0].1.lock().unwrap().clone();
    for s in after_states.lock().unwrap().iter() {
        assert_eq!(
            s, &reference[s.frame as usize],
            "rejoined node drew another state"
        );
    }
    drop(states3_first);
    // Killing and restarting cost at most one deadline of frame-clock ticks.
    let max_dropped =
        (MasterConfig::default().deadline_ns as f64 * HZ as f64 / 1e9).ceil() as u64 + 2;
    assert!(
        run.dropped_ticks <= max_dropped,
        "{} ticks dropped",
        run.dropped_ticks
    );
    assert_eq!(run.submitted, FRAMES);
    // Every live node was sent every frame's state, and the writers counted it.
    assert!(
        run.frame_messages >= 3 * FRAMES,
        "{} FrameStates sent",
        run.frame_messages
    );
    assert!(
        run.frame_bytes >= 50 * run.frame_messages,
        "{} bytes",
        run.frame_bytes
    );
    // DTrack moved alice: the last frames show her at (0.3, 0.4, 0.5).
    let last = reference.last().unwrap();
    assert!(
        (last.heads[0].position - Vec3::new(0.3, 0.4, 0.5)).length() < 1e-6,
        "{:?}",
        last.heads[0]
    );
    assert_eq!(last.heads[1], Pose::default(), "bob is not tracked");
    assert!(last.tracking_time_ns.is_some());
    // One metrics line per presented frame, with the documented keys.
    let text = String::from_utf8(metrics.lock().unwrap().clone()).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(
        lines.len() as u64 >= FRAMES - 8,
        "{} metric lines",
        lines.len()
    );
    for key in [
        "frame",
        "heads",
        "lights",
        "nodes",
        "swap_skew_ms",
        "tracking_to_swap_ms",
        "evicted",
    ] {
        assert!(
            lines[10].get(key).is_some(),
            "metrics lack {key}: {}",
            lines[10]
        );
    }
    let node0 = &lines[10]["nodes"][0];
    for key in ["name", "render_ms", "barrier_wait_ms", "present_offset_ms"] {
        assert!(node0.get(key).is_some(), "node metrics lack {key}");
    }
}

/// Two replays of the same recorded session give bit-identical per-frame
/// output hashes on every node, and the hashes do follow the recording.
/// Two seconds of the scripted walk at 50 datagrams per second, with
/// arrival jitter, as a live recording would have, written to a session
/// file of its own; replayed twice at 120 Hz.
async fn replay_twice(
    scene: &Showcase,
    tag: &str,
) -> (
    showcase_master::cluster::commands::ReplayOutcome,
    showcase_master::cluster::commands::ReplayOutcome,
) {
    use showcase_master::cluster::commands::replay;
    use showcase_master::tracking::recording::Recorder;
    use showcase_master::tracking::scripted::{carried_object, walk_datagram_carrying};
    // The walk carries the scene's virtual object too, where it has one.
    let carried = carried_object(scene).map(|i| &scene.objects[i].transform);
    let mut rec = Recorder::new(Vec::new(), "test walk", None).unwrap();
    for i in 0..100u64 {
        let t = i as f64 * 0.02 + if i % 3 == 0 { 0.004 } else { 0.0 };
        rec.record(t, &walk_datagram_carrying(i, t, carried))
            .unwrap();
    }
    let dir = std::env::temp_dir().join(format!("showcase-replay-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let session = dir.join("walk.jsonl");
    std::fs::write(&session, rec.into_inner()).unwrap();
    let a = timeout(
        Duration::from_secs(60),
        replay(scene, &session, 120.0, None),
    )
    .await
    .unwrap()
    .unwrap();
    let b = timeout(
        Duration::from_secs(60),
        replay(scene, &session, 120.0, None),
    )
    .await
    .unwrap()
    .unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    (a, b)
}

#[track_caller]
fn check_identical_replays(
    scene: &Showcase,
    a: &showcase_master::cluster::commands::ReplayOutcome,
    b: &showcase_master::cluster::commands::ReplayOutcome,
) {
    assert_eq!(a.frames, 239, "the recording's 1.984 s at 120 Hz");
    assert_eq!(a.nodes.len(), scene.faces.len() + scene.projectors.len());
    for (x, y) in a.nodes.iter().zip(&b.nodes) {
        assert_eq!(x.name, y.name);
        assert_eq!(x.hashes.len() as u64, a.frames, "{} missed frames", x.name);
        assert_eq!(x.hashes, y.hashes, "{} differs between replays", x.name);
        let distinct: std::collections::HashSet<u64> = x.hashes.iter().map(|h| h.1).collect();
        assert_eq!(
            distinct.len() as u64,
            a.frames,
            "{}: every frame's state differs",
            x.name
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replays_are_bit_identical() {
    let scene =
        showcase_master::scene_file::load_scene(&showcase_master::demo::default_scene()).unwrap();
    let (a, b) = replay_twice(&scene, "direct").await;
    check_identical_replays(&scene, &a, &b);
}

/// In global mode too: each solution is first drawn a fixed number of
/// frames after the state it solves, whatever the solver's speed, so
/// every node's every frame hash (which digests the solution's version
/// and values) repeats; and they differ from the same replay in direct
/// mode, so the solution is in them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn global_mode_replays_are_bit_identical() {
    let mut scene =
        showcase_master::scene_file::load_any(std::path::Path::new("builtin:figure3")).unwrap();
    let (direct, _) = replay_twice(&scene, "figure3-direct").await;
    scene.illumination = showcase_proto::IlluminationMode::Global;
    let (a, b) = replay_twice(&scene, "figure3-global").await;
    check_identical_replays(&scene, &a, &b);
    for (g, d) in a.nodes.iter().zip(&direct.nodes) {
        assert_ne!(g.hashes, d.hashes, "{}: global mode drew nothing", g.name);
    }
}

/// A node whose certificate the cluster CA signed, under a name the
/// master's roster lacks, is refused at its Hello with a reason naming the
/// claimed name, the certificate's names and the roster; it never takes
/// part in a frame. A listed node with another node's certificate is
/// refused too, and the listed nodes run on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_listed_names_with_their_own_certificates_join() {
    let names: Vec<String> = ["node-0", "node-1", "intruder"].map(String::from).to_vec();
    let c = certs::generate(&names).unwrap();
    let frames = 120;
    let server = Server::bind(settings(
        &c,
        &names[..2],
        "127.0.0.1:0".parse().unwrap(),
        Some(frames),
    ))
    .unwrap();
    let addr = server.local_addr();
    let master = tokio::spawn(server.run(
        scene(),
        Show::new(Tracking::None, HZ as f64),
        CancellationToken::new(),
    ));
    let nodes: Vec<Node> = (0..2).map(|i| start_node(&c, &names[i], addr)).collect();

    // Real node runtimes with valid cluster-CA certificates: the intruder
    // under its own name, the impostor under node-1's. Each must stop by
    // itself with the master's refusal (no cancellation).
    let refused = |name: &str, cert: &str| {
        let rt = NodeRuntime {
            name: name.into(),
            role: Role::Projector,
            master: addr,
            identity: identity(&c, cert),
            bind: "127.0.0.1:0".parse().unwrap(),
            capabilities: Default::default(),
            write_frames: None,
            keep_presented: false,
        };
        let mut r = StateHashRenderer::new(name, Role::Projector);
        tokio::spawn(async move { run_node(rt, &mut r, CancellationToken::new()).await })
    };
    let intruder = refused("intruder", "intruder");
    let impostor = refused("node-1", "intruder");
    let expected = [
        ("intruder", intruder, "the configuration lists no node"),
        ("impostor", impostor, "not issued to that name"),
    ];
    for (who, h, why) in expected {
        // The node is told why, in the master's words.
        match timeout(Duration::from_secs(20), h).await.unwrap().unwrap() {
            Err(NodeRunError::Refused { reason }) => assert!(
                reason.contains(why) && reason.contains("[\"intruder\"]"),
                "{who}: {reason}"
            ),
            other => panic!("{who} was not refused: {other:?}"),
        }
    }

    let run = timeout(Duration::from_secs(30), master)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    let mut logs = Vec::new();
    for (h, s, _) in nodes {
        s.cancel();
        logs.push(timeout(Duration::from_secs(5), h).await.unwrap().unwrap());
    }

    // The listed nodes ran every frame; the intruder and the impostor,
    // refused above, joined no frame.
    for log in &logs {
        assert_eq!(log.presented.len() as u64, frames, "{log:?}");
    }
    let joined: Vec<&str> = run.joins.iter().map(|(n, _)| n.as_str()).collect();
    assert!(!joined.contains(&"intruder"), "{joined:?}");
    // Each refusal names all three: the claim, the certificate, the roster.
    let expected = [
        (
            "intruder",
            [
                "certificate is issued to [\"intruder\"]",
                "lists only [\"node-0\", \"node-1\"]",
            ],
        ),
        ("node-1", ["not issued to that name", "[\"intruder\"]"]),
    ];
    for (claimed, parts) in expected {
        let refusal = run
            .refusals
            .iter()
            .find(|r| r.starts_with(&format!("node {claimed:?}")))
            .unwrap_or_else(|| panic!("no refusal of {claimed}: {:?}", run.refusals));
        assert!(parts.iter().all(|p| refusal.contains(p)), "{refusal}");
    }
}

/// The master dies without a word (its runtime is dropped, as kill -9
/// would) and a new one starts on the same address with the same
/// identity. The nodes learn of it from the new master's stateless reset,
/// not from the idle timeout, and both rejoin and run its frames.
#[test]
fn a_restarted_master_is_noticed_by_reset_and_the_nodes_rejoin() {
    let names: Vec<String> = ["node-0", "node-1"].map(String::from).to_vec();
    let c = certs::generate(&names).unwrap();
    let settings = |listen, frames| settings(&c, &names, listen, frames);
    let rt = |threads| {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(threads)
            .enable_all()
            .build()
            .unwrap()
    };
    // The nodes live in their own runtime for the whole test.
    let nodes_rt = rt(2);
    let old_rt = rt(1);
    let old = old_rt
        .block_on(async { Server::bind(settings("127.0.0.1:0".parse().unwrap(), None)) })
        .unwrap();
    let addr = old.local_addr();
    old_rt.spawn(old.run(
        scene(),
        Show::new(Tracking::None, HZ as f64),
        CancellationToken::new(),
    ));
    let nodes: Vec<Node> =
        nodes_rt.block_on(async { names.iter().map(|n| start_node(&c, n, addr)).collect() });
    let presented = |n: &Node| n.2.lock().unwrap().len();
    let wait = |what: &str, done: &dyn Fn() -> bool| {
        let t0 = std::time::Instant::now();
        while !done() {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "timed out waiting for {what}"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    wait("the first master's frames", &|| {
        nodes.iter().all(|n| presented(n) >= 50)
    });
    // kill -9: no task of the old master runs again, nothing is closed.
    old_rt.shutdown_background();

    let new_rt = rt(1);
    let new = new_rt.block_on(async {
        let t0 = std::time::Instant::now();
        loop {
            match Server::bind(settings(addr, Some(60))) {
                Ok(s) => break s,
                Err(e) if t0.elapsed() < Duration::from_secs(5) => {
                    let _ = e;
                    tokio::time::sleep(Duration::from_millis(10)).await
                }
                Err(e) => panic!("rebinding {addr}: {e}"),
            }
        }
    });
    let run = new_rt
        .block_on(async {
            timeout(
                Duration::from_secs(30),
                new.run(
                    scene(),
                    Show::new(Tracking::None, HZ as f64),
                    CancellationToken::new(),
                ),
            )
            .await
        })
        .unwrap()
        .unwrap();
    let logs: Vec<NodeLog> = nodes_rt.block_on(async {
        let mut logs = Vec::new();
        for (h, s, _) in nodes {
            s.cancel();
            logs.push(timeout(Duration::from_secs(5), h).await.unwrap().unwrap());
        }
        logs
    });
    assert_eq!(run.submitted, 60);
    for log in &logs {
        assert_eq!(log.joins, 2, "{log:?}");
        // The second master's 60 frames were all presented after the
        // first master's (its numbering starts again at 0).
        let frames: Vec<u64> = log.presented.iter().map(|p| p.0).collect();
        let restart = frames
            .windows(2)
            .position(|w| w[1] < w[0])
            .expect("two runs")
            + 1;
        assert!(restart >= 40, "{frames:?}");
        assert_eq!(frames[restart..], (0..60).collect::<Vec<_>>());
        // The first disconnect is the reset, not the idle timeout.
        let first = log.disconnects.first().expect("a disconnect");
        assert!(first.contains("reset"), "{:?}", log.disconnects);
    }
}

/// A node that will write frame images makes their folder before it
/// joins; a folder it cannot make stops it at once, naming the path,
/// instead of taking it down at the first frame to write.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_makes_its_frames_folder_before_it_joins() {
    let c = certs::generate(&["node-0".to_owned()]).unwrap();
    let dir = std::env::temp_dir().join(format!("showcase-frames-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let blocker = dir.join("a-file");
    std::fs::write(&blocker, b"not a folder").unwrap();
    let rt = |frames: std::path::PathBuf| NodeRuntime {
        name: "node-0".into(),
        role: Role::Face,
        // Nothing listens here: only the folder check can end the run.
        master: "127.0.0.1:9".parse().unwrap(),
        identity: identity(&c, "node-0"),
        bind: "127.0.0.1:0".parse().unwrap(),
        capabilities: Default::default(),
        write_frames: Some((frames, vec![20, 40])),
        keep_presented: false,
    };
    let mut r = StateHashRenderer::new("node-0", Role::Face);
    let bad = blocker.join("frames");
    let e = timeout(
        Duration::from_secs(5),
        run_node(rt(bad.clone()), &mut r, CancellationToken::new()),
    )
    .await
    .expect("a node with an impossible frames folder stops at once")
    .unwrap_err();
    assert!(
        matches!(&e, NodeRunError::WriteFrame { path, .. } if *path == bad),
        "{e}"
    );
    assert!(
        e.to_string().contains("cannot create the frames folder"),
        "{e}"
    );

    let nested = dir.join("show").join("frames");
    let stop = CancellationToken::new();
    stop.cancel();
    timeout(
        Duration::from_secs(5),
        run_node(rt(nested.clone()), &mut r, stop),
    )
    .await
    .unwrap()
    .unwrap();
    assert!(nested.is_dir());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Run `plan` (a walk on two nodes) to its end, within a minute.
async fn walk_loopback(
    plan: showcase_master::cluster::LoopbackPlan,
) -> showcase_master::cluster::LoopbackResult {
    let r = timeout(
        Duration::from_secs(60),
        showcase_master::cluster::run_loopback(plan),
    )
    .await
    .expect("the loopback run ends")
    .unwrap();
    assert_eq!(r.logs.len(), 2);
    r
}

/// A live node keeps the count and the last presented frame, not a record
/// per frame (its memory stays flat over a day); asked to keep them (replay
/// checks), it keeps every one, the same last one included.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_live_node_keeps_a_count_not_every_frame() {
    use showcase_master::cluster::LoopbackPlan;
    use showcase_master::cluster::commands::walk_plan;
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml");
    let scene = showcase_master::scene_file::load_any(&path).unwrap();
    const N: u64 = 40;
    for keep in [false, true] {
        let plan = LoopbackPlan {
            keep_presented: keep,
            ..walk_plan(&scene, 2, 120.0, N).unwrap()
        };
        let r = walk_loopback(plan).await;
        for (name, log) in &r.logs {
            assert_eq!(log.presented_count, N, "{name}");
            assert_eq!(log.last_presented.map(|p| p.0), Some(N - 1), "{name}");
            if keep {
                assert_eq!(log.presented.len() as u64, N, "{name}");
                assert_eq!(log.presented.last().copied(), log.last_presented, "{name}");
            } else {
                assert!(
                    log.presented.is_empty(),
                    "{name} kept {} frames",
                    log.presented.len()
                );
            }
        }
    }
}

/// `run --maps DIR`: the maps `capture --out DIR` wrote (its
/// `summary.json` is no map) reach every node in its first snapshot; a
/// folder without maps is refused with how to make them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_master_started_with_captured_maps_sends_them_in_every_snapshot() {
    use glam::{DVec3, Vec3};
    use showcase_light::Image;
    use showcase_light::reflectance::ReflectanceMap;
    use showcase_master::capture::cluster::captured_maps_in;
    use showcase_master::capture::write_reflectance_map;
    use showcase_master::cluster::LoopbackPlan;
    use showcase_master::cluster::commands::walk_plan;
    let dir = std::env::temp_dir().join(format!("showcase-run-maps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let camera = showcase_proto::PinholeDevice::look_at(
        DVec3::new(0.0, 0.5, -0.5),
        DVec3::ZERO,
        DVec3::Y,
        40.0,
        4,
        3,
    );
    let image = |data| Image {
        width: 4,
        height: 3,
        data,
    };
    let map = ReflectanceMap {
        reflectance: image(vec![Vec3::new(0.6, 0.5, 0.4); 12]),
        weight: Image {
            width: 4,
            height: 3,
            data: vec![1.0; 12],
        },
        depth: Image {
            width: 4,
            height: 3,
            data: vec![0.7; 12],
        },
        object: Image {
            width: 4,
            height: 3,
            data: vec![Some(0); 12],
        },
        camera,
        object_transforms: vec![glam::DMat4::IDENTITY],
    };
    let err = captured_maps_in(&dir).unwrap_err();
    assert!(format!("{err:#}").contains("capture --config"), "{err:#}");
    write_reflectance_map(&dir, "plate", &map).unwrap();
    std::fs::write(dir.join("summary.json"), b"{\"methods\": []}").unwrap();
    let maps = captured_maps_in(&dir).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(maps.len(), 1);
    assert_eq!(maps[0].name, "plate");

    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml");
    let scene = showcase_master::scene_file::load_any(&path).unwrap();
    let plan = LoopbackPlan {
        maps,
        ..walk_plan(&scene, 2, 120.0, 10).unwrap()
    };
    let r = walk_loopback(plan).await;
    for (name, log) in &r.logs {
        assert_eq!(log.presented_count, 10, "{name}");
        assert_eq!(
            log.scenes.first().map(|s| s.1),
            Some(1),
            "{name}: {:?}",
            log.scenes
        );
    }
}

/// Digests like the state-hash renderer and keeps, per rendered frame, the
/// global-illumination solution it was drawn with: its version and a
/// digest of its values.
struct Lit {
    inner: StateHashRenderer,
    solution: Option<(u64, u64)>,
    drawn: Arc<Mutex<Vec<Drawn>>>,
}

/// A rendered frame and its solution's version and values digest.
type Drawn = (u64, Option<(u64, u64)>);

impl Renderer for Lit {
    fn set_scene(&mut self, v: u64, s: Arc<Showcase>) -> Result<(), RenderError> {
        self.inner.set_scene(v, s)
    }
    fn set_illumination(
        &mut self,
        illumination: Option<&Arc<showcase_proto::session::Solution>>,
    ) -> Result<(), RenderError> {
        self.solution = illumination.map(|s| {
            let mut h = showcase_light::digest::Fnv64::default();
            for v in s.values.iter().flat_map(|v| v.channels()) {
                h.write(&v.to_bits().to_le_bytes());
            }
            (s.version, h.finish())
        });
        self.inner.set_illumination(illumination)
    }
    fn render(&mut self, f: &FrameState, s: &Showcase) -> Result<RenderOutput, RenderError> {
        self.drawn.lock().unwrap().push((f.frame, self.solution));
        self.inner.render(f, s)
    }
    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        self.inner.present(frame)
    }
}

/// Global mode over real QUIC: the figure-3 scene with its ceiling light
/// moving along the scripted walk. The master solves the first solution
/// before frame 0 and re-solves off the frame loop as the light moves;
/// both projector nodes draw every frame with the version the master
/// named, with the same values, and later versions reach them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn global_mode_draws_every_frame_with_the_named_solution() {
    use showcase_master::cluster::commands::walk_tracking;
    const GI_FRAMES: u64 = 600;
    let mut scene =
        showcase_master::scene_file::load_any(std::path::Path::new("builtin:figure3")).unwrap();
    scene.illumination = showcase_proto::IlluminationMode::Global;
    let names: Vec<String> = scene.projectors.iter().map(|p| p.name.clone()).collect();
    assert_eq!(names.len(), 2);
    let c = certs::generate(&names).unwrap();
    let tracker = Tracker::new(&walk_tracking(&scene, TrackingSource::Scripted), &scene).unwrap();
    let show = Show::new(Tracking::Scripted(tracker), HZ as f64);
    let server = Server::bind(settings(
        &c,
        &names,
        "127.0.0.1:0".parse().unwrap(),
        Some(GI_FRAMES),
    ))
    .unwrap();
    let addr = server.local_addr();
    let stop = CancellationToken::new();
    let master = tokio::spawn(server.run(scene, show, stop.clone()));
    let mut nodes = Vec::new();
    for name in &names {
        let rt = NodeRuntime {
            name: name.clone(),
            role: Role::Projector,
            master: addr,
            identity: identity(&c, name),
            bind: "127.0.0.1:0".parse().unwrap(),
            capabilities: Default::default(),
            write_frames: None,
            keep_presented: true,
        };
        let drawn = Arc::new(Mutex::new(Vec::new()));
        let mut r = Lit {
            inner: StateHashRenderer::new(name, Role::Projector),
            solution: None,
            drawn: drawn.clone(),
        };
        let s = CancellationToken::new();
        let token = s.clone();
        nodes.push((
            tokio::spawn(async move { run_node(rt, &mut r, token).await.unwrap() }),
            s,
            drawn,
        ));
    }
    let run = timeout(Duration::from_secs(120), master)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    let mut drawn = Vec::new();
    for (h, s, d) in nodes {
        s.cancel();
        let log = timeout(Duration::from_secs(5), h).await.unwrap().unwrap();
        let frames: Vec<u64> = log.presented.iter().map(|p| p.0).collect();
        assert_eq!(frames, (0..GI_FRAMES).collect::<Vec<_>>());
        drawn.push(d.lock().unwrap().clone());
    }
    assert!(
        run.illumination_failures.is_empty(),
        "{:?}",
        run.illumination_failures
    );
    // Frame 0 already has a solution; the moving light brought updates.
    assert!(drawn[0][0].1.is_some(), "frame 0 is drawn in global mode");
    assert!(
        !run.illumination_updates.is_empty(),
        "no update was published in {GI_FRAMES} frames"
    );
    eprintln!(
        "{} updates; first {:?}; last {:?}",
        run.illumination_updates.len(),
        run.illumination_updates.first(),
        run.illumination_updates.last()
    );
    for u in &run.illumination_updates {
        assert!(u.first_frame > u.solved_frame, "{u:?}");
        assert!(u.latency_ms >= u.solve_ms, "{u:?}");
    }
    // Both nodes drew every frame with the same solution, and versions
    // only go forward.
    assert_eq!(drawn[0], drawn[1]);
    let versions: Vec<u64> = drawn[0].iter().map(|d| d.1.unwrap().0).collect();
    assert!(versions.windows(2).all(|w| w[0] <= w[1]));
    assert!(
        versions.last() > versions.first(),
        "versions drawn: {:?}",
        versions.first()
    );
}

/// A global-mode scene whose first solve fails (nothing in it emits
/// light): the nodes have joined while it ran, and the master stops with
/// why, closing them, instead of waiting for a solution that never comes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_first_solve_stops_the_master_with_why_and_closes_the_nodes() {
    let mut scene =
        showcase_master::scene_file::load_any(std::path::Path::new("builtin:figure3")).unwrap();
    scene.illumination = showcase_proto::IlluminationMode::Global;
    scene.lights.clear();
    let names: Vec<String> = scene.projectors.iter().map(|p| p.name.clone()).collect();
    let c = certs::generate(&names).unwrap();
    let server = Server::bind(settings(
        &c,
        &names,
        "127.0.0.1:0".parse().unwrap(),
        Some(60),
    ))
    .unwrap();
    let addr = server.local_addr();
    let master = tokio::spawn(server.run(
        scene,
        Show::new(Tracking::None, HZ as f64),
        CancellationToken::new(),
    ));
    let nodes: Vec<Node> = names.iter().map(|n| start_node(&c, n, addr)).collect();
    let err = timeout(Duration::from_secs(60), master)
        .await
        .unwrap()
        .unwrap()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("the first solution") && err.contains("emits light"),
        "{err}"
    );
    for (h, stop, _) in nodes {
        stop.cancel();
        let log = timeout(Duration::from_secs(10), h).await.unwrap().unwrap();
        assert_eq!(log.presented_count, 0);
    }
}
