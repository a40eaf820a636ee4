//! Showcase's master: scene files, device calibration, offline jobs, the
//! cluster server and the command line behind `showcase-master`.

pub mod bench_report;
pub mod calibrate;
pub mod capture;
pub mod certs;
pub mod cli;
pub mod cluster;
pub mod demo;
pub mod pfm;
pub mod plot;
pub mod progress;
pub mod radiosity_job;
pub mod render_bench;
pub mod scene_file;
pub mod tracking;
