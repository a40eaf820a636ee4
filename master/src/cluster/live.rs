//! The live master's statistics in constant memory: HDR histograms of swap
//! skew, tracking-to-swap latency and each node's render and barrier times,
//! each node's state and latest figures, and a fixed ring of the last
//! minutes for the dashboard's plots. Nothing here grows with the length
//! of the show: its size is set by the roster. The frame loop updates it
//! without allocating; [`LiveStats::snapshot`] (a few times a second, for
//! the dashboard) and [`LiveStats::summary`] (at the end) read it.

use super::identity::Roster;
use super::server::ClusterRun;
use hdrhistogram::Histogram;
use serde::Serialize;
use showcase_proto::session::{CloseReason, ConnId, PresentReport, SwapReport};
use showcase_proto::{FrameState, Role, Showcase};
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// The largest value a histogram holds (µs): 60 s. Larger values are
/// recorded as 60 s.
const HIST_MAX_US: u64 = 60_000_000;

/// A constant-memory histogram of durations, recorded in whole
/// microseconds (1 µs to 60 s), with a running sum for the mean.
#[derive(Clone, Debug)]
pub struct LiveHistogram {
    h: Histogram<u64>,
    sum_ms: f64,
}

/// Quantiles of a [`LiveHistogram`] (ms); `None` when it is empty.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Quantiles {
    /// Values recorded.
    pub count: u64,
    /// Sum of the values (ms).
    pub sum_ms: f64,
    /// Median.
    pub p50: Option<f64>,
    /// 90th percentile.
    pub p90: Option<f64>,
    /// 99th percentile.
    pub p99: Option<f64>,
    /// Largest value.
    pub max: Option<f64>,
}

impl LiveHistogram {
    /// An empty histogram with `digits` significant decimal digits: values
    /// are kept to a relative error of `10^-digits` (and to 1 µs).
    pub fn new(digits: u8) -> Self {
        Self {
            h: Histogram::new_with_bounds(1, HIST_MAX_US, digits)
                .expect("1 us to 60 s with 1 to 5 digits are valid bounds"),
            sum_ms: 0.0,
        }
    }

    /// Record a duration in ms; negative and non-finite values are ignored.
    pub fn record_ms(&mut self, ms: f64) {
        if !(ms.is_finite() && ms >= 0.0) {
            return;
        }
        self.h
            .saturating_record(((ms * 1e3).round() as u64).min(HIST_MAX_US));
        self.sum_ms += ms;
    }

    /// The value at quantile `q` (0 to 1, nearest rank), in ms.
    pub fn quantile_ms(&self, q: f64) -> Option<f64> {
        (!self.h.is_empty()).then(|| self.h.value_at_quantile(q) as f64 / 1e3)
    }

    /// Values recorded.
    pub fn count(&self) -> u64 {
        self.h.len()
    }

    /// Counting buckets held: fixed at creation, whatever is recorded.
    pub fn buckets(&self) -> usize {
        self.h.distinct_values()
    }

    /// Count, sum, median, 90th and 99th percentiles and maximum.
    pub fn quantiles(&self) -> Quantiles {
        Quantiles {
            count: self.count(),
            sum_ms: self.sum_ms,
            p50: self.quantile_ms(0.5),
            p90: self.quantile_ms(0.9),
            p99: self.quantile_ms(0.99),
            max: (!self.h.is_empty()).then(|| self.h.max() as f64 / 1e3),
        }
    }
}

/// Where a node of the roster stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum NodeState {
    /// It has not joined yet.
    Waiting,
    /// It is in the frame lock.
    Joined,
    /// It joined again after an eviction or a close, and has not presented
    /// a frame since.
    Rejoining,
    /// The master evicted it for missing a swap deadline.
    Evicted,
    /// Its connection closed otherwise (Bye, lost, refused message).
    Left,
}

impl NodeState {
    /// Its name in the JSON and the Prometheus labels.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Waiting => "waiting",
            Self::Joined => "joined",
            Self::Rejoining => "rejoining",
            Self::Evicted => "evicted",
            Self::Left => "left",
        }
    }

    /// Every state, for exposition.
    pub const ALL: [NodeState; 5] = [
        Self::Waiting,
        Self::Joined,
        Self::Rejoining,
        Self::Evicted,
        Self::Left,
    ];
}

#[derive(Clone, Debug)]
struct NodeLive {
    role: Role,
    state: NodeState,
    conn: Option<ConnId>,
    joins: u64,
    evictions: u64,
    presented: u64,
    /// Frames the cluster had presented when the node first joined.
    cluster_presented_at_join: Option<u64>,
    render_ms: Option<f32>,
    barrier_wait_ms: Option<f32>,
    present_offset_ms: Option<f64>,
    last_close: Option<String>,
    render: LiveHistogram,
    barrier: LiveHistogram,
}

/// One point of the plots: the largest value in its interval.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Point {
    bucket: u64,
    skew_ms: Option<f64>,
    latency_ms: Option<f64>,
}

/// The plots' history: one point per `HISTORY_INTERVAL`, the last
/// `HISTORY_POINTS` of them.
const HISTORY_INTERVAL_NS: u64 = 500_000_000;
/// 600 points of 0.5 s: the last five minutes.
pub const HISTORY_POINTS: usize = 600;

/// The live statistics of one master run.
#[derive(Clone, Debug)]
pub struct LiveStats {
    origin_unix_ms: f64,
    target_hz: f32,
    started: bool,
    presented: u64,
    nodes: BTreeMap<String, NodeLive>,
    skew: LiveHistogram,
    latency: LiveHistogram,
    history: VecDeque<Point>,
    last_state: Option<FrameState>,
}

/// Swap skew and tracking-to-swap latency over a whole run, from the live
/// histograms (3 significant digits, 1 µs).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LiveSummary {
    /// Spread of the nodes' present times.
    pub swap_skew_ms: Quantiles,
    /// From the newest tracking sample to the swap.
    pub tracking_to_swap_ms: Quantiles,
}

impl LiveSummary {
    /// One line for the end of `run`.
    pub fn line(&self) -> String {
        let q = |q: &Quantiles| match (q.p50, q.p99, q.max) {
            (Some(a), Some(b), Some(c)) => format!("p50 {a:.3} / p99 {b:.3} / max {c:.3} ms"),
            _ => "none".to_owned(),
        };
        format!(
            "swap skew {}; tracking to swap {}",
            q(&self.swap_skew_ms),
            q(&self.tracking_to_swap_ms)
        )
    }
}

impl LiveStats {
    /// Statistics for the nodes of `roster` at `target_hz`;
    /// `origin_unix_ms` is the wall-clock time of master-clock zero.
    pub fn new(roster: &Roster, target_hz: f32, origin_unix_ms: f64) -> Self {
        let mut s = Self {
            origin_unix_ms,
            target_hz,
            started: false,
            presented: 0,
            nodes: BTreeMap::new(),
            skew: LiveHistogram::new(3),
            latency: LiveHistogram::new(3),
            history: VecDeque::with_capacity(HISTORY_POINTS + 1),
            last_state: None,
        };
        for (name, role) in roster.entries() {
            s.node_mut(name, role);
        }
        s
    }

    fn node_mut(&mut self, name: &str, role: Role) -> &mut NodeLive {
        if !self.nodes.contains_key(name) {
            self.nodes.insert(
                name.to_owned(),
                NodeLive {
                    role,
                    state: NodeState::Waiting,
                    conn: None,
                    joins: 0,
                    evictions: 0,
                    presented: 0,
                    cluster_presented_at_join: None,
                    render_ms: None,
                    barrier_wait_ms: None,
                    present_offset_ms: None,
                    last_close: None,
                    // Two digits (1 %) per node keep a large roster small.
                    render: LiveHistogram::new(2),
                    barrier: LiveHistogram::new(2),
                },
            );
        }
        self.nodes.get_mut(name).expect("inserted above")
    }

    /// The frame clock started.
    pub fn started(&mut self) {
        self.started = true;
    }

    /// `node` joined on `conn`.
    pub fn joined(&mut self, node: &str, role: Role, conn: ConnId) {
        let presented = self.presented;
        let n = self.node_mut(node, role);
        n.role = role;
        n.state = if n.joins == 0 {
            NodeState::Joined
        } else {
            NodeState::Rejoining
        };
        n.joins += 1;
        n.conn = Some(conn);
        n.cluster_presented_at_join.get_or_insert(presented);
    }

    /// The connection `conn` of `node` closed. A close of a connection the
    /// node has since replaced changes nothing.
    pub fn closed(&mut self, node: Option<&str>, conn: ConnId, reason: &CloseReason) {
        let Some(n) = node.and_then(|name| self.nodes.get_mut(name)) else {
            return;
        };
        if n.conn != Some(conn) {
            return;
        }
        n.conn = None;
        n.state = match reason {
            CloseReason::MissedDeadline { .. } => {
                n.evictions += 1;
                NodeState::Evicted
            }
            _ => NodeState::Left,
        };
        n.last_close = Some(reason.to_string());
    }

    /// A frame's present reports are in: record its figures and keep its
    /// state (the tracked bodies).
    pub fn presented(&mut self, swap: &SwapReport, present: &PresentReport, state: FrameState) {
        self.presented += 1;
        let skew = present.swap_skew_ns.map(|s| s as f64 / 1e6);
        let latency = swap
            .tracking_time_ns
            .map(|t| swap.swap_at_ns.saturating_sub(t) as f64 / 1e6);
        if let Some(s) = skew {
            self.skew.record_ms(s);
        }
        if let Some(l) = latency {
            self.latency.record_ms(l);
        }
        for p in &present.nodes {
            if let Some(n) = self.nodes.get_mut(p.node.as_str()) {
                n.presented += 1;
                n.render_ms = Some(p.render_ms);
                n.barrier_wait_ms = Some(p.barrier_wait_ms);
                n.present_offset_ms = p.present_offset_ns.map(|o| o as f64 / 1e6);
                n.render.record_ms(p.render_ms as f64);
                n.barrier.record_ms(p.barrier_wait_ms as f64);
                if n.state == NodeState::Rejoining {
                    n.state = NodeState::Joined;
                }
            }
        }
        let bucket = swap.swap_at_ns / HISTORY_INTERVAL_NS;
        let max = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
        match self.history.back_mut() {
            Some(p) if p.bucket == bucket => {
                p.skew_ms = max(p.skew_ms, skew);
                p.latency_ms = max(p.latency_ms, latency);
            }
            _ => {
                if self.history.len() == HISTORY_POINTS {
                    self.history.pop_front();
                }
                self.history.push_back(Point {
                    bucket,
                    skew_ms: skew,
                    latency_ms: latency,
                });
            }
        }
        self.last_state = Some(state);
    }

    /// The run's swap skew and latency figures.
    pub fn summary(&self) -> LiveSummary {
        LiveSummary {
            swap_skew_ms: self.skew.quantiles(),
            tracking_to_swap_ms: self.latency.quantiles(),
        }
    }

    /// Everything the dashboard shows, now. `scene` names the observers.
    pub fn snapshot(
        &self,
        run: &ClusterRun,
        scene: &Showcase,
        scene_version: u64,
        now_ns: u64,
    ) -> LiveSnapshot {
        let ms32 = |v: Option<f32>| v.map(f64::from);
        let nodes = self
            .nodes
            .iter()
            .map(|(name, n)| NodeSnapshot {
                name: name.clone(),
                role: n.role.to_string(),
                state: n.state,
                joins: n.joins,
                evictions: n.evictions,
                frames_presented: n.presented,
                frames_dropped: n
                    .cluster_presented_at_join
                    .map_or(0, |at| (self.presented - at).saturating_sub(n.presented)),
                render_ms: ms32(n.render_ms),
                barrier_wait_ms: ms32(n.barrier_wait_ms),
                present_offset_ms: n.present_offset_ms,
                render_ms_p50: n.render.quantile_ms(0.5),
                render_ms_p99: n.render.quantile_ms(0.99),
                barrier_wait_ms_p99: n.barrier.quantile_ms(0.99),
                last_close: n.last_close.clone(),
            })
            .collect();
        let mut bodies = Vec::new();
        if let Some(s) = &self.last_state {
            for (i, h) in s.heads.iter().enumerate() {
                bodies.push(BodySnapshot {
                    kind: "observer",
                    name: scene
                        .observers
                        .get(i)
                        .map_or_else(|| format!("observer {i}"), |o| o.name.clone()),
                    position: h.position.to_array(),
                });
            }
            for l in &s.lights {
                bodies.push(BodySnapshot {
                    kind: "light",
                    name: l.name.clone(),
                    position: l.light.position().to_array(),
                });
            }
            for t in &s.object_transforms {
                bodies.push(BodySnapshot {
                    kind: "object",
                    name: scene
                        .objects
                        .get(t.object as usize)
                        .map_or_else(|| format!("object {}", t.object), |o| o.name.clone()),
                    position: t.transform.translation.to_array(),
                });
            }
        }
        let origin = self.origin_unix_ms;
        LiveSnapshot {
            unix_ms: origin + now_ns as f64 / 1e6,
            uptime_s: now_ns as f64 / 1e9,
            target_hz: self.target_hz,
            frame_clock_started: self.started,
            scene_version,
            frames_submitted: run.submitted,
            frames_presented: run.presented,
            ticks_dropped: run.dropped_ticks,
            evictions: run.evictions,
            swap_skew_ms: self.skew.quantiles(),
            tracking_to_swap_ms: self.latency.quantiles(),
            nodes,
            bodies,
            history: History {
                interval_ms: HISTORY_INTERVAL_NS as f64 / 1e6,
                t_unix_ms: self
                    .history
                    .iter()
                    .map(|p| origin + (p.bucket * HISTORY_INTERVAL_NS) as f64 / 1e6)
                    .collect(),
                swap_skew_ms_max: self.history.iter().map(|p| p.skew_ms).collect(),
                tracking_to_swap_ms_max: self.history.iter().map(|p| p.latency_ms).collect(),
            },
            dashboard: DashboardCost::default(),
        }
    }
}

/// What `/api/state` serves and `/metrics` exposes.
#[derive(Clone, Debug, Default, Serialize)]
pub struct LiveSnapshot {
    /// When it was taken (ms since the Unix epoch).
    pub unix_ms: f64,
    /// Seconds since the master started.
    pub uptime_s: f64,
    /// Target frame rate.
    pub target_hz: f32,
    /// Whether the frame clock runs.
    pub frame_clock_started: bool,
    /// The scene version the frames refer to.
    pub scene_version: u64,
    /// Frames submitted.
    pub frames_submitted: u64,
    /// Frames presented.
    pub frames_presented: u64,
    /// Frame-clock ticks at which no frame could be submitted.
    pub ticks_dropped: u64,
    /// Evictions for a missed deadline.
    pub evictions: u64,
    /// Swap skew over the run.
    pub swap_skew_ms: Quantiles,
    /// Tracking-to-swap latency over the run.
    pub tracking_to_swap_ms: Quantiles,
    /// Every node of the roster.
    pub nodes: Vec<NodeSnapshot>,
    /// The tracked bodies' positions in the newest presented frame.
    pub bodies: Vec<BodySnapshot>,
    /// The plots.
    pub history: History,
    /// What the snapshots before this one cost the frame loop.
    pub dashboard: DashboardCost,
}

/// The dashboard's cost to the frame loop: making and publishing its
/// snapshots (serving them costs the dashboard's own thread).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct DashboardCost {
    /// Snapshots made.
    pub snapshots: u64,
    /// Time spent making and publishing them (s).
    pub snapshot_s: f64,
}

/// One node on the dashboard.
#[derive(Clone, Debug, Serialize)]
pub struct NodeSnapshot {
    /// Name.
    pub name: String,
    /// Role.
    pub role: String,
    /// State.
    pub state: NodeState,
    /// Joins, the first included.
    pub joins: u64,
    /// Evictions.
    pub evictions: u64,
    /// Frames it presented.
    pub frames_presented: u64,
    /// Frames the cluster presented without it since it first joined.
    pub frames_dropped: u64,
    /// Its latest render time (ms).
    pub render_ms: Option<f64>,
    /// Its latest wait between Ready and Swap (ms).
    pub barrier_wait_ms: Option<f64>,
    /// Its latest present time minus the swap time (ms).
    pub present_offset_ms: Option<f64>,
    /// Median render time (ms).
    pub render_ms_p50: Option<f64>,
    /// 99th percentile render time (ms).
    pub render_ms_p99: Option<f64>,
    /// 99th percentile barrier wait (ms).
    pub barrier_wait_ms_p99: Option<f64>,
    /// Why its last connection closed.
    pub last_close: Option<String>,
}

/// A tracked body.
#[derive(Clone, Debug, Serialize)]
pub struct BodySnapshot {
    /// `observer`, `light` or `object`.
    pub kind: &'static str,
    /// The scene's name for it.
    pub name: String,
    /// World position (m).
    pub position: [f32; 3],
}

/// The plots: per interval, the largest swap skew and latency.
#[derive(Clone, Debug, Default, Serialize)]
pub struct History {
    /// Interval of one point (ms).
    pub interval_ms: f64,
    /// Start of each interval (ms since the Unix epoch).
    pub t_unix_ms: Vec<f64>,
    /// Largest swap skew in each interval (ms).
    pub swap_skew_ms_max: Vec<Option<f64>>,
    /// Largest tracking-to-swap latency in each interval (ms).
    pub tracking_to_swap_ms_max: Vec<Option<f64>>,
}

impl History {
    /// The points from the interval that starts at `t_unix_ms` on (all of
    /// them for `None`): what a reader that holds the points up to that
    /// interval lacks. That interval itself is included, because the newest
    /// point grows until its interval ends.
    pub fn from(&self, t_unix_ms: Option<f64>) -> History {
        let start = t_unix_ms.map_or(0, |t| self.t_unix_ms.partition_point(|&x| x < t));
        History {
            interval_ms: self.interval_ms,
            t_unix_ms: self.t_unix_ms[start..].to_vec(),
            swap_skew_ms_max: self.swap_skew_ms_max[start..].to_vec(),
            tracking_to_swap_ms_max: self.tracking_to_swap_ms_max[start..].to_vec(),
        }
    }
}

/// The master's side of the dashboard: publishes a snapshot at most every
/// `every`, so the frame loop does the work a few times a second, and
/// counts the time that work takes (the dashboard's cost to the frame loop,
/// served as `showcase_dashboard_snapshot_seconds_total`).
#[derive(Debug)]
pub struct LivePublisher {
    tx: watch::Sender<Arc<LiveSnapshot>>,
    every: Duration,
    next: Instant,
    spent: Duration,
    made: u64,
}

/// How often the live master publishes a snapshot: 4 times a second, the
/// rate the page polled at before it read a stream. Each publication is
/// one message to every open page, and a message costs the dashboard
/// thread about 100 µs on the 2-core VM whatever it carries, so the rate
/// is most of the dashboard's cost; an eviction still reaches the page in
/// a quarter of a second after the master sees it.
pub const PUBLISH_EVERY: Duration = Duration::from_millis(250);

impl LivePublisher {
    /// A publisher and the receiver the dashboard reads.
    pub fn new(every: Duration) -> (Self, watch::Receiver<Arc<LiveSnapshot>>) {
        let (tx, rx) = watch::channel(Arc::new(LiveSnapshot::default()));
        (
            Self {
                tx,
                every,
                next: Instant::now(),
                spent: Duration::ZERO,
                made: 0,
            },
            rx,
        )
    }

    /// Whether a snapshot is due.
    pub fn due(&self) -> bool {
        Instant::now() >= self.next
    }

    /// Publish `snapshot` now.
    pub fn publish(&mut self, snapshot: LiveSnapshot) {
        self.publish_with(|| snapshot);
    }

    /// Make a snapshot with `make` and publish it now, timing both. The
    /// snapshot carries the time spent on the ones before it.
    pub fn publish_with(&mut self, make: impl FnOnce() -> LiveSnapshot) {
        let t = Instant::now();
        let mut snapshot = make();
        snapshot.dashboard = DashboardCost {
            snapshots: self.made,
            snapshot_s: self.spent.as_secs_f64(),
        };
        self.tx.send_replace(Arc::new(snapshot));
        let now = Instant::now();
        self.spent += now - t;
        self.made += 1;
        self.next = now + self.every;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use showcase_light::metrics::percentile;

    /// A skewed sample (0.01 to about 600 ms), from a fixed SplitMix-style
    /// sequence.
    fn sample(n: usize) -> Vec<f64> {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        (0..n)
            .map(|_| {
                x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
                let mut z = x;
                z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
                z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
                let u = (z ^ (z >> 31)) as f64 / u64::MAX as f64;
                0.01 * (u * 11.0).exp()
            })
            .collect()
    }

    fn empty_state() -> FrameState {
        FrameState {
            frame: 0,
            time_s: 0.0,
            scene_version: 0,
            heads: Vec::new(),
            lights: Vec::new(),
            object_transforms: Vec::new(),
            tracking_time_ns: None,
            illumination_version: None,
        }
    }

    #[test]
    fn histogram_quantiles_agree_with_exact_percentiles_within_its_precision() {
        let values = sample(20_000);
        let mut h = LiveHistogram::new(3);
        for &v in &values {
            h.record_ms(v);
        }
        for q in [1.0, 10.0, 50.0, 90.0, 99.0, 99.9, 100.0] {
            let exact = percentile(&values, q).unwrap();
            let got = h.quantile_ms(q / 100.0).unwrap();
            // 3 significant digits (relative 1e-3) of a value kept to 1 us.
            let tolerance = exact * 1e-3 + 1e-3;
            assert!(
                (got - exact).abs() <= tolerance,
                "p{q}: histogram {got} ms, exact {exact} ms"
            );
        }
        assert_eq!(h.count(), values.len() as u64);
        let sum: f64 = values.iter().sum();
        assert!((h.quantiles().sum_ms - sum).abs() < 1e-6 * sum);
    }

    #[test]
    fn histograms_and_history_hold_constant_memory() {
        let mut h = LiveHistogram::new(3);
        let buckets = h.buckets();
        for &v in &sample(100_000) {
            h.record_ms(v);
        }
        h.record_ms(1e9);
        h.record_ms(f64::NAN);
        h.record_ms(-1.0);
        assert_eq!(h.buckets(), buckets);
        assert_eq!(h.count(), 100_001);
        // 1e9 ms is held as 60 s, to the histogram's precision.
        let top = h.quantile_ms(1.0).unwrap();
        assert!((60_000.0..=60_000.0 * 1.001).contains(&top), "{top}");

        let roster = Roster::new([("a".to_owned(), Role::Face)]);
        let mut live = LiveStats::new(&roster, 120.0, 0.0);
        for frame in 0..(HISTORY_POINTS as u64 * 3) {
            let swap = SwapReport {
                frame,
                sent_at_ns: 0,
                swap_at_ns: frame * HISTORY_INTERVAL_NS,
                tracking_time_ns: Some(frame * HISTORY_INTERVAL_NS),
                ready: Vec::new(),
                evicted: Vec::new(),
                by_deadline: false,
            };
            let present = PresentReport {
                frame,
                swap_at_ns: swap.swap_at_ns,
                nodes: Vec::new(),
                missing: Vec::new(),
                swap_skew_ns: Some(frame),
            };
            live.presented(&swap, &present, empty_state());
        }
        assert_eq!(live.history.len(), HISTORY_POINTS);
        // The newest points stay, the oldest go.
        let last = live.history.back().unwrap();
        assert_eq!(last.bucket, HISTORY_POINTS as u64 * 3 - 1);
    }

    #[test]
    fn each_snapshot_carries_the_time_spent_on_the_ones_before() {
        let (mut publisher, rx) = LivePublisher::new(Duration::from_millis(200));
        let slow = || {
            std::thread::sleep(Duration::from_millis(2));
            LiveSnapshot::default()
        };
        publisher.publish_with(slow);
        assert_eq!(rx.borrow().dashboard, DashboardCost::default());
        assert!(!publisher.due(), "a snapshot was just published");
        publisher.publish_with(slow);
        publisher.publish_with(slow);
        let cost = rx.borrow().dashboard;
        assert_eq!(cost.snapshots, 2);
        assert!(
            (0.004..1.0).contains(&cost.snapshot_s),
            "two 2 ms snapshots counted as {} s",
            cost.snapshot_s
        );
    }

    #[test]
    fn node_states_follow_joins_evictions_and_rejoins() {
        let roster = Roster::new([("a".to_owned(), Role::Face)]);
        let mut live = LiveStats::new(&roster, 60.0, 0.0);
        let state = |l: &LiveStats| l.nodes["a"].state;
        assert_eq!(state(&live), NodeState::Waiting);
        live.joined("a", Role::Face, ConnId(1));
        assert_eq!(state(&live), NodeState::Joined);
        let missed = CloseReason::MissedDeadline {
            node: "a".into(),
            frame: 3,
            waited_ms: 50.0,
            deadline_ms: 50.0,
        };
        live.closed(Some("a"), ConnId(1), &missed);
        assert_eq!(state(&live), NodeState::Evicted);
        live.joined("a", Role::Face, ConnId(2));
        assert_eq!(state(&live), NodeState::Rejoining);
        // The old connection's late close does not touch the new one.
        live.closed(Some("a"), ConnId(1), &missed);
        assert_eq!(state(&live), NodeState::Rejoining);
        let swap = SwapReport {
            frame: 0,
            sent_at_ns: 0,
            swap_at_ns: 0,
            tracking_time_ns: None,
            ready: Vec::new(),
            evicted: Vec::new(),
            by_deadline: false,
        };
        let present = PresentReport {
            frame: 0,
            swap_at_ns: 0,
            nodes: vec![showcase_proto::session::NodePresent {
                conn: ConnId(2),
                node: "a".into(),
                render_ms: 2.5,
                barrier_wait_ms: 1.0,
                present_node_ns: 0,
                present_master_ns: None,
                present_offset_ns: Some(250_000),
            }],
            missing: Vec::new(),
            swap_skew_ns: None,
        };
        live.presented(&swap, &present, empty_state());
        assert_eq!(state(&live), NodeState::Joined);
        assert_eq!(live.nodes["a"].evictions, 1);
        assert_eq!(live.nodes["a"].joins, 2);
        live.closed(
            Some("a"),
            ConnId(2),
            &CloseReason::Left {
                peer: "node 'a'".into(),
                reason: "bye".into(),
            },
        );
        assert_eq!(state(&live), NodeState::Left);
    }
}
