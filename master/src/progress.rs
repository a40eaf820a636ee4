//! Progress of the long jobs: indicatif bars and spinners on stderr, drawn
//! only when stderr is a terminal, and for logs a plain line at most every
//! few seconds ([`LogLines`]). The one home of the bars' look.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The look of [`bar`].
pub fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template("  {prefix} [{bar:30}] {pos}/{len} {msg} ({elapsed})")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ")
}

/// A bar of `len` steps labelled `prefix`, with a message after the count.
pub fn bar(prefix: impl Into<String>, len: u64) -> ProgressBar {
    let pb = ProgressBar::new(len).with_style(bar_style());
    pb.set_prefix(prefix.into());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// A spinner labelled `prefix` for work of unknown length; with `unit`, it
/// shows the count so far (`{pos} shots`).
pub fn spinner(prefix: impl Into<String>, unit: Option<&str>) -> ProgressBar {
    let template = match unit {
        Some(unit) => format!("  {{spinner}} {{prefix}}: {{pos}} {unit}, {{msg}} ({{elapsed}})"),
        None => "  {spinner} {prefix} {msg} ({elapsed})".to_string(),
    };
    let pb = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template(&template)
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    pb.set_prefix(prefix.into());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// Plain progress lines for logs, where the bars are not drawn: at most
/// one every [`LogLines::EVERY`], and none on a terminal.
#[derive(Debug)]
pub struct LogLines {
    last: Mutex<Option<Instant>>,
    on: bool,
}

impl Default for LogLines {
    fn default() -> Self {
        Self {
            last: Mutex::new(None),
            on: !std::io::stderr().is_terminal(),
        }
    }
}

impl LogLines {
    /// The shortest gap between two lines.
    pub const EVERY: Duration = Duration::from_secs(5);

    /// Print `line()` on stderr if the last line is [`Self::EVERY`] old
    /// (the first after [`Self::EVERY`] has passed since the first call).
    pub fn say(&self, line: impl FnOnce() -> String) {
        if !self.on {
            return;
        }
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        let now = Instant::now();
        match *last {
            None => *last = Some(now),
            Some(t) if now.duration_since(t) >= Self::EVERY => {
                *last = Some(now);
                eprintln!("{}", line());
            }
            Some(_) => {}
        }
    }
}

/// A radiosity progress callback drawing on `pb` (one step per shot, the
/// unshot fraction of the running pass as its message) and saying the
/// same in logs every few seconds.
pub fn radiosity_shots(
    pb: &ProgressBar,
    label: &'static str,
) -> showcase_light::radiosity::ShotProgress {
    let pb = pb.clone();
    let log = LogLines::default();
    showcase_light::radiosity::ShotProgress::new(move |p| {
        pb.inc(1);
        pb.set_message(format!("unshot {:.4} in this pass", p.unshot_fraction));
        log.say(|| {
            format!(
                "{label}: {} shots, unshot {:.4} in this pass",
                pb.position(),
                p.unshot_fraction
            )
        });
    })
}

/// The hierarchical radiosity solver's progress on `pb` (gathers, links,
/// residual) and in the log every few seconds; with `budget`, it tells the
/// solver to stop once that much time has passed since this was made.
pub fn radiosity_gathers(
    pb: &ProgressBar,
    label: &'static str,
    budget: Option<std::time::Duration>,
) -> showcase_light::radiosity::HierarchyProgress {
    let pb = pb.clone();
    let log = LogLines::default();
    let start = std::time::Instant::now();
    showcase_light::radiosity::HierarchyProgress::new(move |p| {
        pb.inc(1);
        let text = format!(
            "refinement round {}, {} links, gather {}, residual {:.4}",
            p.round, p.links, p.iterations, p.residual
        );
        pb.set_message(text.clone());
        log.say(|| format!("{label}: {text}"));
        budget.is_none_or(|b| start.elapsed() < b)
    })
}
