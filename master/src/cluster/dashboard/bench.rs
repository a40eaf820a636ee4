//! `bench dashboard`: what serving the dashboard costs the master, and how
//! soon the page shows an eviction. Each pair runs two real clusters of
//! processes on loopback at the same time, each this binary's `run` and
//! four state-hash `showcase-node`s at 120 Hz, one with the dashboard and
//! one without; whatever the machine does during the window happens to
//! both. (Runs one after the other drifted by more than the effect: 0.06 to
//! 0.099 CPU s/s between rounds.) With the dashboard on, a client reads the
//! page's event stream and scrapes `/metrics` every 250 ms on one
//! kept-alive connection. The figure is each master's CPU time (its
//! threads' run time in `/proc/PID/task/*/schedstat`) per second of the
//! window; the dashboard's share is the median over pairs of on / off - 1,
//! with a bootstrap interval, beside the cost attributed to it (its thread
//! and the frame loop's snapshots). Two identical clusters side by side
//! differ by up to 8 % in a window, so after it the master with the
//! dashboard is also measured with the client on and off in turn (on,
//! off, off, on, twice). Then one of its nodes is killed (-9) and the
//! stream is read until an event shows it evicted. Every wait is bounded;
//! the processes are killed on return.
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
/// How often the client scrapes `/metrics`: the rate the page polled at
/// before it read a stream, far more often than Prometheus scrapes (15 s
/// is usual). It keeps its connection open between scrapes, as
/// Prometheus does.
const SCRAPE_EVERY: Duration = Duration::from_millis(250);
/// Linux's `USER_HZ`: the unit of `/proc/PID/stat`'s CPU times.
const CLOCK_TICKS_PER_S: f64 = 100.0;

/// Settings of the bench.
#[derive(Clone, Debug)]
pub struct DashboardBenchOptions {
    /// The scene file the master shows.
    pub scene: PathBuf,
    /// The `showcase-node` binary (default: beside this one).
    pub node_bin: Option<PathBuf>,
    /// Pairs of clusters (one with the dashboard, one without).
    pub pairs: usize,
    /// The measured window of each run.
    pub window: Duration,
    /// Keep the work folder (config, logs) afterwards.
    pub keep: bool,
}

/// The record `bench dashboard --json` prints.
#[derive(Clone, Debug, Serialize)]
pub struct DashboardBenchRecord {
    /// Render nodes (processes) of each cluster.
    pub nodes: usize,
    /// Target frame rate.
    pub hz: f64,
    /// Pairs of clusters, each run at the same time.
    pub pairs: usize,
    /// Length of each measured window (s).
    pub window_s: f64,
    /// What the client did with the dashboard.
    pub client: String,
    /// Master CPU seconds per second, dashboard off, per pair.
    pub cpu_off: Vec<f64>,
    /// The same with the dashboard on and the client reading, per pair.
    pub cpu_on: Vec<f64>,
    /// Median of `cpu_off`.
    pub cpu_off_p50: f64,
    /// Median of `cpu_on`.
    pub cpu_on_p50: f64,
    /// Per pair, `cpu_on / cpu_off - 1`.
    pub cpu_overhead_per_pair: Vec<f64>,
    /// Median of `cpu_overhead_per_pair`: the dashboard's share (0.02 = 2 %).
    pub cpu_overhead: f64,
    /// A 95 % interval of `cpu_overhead` (percentile bootstrap): how
    /// finely this machine resolved it.
    pub cpu_overhead_ci95: [f64; 2],
    /// The dashboard thread's own CPU (s/s) per pair: what serving costs,
    /// without the noise of comparing two processes.
    pub dashboard_thread_cpu: Vec<f64>,
    /// The frame loop's time making and publishing snapshots (s/s) per
    /// pair, from `showcase_dashboard_snapshot_seconds_total`.
    pub snapshot_cpu: Vec<f64>,
    /// Median over pairs of `dashboard_thread_cpu + snapshot_cpu` over the
    /// rest of that master's CPU: the dashboard's cost, attributed. On
    /// loopback the kernel runs the receiving client's side of each send in
    /// the sender's thread, so this holds some of the client's work that a
    /// browser on another machine would do there; not in it is what sharing
    /// the cores does to the frame loop.
    pub attributed_overhead: f64,
    /// Slots of the toggled measurement, after each window: the master
    /// with the dashboard, its client on and off in turn (on, off, off,
    /// on, twice).
    pub toggle_slots: usize,
    /// Length of each slot (s).
    pub toggle_slot_s: f64,
    /// Per pair, that master's CPU in the slots with the client over the
    /// slots without it, less the snapshots it makes in both (their own
    /// counter), minus 1: the dashboard's cost with no noise between two
    /// processes (two identical clusters side by side differ by up to
    /// 8 %). A slot with the client includes opening its connections.
    pub toggled_overhead_per_pair: Vec<f64>,
    /// Median of `toggled_overhead_per_pair`.
    pub toggled_overhead: f64,
    /// A 95 % interval of `toggled_overhead` (percentile bootstrap).
    pub toggled_overhead_ci95: [f64; 2],
    /// Events the page's stream delivered in each window (4 a second).
    pub stream_events: Vec<usize>,
    /// From kill -9 of a node to the stream's event showing it evicted
    /// (ms), per pair: what the page shows, with nothing added.
    pub eviction_to_page_ms: Vec<f64>,
    /// Median of `eviction_to_page_ms`.
    pub eviction_to_page_ms_p50: Option<f64>,
    /// Where the processes' logs were kept (removed unless `--keep`).
    pub work_dir: String,
}

/// A connection to `addr` whose every read and write is bounded by a 5 s
/// timeout.
fn connect(addr: SocketAddr) -> Result<BufReader<TcpStream>> {
    let s = TcpStream::connect_timeout(&addr, Duration::from_secs(5))
        .with_context(|| format!("cannot connect to {addr}"))?;
    s.set_read_timeout(Some(Duration::from_secs(5)))?;
    s.set_write_timeout(Some(Duration::from_secs(5)))?;
    Ok(BufReader::new(s))
}

/// An answer's status line and the headers the bench's clients read.
struct Head {
    status: u16,
    status_line: String,
    content_length: Option<usize>,
    /// `Connection: close`.
    close: bool,
}

/// Read an answer's head, up to the empty line that ends it.
fn read_head(conn: &mut BufReader<TcpStream>) -> Result<Head> {
    let mut status_line = String::new();
    anyhow::ensure!(
        conn.read_line(&mut status_line)? > 0,
        "the server closed the connection"
    );
    let status_line = status_line.trim_end().to_owned();
    let status = status_line
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .with_context(|| format!("no status in {status_line:?}"))?;
    let mut head = Head {
        status,
        status_line,
        content_length: None,
        close: false,
    };
    loop {
        let mut line = String::new();
        anyhow::ensure!(
            conn.read_line(&mut line)? > 0,
            "the answer ended in its header"
        );
        let line = line.trim_end_matches(['\r', '\n']);
        if line.is_empty() {
            return Ok(head);
        }
        if let Some((name, value)) = line.split_once(':') {
            let value = value.trim();
            if name.eq_ignore_ascii_case("content-length") {
                head.content_length = Some(value.parse::<usize>().context("a bad Content-Length")?);
            } else if name.eq_ignore_ascii_case("connection") {
                head.close = value.eq_ignore_ascii_case("close");
            }
        }
    }
}

/// A GET of `path` on `addr` over HTTP/1.1 with `headers` (`Name: value`),
/// the connection closed after it: the status and the body. Bounded by a
/// 5 s timeout on each read and write.
pub fn http_get(addr: SocketAddr, path: &str, headers: &[&str]) -> Result<(u16, String)> {
    let mut conn = connect(addr)?;
    let mut req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for h in headers {
        req += h;
        req += "\r\n";
    }
    req += "\r\n";
    conn.get_mut().write_all(req.as_bytes())?;
    let head = read_head(&mut conn)?;
    let mut body = String::new();
    conn.read_to_string(&mut body)
        .context("the answer is not UTF-8")?;
    Ok((head.status, body))
}

/// The largest body [`KeepAlive`] reads (bytes).
const MAX_BODY: usize = 16 << 20;

/// A client that keeps one HTTP/1.1 connection open for its GETs, as a
/// Prometheus scraper does, and opens another when the server has closed
/// it. Every read and write is bounded by a 5 s timeout.
pub struct KeepAlive {
    addr: SocketAddr,
    conn: Option<BufReader<TcpStream>>,
}

impl KeepAlive {
    /// A client of `addr`; it connects on the first GET.
    pub fn new(addr: SocketAddr) -> Self {
        Self { addr, conn: None }
    }

    /// GET `path`: the status and the body, which must come with a
    /// `Content-Length`. A connection the server closed between two GETs
    /// is opened again once.
    pub fn get(&mut self, path: &str) -> Result<(u16, String)> {
        let reused = self.conn.is_some();
        match self.exchange(path) {
            Err(_) if reused => self.exchange(path),
            r => r,
        }
    }

    /// One GET on the open connection (or a new one), which is taken while
    /// in use: an error or a `Connection: close` drops it.
    fn exchange(&mut self, path: &str) -> Result<(u16, String)> {
        let mut conn = match self.conn.take() {
            Some(c) => c,
            None => connect(self.addr)?,
        };
        conn.get_mut()
            .write_all(format!("GET {path} HTTP/1.1\r\nHost: {}\r\n\r\n", self.addr).as_bytes())?;
        let head = read_head(&mut conn)?;
        let length = head
            .content_length
            .context("the answer has no Content-Length")?;
        anyhow::ensure!(
            length <= MAX_BODY,
            "the answer's Content-Length {length} is over the {MAX_BODY} bytes a scrape may be"
        );
        let mut body = vec![0; length];
        conn.read_exact(&mut body)?;
        let body = String::from_utf8(body).context("the answer is not UTF-8")?;
        if !head.close {
            self.conn = Some(conn);
        }
        Ok((head.status, body))
    }
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
        let mut reader = connect(addr)?;
        reader
            .get_mut()
            .write_all(format!("GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").as_bytes())?;
        let head = read_head(&mut reader).with_context(|| format!("opening {path}"))?;
        if head.status != 200 {
            let mut rest = String::new();
            let _ = reader.read_to_string(&mut rest);
            bail!("{path} answered {:?}: {rest}", head.status_line);
        }
        Ok(Self { reader })
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

/// One cluster of processes: a master, with the dashboard or without, and
/// its nodes. Dropping it kills what is still running.
struct Cluster {
    procs: Procs,
    log: PathBuf,
}

impl Cluster {
    fn start(run: &Run<'_>, dashboard: bool, tag: &str) -> Result<Self> {
        let cfg = loopback_config_at(free_port()?, run.scene, "source = \"scripted\"", &NODES, HZ);
        let config = run.dir.join(format!("cluster-{tag}.toml"));
        std::fs::write(&config, cfg)?;
        let log = run.dir.join(format!("master-{tag}.log"));
        let mut master = Command::new(run.exe);
        master.arg("run").arg("--config").arg(&config);
        if dashboard {
            master.args(["--dashboard", "127.0.0.1:0"]);
        }
        let master = master
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log)?)
            .spawn()
            .with_context(|| format!("cannot start {}", run.exe.display()))?;
        let mut procs = Procs(vec![master]);
        for (name, _) in NODES {
            let node_log = std::fs::File::create(run.dir.join(format!("{name}-{tag}.log")))?;
            procs.0.push(
                Command::new(run.node_bin)
                    .arg("--config")
                    .arg(&config)
                    .args(["--name", name, "--renderer", "state-hash"])
                    .stdout(Stdio::null())
                    .stderr(node_log)
                    .spawn()
                    .with_context(|| format!("cannot start {}", run.node_bin.display()))?,
            );
        }
        Ok(Self { procs, log })
    }

    fn pid(&self) -> u32 {
        self.procs.0[0].id()
    }

    fn started(&self) -> bool {
        std::fs::read_to_string(&self.log).is_ok_and(|t| t.contains("frame clock started"))
    }

    /// SIGTERM to the master, and a bounded wait for it.
    fn stop(mut self) -> Result<()> {
        signal(&self.procs.0[0], "-TERM")?;
        wait_for(Duration::from_secs(10), || {
            self.procs.0[0].try_wait().ok().flatten().is_some()
        });
        Ok(())
    }
}

/// What every pair shares.
struct Run<'a> {
    exe: &'a Path,
    node_bin: &'a Path,
    dir: &'a Path,
    scene: &'a Path,
    window: Duration,
}

struct PairFigures {
    /// The master with the dashboard, CPU s/s: the mean of the toggled
    /// slots with the client on, and with it off.
    toggled_on: f64,
    toggled_off: f64,
    cpu_on: f64,
    cpu_off: f64,
    /// The dashboard thread's share of `cpu_on` (CPU s/s).
    dashboard_cpu: f64,
    /// The frame loop's time making snapshots (s/s).
    snapshot_cpu: f64,
    /// Events the page's stream delivered in the window.
    events: usize,
    eviction_ms: Option<f64>,
}

/// The bench's client of the dashboard: the page's event stream, read on
/// a thread of its own (each event with its time of arrival), and a
/// scraper of `/metrics` every [`SCRAPE_EVERY`] on one kept-alive
/// connection. [`Client::stop`] closes both.
struct Client {
    addr: SocketAddr,
    events: std::sync::mpsc::Receiver<(Instant, String)>,
    /// The stream's connection, to shut it down.
    stream: TcpStream,
    stop: Arc<AtomicBool>,
    scraper: std::thread::JoinHandle<u64>,
}

impl Client {
    fn start(addr: SocketAddr) -> Result<Self> {
        let mut stream = EventStream::open(addr, "/api/stream")?;
        let handle = stream.reader.get_ref().try_clone()?;
        let (tx, events) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            // Ends with the stream (the master stops, or the client is
            // stopped) or when nobody listens.
            while let Ok(Some((name, data))) = stream.next_event() {
                if name == "state" && tx.send((Instant::now(), data)).is_err() {
                    break;
                }
            }
        });
        let stop = Arc::new(AtomicBool::new(false));
        let scraper = {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let mut scrapes = 0u64;
                let mut client = KeepAlive::new(addr);
                while !stop.load(Ordering::Relaxed) {
                    let t = Instant::now();
                    if client.get("/metrics").is_ok_and(|(s, _)| s == 200) {
                        scrapes += 1;
                    }
                    std::thread::sleep(SCRAPE_EVERY.saturating_sub(t.elapsed()));
                }
                scrapes
            })
        };
        Ok(Self {
            addr,
            events,
            stream: handle,
            stop,
            scraper,
        })
    }

    /// Close the stream and stop scraping; an error when no scrape
    /// succeeded.
    fn stop(self) -> Result<()> {
        let _ = self.stream.shutdown(std::net::Shutdown::Both);
        self.stop.store(true, Ordering::Relaxed);
        let scrapes = self.scraper.join().unwrap_or(0);
        anyhow::ensure!(scrapes > 0, "the client scraped nothing from {}", self.addr);
        Ok(())
    }
}

/// The slots of the toggled measurement, in order: whether the client is
/// on in each (ABBA twice, so a drift in time cancels).
const TOGGLE: [bool; 8] = [true, false, false, true, true, false, false, true];

/// How long each slot of the toggled measurement lasts.
const TOGGLE_SLOT: Duration = Duration::from_millis(1250);

/// The master `pid`'s CPU s/s in the slots of [`TOGGLE`], with the client
/// on and off: the mean of each.
fn toggled(addr: SocketAddr, pid: u32) -> Result<(f64, f64)> {
    let (mut on, mut off) = (Vec::new(), Vec::new());
    for client_on in TOGGLE {
        let client = client_on.then(|| Client::start(addr)).transpose()?;
        let (t0, c0) = (Instant::now(), cpu_seconds(pid)?);
        std::thread::sleep(TOGGLE_SLOT);
        let rate = (cpu_seconds(pid)? - c0) / t0.elapsed().as_secs_f64();
        if let Some(c) = client {
            c.stop()?;
        }
        if client_on { &mut on } else { &mut off }.push(rate);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    Ok((mean(&on), mean(&off)))
}

/// Whether a stream event shows `node` evicted.
fn shows_evicted(event: &str, node: &str) -> bool {
    serde_json::from_str::<serde_json::Value>(event).is_ok_and(|v| {
        v["state"]["nodes"].as_array().is_some_and(|nodes| {
            nodes
                .iter()
                .any(|n| n["name"] == node && n["state"] == "evicted")
        })
    })
}

/// One pair: a cluster with the dashboard and one without, running at the
/// same time, so that whatever the machine does in the window happens to
/// both. `on_first` says which is started first.
fn one_pair(run: &Run<'_>, index: usize, on_first: bool) -> Result<PairFigures> {
    let (on, off) = if on_first {
        let on = Cluster::start(run, true, &format!("{index}-on"))?;
        (on, Cluster::start(run, false, &format!("{index}-off"))?)
    } else {
        let off = Cluster::start(run, false, &format!("{index}-off"))?;
        (Cluster::start(run, true, &format!("{index}-on"))?, off)
    };
    if !wait_for(Duration::from_secs(60), || on.started() && off.started()) {
        bail!(
            "the frame clocks did not start within 60 s; see {} and {}",
            on.log.display(),
            off.log.display()
        );
    }
    let addr = dashboard_addr(&on.log).context("the master printed no dashboard address")?;
    // Settle: clock probes and the first frames' catch-up.
    std::thread::sleep(Duration::from_secs(1));
    let client = Client::start(addr)?;
    let s0 = snapshot_seconds(addr)?;
    let (t0, on0, off0, d0) = (
        Instant::now(),
        cpu_seconds(on.pid())?,
        cpu_seconds(off.pid())?,
        dashboard_thread_seconds(on.pid())?,
    );
    std::thread::sleep(run.window);
    let (on1, off1, d1, elapsed) = (
        cpu_seconds(on.pid())?,
        cpu_seconds(off.pid())?,
        dashboard_thread_seconds(on.pid())?,
        t0.elapsed().as_secs_f64(),
    );
    let s1 = snapshot_seconds(addr)?;
    let in_window = client.events.try_iter().count();
    client.stop()?;
    anyhow::ensure!(
        d1 > 0.0,
        "the master has no thread named {:?} (or it never ran): the dashboard's own cost cannot be told apart",
        super::THREAD_NAME
    );
    anyhow::ensure!(in_window > 0, "the page's stream delivered nothing");
    let (toggled_on, toggled_off) = toggled(addr, on.pid())?;
    let watcher = Client::start(addr)?;
    // kill -9 a node of the cluster with the dashboard; the page sees its
    // eviction when an event of the stream shows it.
    let mut on = on;
    let victim = NODES.len();
    let t_kill = Instant::now();
    on.procs.0[victim].kill()?;
    on.procs.0[victim].wait()?;
    let mut eviction_ms = None;
    while let Ok((at, event)) = watcher.events.recv_timeout(Duration::from_secs(5)) {
        if at >= t_kill && shows_evicted(&event, NODES[victim - 1].0) {
            eviction_ms = Some(at.duration_since(t_kill).as_secs_f64() * 1e3);
            break;
        }
        if t_kill.elapsed() > Duration::from_secs(5) {
            break;
        }
    }
    // Its scrapes are not the figure; the eviction was.
    let _ = watcher.stop();
    on.stop()?;
    off.stop()?;
    Ok(PairFigures {
        toggled_on,
        toggled_off,
        cpu_on: (on1 - on0) / elapsed,
        cpu_off: (off1 - off0) / elapsed,
        dashboard_cpu: (d1 - d0) / elapsed,
        snapshot_cpu: (s1 - s0) / elapsed,
        events: in_window,
        eviction_ms,
    })
}

fn median(v: &[f64]) -> f64 {
    percentile(v, 50.0).unwrap_or(f64::NAN)
}

/// A 95 % interval of the median of `v`: the percentile bootstrap, 2,000
/// resamples from a fixed seed (so a record can be recomputed).
fn median_ci95(v: &[f64]) -> [f64; 2] {
    use rand::{Rng, SeedableRng};
    if v.is_empty() {
        return [f64::NAN; 2];
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x5eed);
    let mut medians: Vec<f64> = (0..2000)
        .map(|_| {
            let resample: Vec<f64> = (0..v.len())
                .map(|_| v[rng.random_range(0..v.len())])
                .collect();
            median(&resample)
        })
        .collect();
    medians.sort_by(f64::total_cmp);
    [medians[49], medians[1949]]
}

/// Run the bench.
pub fn bench_dashboard(opts: &DashboardBenchOptions) -> Result<DashboardBenchRecord> {
    anyhow::ensure!(opts.pairs >= 1, "the bench needs at least one pair");
    let ProcessBench {
        exe,
        node_bin,
        scene,
        dir,
    } = ProcessBench::prepare(opts.node_bin.as_deref(), &opts.scene, "dashboard", &NODES)?;
    let run = Run {
        exe: &exe,
        node_bin: &node_bin,
        dir: &dir,
        scene: &scene,
        window: opts.window,
    };
    let (mut off, mut on, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    let (mut thread, mut snapshot, mut attributed) = (Vec::new(), Vec::new(), Vec::new());
    let (mut events, mut evictions, mut toggled) = (Vec::new(), Vec::new(), Vec::new());
    for pair in 0..opts.pairs {
        let r = one_pair(&run, pair, pair % 2 == 0)?;
        eprintln!(
            "bench dashboard: pair {pair}: {:.4} CPU s/s on, {:.4} off ({:+.1} %); toggled {:.4} client on, {:.4} off; its thread {:.5}, snapshots {:.6}; {} events; eviction seen after {:?} ms",
            r.cpu_on,
            r.cpu_off,
            (r.cpu_on / r.cpu_off - 1.0) * 100.0,
            r.toggled_on,
            r.toggled_off,
            r.dashboard_cpu,
            r.snapshot_cpu,
            r.events,
            r.eviction_ms
        );
        on.push(r.cpu_on);
        off.push(r.cpu_off);
        ratio.push(r.cpu_on / r.cpu_off - 1.0);
        thread.push(r.dashboard_cpu);
        snapshot.push(r.snapshot_cpu);
        attributed.push(
            (r.dashboard_cpu + r.snapshot_cpu) / (r.cpu_on - r.dashboard_cpu - r.snapshot_cpu),
        );
        // Off slots still make snapshots: without them is without the
        // dashboard.
        toggled.push(r.toggled_on / (r.toggled_off - r.snapshot_cpu) - 1.0);
        events.push(r.events);
        evictions.extend(r.eviction_ms);
    }
    if !opts.keep {
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(DashboardBenchRecord {
        nodes: NODES.len(),
        hz: HZ,
        pairs: opts.pairs,
        window_s: opts.window.as_secs_f64(),
        client: format!(
            "the page's event stream (/api/stream), and GET /metrics every {} ms on one kept-alive connection",
            SCRAPE_EVERY.as_millis()
        ),
        cpu_off_p50: median(&off),
        cpu_on_p50: median(&on),
        cpu_off: off,
        cpu_on: on,
        cpu_overhead: median(&ratio),
        cpu_overhead_ci95: median_ci95(&ratio),
        cpu_overhead_per_pair: ratio,
        dashboard_thread_cpu: thread,
        snapshot_cpu: snapshot,
        attributed_overhead: median(&attributed),
        toggle_slots: TOGGLE.len(),
        toggle_slot_s: TOGGLE_SLOT.as_secs_f64(),
        toggled_overhead: median(&toggled),
        toggled_overhead_ci95: median_ci95(&toggled),
        toggled_overhead_per_pair: toggled,
        stream_events: events,
        eviction_to_page_ms_p50: percentile(&evictions, 50.0),
        eviction_to_page_ms: evictions,
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
    fn the_interval_of_the_median_holds_it_and_narrows_with_more_pairs() {
        assert_eq!(median_ci95(&[0.03; 5]), [0.03, 0.03]);
        // A spread like the bench's: pairs a few percent either side.
        let spread = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| 0.02 + 0.05 * ((i * 7919 % 101) as f64 / 100.0 - 0.5))
                .collect()
        };
        let (few, many) = (spread(8), spread(200));
        let [lo, hi] = median_ci95(&few);
        let m = median(&few);
        assert!(lo <= m && m <= hi, "{lo} {m} {hi}");
        assert!(lo >= -0.0051 && hi <= 0.0451, "{lo} {hi}");
        let [lo2, hi2] = median_ci95(&many);
        assert!(
            hi2 - lo2 < (hi - lo) / 2.0,
            "{lo2}..{hi2} against {lo}..{hi}"
        );
        // The same record gives the same interval.
        assert_eq!(median_ci95(&few), [lo, hi]);
    }

    #[test]
    fn the_scraper_keeps_its_connection_and_opens_another_when_the_server_closed_it() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let server = std::thread::spawn(move || {
            let answer = |conn: &mut BufReader<TcpStream>, reply: &str| {
                let mut line = String::new();
                while conn.read_line(&mut line).unwrap() > 0 && line != "\r\n" {
                    line.clear();
                }
                conn.get_mut().write_all(reply.as_bytes()).unwrap();
            };
            let accept = || {
                let (s, _) = listener.accept().unwrap();
                s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
                BufReader::new(s)
            };
            let mut first = accept();
            answer(
                &mut first,
                "HTTP/1.1 200 OK\r\nContent-Length: 3\r\n\r\none",
            );
            answer(
                &mut first,
                "HTTP/1.1 200 OK\r\ncontent-length: 3\r\n\r\ntwo",
            );
            drop(first);
            let mut second = accept();
            answer(
                &mut second,
                "HTTP/1.1 404 Not Found\r\nContent-Length: 5\r\nConnection: close\r\n\r\nthree",
            );
        });
        let mut client = KeepAlive::new(addr);
        assert_eq!(client.get("/metrics").unwrap(), (200, "one".to_owned()));
        assert_eq!(client.get("/metrics").unwrap(), (200, "two".to_owned()));
        // The server closed the first connection: one more is opened.
        assert_eq!(client.get("/x").unwrap(), (404, "three".to_owned()));
        assert!(client.conn.is_none(), "Connection: close was not heeded");
        server.join().unwrap();
    }

    #[test]
    fn an_eviction_is_read_from_the_named_node_of_a_stream_event() {
        let event = r#"{"append":true,"state":{"nodes":[
            {"name":"face-0","state":"joined"},{"name":"face-1","state":"evicted"}]}}"#;
        assert!(shows_evicted(event, "face-1"));
        assert!(!shows_evicted(event, "face-0"));
        assert!(!shows_evicted(event, "projector-0"));
        assert!(!shows_evicted("not json", "face-1"));
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
