//! `bench dashboard`: what serving the dashboard costs the master, and how
//! soon it shows an eviction. A real cluster of processes on loopback (this
//! binary's `run` and four state-hash `showcase-node`s at 120 Hz), run
//! `runs` times with the dashboard off and `runs` times on, alternated
//! (off-on, then on-off); with it on, a client fetches `/api/state` and
//! `/metrics` at the page's rate (every 250 ms). The figure is the master
//! process's CPU time (its threads' run time in `/proc/PID/task/*/schedstat`)
//! per second of the measured window. After each run with the dashboard on, one
//! node is killed (-9) and `/api/state` is polled every 5 ms until it shows
//! the node evicted. Every wait is bounded; the processes are killed on
//! return.

use super::super::faults::{ProcessBench, Procs, free_port, loopback_config_at, signal, wait_for};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use showcase_light::metrics::percentile;
use showcase_proto::Role;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const NODES: [(&str, Role); 4] = [
    ("face-0", Role::Face),
    ("face-1", Role::Face),
    ("projector-0", Role::Projector),
    ("projector-1", Role::Projector),
];
const HZ: f64 = 120.0;
/// The page's poll interval (`page.html`'s `POLL_MS`).
const CLIENT_EVERY: Duration = Duration::from_millis(250);
/// Linux's `USER_HZ`: the unit of `/proc/PID/stat`'s CPU times.
const CLOCK_TICKS_PER_S: f64 = 100.0;

/// Settings of the bench.
#[derive(Clone, Debug)]
pub struct DashboardBenchOptions {
    /// The scene file the master shows.
    pub scene: PathBuf,
    /// The `showcase-node` binary (default: beside this one).
    pub node_bin: Option<PathBuf>,
    /// Runs with the dashboard off, and as many with it on.
    pub runs: usize,
    /// The measured window of each run.
    pub window: Duration,
    /// Keep the work folder (config, logs) afterwards.
    pub keep: bool,
}

/// The record `bench dashboard --json` prints.
#[derive(Clone, Debug, Serialize)]
pub struct DashboardBenchRecord {
    /// Render nodes (processes).
    pub nodes: usize,
    /// Target frame rate.
    pub hz: f64,
    /// Runs per side.
    pub runs: usize,
    /// Length of each measured window (s).
    pub window_s: f64,
    /// What the client did while the dashboard was on.
    pub client: String,
    /// Master CPU seconds per second, dashboard off, per run.
    pub cpu_off: Vec<f64>,
    /// The same with the dashboard on and the client fetching.
    pub cpu_on: Vec<f64>,
    /// Median of `cpu_off`.
    pub cpu_off_p50: f64,
    /// Median of `cpu_on`.
    pub cpu_on_p50: f64,
    /// `cpu_on_p50 / cpu_off_p50 - 1`: the dashboard's share (0.02 = 2 %).
    pub cpu_overhead: f64,
    /// Per pair of runs (one off, one on, back to back), on minus off
    /// (CPU s/s): the machine's drift cancels within a pair.
    pub cpu_on_minus_off: Vec<f64>,
    /// Median of `cpu_on_minus_off` over `cpu_off_p50`.
    pub cpu_overhead_paired: f64,
    /// The dashboard thread's own CPU (s/s) in each run with it on: what
    /// serving costs, without the run-to-run noise of the whole master.
    pub dashboard_thread_cpu: Vec<f64>,
    /// The frame loop's time making and publishing snapshots (s/s) in each
    /// run with it on, from `showcase_dashboard_snapshot_seconds_total`.
    pub snapshot_cpu: Vec<f64>,
    /// Median of `dashboard_thread_cpu + snapshot_cpu` over `cpu_off_p50`:
    /// the dashboard's cost, attributed. Not in it: the client's side of the
    /// loopback traffic, and what sharing the cores does to the frame loop.
    pub attributed_overhead: f64,
    /// From kill -9 of a node to `/api/state` showing it evicted (ms), per
    /// run with the dashboard on; the page adds up to its 250 ms poll.
    pub eviction_to_state_ms: Vec<f64>,
    /// Median of `eviction_to_state_ms`.
    pub eviction_to_state_ms_p50: Option<f64>,
    /// Where the processes' logs were kept (removed unless `--keep`).
    pub work_dir: String,
}

/// A GET of `path` on `addr` over HTTP/1.1 with `headers` (`Name: value`),
/// the connection closed after it: the status and the body. Bounded by a
/// 5 s timeout on each read and write.
pub fn http_get(addr: SocketAddr, path: &str, headers: &[&str]) -> Result<(u16, String)> {
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_secs(5))
        .with_context(|| format!("cannot connect to {addr}"))?;
    s.set_read_timeout(Some(Duration::from_secs(5)))?;
    s.set_write_timeout(Some(Duration::from_secs(5)))?;
    let mut req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for h in headers {
        req += h;
        req += "\r\n";
    }
    req += "\r\n";
    s.write_all(req.as_bytes())?;
    let mut raw = Vec::new();
    s.read_to_end(&mut raw)?;
    let text = String::from_utf8(raw).context("the answer is not UTF-8")?;
    let (head, body) = text
        .split_once("\r\n\r\n")
        .context("the answer has no header end")?;
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .with_context(|| format!("no status in {:?}", head.lines().next()))?;
    Ok((status, body.to_owned()))
}

/// A reader of the dashboard's event stream (`/api/stream`), as a page
/// holds it: one connection, each published snapshot an event. It asks in
/// HTTP/1.0, so the body comes unchunked until the server closes it. Every
/// read is bounded by a 5 s timeout.
pub struct EventStream {
    reader: BufReader<TcpStream>,
}

impl EventStream {
    /// Open `path` (with `?token=` where the dashboard needs one) on `addr`.
    pub fn open(addr: SocketAddr, path: &str) -> Result<Self> {
        let s = TcpStream::connect_timeout(&addr, Duration::from_secs(5))
            .with_context(|| format!("cannot connect to {addr}"))?;
        s.set_read_timeout(Some(Duration::from_secs(5)))?;
        s.set_write_timeout(Some(Duration::from_secs(5)))?;
        (&s).write_all(format!("GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").as_bytes())?;
        let mut reader = BufReader::new(s);
        let mut status = String::new();
        reader.read_line(&mut status)?;
        let code = status.split(' ').nth(1).unwrap_or("");
        if code != "200" {
            let mut rest = String::new();
            let _ = reader.read_to_string(&mut rest);
            bail!("{path} answered {:?}: {rest}", status.trim_end());
        }
        loop {
            let mut line = String::new();
            if reader.read_line(&mut line)? == 0 {
                bail!("{path}: the answer ended in its header");
            }
            if line == "\r\n" || line == "\n" {
                return Ok(Self { reader });
            }
        }
    }

    /// The next event's name and data; `None` once the server has ended
    /// the stream.
    pub fn next_event(&mut self) -> Result<Option<(String, String)>> {
        let (mut name, mut data) = (String::from("message"), None::<String>);
        loop {
            let mut line = String::new();
            if self.reader.read_line(&mut line)? == 0 {
                return Ok(None);
            }
            let line = line.trim_end_matches(['\r', '\n']);
            if line.is_empty() {
                match data.take() {
                    Some(d) => return Ok(Some((name, d))),
                    None => continue,
                }
            }
            let (field, value) = line.split_once(':').unwrap_or((line, ""));
            let value = value.strip_prefix(' ').unwrap_or(value);
            match field {
                "event" => name = value.to_owned(),
                "data" => match data.as_mut() {
                    Some(d) => {
                        d.push('\n');
                        d.push_str(value);
                    }
                    None => data = Some(value.to_owned()),
                },
                _ => {}
            }
        }
    }
}

/// The master's CPU time so far (s): the sum of its threads' run time
/// from `/proc/PID/task/*/schedstat` (ns), else utime + stime from
/// `/proc/PID/stat` (10 ms ticks: too coarse for a 2 % difference in a
/// 10 s window at 10 % CPU). The master's threads live as long as it
/// does, so no exited thread's time is lost.
fn cpu_seconds(pid: u32) -> Result<f64> {
    if let Some(s) = thread_run_time(pid) {
        return Ok(s);
    }
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .with_context(|| format!("cannot read /proc/{pid}/stat (Linux only)"))?;
    // Fields after the command name, which is in parentheses and may hold spaces.
    let rest = stat
        .rsplit_once(')')
        .map(|(_, r)| r)
        .context("no command field")?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    // rest[0] is field 3 (state): utime is field 14, stime field 15.
    let tick =
        |i: usize| -> Result<f64> { Ok(f.get(i - 3).context("short stat line")?.parse::<f64>()?) };
    Ok((tick(14)? + tick(15)?) / CLOCK_TICKS_PER_S)
}

/// The sum of `pid`'s threads' run time (s), from schedstat.
fn thread_run_time(pid: u32) -> Option<f64> {
    threads_run_time(pid, |_| true)
}

/// The run time (s) of `pid`'s threads whose name (`comm`) `keep` accepts.
fn threads_run_time(pid: u32, keep: impl Fn(&str) -> bool) -> Option<f64> {
    let mut ns = 0u64;
    for t in std::fs::read_dir(format!("/proc/{pid}/task")).ok()? {
        let t = t.ok()?.path();
        let name = std::fs::read_to_string(t.join("comm")).ok()?;
        if !keep(name.trim_end()) {
            continue;
        }
        let stat = std::fs::read_to_string(t.join("schedstat")).ok()?;
        ns += stat.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(ns as f64 / 1e9)
}

/// The time the master's frame loop has spent making the dashboard's
/// snapshots (s), from `/metrics`.
fn snapshot_seconds(addr: SocketAddr) -> Result<f64> {
    let (status, text) = http_get(addr, "/metrics", &[])?;
    anyhow::ensure!(status == 200, "/metrics answered {status}");
    let name = "showcase_dashboard_snapshot_seconds_total ";
    text.lines()
        .find_map(|l| l.strip_prefix(name))
        .and_then(|v| v.trim().parse().ok())
        .with_context(|| format!("/metrics has no {}", name.trim_end()))
}

/// The dashboard thread's run time (s): what serving costs, by itself.
fn dashboard_thread_seconds(pid: u32) -> Result<f64> {
    threads_run_time(pid, |name| name == super::THREAD_NAME)
        .with_context(|| format!("cannot read /proc/{pid}/task/*/schedstat (Linux only)"))
}

/// The dashboard address the master printed on its log.
pub fn dashboard_addr(log: &Path) -> Option<SocketAddr> {
    let text = std::fs::read_to_string(log).ok()?;
    let at = text.find("dashboard on http://")? + "dashboard on http://".len();
    text[at..].split('/').next()?.parse().ok()
}

/// The state `/api/state` gives `node`.
pub fn node_state(addr: SocketAddr, node: &str) -> Option<String> {
    let (status, body) = http_get(addr, "/api/state", &[]).ok()?;
    if status != 200 {
        return None;
    }
    let v: serde_json::Value = serde_json::from_str(&body).ok()?;
    v["nodes"]
        .as_array()?
        .iter()
        .find(|n| n["name"] == node)
        .and_then(|n| n["state"].as_str().map(str::to_owned))
}

struct RunFigures {
    cpu: f64,
    /// The dashboard thread's share of `cpu` (CPU s/s); 0 with it off.
    dashboard_cpu: f64,
    /// The frame loop's time making snapshots (s/s); 0 with it off.
    snapshot_cpu: f64,
    eviction_ms: Option<f64>,
}

/// One run of the cluster with the dashboard off or on.
fn one_run(
    exe: &Path,
    node_bin: &Path,
    dir: &Path,
    scene: &Path,
    window: Duration,
    dashboard: bool,
    index: usize,
) -> Result<RunFigures> {
    let cfg = loopback_config_at(free_port()?, scene, "source = \"scripted\"", &NODES, HZ);
    let config = dir.join(format!("cluster-{index}.toml"));
    std::fs::write(&config, cfg)?;
    let master_log = dir.join(format!("master-{index}.log"));
    let mut master = Command::new(exe);
    master.arg("run").arg("--config").arg(&config);
    if dashboard {
        master.args(["--dashboard", "127.0.0.1:0"]);
    }
    let master = master
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&master_log)?)
        .spawn()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    let pid = master.id();
    let mut procs = Procs(vec![master]);
    for (name, _) in NODES {
        let log = std::fs::File::create(dir.join(format!("{name}-{index}.log")))?;
        procs.0.push(
            Command::new(node_bin)
                .arg("--config")
                .arg(&config)
                .args(["--name", name, "--renderer", "state-hash"])
                .stdout(Stdio::null())
                .stderr(log)
                .spawn()
                .with_context(|| format!("cannot start {}", node_bin.display()))?,
        );
    }
    let started = wait_for(Duration::from_secs(60), || {
        std::fs::read_to_string(&master_log).is_ok_and(|t| t.contains("frame clock started"))
    });
    if !started {
        bail!(
            "the frame clock did not start within 60 s; see {}",
            master_log.display()
        );
    }
    let addr = if dashboard {
        Some(dashboard_addr(&master_log).context("the master printed no dashboard address")?)
    } else {
        None
    };
    // Settle: clock probes and the first frames' catch-up.
    std::thread::sleep(Duration::from_secs(1));
    let stop = Arc::new(AtomicBool::new(false));
    let client = addr.map(|addr| {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let mut fetches = 0u64;
            while !stop.load(Ordering::Relaxed) {
                let t = Instant::now();
                if http_get(addr, "/api/state", &[]).is_ok_and(|(s, _)| s == 200) {
                    fetches += 1;
                }
                if http_get(addr, "/metrics", &[]).is_ok_and(|(s, _)| s == 200) {
                    fetches += 1;
                }
                std::thread::sleep(CLIENT_EVERY.saturating_sub(t.elapsed()));
            }
            fetches
        })
    });
    let snapshots = |addr: Option<SocketAddr>| addr.map_or(Ok(0.0), snapshot_seconds);
    let s0 = snapshots(addr)?;
    let (t0, c0, d0) = (
        Instant::now(),
        cpu_seconds(pid)?,
        dashboard_thread_seconds(pid)?,
    );
    std::thread::sleep(window);
    let (c1, d1, elapsed) = (
        cpu_seconds(pid)?,
        dashboard_thread_seconds(pid)?,
        t0.elapsed().as_secs_f64(),
    );
    let s1 = snapshots(addr)?;
    if dashboard {
        anyhow::ensure!(
            d1 > 0.0,
            "the master has no thread named {:?} (or it never ran): the dashboard's own cost cannot be told apart",
            super::THREAD_NAME
        );
    }
    stop.store(true, Ordering::Relaxed);
    if let Some(c) = client {
        let fetches = c.join().unwrap_or(0);
        anyhow::ensure!(fetches > 0, "the client fetched nothing from {addr:?}");
    }
    let eviction_ms = match addr {
        Some(addr) => {
            let victim = NODES.len();
            let t_kill = Instant::now();
            procs.0[victim].kill()?;
            procs.0[victim].wait()?;
            let mut seen = None;
            wait_for(Duration::from_secs(5), || {
                let evicted = node_state(addr, NODES[victim - 1].0).as_deref() == Some("evicted");
                if evicted {
                    seen = Some(t_kill.elapsed().as_secs_f64() * 1e3);
                }
                evicted
            });
            seen
        }
        None => None,
    };
    signal(&procs.0[0], "-TERM")?;
    wait_for(Duration::from_secs(10), || {
        procs.0[0].try_wait().ok().flatten().is_some()
    });
    drop(procs);
    Ok(RunFigures {
        cpu: (c1 - c0) / elapsed,
        dashboard_cpu: (d1 - d0) / elapsed,
        snapshot_cpu: (s1 - s0) / elapsed,
        eviction_ms,
    })
}

fn median(v: &[f64]) -> f64 {
    percentile(v, 50.0).unwrap_or(f64::NAN)
}

/// Run the bench.
pub fn bench_dashboard(opts: &DashboardBenchOptions) -> Result<DashboardBenchRecord> {
    anyhow::ensure!(opts.runs >= 1, "the bench needs at least one run per side");
    let ProcessBench {
        exe,
        node_bin,
        scene,
        dir,
    } = ProcessBench::prepare(opts.node_bin.as_deref(), &opts.scene, "dashboard", &NODES)?;
    let (mut off, mut on, mut evictions) = (Vec::new(), Vec::new(), Vec::new());
    let (mut thread, mut snapshot, mut attributed) = (Vec::new(), Vec::new(), Vec::new());
    let mut paired = Vec::new();
    for pair in 0..opts.runs {
        let order = if pair % 2 == 0 {
            [false, true]
        } else {
            [true, false]
        };
        let mut pair_cpu = [0.0; 2];
        for (k, dashboard) in order.into_iter().enumerate() {
            let r = one_run(
                &exe,
                &node_bin,
                &dir,
                &scene,
                opts.window,
                dashboard,
                pair * 2 + k,
            )?;
            eprintln!(
                "bench dashboard: run {} dashboard {}: {:.4} CPU s/s (its thread {:.5}, snapshots {:.6}), eviction seen after {:?} ms",
                pair * 2 + k,
                if dashboard { "on" } else { "off" },
                r.cpu,
                r.dashboard_cpu,
                r.snapshot_cpu,
                r.eviction_ms
            );
            pair_cpu[usize::from(dashboard)] = r.cpu;
            if dashboard {
                on.push(r.cpu);
                thread.push(r.dashboard_cpu);
                snapshot.push(r.snapshot_cpu);
                attributed.push(r.dashboard_cpu + r.snapshot_cpu);
                evictions.extend(r.eviction_ms);
            } else {
                off.push(r.cpu);
            }
        }
        paired.push(pair_cpu[1] - pair_cpu[0]);
    }
    if !opts.keep {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let (cpu_off_p50, cpu_on_p50) = (median(&off), median(&on));
    Ok(DashboardBenchRecord {
        nodes: NODES.len(),
        hz: HZ,
        runs: opts.runs,
        window_s: opts.window.as_secs_f64(),
        client: format!(
            "GET /api/state and /metrics every {} ms",
            CLIENT_EVERY.as_millis()
        ),
        cpu_off: off,
        cpu_on: on,
        cpu_off_p50,
        cpu_on_p50,
        cpu_overhead: cpu_on_p50 / cpu_off_p50 - 1.0,
        cpu_overhead_paired: median(&paired) / cpu_off_p50,
        cpu_on_minus_off: paired,
        dashboard_thread_cpu: thread,
        snapshot_cpu: snapshot,
        attributed_overhead: median(&attributed) / cpu_off_p50,
        eviction_to_state_ms_p50: percentile(&evictions, 50.0),
        eviction_to_state_ms: evictions,
        work_dir: dir.display().to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_time_counts_what_this_process_spends() {
        let pid = std::process::id();
        let before = cpu_seconds(pid).unwrap();
        let t0 = Instant::now();
        let mut x = 0u64;
        while t0.elapsed() < Duration::from_millis(200) {
            x = std::hint::black_box(x.wrapping_add(1));
        }
        let spent = cpu_seconds(pid).unwrap() - before;
        let wall = t0.elapsed().as_secs_f64();
        // At least a share of the busy loop (the machine may be loaded), and
        // no more than every core for the whole time.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        assert!(
            spent > 0.005 && spent <= wall * cores + 0.05,
            "{spent} s in {wall} s"
        );
    }

    #[test]
    fn the_dashboard_address_is_read_from_the_log() {
        let dir = std::env::temp_dir().join(format!("showcase-dash-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let log = dir.join("master.log");
        std::fs::write(
            &log,
            "master listening\ndashboard on http://127.0.0.1:4321/\n",
        )
        .unwrap();
        assert_eq!(
            dashboard_addr(&log),
            Some("127.0.0.1:4321".parse().unwrap())
        );
        std::fs::write(&log, "master listening\n").unwrap();
        assert_eq!(dashboard_addr(&log), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
