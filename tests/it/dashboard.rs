//! The master's live dashboard (`run --dashboard`): its HTTP endpoints
//! (Prometheus text, JSON, the access token, the loopback rule), and the
//! page in headless Chromium over a real cluster of processes: a master
//! and four nodes, one of which is killed.

use crate::browser::Browser;
use crate::shutdown::spawn_master;
use showcase_master::certs;
use showcase_master::cli::{Cli, run};
use showcase_master::cluster::ClusterRun;
use showcase_master::cluster::Roster;
use showcase_master::cluster::dashboard::bench::{
    EventStream, dashboard_addr, http_get, node_state,
};
use showcase_master::cluster::dashboard::{Dashboard, DashboardOptions};
use showcase_master::cluster::faults::loopback_config;
use showcase_master::cluster::live::{History, LivePublisher, LiveSnapshot, LiveStats};
use showcase_proto::Role;
use showcase_proto::session::ConnId;
use showcase_render::net::ClusterIdentity;
use showcase_render::node::{NodeRuntime, StateHashRenderer, run_node};
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tokio_util::sync::CancellationToken;

/// One sample of a Prometheus text exposition.
#[derive(Debug)]
struct Sample {
    name: String,
    labels: BTreeMap<String, String>,
    value: f64,
}

/// Parse the Prometheus text format 0.0.4 strictly: every sample belongs to
/// a family declared once by `# TYPE` before it (summaries and histograms
/// own their `_sum`, `_count` and `_bucket`), names and label names are
/// valid, label values are quoted with only `\\`, `\"` and `\n` escaped,
/// and every value is a float. Panics with the line on anything else.
fn parse_prometheus(text: &str) -> Vec<Sample> {
    let valid_name = |n: &str| {
        !n.is_empty()
            && !n.starts_with(|c: char| c.is_ascii_digit())
            && n.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':')
    };
    let mut types: BTreeMap<String, String> = BTreeMap::new();
    let mut samples = Vec::new();
    assert!(
        text.ends_with('\n'),
        "the exposition must end with a newline"
    );
    for line in text.lines() {
        if line.is_empty() {
            continue;
        }
        if let Some(rest) = line.strip_prefix("# ") {
            let mut parts = rest.splitn(3, ' ');
            match (parts.next(), parts.next(), parts.next()) {
                (Some("TYPE"), Some(name), Some(kind)) => {
                    assert!(valid_name(name), "bad family name: {line}");
                    assert!(
                        ["counter", "gauge", "summary", "histogram", "untyped"].contains(&kind),
                        "bad type: {line}"
                    );
                    assert!(
                        types.insert(name.to_owned(), kind.to_owned()).is_none(),
                        "TYPE twice: {line}"
                    );
                }
                (Some("HELP"), Some(name), _) => assert!(valid_name(name), "{line}"),
                _ => {}
            }
            continue;
        }
        let (name, rest) = match line.find(['{', ' ']) {
            Some(i) => line.split_at(i),
            None => panic!("sample without value: {line}"),
        };
        assert!(valid_name(name), "bad metric name: {line}");
        let mut labels = BTreeMap::new();
        let mut rest = rest;
        if let Some(body) = rest.strip_prefix('{') {
            let mut chars = body.char_indices().peekable();
            let end = loop {
                let (i, c) = chars.next().unwrap_or_else(|| panic!("unclosed: {line}"));
                if c == '}' {
                    break i;
                }
                if c == ',' {
                    continue;
                }
                let mut key = String::from(c);
                for (_, c) in chars.by_ref() {
                    if c == '=' {
                        break;
                    }
                    key.push(c);
                }
                assert!(valid_name(&key), "bad label name {key:?}: {line}");
                assert_eq!(chars.next().map(|c| c.1), Some('"'), "unquoted: {line}");
                let mut value = String::new();
                loop {
                    match chars.next().map(|c| c.1) {
                        Some('"') => break,
                        Some('\\') => match chars.next().map(|c| c.1) {
                            Some('\\') => value.push('\\'),
                            Some('"') => value.push('"'),
                            Some('n') => value.push('\n'),
                            other => panic!("bad escape {other:?}: {line}"),
                        },
                        Some(c) => value.push(c),
                        None => panic!("unterminated label value: {line}"),
                    }
                }
                assert!(labels.insert(key, value).is_none(), "label twice: {line}");
            };
            rest = &body[end + 1..];
        }
        let mut fields = rest.split_whitespace();
        let value = fields.next().unwrap_or_else(|| panic!("no value: {line}"));
        let value: f64 = match value {
            "+Inf" => f64::INFINITY,
            "-Inf" => f64::NEG_INFINITY,
            v => v.parse().unwrap_or_else(|_| panic!("bad value: {line}")),
        };
        if let Some(ts) = fields.next() {
            ts.parse::<i64>()
                .unwrap_or_else(|_| panic!("bad timestamp: {line}"));
        }
        assert!(fields.next().is_none(), "trailing fields: {line}");
        let family = types.get(name).map(|_| name).or_else(|| {
            ["_sum", "_count", "_bucket"].iter().find_map(|s| {
                let base = name.strip_suffix(s)?;
                matches!(
                    types.get(base).map(String::as_str),
                    Some("summary" | "histogram")
                )
                .then_some(base)
            })
        });
        assert!(family.is_some(), "sample of an undeclared family: {line}");
        samples.push(Sample {
            name: name.to_owned(),
            labels,
            value,
        });
    }
    samples
}

fn find<'a>(samples: &'a [Sample], name: &str, labels: &[(&str, &str)]) -> Option<&'a Sample> {
    samples.iter().find(|s| {
        s.name == name
            && labels
                .iter()
                .all(|(k, v)| s.labels.get(*k).map(String::as_str) == Some(*v))
    })
}

#[test]
fn the_prometheus_parser_refuses_what_prometheus_would() {
    let good = "# HELP a_total x\n# TYPE a_total counter\na_total{n=\"q\\\"\"} 1\n\
                # TYPE s summary\ns{quantile=\"0.5\"} NaN\ns_sum 1\ns_count 2\n";
    let samples = parse_prometheus(good);
    assert_eq!(samples.len(), 4);
    assert_eq!(samples[0].labels["n"], "q\"");
    for bad in [
        "a 1\n",
        "# TYPE a gauge\na{n=1} 1\n",
        "# TYPE a gauge\na one\n",
        "# TYPE a gauge\n# TYPE a gauge\n",
        "# TYPE a gauge\na{n=\"\\x\"} 1\n",
        "# TYPE a gauge\na_count 1\n",
    ] {
        let r = std::panic::catch_unwind(|| parse_prometheus(bad));
        assert!(r.is_err(), "accepted {bad:?}");
    }
}

/// A dashboard in this process, serving one snapshot of a roster of two
/// nodes (one joined), with `token`.
async fn serve_one_snapshot(
    token: Option<&str>,
) -> (
    SocketAddr,
    CancellationToken,
    showcase_master::cluster::dashboard::DashboardTask,
) {
    let roster = Roster::new([
        ("face-0".to_owned(), Role::Face),
        ("projector-0".to_owned(), Role::Projector),
    ]);
    let mut live = LiveStats::new(&roster, 120.0, 0.0);
    live.joined("face-0", Role::Face, ConnId(0));
    let snap = live.snapshot(
        &ClusterRun::default(),
        &showcase_proto::Showcase::default(),
        3,
        1_000_000_000,
    );
    let (mut publisher, rx) = LivePublisher::new(Duration::from_millis(100));
    publisher.publish(snap);
    let dash = Dashboard::bind(&DashboardOptions {
        addr: "127.0.0.1:0".parse().unwrap(),
        public: false,
        token: token.map(str::to_owned),
    })
    .unwrap();
    let addr = dash.local_addr();
    let stop = CancellationToken::new();
    let task = dash.serve(rx, stop.clone()).unwrap();
    (addr, stop, task)
}

async fn get(addr: SocketAddr, path: &str, headers: &[&str]) -> (u16, String) {
    let (path, headers): (String, Vec<String>) = (
        path.to_owned(),
        headers.iter().map(|h| (*h).to_owned()).collect(),
    );
    tokio::task::spawn_blocking(move || {
        let h: Vec<&str> = headers.iter().map(String::as_str).collect();
        http_get(addr, &path, &h).unwrap()
    })
    .await
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_and_state_serve_the_published_snapshot() {
    let (addr, stop, task) = serve_one_snapshot(None).await;
    let (status, body) = get(addr, "/metrics", &[]).await;
    assert_eq!(status, 200, "{body}");
    let samples = parse_prometheus(&body);
    let joined = find(
        &samples,
        "showcase_node_state",
        &[("node", "face-0"), ("role", "face"), ("state", "joined")],
    )
    .expect("face-0's state line");
    assert_eq!(joined.value, 1.0);
    let waiting = find(
        &samples,
        "showcase_node_state",
        &[
            ("node", "projector-0"),
            ("role", "projector"),
            ("state", "waiting"),
        ],
    )
    .expect("projector-0's state line");
    assert_eq!(waiting.value, 1.0);
    assert_eq!(
        find(&samples, "showcase_scene_version", &[]).unwrap().value,
        3.0
    );
    // The first snapshot carries the cost of none before it.
    for counter in [
        "showcase_dashboard_snapshots_total",
        "showcase_dashboard_snapshot_seconds_total",
    ] {
        assert_eq!(
            find(&samples, counter, &[]).unwrap().value,
            0.0,
            "{counter}"
        );
    }
    assert_eq!(
        find(&samples, "showcase_node_joins_total", &[("node", "face-0")])
            .unwrap()
            .value,
        1.0
    );

    let (status, body) = get(addr, "/api/state", &[]).await;
    assert_eq!(status, 200);
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(v["scene_version"], 3);
    assert_eq!(v["nodes"][0]["name"], "face-0");
    assert_eq!(v["nodes"][0]["state"], "joined");
    assert_eq!(v["nodes"][1]["state"], "waiting");

    let (status, page) = get(addr, "/", &[]).await;
    assert_eq!(status, 200);
    assert!(
        page.contains("api/stream"),
        "the page does not read the event stream"
    );
    let (status, body) = get(addr, "/nothing", &[]).await;
    assert_eq!(status, 404);
    assert!(body.contains("/api/state"), "{body}");
    stop.cancel();
    showcase_master::cluster::dashboard::stop(task).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_a_token_requests_without_it_get_401() {
    let token = "s3cret-token-0123456789";
    let (addr, stop, task) = serve_one_snapshot(Some(token)).await;
    for path in ["/", "/api/state", "/metrics"] {
        let (status, body) = get(addr, path, &[]).await;
        assert_eq!(status, 401, "{path}: {body}");
        assert!(body.contains("access token"), "{body}");
        let (status, _) = get(
            addr,
            path,
            &["Authorization: Bearer wrong-token-0123456789"],
        )
        .await;
        assert_eq!(status, 401, "{path} with a wrong token");
        let (status, _) = get(addr, path, &[&format!("Authorization: Bearer {token}")]).await;
        assert_eq!(status, 200, "{path} with the token");
        let (status, _) = get(addr, &format!("{path}?token={token}"), &[]).await;
        assert_eq!(status, 200, "{path}?token=");
    }
    stop.cancel();
    showcase_master::cluster::dashboard::stop(task).await;
}

/// `/api/stream` sends the current snapshot with every plot point, then
/// each published one with the points from the newest it sent (which may
/// have grown) on; it asks for the token like every other path, and says
/// `end` and closes when the dashboard stops (rather than being dropped
/// after the stop's grace), so an open page does not hold the master.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_event_stream_sends_each_snapshot_with_the_points_a_page_lacks() {
    let token = "s3cret-token-0123456789";
    let snapshot = |version: u64, t: &[f64], skew: &[f64]| LiveSnapshot {
        scene_version: version,
        history: History {
            interval_ms: 500.0,
            t_unix_ms: t.to_vec(),
            swap_skew_ms_max: skew.iter().map(|&v| Some(v)).collect(),
            tracking_to_swap_ms_max: vec![None; t.len()],
        },
        ..LiveSnapshot::default()
    };
    let (mut publisher, rx) = LivePublisher::new(Duration::from_millis(100));
    publisher.publish(snapshot(1, &[1000.0, 1500.0, 2000.0], &[0.1, 0.2, 0.3]));
    let dash = Dashboard::bind(&DashboardOptions {
        addr: "127.0.0.1:0".parse().unwrap(),
        public: false,
        token: Some(token.to_owned()),
    })
    .unwrap();
    let addr = dash.local_addr();
    let stop = CancellationToken::new();
    let task = dash.serve(rx, stop.clone()).unwrap();

    let (status, body) = get(addr, "/api/stream", &[]).await;
    assert_eq!(status, 401, "{body}");
    let path = format!("/api/stream?token={token}");
    let events = tokio::task::spawn_blocking(move || {
        let mut stream = EventStream::open(addr, &path).unwrap();
        let mut next = || {
            let (name, data) = stream.next_event().unwrap().expect("an event");
            assert_eq!(name, "state", "{data}");
            serde_json::from_str::<serde_json::Value>(&data).unwrap()
        };
        let mut events = vec![next()];
        // The oldest point has left the master's history; the one at 2000
        // grew and one at 2500 is new.
        publisher.publish(snapshot(2, &[1500.0, 2000.0, 2500.0], &[0.2, 0.35, 0.4]));
        events.push(next());
        publisher.publish(snapshot(3, &[1500.0, 2000.0, 2500.0], &[0.2, 0.35, 0.45]));
        events.push(next());
        stop.cancel();
        let end = stream.next_event().unwrap();
        assert_eq!(
            end.as_ref().map(|(name, _)| name.as_str()),
            Some("end"),
            "the stream did not say it ended: {end:?}"
        );
        assert!(
            stream.next_event().unwrap().is_none(),
            "the stream went on after its end"
        );
        drop(publisher);
        events
    })
    .await
    .unwrap();
    let points = |e: &serde_json::Value| {
        let h = &e["state"]["history"];
        let t: Vec<f64> = serde_json::from_value(h["t_unix_ms"].clone()).unwrap();
        let v: Vec<f64> = serde_json::from_value(h["swap_skew_ms_max"].clone()).unwrap();
        (t, v)
    };
    assert_eq!(events[0]["append"], false);
    assert_eq!(events[0]["state"]["scene_version"], 1);
    assert_eq!(
        points(&events[0]),
        (vec![1000.0, 1500.0, 2000.0], vec![0.1, 0.2, 0.3])
    );
    assert_eq!(events[1]["append"], true);
    assert_eq!(events[1]["state"]["scene_version"], 2);
    assert_eq!(points(&events[1]), (vec![2000.0, 2500.0], vec![0.35, 0.4]));
    assert_eq!(events[2]["state"]["scene_version"], 3);
    assert_eq!(points(&events[2]), (vec![2500.0], vec![0.45]));
    showcase_master::cluster::dashboard::stop(task).await;
}

#[test]
fn a_dashboard_beyond_loopback_is_refused_without_the_flag_and_a_token() {
    let refused = |args: &[&str]| {
        let mut all = vec!["showcase-master", "run", "--config", "no-such-cluster.toml"];
        all.extend_from_slice(args);
        let cli = <Cli as clap::Parser>::try_parse_from(all).unwrap();
        run(cli).unwrap_err().to_string()
    };
    let e = refused(&["--dashboard", "0.0.0.0:0"]);
    assert!(
        e.contains("not a loopback address") && e.contains("--dashboard-public"),
        "{e}"
    );
    // Refused before the configuration is read.
    assert!(!e.contains("no-such-cluster"), "{e}");
    let e = refused(&[
        "--dashboard",
        "0.0.0.0:0",
        "--dashboard-public",
        "--dashboard-token",
        "short",
    ]);
    assert!(e.contains("at least 16 characters"), "{e}");
    let e = DashboardOptions {
        addr: "0.0.0.0:0".parse().unwrap(),
        public: true,
        token: None,
    }
    .check()
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("needs an access token") && e.contains("SHOWCASE_DASHBOARD_TOKEN"),
        "{e}"
    );
}

/// Holds the child node's `[name, role, master address, certs folder]` (JSON).
const CHILD_NODE: &str = "SHOWCASE_IT_CHILD_NODE";

/// A state-hash node as a child process of the browser test, so that it
/// can be killed -9; it stops by itself after 120 s.
#[test]
#[ignore = "run as a child process by the_page_shows_the_nodes_and_an_eviction"]
fn child_node() {
    let args = std::env::var(CHILD_NODE).expect("only the dashboard test runs this");
    let [name, role, master, certs]: [String; 4] = serde_json::from_str(&args).unwrap();
    let role = if role == "projector" {
        Role::Projector
    } else {
        Role::Face
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let runtime = NodeRuntime {
            name: name.clone(),
            role,
            master: master.parse().unwrap(),
            identity: ClusterIdentity::load(std::path::Path::new(&certs), &name).unwrap(),
            bind: "127.0.0.1:0".parse().unwrap(),
            capabilities: Default::default(),
            write_frames: None,
            keep_presented: false,
        };
        let stop = CancellationToken::new();
        let s = stop.clone();
        tokio::spawn(async move {
            tokio::time::sleep(Duration::from_secs(120)).await;
            s.cancel();
        });
        let mut r = StateHashRenderer::new(&name, role);
        run_node(runtime, &mut r, stop).await.unwrap();
    });
}

/// Child processes, killed on drop.
struct Children(Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Poll `f` every 50 ms until it returns `Some`, for at most `limit`.
fn poll<T>(limit: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let t0 = Instant::now();
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if t0.elapsed() > limit {
            return None;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn the_page_shows_the_nodes_and_an_eviction() {
    let dir = std::env::temp_dir().join(format!("showcase-dashboard-it-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let nodes = [
        ("face-0", Role::Face),
        ("face-1", Role::Face),
        ("projector-0", Role::Projector),
        ("projector-1", Role::Projector),
    ];
    let names = nodes.map(|(n, _)| n);
    let owned: Vec<String> = names.iter().map(|n| (*n).to_owned()).collect();
    certs::write(&dir.join("certs"), &certs::generate(&owned).unwrap()).unwrap();
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    // The demo cabinet's two faces and two projectors.
    let scene =
        showcase_master::scene_file::absolute(&showcase_master::demo::default_scene()).unwrap();
    let cfg = loopback_config(port, &scene, "source = \"scripted\"", &nodes);
    let config = dir.join("cluster.toml");
    std::fs::write(&config, cfg).unwrap();
    let log = dir.join("master.log");
    let master = spawn_master(
        &[
            "run",
            "--config",
            config.to_str().unwrap(),
            "--dashboard",
            "127.0.0.1:0",
        ],
        &log,
    );
    let mut procs = Children(vec![master]);
    let master_log = || std::fs::read_to_string(&log).unwrap_or_default();
    let addr = poll(Duration::from_secs(60), || dashboard_addr(&log))
        .unwrap_or_else(|| panic!("no dashboard address; master log:\n{}", master_log()));
    for (name, role) in nodes {
        let args = serde_json::to_string(&[
            name,
            &role.to_string(),
            &format!("127.0.0.1:{port}"),
            dir.join("certs").to_str().unwrap(),
        ])
        .unwrap();
        procs.0.push(
            Command::new(std::env::current_exe().unwrap())
                .args(["--ignored", "--exact", "dashboard::child_node"])
                .env(CHILD_NODE, args)
                .stdout(Stdio::null())
                .stderr(std::fs::File::create(dir.join(format!("{name}.log"))).unwrap())
                .spawn()
                .unwrap(),
        );
    }
    let all_joined = || {
        names
            .iter()
            .all(|n| node_state(addr, n).as_deref() == Some("joined"))
            .then_some(())
    };
    poll(Duration::from_secs(60), all_joined)
        .unwrap_or_else(|| panic!("the 4 nodes did not join; master log:\n{}", master_log()));

    // The Prometheus endpoint of the real master has every node's lines.
    let (status, text) = http_get(addr, "/metrics", &[]).unwrap();
    assert_eq!(status, 200);
    let samples = parse_prometheus(&text);
    for (n, role) in nodes {
        let role = role.to_string();
        assert!(
            find(
                &samples,
                "showcase_node_frames_presented_total",
                &[("node", n), ("role", &role)]
            )
            .is_some(),
            "no line for {n}:\n{text}"
        );
    }

    let browser = Browser::launch();
    let mut browser = browser;
    if let Some(b) = browser.as_mut() {
        b.open(&format!("http://{addr}/"));
        b.wait_for(
            "document.querySelectorAll('#nodes tr[data-node]').length === 4 && \
             document.querySelectorAll('#nodes tr[data-state=\"joined\"]').length === 4",
            Duration::from_secs(20),
        );
        // The page's plot points, merged from the stream's events, are the
        // master's: none doubled where an event resent the newest, none
        // lost. Only the closed intervals before the page's newest point
        // are compared; the master may have published since.
        b.wait_for(
            "points !== null && points.t_unix_ms.length >= 6",
            Duration::from_secs(20),
        );
        let page: serde_json::Value =
            serde_json::from_str(b.eval("JSON.stringify(points)").as_str().unwrap()).unwrap();
        let (_, state) = http_get(addr, "/api/state", &[]).unwrap();
        let master: serde_json::Value = serde_json::from_str(&state).unwrap();
        let closed = |h: &serde_json::Value, before: f64| -> Vec<(f64, serde_json::Value)> {
            let t = h["t_unix_ms"].as_array().unwrap();
            t.iter()
                .zip(h["swap_skew_ms_max"].as_array().unwrap())
                .map(|(t, v)| (t.as_f64().unwrap(), v.clone()))
                .filter(|(t, _)| *t < before)
                .collect()
        };
        let newest = page["t_unix_ms"].as_array().unwrap().last().unwrap();
        let newest = newest.as_f64().unwrap();
        let on_page = closed(&page, newest);
        assert!(on_page.len() >= 5, "{page}");
        assert_eq!(on_page, closed(&master["history"], newest));
    }

    // kill -9 face-1 (the second node process).
    let victim = &mut procs.0[2];
    victim.kill().unwrap();
    victim.wait().unwrap();
    if let Some(b) = browser.as_mut() {
        let shown = b.wait_for(
            "(() => { const r = document.querySelector('#nodes tr[data-node=\"face-1\"]'); \
             return r && r.dataset.state === 'evicted' && r.querySelector('.state').textContent; })()",
            Duration::from_secs(10),
        );
        assert_eq!(shown, "evicted");
        let others = b.eval("document.querySelectorAll('#nodes tr[data-node]').length");
        assert_eq!(others, 4);
        let errors = b.errors();
        assert!(errors.is_empty(), "the page reported errors: {errors:?}");
    }
    let evicted = poll(Duration::from_secs(10), || {
        (node_state(addr, "face-1").as_deref() == Some("evicted")).then_some(())
    });
    assert!(evicted.is_some(), "/api/state never showed face-1 evicted");
    let (_, text) = http_get(addr, "/metrics", &[]).unwrap();
    let samples = parse_prometheus(&text);
    let line = find(
        &samples,
        "showcase_node_state",
        &[("node", "face-1"), ("state", "evicted")],
    )
    .unwrap();
    assert_eq!(line.value, 1.0);
    assert!(
        find(&samples, "showcase_evictions_total", &[])
            .unwrap()
            .value
            >= 1.0,
        "{text}"
    );

    // SIGTERM: the master stops cleanly, with the live statistics' summary.
    let pid = procs.0[0].id().to_string();
    assert!(
        Command::new("kill")
            .args(["-TERM", &pid])
            .status()
            .unwrap()
            .success()
    );
    let status = poll(Duration::from_secs(20), || procs.0[0].try_wait().unwrap())
        .expect("SIGTERM did not stop the master");
    assert!(status.success(), "master log:\n{}", master_log());
    assert!(master_log().contains("swap skew p50"), "{}", master_log());
    drop(procs);
    let _ = std::fs::remove_dir_all(&dir);
}
