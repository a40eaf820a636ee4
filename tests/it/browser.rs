//! A real headless Chromium for the web-page tests, driven over the Chrome
//! DevTools Protocol: open a page, evaluate JavaScript in it, wait for a
//! condition, and collect everything the page reported as an error (uncaught
//! exceptions, `console.error`, failed loads).
//!
//! Chromium comes from Debian's `chromium` package, which `scripts/setup.sh`
//! installs. Without it a test skips with a message, except under `CI`,
//! where it fails: a browser test that silently did not run is a defect.

use serde_json::{Value, json};
use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tungstenite::{Message, WebSocket, stream::MaybeTlsStream};

/// The Chromium binary: `$CHROMIUM`, else the first of the usual names on
/// `PATH`.
fn chromium_path() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |dir| dir.join(name)))
        .find(|p| p.is_file())
}

/// A headless Chromium with one page, killed (and its profile removed) on
/// drop.
pub(crate) struct Browser {
    child: Child,
    ws: WebSocket<MaybeTlsStream<TcpStream>>,
    session: String,
    next_id: u64,
    errors: Vec<String>,
    profile: PathBuf,
}

impl Browser {
    /// Start Chromium, or `None` (after saying why) when it is not installed
    /// and `CI` is unset. Panics under `CI` without Chromium.
    pub(crate) fn launch() -> Option<Self> {
        let Some(exe) = chromium_path() else {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI is set but no Chromium was found: scripts/setup.sh installs Debian's chromium"
            );
            eprintln!("skipping: no Chromium (scripts/setup.sh installs it)");
            return None;
        };
        let profile = std::env::temp_dir().join(format!(
            "showcase-chromium-{}-{}",
            std::process::id(),
            NEXT_PROFILE.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&profile);
        // The flags keep a headless Chromium off the (closed) network and
        // out of its first-run and sandbox machinery.
        let mut child = Command::new(&exe)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-extensions",
                "--remote-debugging-port=0",
                "--remote-allow-origins=*",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg("about:blank")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", exe.display()));
        // Chromium prints the browser's DevTools address on stderr.
        let stderr = child.stderr.take().expect("piped stderr");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut sent = false;
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if !sent && let Some(at) = line.find("ws://") {
                    let _ = tx.send(line[at..].trim().to_string());
                    sent = true;
                }
            }
        });
        let url = match rx.recv_timeout(Duration::from_secs(30)) {
            Ok(url) => url,
            Err(_) => {
                let _ = child.kill();
                panic!("{} printed no DevTools address in 30 s", exe.display());
            }
        };
        let (mut ws, _) = tungstenite::connect(&url)
            .unwrap_or_else(|e| panic!("cannot connect to DevTools at {url}: {e}"));
        if let MaybeTlsStream::Plain(s) = ws.get_mut() {
            s.set_read_timeout(Some(Duration::from_millis(200)))
                .expect("read timeout");
        }
        let mut browser = Self {
            child,
            ws,
            session: String::new(),
            next_id: 0,
            errors: Vec::new(),
            profile,
        };
        let target = browser.call("Target.createTarget", json!({"url": "about:blank"}));
        let target_id = target["targetId"].as_str().expect("targetId").to_string();
        let attached = browser.call(
            "Target.attachToTarget",
            json!({"targetId": target_id, "flatten": true}),
        );
        browser.session = attached["sessionId"]
            .as_str()
            .expect("sessionId")
            .to_string();
        for domain in ["Page.enable", "Runtime.enable", "Log.enable"] {
            browser.call(domain, json!({}));
        }
        Some(browser)
    }

    /// Send one DevTools command (to the page once attached) and return its
    /// result, collecting the events that arrive meanwhile.
    fn call(&mut self, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut msg = json!({"id": id, "method": method, "params": params});
        if !self.session.is_empty() {
            msg["sessionId"] = json!(self.session);
        }
        self.ws
            .send(Message::text(msg.to_string()))
            .unwrap_or_else(|e| panic!("DevTools {method}: {e}"));
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            assert!(
                Instant::now() < deadline,
                "DevTools {method}: no answer in 30 s"
            );
            let Some(reply) = self.read() else { continue };
            if reply["id"].as_u64() == Some(id) {
                if let Some(err) = reply.get("error") {
                    panic!("DevTools {method}: {err}");
                }
                return reply["result"].clone();
            }
        }
    }

    /// One message from DevTools, or `None` after a short wait; events are
    /// sorted into the error log on the way.
    fn read(&mut self) -> Option<Value> {
        match self.ws.read() {
            Ok(Message::Text(t)) => {
                let v: Value = serde_json::from_str(t.as_str()).expect("DevTools sends JSON");
                self.note_event(&v);
                Some(v)
            }
            Ok(_) => None,
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                None
            }
            Err(e) => panic!("DevTools connection: {e}"),
        }
    }

    fn note_event(&mut self, v: &Value) {
        let p = &v["params"];
        match v["method"].as_str() {
            Some("Runtime.exceptionThrown") => {
                let d = &p["exceptionDetails"];
                self.errors.push(format!(
                    "uncaught: {} {}",
                    d["text"].as_str().unwrap_or(""),
                    d["exception"]["description"].as_str().unwrap_or("")
                ));
            }
            Some("Runtime.consoleAPICalled") if p["type"] == "error" => {
                self.errors.push(format!("console.error: {}", p["args"]));
            }
            Some("Log.entryAdded") if p["entry"]["level"] == "error" => {
                self.errors.push(format!(
                    "log: {} {}",
                    p["entry"]["text"].as_str().unwrap_or(""),
                    p["entry"]["url"].as_str().unwrap_or("")
                ));
            }
            _ => {}
        }
    }

    /// Load `url` and wait until the document has loaded.
    pub(crate) fn open(&mut self, url: &str) {
        let nav = self.call("Page.navigate", json!({"url": url}));
        if let Some(err) = nav.get("errorText") {
            panic!("cannot open {url}: {err}");
        }
        self.wait_for(
            "document.readyState === 'complete'",
            Duration::from_secs(30),
        );
    }

    /// Evaluate a JavaScript expression in the page and return its value.
    pub(crate) fn eval(&mut self, expr: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expr, "returnByValue": true, "awaitPromise": true}),
        );
        if let Some(ex) = r.get("exceptionDetails") {
            panic!("evaluating {expr:?}: {ex}");
        }
        r["result"]["value"].clone()
    }

    /// Poll `expr` until it is truthy (then return its value), for at most
    /// `timeout`; panics with the expression on time-out.
    pub(crate) fn wait_for(&mut self, expr: &str, timeout: Duration) -> Value {
        let deadline = Instant::now() + timeout;
        loop {
            let v = self.eval(expr);
            let truthy = match &v {
                Value::Null => false,
                Value::Bool(b) => *b,
                Value::Number(n) => n.as_f64() != Some(0.0),
                Value::String(s) => !s.is_empty(),
                _ => true,
            };
            if truthy {
                return v;
            }
            assert!(
                Instant::now() < deadline,
                "waited {timeout:?} for {expr:?}; last value {v}"
            );
            // Take in the events that came meanwhile (errors among them).
            let _ = self.read();
        }
    }

    /// Everything the page reported as an error so far.
    pub(crate) fn errors(&mut self) -> Vec<String> {
        while self.read().is_some() {}
        self.errors.clone()
    }
}

static NEXT_PROFILE: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

#[test]
fn the_browser_runs_scripts_and_reports_page_errors() {
    let Some(mut b) = Browser::launch() else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("showcase-browser-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let page = dir.join("page.html");
    std::fs::write(
        &page,
        "<!doctype html><p id=x>before</p><script>\
         setTimeout(() => { document.getElementById('x').textContent = 'after'; }, 300);\
         setTimeout(() => { console.error('boom'); }, 350);\
         </script>",
    )
    .unwrap();
    b.open(&format!("file://{}", page.display()));
    let text = b.wait_for(
        "document.getElementById('x').textContent === 'after' && 'after'",
        Duration::from_secs(10),
    );
    assert_eq!(text, "after");
    b.wait_for(
        "new Promise(r => setTimeout(() => r(true), 200))",
        Duration::from_secs(5),
    );
    let errors = b.errors();
    assert!(
        errors.iter().any(|e| e.contains("boom")),
        "the console error was not caught: {errors:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
