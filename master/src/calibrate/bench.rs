//! The calibration benchmark behind `showcase-master bench calibration`:
//! error against run time for LM and Powell over noise, point count and
//! coplanarity, on synthetic projectors inside a showcase, plus its report.

use super::io::rms;
use super::simulate::{fiducial_plate, fiducial_rig, projector_in_showcase, simulate_fiducials};
use super::{
    CalibrateOptions, Calibration, CalibrationInput, Correspondence, Intrinsics, Method, calibrate,
};
use crate::plot::{Marker, Plot, Point, Series};
use glam::{DMat3, DVec3};
use serde::Serialize;
use showcase_light::metrics::percentile;
use showcase_proto::scene::PinholeDevice;
use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

/// Pixel noise levels of the sweep (standard deviation per axis).
pub const BENCH_NOISE_PX: [f64; 4] = [0.1, 0.5, 1.0, 2.0];
/// Fit point counts of the sweep.
pub const BENCH_POINTS: [usize; 5] = [6, 10, 20, 50, 100];
/// Seeds per configuration; records hold the median over them.
pub const BENCH_SEEDS: u64 = 5;
/// Held-out points per case, never used in the fit.
pub const HELDOUT_POINTS: usize = 50;

/// Where a record's correspondences come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Marked fiducials (simulated: the true projection plus Gaussian noise).
    #[default]
    Fiducials,
    /// Decoded Gray-code patterns ([`super::structured_light`]).
    StructuredLight,
}

impl Source {
    /// Fiducials (the key is left out of the records then).
    pub fn is_fiducials(&self) -> bool {
        *self == Source::Fiducials
    }
}

/// One line of the benchmark: medians over [`BENCH_SEEDS`] seeds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BenchRecord {
    /// `lm` or `powell`.
    pub method: Method,
    /// Fiducials or structured light (written only for structured light).
    #[serde(skip_serializing_if = "Source::is_fiducials")]
    pub source: Source,
    /// The showcase scene's projector, for the records on it; none for the
    /// synthetic sweep.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
    /// Fit points.
    pub points: usize,
    /// Pixel noise of the correspondences (standard deviation per axis):
    /// the simulated marking's, or for structured light the measured
    /// distance of the decoded pixels from the true projection.
    pub noise_px: f64,
    /// Coplanar fiducials with known intrinsics (else a non-coplanar rig, unknown intrinsics).
    pub coplanar: bool,
    /// RMS pixel error on the fit points.
    pub rms_fit_px: f64,
    /// RMS pixel error on held-out points, against their marked (noisy)
    /// or decoded pixels: what can be measured without the truth.
    pub rms_heldout_px: f64,
    /// The showcase's records: RMS pixel distance between the fitted and
    /// the true projector's projections of held-out points where its light
    /// lands on the scene (no marking noise; one metric for every method).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_heldout_true_px: Option<f64>,
    /// Distance of the solved centre of projection from the truth (metres).
    pub center_error_m: f64,
    /// Angle between the solved and the true rotation (degrees).
    pub rotation_error_deg: f64,
    /// Solve time (seconds); for structured light the whole job of one
    /// projector (the sim's light transport, capture, decode and solves).
    pub seconds: f64,
}

/// A synthetic calibration problem with its ground truth.
#[derive(Clone, Debug)]
pub struct SyntheticCase {
    /// The true device.
    pub truth: PinholeDevice,
    /// The fit input (coplanar cases carry the true intrinsics).
    pub fit: CalibrationInput,
    /// Noisy held-out correspondences from the same fiducial set.
    pub heldout: Vec<Correspondence>,
}

/// A projector from [`projector_in_showcase`] with `points` fit and
/// [`HELDOUT_POINTS`] held-out fiducials, on the rig or (coplanar) on the
/// floor plate with the true intrinsics given.
pub fn synthetic_case(points: usize, noise_px: f64, coplanar: bool, seed: u64) -> SyntheticCase {
    let truth = projector_in_showcase(seed);
    let wanted = points + HELDOUT_POINTS;
    let mut candidates = 2 * wanted;
    let mut all = loop {
        let fiducials = if coplanar {
            fiducial_plate(candidates, seed)
        } else {
            fiducial_rig(candidates, seed)
        };
        let marked = simulate_fiducials(&truth, &fiducials, noise_px, seed.wrapping_add(1));
        if marked.points.len() >= wanted || candidates > 64 * wanted {
            break marked;
        }
        candidates *= 2;
    };
    let heldout = all.points.split_off(points.min(all.points.len()));
    all.points.truncate(points);
    all.device = format!("projector-sim-{seed}");
    if coplanar {
        let k = truth.k.transpose().to_cols_array_2d();
        all.intrinsics = Some(Intrinsics {
            camera_matrix: k.iter().map(|r| r.to_vec()).collect(),
            dist_coeffs: None,
        });
    }
    SyntheticCase {
        truth,
        fit: all,
        heldout: heldout.into_iter().take(HELDOUT_POINTS).collect(),
    }
}

/// RMS pixel distance of `points` under `calibration` (points behind it
/// count as infinitely far).
pub fn heldout_rms(calibration: &Calibration, points: &[Correspondence]) -> f64 {
    let residuals: Vec<f64> = points
        .iter()
        .map(|p| match calibration.project(DVec3::from_array(p.world)) {
            Some(px) => (px - glam::DVec2::from_array(p.pixel)).length(),
            None => f64::INFINITY,
        })
        .collect();
    rms(&residuals)
}

/// Angle between two rotations in degrees (accurate for small angles).
pub fn rotation_angle_deg(a: &DMat3, b: &DMat3) -> f64 {
    let d = *a * b.transpose();
    let v = DVec3::new(
        d.y_axis.z - d.z_axis.y,
        d.z_axis.x - d.x_axis.z,
        d.x_axis.y - d.y_axis.x,
    );
    let trace = d.x_axis.x + d.y_axis.y + d.z_axis.z;
    (0.5 * v.length()).atan2(0.5 * (trace - 1.0)).to_degrees()
}

/// The solve time of `f`: the fastest of five blocks, each averaging
/// enough calls to span a millisecond (the minimum is the least disturbed
/// by other load on the machine).
pub(crate) fn time_per_call<T>(mut f: impl FnMut() -> T) -> (T, f64) {
    let out = f();
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        let mut reps = 0u32;
        while reps == 0 || start.elapsed() < Duration::from_millis(1) {
            std::hint::black_box(f());
            reps += 1;
        }
        best = best.min(start.elapsed().as_secs_f64() / f64::from(reps));
    }
    (out, best)
}

/// One configuration, medians over seeds; `None` when every seed failed.
pub fn bench_configuration(
    method: Method,
    points: usize,
    noise_px: f64,
    coplanar: bool,
) -> Option<BenchRecord> {
    let opts = CalibrateOptions::with_method(method);
    let mut cols: [Vec<f64>; 5] = Default::default();
    for seed in 0..BENCH_SEEDS {
        let case = synthetic_case(points, noise_px, coplanar, seed);
        let (result, seconds) = time_per_call(|| calibrate(&case.fit, &opts));
        let cal = match result {
            Ok(cal) => cal,
            Err(e) => {
                tracing::warn!(%method, points, noise_px, coplanar, seed, error = %e, "calibration failed");
                continue;
            }
        };
        let device = cal.to_device();
        let values = [
            cal.rms_px,
            heldout_rms(&cal, &case.heldout),
            (device.center() - case.truth.center()).length(),
            rotation_angle_deg(&device.rotation, &case.truth.rotation),
            seconds,
        ];
        for (c, v) in cols.iter_mut().zip(values) {
            c.push(v);
        }
    }
    if cols[0].is_empty() {
        return None;
    }
    let [fit, heldout, center, rotation, seconds] =
        cols.map(|v| percentile(&v, 50.0).unwrap_or(f64::NAN));
    Some(BenchRecord {
        method,
        source: Source::Fiducials,
        device: None,
        points,
        noise_px,
        coplanar,
        rms_fit_px: fit,
        rms_heldout_px: heldout,
        rms_heldout_true_px: None,
        center_error_m: center,
        rotation_error_deg: rotation,
        seconds,
    })
}

/// The whole sweep: both methods, coplanar and not, every noise level and
/// point count of [`BENCH_NOISE_PX`] and [`BENCH_POINTS`].
pub fn bench_calibration() -> Vec<BenchRecord> {
    bench_calibration_with(&|_, _| {})
}

/// Configurations [`bench_calibration`] runs.
pub const BENCH_CONFIGURATIONS: usize = 2 * BENCH_POINTS.len() * BENCH_NOISE_PX.len() * 2;

/// [`bench_calibration`], calling `done(k, what)` after the `k`-th of
/// [`BENCH_CONFIGURATIONS`] configurations (progress display).
pub fn bench_calibration_with(done: &dyn Fn(usize, &str)) -> Vec<BenchRecord> {
    let mut records = Vec::new();
    let mut k = 0;
    for coplanar in [false, true] {
        for points in BENCH_POINTS {
            for noise_px in BENCH_NOISE_PX {
                for method in [Method::Lm, Method::Powell] {
                    records.extend(bench_configuration(method, points, noise_px, coplanar));
                    k += 1;
                    done(
                        k,
                        &format!(
                            "{method:?}, {points} points, {noise_px} px{}",
                            if coplanar { ", coplanar" } else { "" }
                        ),
                    );
                }
            }
        }
    }
    records
}

/// Write `calibration.csv`, `calibration.md` (a table plus the LM/Powell
/// speed ratios) and `calibration.svg` (held-out error against time, log
/// axes) into `dir`, creating it.
pub fn write_bench_report(records: &[BenchRecord], dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut csv = String::from(
        "method,points,noise_px,coplanar,rms_fit_px,rms_heldout_px,center_error_m,rotation_error_deg,seconds,source,device,rms_heldout_true_px\n",
    );
    let mut md = String::from(
        "# Calibration: error against time\n\nMedians over seeds. LM = Levenberg-Marquardt, Powell = the paper's baseline.\n\n\
         | method | points | noise px | coplanar | rms fit px | rms held-out px | centre err m | rot err deg | seconds | source | device | held-out vs truth px |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in records {
        let truth = r
            .rms_heldout_true_px
            .map_or(String::new(), |v| format!("{v:.6}"));
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.6},{:.6},{:.6e},{:.6e},{:.6e},{},{},{truth}",
            r.method,
            r.points,
            r.noise_px,
            r.coplanar,
            r.rms_fit_px,
            r.rms_heldout_px,
            r.center_error_m,
            r.rotation_error_deg,
            r.seconds,
            source_name(r.source),
            r.device.as_deref().unwrap_or(""),
        );
        let _ = writeln!(
            md,
            "| {} | {} | {:.3} | {} | {:.4} | {:.4} | {:.2e} | {:.2e} | {:.2e} | {} | {} | {} |",
            r.method,
            r.points,
            r.noise_px,
            r.coplanar,
            r.rms_fit_px,
            r.rms_heldout_px,
            r.center_error_m,
            r.rotation_error_deg,
            r.seconds,
            source_name(r.source),
            r.device.as_deref().unwrap_or("synthetic"),
            r.rms_heldout_true_px
                .map_or("-".to_string(), |v| format!("{v:.4}")),
        );
    }
    md.push_str("\n## Powell time / LM time\n\n| points | noise px | coplanar | speed-up | LM held-out px | Powell held-out px |\n|---|---|---|---|---|---|\n");
    for lm in records
        .iter()
        .filter(|r| r.method == Method::Lm && r.source == Source::Fiducials && r.device.is_none())
    {
        if let Some(pw) = records.iter().find(|r| {
            r.method == Method::Powell
                && r.device.is_none()
                && r.points == lm.points
                && r.noise_px == lm.noise_px
                && r.coplanar == lm.coplanar
        }) {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.0}x | {:.4} | {:.4} |",
                lm.points,
                lm.noise_px,
                lm.coplanar,
                pw.seconds / lm.seconds,
                lm.rms_heldout_px,
                pw.rms_heldout_px
            );
        }
    }
    std::fs::write(dir.join("calibration.csv"), csv)?;
    std::fs::write(dir.join("calibration.md"), md)?;
    std::fs::write(dir.join("calibration.svg"), scatter_svg(records))
}

fn source_name(s: Source) -> &'static str {
    match s {
        Source::Fiducials => "fiducials",
        Source::StructuredLight => "structured_light",
    }
}

/// A log-log scatter of held-out error against time, LM against Powell.
fn scatter_svg(records: &[BenchRecord]) -> String {
    let series = |method: Method, source: Source, name: &str, colour: &str| Series {
        name: name.into(),
        colour: colour.into(),
        joined: false,
        points: records
            .iter()
            .filter(|r| r.method == method && r.source == source)
            .map(|r| Point {
                marker: if r.coplanar {
                    Marker::Square
                } else {
                    Marker::Circle
                },
                tooltip: format!(
                    "{} {} pts {} px{}",
                    r.method,
                    r.points,
                    r.noise_px,
                    if r.coplanar { " coplanar" } else { "" }
                ),
                ..Point::at(r.seconds, r.rms_heldout_px)
            })
            .collect(),
    };
    Plot {
        title: "Calibration: held-out error against solve time".into(),
        x_label: "solve time (s); structured light: the whole job".into(),
        y_label: "held-out RMS (px): marked or decoded points".into(),
        series: vec![
            series(Method::Lm, Source::Fiducials, "LM", "#1f77b4"),
            series(Method::Powell, Source::Fiducials, "Powell", "#d62728"),
            series(
                Method::Lm,
                Source::StructuredLight,
                "structured light + LM",
                "#2ca02c",
            ),
        ],
        note: "circle: rig, square: coplanar (known K)".into(),
        ..Plot::default()
    }
    .to_svg()
}
