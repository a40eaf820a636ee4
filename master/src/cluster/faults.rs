//! `bench faults`: a real cluster of processes on loopback, the master
//! (this binary's `run`) and three state-hash nodes (`showcase-node`
//! beside it), put through the faults a show meets: hostile DTrack
//! datagrams, kill -9 of a node, SIGSTOP of a node, and kill -9 of the
//! master followed by a new one. The figures come from the master's
//! per-frame metrics (`swap_unix_ms`) against the wall-clock instants of
//! each fault. Every wait is bounded; the processes are killed on return.

use super::metrics::unix_ms;
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use showcase_proto::Role;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const NODES: [(&str, Role); 3] = [
    ("face-0", Role::Face),
    ("face-1", Role::Face),
    ("projector-0", Role::Projector),
];
const HZ: f64 = 60.0;
const DEADLINE_MS: f64 = 50.0;

/// The record `bench faults --json` prints.
#[derive(Clone, Debug, Serialize)]
pub struct FaultRecord {
    /// Render nodes (processes).
    pub nodes: usize,
    /// Target frame rate.
    pub hz: f64,
    /// The swap deadline.
    pub deadline_ms: f64,
    /// Hostile datagrams.
    pub hostile: HostileFigures,
    /// kill -9 of a node, restarted 300 ms later.
    pub node_kill: NodeKillFigures,
    /// SIGSTOP of a node, SIGCONT after its eviction.
    pub node_stop: NodeStopFigures,
    /// kill -9 of the master, a new one started at once.
    pub master_restart: MasterRestartFigures,
    /// The first master's `--record` session, hostile datagrams and the
    /// kill -9 included, replayed twice.
    pub recording: RecordingFigures,
    /// Evictions, over both masters' runs, of nodes that were neither
    /// killed nor stopped (false evictions; 0 expected).
    pub false_evictions: usize,
    /// The runtime timer's own lateness, the floor under every stall
    /// figure: median overshoot of a 5 ms tokio sleep on this machine (ms).
    pub timer_late_ms_p50: f64,
    /// Where the processes' logs and metrics were kept (removed unless
    /// `--keep`).
    pub work_dir: String,
}

/// What the hostile datagrams did.
#[derive(Clone, Debug, Serialize)]
pub struct HostileFigures {
    /// Datagrams sent.
    pub sent: usize,
    /// Distinct kinds among them.
    pub kinds: usize,
    /// The master process was still running afterwards.
    pub master_survived: bool,
    /// Frames presented in the second after the last hostile datagram.
    pub frames_after: usize,
    /// Every head position in every metrics line was finite.
    pub heads_finite: bool,
    /// Good samples sent after the hostile ones moved the tracked head
    /// there (the filter recovered).
    pub tracking_recovered: bool,
}

/// What killing a node did.
#[derive(Clone, Debug, Serialize)]
pub struct NodeKillFigures {
    /// Longest gap between two swaps of the others from the kill to the
    /// restart (ms); the target is the deadline plus one frame.
    pub stall_ms: Option<f64>,
    /// From starting the node again to its first presented frame (ms).
    pub rejoin_ms: Option<f64>,
}

/// What stopping a node did.
#[derive(Clone, Debug, Serialize)]
pub struct NodeStopFigures {
    /// From SIGSTOP to the swap that evicted it (ms).
    pub eviction_ms: Option<f64>,
    /// Longest gap between two swaps of the others meanwhile (ms).
    pub stall_ms: Option<f64>,
    /// From SIGCONT to its first presented frame again (ms).
    pub rejoin_ms: Option<f64>,
}

/// What restarting the master did.
#[derive(Clone, Debug, Serialize)]
pub struct MasterRestartFigures {
    /// From starting the new master process to its first frame presented
    /// by every node (ms).
    pub recovery_ms: Option<f64>,
    /// Nodes whose log shows the old connection ended by a stateless reset
    /// (rather than the idle timeout).
    pub noticed_by_reset: usize,
}

/// What the recording of the faulted show did on replay.
#[derive(Clone, Debug, Serialize)]
pub struct RecordingFigures {
    /// Datagram lines it kept.
    pub datagrams: usize,
    /// Lines that say the live show rejected something.
    pub with_rejections: usize,
    /// The kill -9 left a partial last line (dropped on replay).
    pub cut_by_kill: bool,
    /// Frames each replay ran.
    pub frames: u64,
    /// Every node's per-frame output hashes were identical in both replays.
    pub replays_identical: bool,
}

/// Settings of the bench.
#[derive(Clone, Debug, Default)]
pub struct FaultOptions {
    /// The scene file the master shows.
    pub scene: PathBuf,
    /// The `showcase-node` binary (default: beside this one).
    pub node_bin: Option<PathBuf>,
    /// Keep the work folder (logs, metrics, config) afterwards.
    pub keep: bool,
}

/// One metrics line, the fields the bench reads.
#[derive(Debug, Deserialize)]
struct Line {
    swap_unix_ms: f64,
    heads: Vec<[f32; 3]>,
    nodes: Vec<NamedNode>,
    evicted: Vec<String>,
}

#[derive(Debug, Deserialize)]
struct NamedNode {
    name: String,
}

/// Whole lines of a metrics file written so far (a partial last line is
/// left for the next read).
fn read_metrics(path: &Path) -> Vec<Line> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Vec::new();
    };
    text.lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// Poll `done` every 5 ms until it holds or `limit` passes.
pub(crate) fn wait_for(limit: Duration, mut done: impl FnMut() -> bool) -> bool {
    let t0 = Instant::now();
    while t0.elapsed() < limit {
        if done() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    done()
}

pub(crate) fn free_port() -> Result<u16> {
    Ok(UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// The longest gap between consecutive swaps from the last one before
/// `from` to the last one before `to` (ms).
fn longest_gap(lines: &[Line], from: f64, to: f64) -> Option<f64> {
    let start = lines.iter().rposition(|l| l.swap_unix_ms < from)?;
    let swaps: Vec<f64> = lines[start..]
        .iter()
        .map(|l| l.swap_unix_ms)
        .take_while(|&t| t <= to)
        .collect();
    swaps.windows(2).map(|w| w[1] - w[0]).reduce(f64::max)
}

/// The first frame at or after `after` that `node` presented, as ms after
/// `after`.
fn first_presented(lines: &[Line], node: &str, after: f64) -> Option<f64> {
    lines
        .iter()
        .find(|l| l.swap_unix_ms >= after && l.nodes.iter().any(|n| n.name == node))
        .map(|l| l.swap_unix_ms - after)
}

/// Processes the bench started; killed when dropped.
pub(crate) struct Procs(pub(crate) Vec<Child>);

impl Drop for Procs {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

pub(crate) fn signal(child: &Child, sig: &str) -> Result<()> {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .context("running kill")?
        .success();
    anyhow::ensure!(ok, "kill {sig} {} failed", child.id());
    Ok(())
}

/// The hostile datagrams: each is one kind the parser or filter must
/// survive. The first sample of body 0 is the 1e43 mm one.
fn hostile_datagrams() -> Vec<Vec<u8>> {
    let id = "[1 0 0 0 1 0 0 0 1]";
    let mut out: Vec<Vec<u8>> = [
        "6d 12297829382473034411 [0 1.000]".to_owned(),
        format!("fr 1\n6d 1 [0 1.000][1e43 0 0 0 0 0]{id}"),
        format!("6d 1 [0 1.000][1e300 -1e300 1e300 0 0 0]{id}"),
        format!("6d 1 [0 1.000][100000 0 0 0 0 0]{id}"),
        format!("6d 1 [0 1.000][nan 0 0 0 0 0]{id}"),
        "6d 1 [0 1.0][0 0 0 0 0 0][1e308 1e308 1e308 1e308 1e308 1e308 1e308 1e308 1e308]"
            .to_owned(),
        format!("6d 1 [4294967296 1.0][0 0 0 0 0 0]{id}"),
        "6d 4294967296 [0 1]".to_owned(),
        "6d -1".to_owned(),
        "6d 2 [0 1.0]".to_owned(),
        "fr 99999999999999999999999999".to_owned(),
        "ts inf".to_owned(),
        String::new(),
        "[".repeat(60_000),
        "fr 1\n".repeat(10_000),
    ]
    .into_iter()
    .map(String::into_bytes)
    .collect();
    out.push(vec![0xff, 0xfe, 0x00, 0x80, b'6', b'd']);
    out
}

/// Replay the session twice through loopback clusters and compare.
fn replay_twice(session: &Path, scene_file: &Path) -> Result<RecordingFigures> {
    let recorded = crate::tracking::recording::read_recording(session)?;
    let scene = crate::scene_file::load_any(scene_file)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let replay = || rt.block_on(super::commands::replay(&scene, session, HZ as f32, None));
    let (a, b) = (replay()?, replay()?);
    Ok(RecordingFigures {
        datagrams: recorded.entries.len(),
        with_rejections: recorded
            .entries
            .iter()
            .filter(|e| e.rejected.as_ref().is_some_and(|r| !r.is_empty()))
            .count(),
        cut_by_kill: recorded.cut.is_some(),
        frames: a.frames,
        replays_identical: a == b && a.nodes.iter().all(|n| !n.hashes.is_empty()),
    })
}

/// Median overshoot of 50 tokio sleeps of 5 ms (ms): tokio's timer has
/// whole-millisecond granularity, and every eviction waits on it.
fn timer_lateness_ms() -> Result<f64> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()?;
    let late: Vec<f64> = rt.block_on(async {
        let mut late = Vec::new();
        for _ in 0..50 {
            let t0 = Instant::now();
            tokio::time::sleep(Duration::from_millis(5)).await;
            late.push(t0.elapsed().as_secs_f64() * 1e3 - 5.0);
        }
        late
    });
    Ok(showcase_light::metrics::percentile(&late, 50.0).unwrap_or(f64::NAN))
}

/// A cluster configuration for processes on this machine: the master on
/// 127.0.0.1:`port` showing `scene` at 60 Hz with a 50 ms deadline and the
/// certificates in `certs/`; `tracking` holds the `[tracking]` source lines,
/// to which body 0 on observer-0 is added; one node per `(name, role)`
/// drives the scene output of its name (a projector with the scene's
/// calibration).
pub fn loopback_config(port: u16, scene: &Path, tracking: &str, nodes: &[(&str, Role)]) -> String {
    loopback_config_at(port, scene, tracking, nodes, HZ)
}

/// [`loopback_config`] at `hz` instead of 60 Hz (the deadline stays 50 ms).
pub fn loopback_config_at(
    port: u16,
    scene: &Path,
    tracking: &str,
    nodes: &[(&str, Role)],
    hz: f64,
) -> String {
    let mut cfg = format!(
        "[master]\nhost = \"localhost\"\nlisten = \"127.0.0.1:{port}\"\nscene = {scene:?}\n\
         certs = \"certs\"\ntarget_hz = {hz}\ndeadline_ms = {DEADLINE_MS}\n\n\
         [tracking]\n{tracking}\nbody = [{{ id = 0, target = \"observer:observer-0\" }}]\n"
    );
    for (name, role) in nodes {
        cfg += &format!(
            "\n[[node]]\nname = \"{name}\"\nrole = \"{role}\"\nhost = \"localhost\"\noutput = \"{name}\"\n{}",
            if *role == Role::Projector {
                "calibration = \"scene\"\n"
            } else {
                ""
            }
        );
    }
    cfg
}

/// What a bench of real processes starts from: this binary (the master),
/// the node binary, the scene as a config elsewhere names it, and a work
/// folder holding the nodes' certificates.
pub(crate) struct ProcessBench {
    /// This binary.
    pub exe: PathBuf,
    /// `showcase-node`: `--node-bin`, else the one beside this binary.
    pub node_bin: PathBuf,
    /// The scene, absolute (or a built-in name).
    pub scene: PathBuf,
    /// `$TMP/showcase-{tag}-{pid}`, with `certs/` for `nodes`.
    pub dir: PathBuf,
}

impl ProcessBench {
    /// Find the binaries, name the scene and make the work folder and
    /// certificates.
    pub(crate) fn prepare(
        node_bin: Option<&Path>,
        scene: &Path,
        tag: &str,
        nodes: &[(&str, Role)],
    ) -> Result<Self> {
        let exe = std::env::current_exe().context("cannot find this binary")?;
        let node_bin =
            node_bin.map_or_else(|| exe.with_file_name("showcase-node"), Path::to_path_buf);
        if !node_bin.is_file() {
            bail!(
                "{}: no showcase-node binary; build it beside showcase-master \
                 (cargo build --release -p showcase-render) or pass --node-bin",
                node_bin.display()
            );
        }
        // The config lies in another folder: a file must be absolute there.
        let scene = crate::scene_file::absolute(scene)
            .with_context(|| format!("scene {}", scene.display()))?;
        let dir = std::env::temp_dir().join(format!("showcase-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let names: Vec<String> = nodes.iter().map(|(n, _)| (*n).to_owned()).collect();
        crate::certs::write(&dir.join("certs"), &crate::certs::generate(&names)?)?;
        Ok(Self {
            exe,
            node_bin,
            scene,
            dir,
        })
    }
}

/// Run the bench.
pub fn bench_faults(opts: &FaultOptions) -> Result<FaultRecord> {
    let ProcessBench {
        exe,
        node_bin,
        scene,
        dir,
    } = ProcessBench::prepare(opts.node_bin.as_deref(), &opts.scene, "faults", &NODES)?;
    let (quic, dtrack) = (free_port()?, free_port()?);
    let cfg = loopback_config(
        quic,
        &scene,
        &format!("source = \"dtrack\"\nport = {dtrack}"),
        &NODES,
    );
    let config = dir.join("cluster.toml");
    std::fs::write(&config, cfg)?;
    let log = |name: &str| -> Result<Stdio> {
        Ok(std::fs::File::create(dir.join(format!("{name}.log")))?.into())
    };
    let master = |run: &str| -> Result<Child> {
        Command::new(&exe)
            .arg("run")
            .arg("--config")
            .arg(&config)
            .arg("--metrics")
            .arg(dir.join(format!("metrics-{run}.jsonl")))
            .arg("--record")
            .arg(dir.join(format!("session-{run}.jsonl")))
            .stdout(Stdio::null())
            .stderr(log(&format!("master-{run}"))?)
            .spawn()
            .with_context(|| format!("cannot start {}", exe.display()))
    };
    let node = |name: &str, run: usize| -> Result<Child> {
        Command::new(&node_bin)
            .arg("--config")
            .arg(&config)
            .args(["--name", name, "--renderer", "state-hash"])
            .stdout(Stdio::null())
            .stderr(log(&format!("{name}-{run}"))?)
            .spawn()
            .with_context(|| format!("cannot start {}", node_bin.display()))
    };
    let metrics1 = dir.join("metrics-1.jsonl");
    let mut procs = Procs(vec![master("1")?]);
    for (name, _) in NODES {
        procs.0.push(node(name, 1)?);
    }
    let everyone = |l: &Line| {
        NODES
            .iter()
            .all(|(n, _)| l.nodes.iter().any(|m| m.name == *n))
    };
    let warm = wait_for(Duration::from_secs(60), || {
        read_metrics(&metrics1)
            .iter()
            .filter(|l| everyone(l))
            .count()
            >= 60
    });
    if !warm {
        bail!(
            "the cluster did not run 60 frames with all nodes within 60 s; see the logs in {}",
            dir.display()
        );
    }
    eprintln!("bench faults: cluster up");

    // Hostile datagrams, then good samples of body 0.
    let udp = UdpSocket::bind("127.0.0.1:0")?;
    let target = ("127.0.0.1", dtrack);
    let hostile = hostile_datagrams();
    let mut sent = 0;
    for round in 0..10 {
        for d in &hostile {
            if round > 0 && d.len() > 1000 {
                continue;
            }
            udp.send_to(d, target)?;
            sent += 1;
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    let after_hostile = unix_ms();
    for i in 0..50 {
        let d = format!("fr {i}\n6d 1 [0 1.000][300 400 500 0 0 0][1 0 0 0 1 0 0 0 1]\n");
        udp.send_to(d.as_bytes(), target)?;
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(500));
    let master_survived = procs.0[0].try_wait()?.is_none();
    let lines = read_metrics(&metrics1);
    let frames_after = lines
        .iter()
        .filter(|l| l.swap_unix_ms > after_hostile && l.swap_unix_ms < after_hostile + 1000.0)
        .count();
    let heads_finite = lines
        .iter()
        .all(|l| l.heads.iter().flatten().all(|v| v.is_finite()));
    let tracking_recovered = lines.last().is_some_and(|l| {
        let h = l.heads[0];
        (h[0] - 0.3).abs() < 1e-4 && (h[1] - 0.4).abs() < 1e-4 && (h[2] - 0.5).abs() < 1e-4
    });
    let hostile = HostileFigures {
        sent,
        kinds: hostile.len(),
        master_survived,
        frames_after,
        heads_finite,
        tracking_recovered,
    };
    eprintln!("bench faults: hostile datagrams {hostile:?}");
    if !master_survived {
        bail!(
            "the master died under hostile datagrams; see {}",
            dir.join("master-1.log").display()
        );
    }

    // kill -9 of face-1, started again after 300 ms: long enough for the
    // master to evict it (a node restarted sooner replaces its dead
    // connection at its Hello, and the stall never shows).
    let killed = 2;
    let t_kill = unix_ms();
    procs.0[killed].kill()?;
    procs.0[killed].wait()?;
    std::thread::sleep(Duration::from_millis(300));
    let t_restart = unix_ms();
    procs.0[killed] = node("face-1", 2)?;
    wait_for(Duration::from_secs(5), || {
        first_presented(&read_metrics(&metrics1), "face-1", t_restart).is_some()
    });
    std::thread::sleep(Duration::from_millis(300));
    let lines = read_metrics(&metrics1);
    let node_kill = NodeKillFigures {
        stall_ms: longest_gap(&lines, t_kill, t_restart),
        rejoin_ms: first_presented(&lines, "face-1", t_restart),
    };
    eprintln!("bench faults: node kill {node_kill:?}");

    // SIGSTOP of projector-0 until the master evicts it, then SIGCONT.
    let stopped = 3;
    let t_stop = unix_ms();
    signal(&procs.0[stopped], "-STOP")?;
    let evicted = |lines: &[Line]| {
        lines
            .iter()
            .find(|l| l.swap_unix_ms >= t_stop && l.evicted.iter().any(|e| e == "projector-0"))
            .map(|l| l.swap_unix_ms - t_stop)
    };
    wait_for(Duration::from_secs(5), || {
        evicted(&read_metrics(&metrics1)).is_some()
    });
    std::thread::sleep(Duration::from_millis(200));
    let t_cont = unix_ms();
    signal(&procs.0[stopped], "-CONT")?;
    wait_for(Duration::from_secs(5), || {
        first_presented(&read_metrics(&metrics1), "projector-0", t_cont).is_some()
    });
    let lines = read_metrics(&metrics1);
    let node_stop = NodeStopFigures {
        eviction_ms: evicted(&lines),
        stall_ms: longest_gap(&lines, t_stop, t_cont),
        rejoin_ms: first_presented(&lines, "projector-0", t_cont),
    };
    eprintln!("bench faults: node stop {node_stop:?}");

    // kill -9 of the master, a new one at once.
    procs.0[0].kill()?;
    procs.0[0].wait()?;
    let t_master = unix_ms();
    procs.0[0] = master("2")?;
    let metrics2 = dir.join("metrics-2.jsonl");
    let recovered = |lines: &[Line]| {
        lines
            .iter()
            .find(|l| everyone(l))
            .map(|l| l.swap_unix_ms - t_master)
    };
    wait_for(Duration::from_secs(10), || {
        recovered(&read_metrics(&metrics2)).is_some()
    });
    let recovery_ms = recovered(&read_metrics(&metrics2));
    // Let the nodes' logs catch up before reading them.
    std::thread::sleep(Duration::from_millis(100));
    let noticed_by_reset = NODES
        .iter()
        .filter(|(name, _)| {
            let run = if *name == "face-1" { 2 } else { 1 };
            std::fs::read_to_string(dir.join(format!("{name}-{run}.log")))
                .is_ok_and(|t| t.contains("reset by peer"))
        })
        .count();
    let faulted = |l: &Line, e: &String| {
        (e == "face-1" && l.swap_unix_ms >= t_kill && l.swap_unix_ms < t_restart + 1000.0)
            || (e == "projector-0" && l.swap_unix_ms >= t_stop && l.swap_unix_ms < t_cont + 1000.0)
    };
    let false_evictions = [&metrics1, &metrics2]
        .iter()
        .flat_map(|m| read_metrics(m))
        .map(|l| l.evicted.iter().filter(|e| !faulted(&l, e)).count())
        .sum();
    let master_restart = MasterRestartFigures {
        recovery_ms,
        noticed_by_reset,
    };
    eprintln!("bench faults: master restart {master_restart:?}");
    drop(procs);
    let recording = replay_twice(&dir.join("session-1.jsonl"), &scene)?;
    eprintln!("bench faults: recording {recording:?}");
    if !opts.keep {
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(FaultRecord {
        nodes: NODES.len(),
        hz: HZ,
        deadline_ms: DEADLINE_MS,
        hostile,
        node_kill,
        node_stop,
        master_restart,
        recording,
        false_evictions,
        timer_late_ms_p50: timer_lateness_ms()?,
        work_dir: dir.display().to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(t: f64, nodes: &[&str]) -> Line {
        Line {
            swap_unix_ms: t,
            heads: Vec::new(),
            nodes: nodes
                .iter()
                .map(|n| NamedNode {
                    name: (*n).to_owned(),
                })
                .collect(),
            evicted: Vec::new(),
        }
    }

    #[test]
    fn gaps_and_first_frames_come_from_the_swap_times() {
        let lines = [
            line(0.0, &["a", "b"]),
            line(16.0, &["a", "b"]),
            line(83.0, &["a"]),
            line(100.0, &["a"]),
            line(117.0, &["a", "b"]),
        ];
        // From the last swap before 20 (at 16) on: the 67 ms stall.
        assert_eq!(longest_gap(&lines, 20.0, 1000.0), Some(67.0));
        assert_eq!(longest_gap(&lines, 90.0, 1000.0), Some(17.0));
        assert_eq!(longest_gap(&lines, -1.0, 1000.0), None);
        assert_eq!(first_presented(&lines, "b", 20.0), Some(97.0));
        assert_eq!(first_presented(&lines, "c", 0.0), None);
    }
}
