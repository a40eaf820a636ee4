//! SIGTERM (what `systemctl stop` sends) stops a real master process
//! cleanly: its nodes get Bye, the metrics and the recording end on whole
//! lines, it prints its summary and exits 0. The master runs as a child
//! process: this test binary again, running only `child_master`.

use showcase_master::certs;
use showcase_master::cli::{Cli, run};
use showcase_master::cluster::faults::loopback_config;
use showcase_proto::Role;
use showcase_render::net::ClusterIdentity;
use showcase_render::node::{NodeRuntime, StateHashRenderer, run_node};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use tokio::time::timeout;
use tokio_util::sync::CancellationToken;

/// Holds the child's `showcase-master` arguments (a JSON array).
const CHILD_ARGS: &str = "SHOWCASE_IT_CHILD_MASTER_ARGS";

/// The child process of `sigterm_stops_a_master_cleanly` (and of the
/// dashboard's tests), not a test of its own: it runs `showcase-master`
/// with the arguments in [`CHILD_ARGS`].
#[test]
#[ignore = "run as a child process by spawn_master"]
fn child_master() {
    let args = std::env::var(CHILD_ARGS)
        .expect("only sigterm_stops_a_master_cleanly runs this, with its arguments");
    let args: Vec<String> = serde_json::from_str(&args).unwrap();
    run(<Cli as clap::Parser>::try_parse_from(args).unwrap()).unwrap();
}

/// A `showcase-master` process running `args` (after the program name):
/// this test binary again, running only [`child_master`]. It exits 0 when
/// the command succeeds and non-zero when it fails; with
/// `--nocapture`, the command's stdout and stderr are the child's.
pub(crate) fn master_process(args: &[&str]) -> Command {
    let args = serde_json::to_string(
        &std::iter::once("showcase-master")
            .chain(args.iter().copied())
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    cmd.args([
        "--ignored",
        "--exact",
        "shutdown::child_master",
        "--nocapture",
    ])
    .env(CHILD_ARGS, args);
    cmd
}

/// `showcase-master ARGS` as a child process ([`master_process`]), its
/// stdout dropped and its stderr to `stderr`.
pub(crate) fn spawn_master(args: &[&str], stderr: &std::path::Path) -> std::process::Child {
    master_process(args)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(stderr).unwrap())
        .spawn()
        .unwrap()
}

fn lines_of(path: &std::path::Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l:?}: {e}")))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_stops_a_master_cleanly() {
    let dir = std::env::temp_dir().join(format!("showcase-sigterm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let names = ["face-0", "face-1"].map(String::from);
    certs::write(&dir.join("certs"), &certs::generate(&names).unwrap()).unwrap();
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    // The built-in cabinet by name: no file, so the config may lie anywhere.
    let scene = showcase_master::demo::default_scene();
    let nodes: Vec<(&str, Role)> = names.iter().map(|n| (n.as_str(), Role::Face)).collect();
    // The master listens on a host name, which `run` resolves (to
    // 127.0.0.1, where the nodes dial).
    let cfg = loopback_config(port, &scene, "source = \"scripted\"", &nodes)
        .replace("\"127.0.0.1:", "\"localhost:");
    assert!(
        cfg.contains(&format!("listen = \"localhost:{port}\"")),
        "{cfg}"
    );
    let config = dir.join("cluster.toml");
    std::fs::write(&config, cfg).unwrap();
    let (metrics, session, stderr) = (
        dir.join("metrics.jsonl"),
        dir.join("session.jsonl"),
        dir.join("master.log"),
    );
    let mut master = spawn_master(
        &[
            "run",
            "--config",
            config.to_str().unwrap(),
            "--metrics",
            metrics.to_str().unwrap(),
            "--record",
            session.to_str().unwrap(),
        ],
        &stderr,
    );

    let nodes: Vec<_> = names
        .iter()
        .map(|n| {
            let rt = NodeRuntime {
                name: n.clone(),
                role: Role::Face,
                master: format!("127.0.0.1:{port}").parse().unwrap(),
                identity: ClusterIdentity::load(&dir.join("certs"), n).unwrap(),
                bind: "127.0.0.1:0".parse().unwrap(),
                capabilities: Default::default(),
                write_frames: None,
                keep_presented: false,
            };
            let stop = CancellationToken::new();
            let s = stop.clone();
            let mut r = StateHashRenderer::new(n, Role::Face);
            (
                tokio::spawn(async move { run_node(rt, &mut r, s).await.unwrap() }),
                stop,
            )
        })
        .collect();

    // Let the show run 30 frames, then stop it as systemd would.
    let t0 = Instant::now();
    while lines_of(&metrics).len() < 30 {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the master ran no 30 frames; its log: {}",
            std::fs::read_to_string(&stderr).unwrap_or_default()
        );
        assert!(
            master.try_wait().unwrap().is_none(),
            "the master exited early"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let term = Command::new("kill")
        .args(["-TERM", &master.id().to_string()])
        .status()
        .unwrap();
    assert!(term.success());
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = master.try_wait().unwrap() {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "SIGTERM did not stop the master"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    let log = std::fs::read_to_string(&stderr).unwrap();
    assert!(status.success(), "exit {status:?}; log: {log}");
    assert!(log.contains("master stopped after"), "no summary: {log}");

    // Whole lines only, and nothing lost: a line per presented frame and a
    // recorded datagram per frame.
    for file in [&metrics, &session] {
        let text = std::fs::read_to_string(file).unwrap();
        assert!(text.ends_with('\n'), "{} ends mid-line", file.display());
    }
    let frames = lines_of(&metrics);
    assert!(frames.len() >= 30 && frames.iter().all(|f| f["frame"].is_u64()));
    let recorded = lines_of(&session);
    assert!(recorded.len() > frames.len(), "{} lines", recorded.len());

    // Each node heard the master's Bye.
    for (h, stop) in nodes {
        stop.cancel();
        let log = timeout(Duration::from_secs(10), h).await.unwrap().unwrap();
        assert!(
            log.disconnects
                .iter()
                .any(|d| d.contains("master said bye")),
            "{:?}",
            log.disconnects
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
