//! The live dashboard `run --dashboard ADDR` serves: one page (`/`,
//! self-contained), the event stream it reads (`/api/stream`), the JSON
//! snapshot (`/api/state`) and a Prometheus text endpoint (`/metrics`). It
//! reads the snapshot the frame loop publishes a few times a second
//! ([`LivePublisher`]) and never touches the loop itself: it serves from a
//! thread of its own ([`THREAD_NAME`], a single-threaded runtime), so a
//! client never wakes the frame loop's workers and its whole cost is that
//! thread's CPU time. The page holds one connection open and is sent each
//! snapshot as it is published, with only the plot points it lacks, rather
//! than fetching the whole history each time. Each message costs that
//! thread about 100 µs on the 2-core VM, most of it the kernel's loopback
//! delivery (`bench dashboard`). `/api/state` and `/metrics` serialise each
//! snapshot once, however many requests read it.
//! It binds loopback unless told otherwise: a
//! non-loopback address needs `--dashboard-public` and an access token,
//! and every request then carries it (`Authorization: Bearer TOKEN` or
//! `?token=TOKEN`).
//!
//! [`LivePublisher`]: super::live::LivePublisher

pub mod bench;
pub mod prometheus;

use super::live::LiveSnapshot;
use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, Uri, header};
use axum::response::sse::{Event, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::watch;
use tokio_util::sync::CancellationToken;

/// The page: HTML, CSS and JavaScript in one file, no outside resources.
const PAGE: &str = include_str!("page.html");

/// The environment variable that may hold the access token.
pub const TOKEN_ENV: &str = "SHOWCASE_DASHBOARD_TOKEN";

/// The shortest access token accepted.
pub const MIN_TOKEN_LEN: usize = 16;

/// The name of the thread that serves the dashboard (`/proc/PID/task/*/comm`).
pub const THREAD_NAME: &str = "dashboard";

/// How long a stopped dashboard waits for open requests before it drops
/// them: a browser holding a connection open does not hold the master.
const STOP_GRACE: Duration = Duration::from_secs(2);

/// How soon a page reconnects a dropped event stream (the SSE `retry`).
const STREAM_RETRY: Duration = Duration::from_secs(1);

/// Where and how to serve the dashboard.
#[derive(Clone, Debug)]
pub struct DashboardOptions {
    /// Address to bind.
    pub addr: SocketAddr,
    /// Allow a non-loopback address.
    pub public: bool,
    /// Access token every request must carry (required with `public`).
    pub token: Option<String>,
}

/// Why the dashboard cannot be served.
#[derive(Debug, thiserror::Error)]
pub enum DashboardError {
    /// A non-loopback address without `--dashboard-public`.
    #[error(
        "--dashboard {0}: not a loopback address; the dashboard binds loopback (127.0.0.1, ::1) \
         unless --dashboard-public is given, with an access token in --dashboard-token or \
         ${TOKEN_ENV}"
    )]
    NotLoopback(SocketAddr),
    /// `--dashboard-public` without a token.
    #[error(
        "--dashboard-public needs an access token: set ${TOKEN_ENV} (or --dashboard-token) to \
         a secret of at least {MIN_TOKEN_LEN} characters"
    )]
    NoToken,
    /// A token too short or with characters that do not survive a URL.
    #[error(
        "the dashboard access token must be at least {MIN_TOKEN_LEN} characters of A-Z, a-z, \
         0-9, '-', '_', '.' or '~' (got {len} characters)"
    )]
    BadToken {
        /// Its length.
        len: usize,
    },
    /// The address could not be bound.
    #[error("cannot serve the dashboard on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The IO error.
        source: std::io::Error,
    },
    /// Its thread or runtime could not be started.
    #[error("cannot start the dashboard's thread: {0}")]
    Thread(std::io::Error),
}

impl DashboardOptions {
    /// Check the address against the flag and the token.
    pub fn check(&self) -> Result<(), DashboardError> {
        if let Some(t) = &self.token {
            let url_safe = t
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-_.~".contains(&b));
            if t.len() < MIN_TOKEN_LEN || !url_safe {
                return Err(DashboardError::BadToken { len: t.len() });
            }
        }
        if !self.addr.ip().is_loopback() {
            if !self.public {
                return Err(DashboardError::NotLoopback(self.addr));
            }
            if self.token.is_none() {
                return Err(DashboardError::NoToken);
            }
        }
        Ok(())
    }
}

/// A bound dashboard, ready to serve.
pub struct Dashboard {
    listener: std::net::TcpListener,
    addr: SocketAddr,
    token: Option<Arc<str>>,
}

/// A served body, made once per published snapshot: requests between two
/// snapshots share it.
type Cached = Mutex<Option<(Arc<LiveSnapshot>, Bytes)>>;

#[derive(Clone)]
struct App {
    snapshot: watch::Receiver<Arc<LiveSnapshot>>,
    token: Option<Arc<str>>,
    json: Arc<Cached>,
    prometheus: Arc<Cached>,
    /// Ends the event streams, which would otherwise hold a stopping
    /// dashboard open.
    stop: CancellationToken,
}

impl App {
    /// `render` of the newest snapshot, from `cache` when it already holds it.
    fn body(
        &self,
        cache: &Cached,
        render: impl FnOnce(&LiveSnapshot) -> Result<String, String>,
    ) -> Result<Bytes, String> {
        let snap = self.snapshot.borrow().clone();
        let mut cached = cache.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((of, body)) = cached.as_ref()
            && Arc::ptr_eq(of, &snap)
        {
            return Ok(body.clone());
        }
        let body = Bytes::from(render(&snap)?);
        *cached = Some((snap, body.clone()));
        Ok(body)
    }
}

/// The dashboard's thread: join it with [`stop`] after cancelling its
/// stop token.
pub struct DashboardTask(std::thread::JoinHandle<std::io::Result<()>>);

impl Dashboard {
    /// Check the options and bind the address.
    pub fn bind(opts: &DashboardOptions) -> Result<Self, DashboardError> {
        opts.check()?;
        let bind = |source| DashboardError::Bind {
            addr: opts.addr,
            source,
        };
        let listener = std::net::TcpListener::bind(opts.addr).map_err(bind)?;
        listener.set_nonblocking(true).map_err(bind)?;
        Ok(Self {
            addr: listener.local_addr().map_err(bind)?,
            listener,
            token: opts.token.as_deref().map(Arc::from),
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Serve `snapshot` from the dashboard's own thread until `stop` is
    /// cancelled; then open requests get a grace of 2 s to finish.
    pub fn serve(
        self,
        snapshot: watch::Receiver<Arc<LiveSnapshot>>,
        stop: CancellationToken,
    ) -> Result<DashboardTask, DashboardError> {
        let app = App {
            snapshot,
            token: self.token,
            json: Arc::default(),
            prometheus: Arc::default(),
            stop: stop.clone(),
        };
        let router = Router::new()
            .route("/", get(page))
            .route("/api/stream", get(stream))
            .route("/api/state", get(state))
            .route("/metrics", get(metrics))
            .fallback(not_found)
            .with_state(app);
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(DashboardError::Thread)?;
        let listener = self.listener;
        let thread = std::thread::Builder::new()
            .name(THREAD_NAME.to_owned())
            .spawn(move || {
                runtime.block_on(async move {
                    let listener = tokio::net::TcpListener::from_std(listener)?;
                    let serve = axum::serve(listener, router)
                        .with_graceful_shutdown(stop.clone().cancelled_owned())
                        .into_future();
                    let deadline = async {
                        stop.cancelled().await;
                        tokio::time::sleep(STOP_GRACE).await;
                    };
                    tokio::select! {
                        served = serve => served,
                        () = deadline => Ok(()),
                    }
                })
                // Dropping the runtime here drops what is still open.
            })
            .map_err(DashboardError::Thread)?;
        Ok(DashboardTask(thread))
    }
}

/// Wait for a dashboard whose stop token was cancelled: at most
/// the 2 s grace and a little more.
pub async fn stop(task: DashboardTask) {
    match tokio::task::spawn_blocking(move || task.0.join()).await {
        Ok(Ok(Ok(()))) => {}
        Ok(Ok(Err(e))) => tracing::warn!(error = %e, "dashboard"),
        Ok(Err(_)) => tracing::warn!("the dashboard's thread panicked"),
        Err(e) => tracing::warn!(error = %e, "waiting for the dashboard"),
    }
}

/// Whether a request carries the token (when there is one): in
/// `Authorization: Bearer`, or as the `token` query parameter.
fn authorized(app: &App, headers: &HeaderMap, uri: &Uri) -> bool {
    let Some(want) = app.token.as_deref() else {
        return true;
    };
    let bearer = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "));
    let query = uri
        .query()
        .and_then(|q| q.split('&').find_map(|kv| kv.strip_prefix("token=")));
    bearer.into_iter().chain(query).any(|t| same(t, want))
}

/// Whether a request may be served: with a token, it must carry it; without
/// one (a loopback dashboard), its `Host` must name loopback, so that a web
/// page the operator visits cannot read the dashboard by pointing a name of
/// its own at 127.0.0.1 (DNS rebinding). `None`: serve it.
fn refuse(app: &App, headers: &HeaderMap, uri: &Uri) -> Option<Response> {
    if app.token.is_some() {
        return (!authorized(app, headers, uri)).then(unauthorized);
    }
    let host = headers.get(header::HOST).and_then(|v| v.to_str().ok());
    match host {
        Some(h) if !loopback_host(h) => Some(
            (
                StatusCode::MISDIRECTED_REQUEST,
                format!(
                    "this dashboard answers only to a loopback host (localhost, 127.0.0.1, [::1]),                      not {:?}; to reach it by another name, run it with --dashboard-public and a token\n",
                    h.chars().take(64).collect::<String>()
                ),
            )
                .into_response(),
        ),
        _ => None,
    }
}

/// Whether an HTTP `Host` value (`name[:port]`, `[v6][:port]`) names this
/// machine's loopback.
fn loopback_host(host: &str) -> bool {
    let name = match host.strip_prefix('[') {
        Some(rest) => rest.split(']').next().unwrap_or(""),
        None => host.rsplit_once(':').map_or(host, |(n, _)| n),
    };
    name.eq_ignore_ascii_case("localhost")
        || name
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

/// 401, saying how to send the token.
fn unauthorized() -> Response {
    let mut r = (
        StatusCode::UNAUTHORIZED,
        "this dashboard needs its access token: send `Authorization: Bearer TOKEN` or add \
         ?token=TOKEN to the URL\n",
    )
        .into_response();
    r.headers_mut().insert(
        header::WWW_AUTHENTICATE,
        HeaderValue::from_static("Bearer realm=\"showcase\""),
    );
    r
}

/// Compare without stopping at the first difference, so the time taken
/// does not tell how much of a guess was right.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

fn with_type(body: impl Into<Body>, content_type: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body.into(),
    )
        .into_response()
}

async fn page(State(app): State<App>, headers: HeaderMap, uri: Uri) -> Response {
    if let Some(r) = refuse(&app, &headers, &uri) {
        return r;
    }
    with_type(PAGE.to_owned(), "text/html; charset=utf-8")
}

/// One `state` event of `/api/stream`: the newest snapshot, whose history holds
/// either every point (`append` false: the first event of a connection) or
/// only those from the newest one the connection was already sent, which
/// replace the reader's points from that time on.
#[derive(serde::Serialize)]
struct StreamEvent<'a> {
    append: bool,
    state: &'a LiveSnapshot,
}

/// What one `/api/stream` connection has been sent.
struct StreamCursor {
    snapshot: watch::Receiver<Arc<LiveSnapshot>>,
    stop: CancellationToken,
    /// Whether the first event has been sent.
    started: bool,
    /// Whether the `end` event has been sent.
    ended: bool,
    /// The start of the newest plot point sent.
    newest: Option<f64>,
}

impl StreamCursor {
    /// The next event: the current snapshot at once on a new connection,
    /// then each newly published one. When the dashboard stops or the
    /// frame loop ends, an `end` event, and then `None` ends the stream.
    async fn next(mut self) -> Option<(Result<Event, Infallible>, Self)> {
        if self.ended {
            return None;
        }
        if self.started {
            let changed = tokio::select! {
                changed = self.snapshot.changed() => changed.is_ok(),
                () = self.stop.cancelled() => false,
            };
            if !changed {
                self.ended = true;
                let end = Event::default().event("end").data("the master is stopping");
                return Some((Ok(end), self));
            }
        }
        let snap = self.snapshot.borrow_and_update().clone();
        let append = std::mem::replace(&mut self.started, true);
        let history = snap.history.from(self.newest);
        self.newest = history.t_unix_ms.last().copied().or(self.newest);
        let state = LiveSnapshot {
            history,
            ..(*snap).clone()
        };
        let event = match serde_json::to_string(&StreamEvent {
            append,
            state: &state,
        }) {
            Ok(json) => Event::default().event("state").data(json),
            Err(e) => Event::default().event("error").data(e.to_string()),
        };
        let event = if append {
            event
        } else {
            event.retry(STREAM_RETRY)
        };
        Some((Ok(event), self))
    }
}

async fn stream(State(app): State<App>, headers: HeaderMap, uri: Uri) -> Response {
    if let Some(r) = refuse(&app, &headers, &uri) {
        return r;
    }
    let cursor = StreamCursor {
        snapshot: app.snapshot.clone(),
        stop: app.stop.clone(),
        started: false,
        ended: false,
        newest: None,
    };
    let events = futures_util::stream::unfold(cursor, StreamCursor::next);
    ([(header::CACHE_CONTROL, "no-store")], Sse::new(events)).into_response()
}

async fn state(State(app): State<App>, headers: HeaderMap, uri: Uri) -> Response {
    if let Some(r) = refuse(&app, &headers, &uri) {
        return r;
    }
    match app.body(&app.json, |s| {
        serde_json::to_string(s).map_err(|e| e.to_string())
    }) {
        Ok(json) => with_type(json, "application/json"),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e).into_response(),
    }
}

async fn metrics(State(app): State<App>, headers: HeaderMap, uri: Uri) -> Response {
    if let Some(r) = refuse(&app, &headers, &uri) {
        return r;
    }
    match app.body(&app.prometheus, |s| Ok(prometheus::render(s))) {
        Ok(text) => with_type(text, prometheus::CONTENT_TYPE),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e).into_response(),
    }
}

async fn not_found(uri: Uri) -> Response {
    (
        StatusCode::NOT_FOUND,
        format!(
            "not found: {}; the dashboard serves /, /api/stream, /api/state and /metrics\n",
            uri.path()
        ),
    )
        .into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(addr: &str, public: bool, token: Option<&str>) -> DashboardOptions {
        DashboardOptions {
            addr: addr.parse().unwrap(),
            public,
            token: token.map(str::to_owned),
        }
    }

    #[test]
    fn only_loopback_without_the_flag_and_a_token() {
        let good = "0123456789abcdef";
        assert!(opts("127.0.0.1:0", false, None).check().is_ok());
        assert!(opts("[::1]:0", false, None).check().is_ok());
        assert!(matches!(
            opts("0.0.0.0:8080", false, Some(good)).check(),
            Err(DashboardError::NotLoopback(_))
        ));
        assert!(matches!(
            opts("0.0.0.0:8080", true, None).check(),
            Err(DashboardError::NoToken)
        ));
        assert!(opts("0.0.0.0:8080", true, Some(good)).check().is_ok());
        for bad in ["short", "0123456789abcdef gh", "0123456789abcdef&x"] {
            assert!(matches!(
                opts("127.0.0.1:0", false, Some(bad)).check(),
                Err(DashboardError::BadToken { .. })
            ));
        }
    }

    #[test]
    fn without_a_token_only_loopback_hosts_are_served() {
        for ok in [
            "localhost",
            "localhost:8080",
            "LOCALHOST:1",
            "127.0.0.1:9",
            "127.1.2.3",
            "[::1]:8080",
            "[::1]",
        ] {
            assert!(loopback_host(ok), "{ok}");
        }
        for bad in [
            "evil.example:8080",
            "localhost.evil.example",
            "10.0.0.1:80",
            "[::2]:80",
            "",
        ] {
            assert!(!loopback_host(bad), "{bad}");
        }
        let (tx, rx) = watch::channel(Arc::new(LiveSnapshot::default()));
        let app = App {
            snapshot: rx,
            token: None,
            json: Arc::default(),
            prometheus: Arc::default(),
            stop: CancellationToken::new(),
        };
        let uri: Uri = "/api/state".parse().unwrap();
        let mut headers = HeaderMap::new();
        headers.insert(header::HOST, HeaderValue::from_static("evil.example:8080"));
        let r = refuse(&app, &headers, &uri).expect("a foreign Host is refused");
        assert_eq!(r.status(), StatusCode::MISDIRECTED_REQUEST);
        headers.insert(header::HOST, HeaderValue::from_static("127.0.0.1:8080"));
        assert!(refuse(&app, &headers, &uri).is_none());
        drop(tx);
    }

    #[test]
    fn a_body_is_made_once_per_published_snapshot() {
        let snapshot = |version| {
            Arc::new(LiveSnapshot {
                scene_version: version,
                ..LiveSnapshot::default()
            })
        };
        let (tx, rx) = watch::channel(snapshot(1));
        let app = App {
            snapshot: rx,
            token: None,
            json: Arc::default(),
            prometheus: Arc::default(),
            stop: CancellationToken::new(),
        };
        let made = std::cell::Cell::new(0);
        let render = |s: &LiveSnapshot| {
            made.set(made.get() + 1);
            Ok(s.scene_version.to_string())
        };
        assert_eq!(app.body(&app.json, render).unwrap(), "1");
        assert_eq!(app.body(&app.json, render).unwrap(), "1");
        assert_eq!(made.get(), 1, "the second request made the body again");
        tx.send_replace(snapshot(2));
        assert_eq!(app.body(&app.json, render).unwrap(), "2");
        assert_eq!(made.get(), 2);
        // Each endpoint keeps its own body.
        assert_eq!(app.body(&app.prometheus, render).unwrap(), "2");
        assert_eq!(made.get(), 3);
    }

    #[test]
    fn tokens_compare_whole() {
        assert!(same("abc", "abc"));
        assert!(!same("abc", "abd"));
        assert!(!same("abc", "abcd"));
        assert!(!same("", "a"));
    }
}
