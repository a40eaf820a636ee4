//! `showcase-master`: parses the command line, sets up logging, runs.

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
                // The demo and replay run nodes in-process: keep their
                // per-connection chatter out of the console.
                tracing_subscriber::EnvFilter::new("info,showcase_proto=warn,showcase_render=warn")
            }),
        )
        .with_writer(std::io::stderr)
        // Colours only for a person at a terminal, not in files or the journal.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = showcase_master::cli::Cli::parse();
    match showcase_master::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
