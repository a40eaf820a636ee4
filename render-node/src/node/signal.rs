//! The signals that stop a master or a node cleanly: SIGINT (Ctrl-C) and,
//! on Unix, SIGTERM, which `systemctl stop` sends. Either cancels the run,
//! so the master says Bye to its nodes, files end on whole lines and the
//! binary prints its summary and exits 0.

use tokio_util::sync::CancellationToken;

/// Cancel `stop` on the first SIGINT or SIGTERM. Spawns a task on the
/// current tokio runtime; call it inside one.
pub fn cancel_on_stop_signal(stop: CancellationToken) {
    tokio::spawn(async move {
        let signal = stop_signal().await;
        tracing::info!(%signal, "stopping cleanly");
        stop.cancel();
    });
}

/// The name of the first stop signal received.
async fn stop_signal() -> &'static str {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => tokio::select! {
                _ = tokio::signal::ctrl_c() => "SIGINT",
                _ = term.recv() => "SIGTERM",
            },
            Err(e) => {
                tracing::warn!(error = %e, "cannot watch SIGTERM; only Ctrl-C stops cleanly");
                let _ = tokio::signal::ctrl_c().await;
                "SIGINT"
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
        "Ctrl-C"
    }
}
