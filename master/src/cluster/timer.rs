//! The master driver's deadline timer: a thread that wakes the driver at
//! the core's next timeout to within a fraction of a millisecond. tokio's
//! timer rounds every sleep up to a whole millisecond (its median
//! overshoot of a 5 ms sleep is 1.1 ms on the 2-core machine, `bench
//! faults`), and every eviction waits on it, so it added that much to the
//! others' stall behind a dead node.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::{Duration, Instant};
use tokio::sync::Notify;

/// With no deadline set the driver is still woken this often, as before.
const IDLE_WAKE: Duration = Duration::from_millis(100);

/// Wakes [`DeadlineTimer::fired`] at the deadline last [`set`](Self::set).
/// The thread ends when the timer is dropped.
#[derive(Debug)]
pub struct DeadlineTimer {
    set: Sender<Option<Instant>>,
    fired: Arc<Notify>,
    current: Option<Option<Instant>>,
}

impl DeadlineTimer {
    /// Start the timer thread.
    pub fn start() -> std::io::Result<Self> {
        let (set, rx) = channel();
        let fired = Arc::new(Notify::new());
        let f = fired.clone();
        std::thread::Builder::new()
            .name("deadline-timer".into())
            .spawn(move || run(&rx, &f))?;
        Ok(Self {
            set,
            fired,
            current: None,
        })
    }

    /// Wake at `deadline` (replacing the previous one), or after the idle
    /// interval when `None`. Setting the same deadline again is free.
    pub fn set(&mut self, deadline: Option<Instant>) {
        if self.current != Some(deadline) {
            self.current = Some(deadline);
            // The thread lives as long as this handle: send cannot fail.
            let _ = self.set.send(deadline);
        }
    }

    /// Resolves when the deadline is reached (a wake that arrived while
    /// nobody waited is kept for the next call).
    pub async fn fired(&mut self) {
        self.fired.notified().await;
        self.current = None;
    }
}

fn run(rx: &Receiver<Option<Instant>>, fired: &Notify) {
    let mut next = Some(Instant::now() + IDLE_WAKE);
    loop {
        let got = match next {
            None => rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
            Some(t) => match t.checked_duration_since(Instant::now()) {
                Some(wait) if !wait.is_zero() => rx.recv_timeout(wait),
                _ => Err(RecvTimeoutError::Timeout),
            },
        };
        match got {
            Ok(deadline) => next = Some(deadline.unwrap_or_else(|| Instant::now() + IDLE_WAKE)),
            Err(RecvTimeoutError::Timeout) => {
                fired.notify_one();
                next = None;
            }
            Err(RecvTimeoutError::Disconnected) => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn fires_at_the_latest_deadline_set_and_not_before() {
        let mut timer = DeadlineTimer::start().unwrap();
        let t0 = Instant::now();
        // A far deadline replaced by a near one: the near one fires.
        timer.set(Some(t0 + Duration::from_secs(60)));
        timer.set(Some(t0 + Duration::from_millis(20)));
        tokio::time::timeout(Duration::from_secs(10), timer.fired())
            .await
            .expect("the near deadline fires");
        assert!(t0.elapsed() >= Duration::from_millis(20));
        // A near deadline replaced by a far one does not fire early.
        timer.set(Some(Instant::now() + Duration::from_millis(50)));
        timer.set(Some(Instant::now() + Duration::from_secs(60)));
        let early = tokio::time::timeout(Duration::from_millis(200), timer.fired()).await;
        assert!(early.is_err(), "fired before its deadline");
    }
}
