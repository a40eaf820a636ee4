//! What the demo's figures mean: the one home of each figure's label, unit,
//! target and one-line meaning, and of how the page writes numbers and
//! marks a figure pass or miss. `report.json` keeps the raw numbers.
//!
//! Targets are only those the project states: the issues' and the demo
//! test's bounds (README, ARCHITECTURE, `tests/it/demo.rs`). A figure with
//! none shows "—", never an invented one.

/// How a value is held to its target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::demo) enum Target {
    /// At most this value.
    AtMost(f64),
    /// Exactly this value.
    Equal(f64),
}

impl Target {
    /// Whether `v` meets the target (`None` when `v` is not a finite
    /// number: no mark).
    pub(in crate::demo) fn met_by(self, v: f64) -> Option<bool> {
        if !v.is_finite() {
            return None;
        }
        Some(match self {
            Target::AtMost(t) => v <= t,
            Target::Equal(t) => v == t,
        })
    }

    /// The bound itself: what a plot draws as the target line.
    pub(in crate::demo) fn value(self) -> f64 {
        match self {
            Target::AtMost(t) | Target::Equal(t) => t,
        }
    }

    /// "≤ 1 ms" and the like.
    fn text(self, unit: &str) -> String {
        let (op, t) = match self {
            Target::AtMost(t) => ("≤", t),
            Target::Equal(t) => ("=", t),
        };
        // Targets are round numbers: their shortest form.
        with_unit(&format!("{op} {t}"), unit)
    }
}

/// What the page says about one figure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::demo) struct Figure {
    /// Short human name.
    pub label: &'static str,
    /// Unit of the numbers ("ratio" for a plain ratio, "text" for words).
    pub unit: &'static str,
    /// The stated target, if any.
    pub target: Option<Target>,
    /// What it measures, in one line.
    pub meaning: &'static str,
}

const fn fig(
    label: &'static str,
    unit: &'static str,
    target: Option<Target>,
    meaning: &'static str,
) -> Figure {
    Figure {
        label,
        unit,
        target,
        meaning,
    }
}

/// Every figure the demo writes, in the page's order.
const FIGURES: &[(&str, Figure)] = &[
    (
        "calibration_rms_px",
        fig(
            "Calibration reprojection error",
            "px",
            Some(Target::AtMost(1.0)),
            "worst device's RMS distance between the fiducial marks (0.5 px noise) and their calibrated projections",
        ),
    ),
    (
        "calibration_center_error_m",
        fig(
            "Calibrated device position error",
            "m",
            None,
            "worst distance between a calibrated device's centre and the true one",
        ),
    ),
    (
        "reflectance_rel_rmse",
        fig(
            "Reflectance map error",
            "ratio",
            Some(Target::AtMost(0.02)),
            "relative RMSE of the captured reflectance against the sim's true albedo",
        ),
    ),
    (
        "reflectance_coverage",
        fig(
            "Reflectance coverage",
            "ratio",
            None,
            "fraction of the visible object pixels that got a reflectance (I_int above its floor, phi ≤ 60°)",
        ),
    ),
    (
        "reflectance_eta_rel_error",
        fig(
            "Projector eta error",
            "ratio",
            Some(Target::AtMost(0.01)),
            "relative error of the projector efficiency eta fitted by Brent on the board",
        ),
    ),
    (
        "radiosity_elements",
        fig(
            "Radiosity elements",
            "elements",
            None,
            "elements of the demo scene's radiosity solution, after refinement",
        ),
    ),
    (
        "radiosity_links",
        fig(
            "Radiosity links",
            "links",
            None,
            "links of the hierarchical B0 solve (0 when the progressive solver ran)",
        ),
    ),
    (
        "radiosity_shots",
        fig(
            "Radiosity shots or gathers",
            "count",
            None,
            "progressive-refinement shots, or hierarchical gathers, over all passes",
        ),
    ),
    (
        "radiosity_unshot_fraction",
        fig(
            "Radiosity unshot energy",
            "ratio",
            None,
            "energy left unshot when the progressive solver stopped, as a fraction of the \
             emitted; the hierarchical solver's last relative change of B0",
        ),
    ),
    (
        "radiosity_b3_b0_deviation_rgb",
        fig(
            "Radiosity B3 against B0",
            "ratio",
            None,
            "relative mean |B3 - B0| per RGB channel, on the demo scene",
        ),
    ),
    (
        "radiosity_clipped_fractions",
        fig(
            "Projector clipping",
            "ratio",
            None,
            "fraction of each projector's valid pixels clamped to the device range, on the demo scene",
        ),
    ),
    (
        "radiosity_figure3_consistency_rel_rmse",
        fig(
            "Figure 3: radiosity consistency",
            "ratio",
            Some(Target::AtMost(0.03)),
            "projectors' irradiance maps through the sim onto the real walls, against B0 (B2 gathered at the vertices)",
        ),
    ),
    (
        "radiosity_figure3_paper_consistency_rel_rmse",
        fig(
            "Figure 3: radiosity consistency, paper's B1",
            "ratio",
            None,
            "the same with the paper's converged B1, reported beside the headline",
        ),
    ),
    (
        "radiosity_figure3_b3_b0_deviation_rgb",
        fig(
            "Figure 3: B3 against B0",
            "ratio",
            None,
            "relative mean |B3 - B0| per RGB channel",
        ),
    ),
    (
        "radiosity_figure3_clipped_fractions",
        fig(
            "Figure 3: projector clipping",
            "ratio",
            None,
            "fraction of each projector's valid pixels clamped to the device range",
        ),
    ),
    (
        "frame_rate_hz",
        fig(
            "Frame rate",
            "Hz",
            None,
            "frames presented per second, from the first swap to the last (the clock ticks at 60 Hz)",
        ),
    ),
    (
        "swap_skew_ms_p99",
        fig(
            "Swap skew, p99",
            "ms",
            Some(Target::AtMost(1.0)),
            "global mode: spread of the nodes' present times per frame, clock offsets estimated NTP-style",
        ),
    ),
    (
        "swap_skew_ms_p99_direct_mode",
        fig(
            "Swap skew, p99, direct mode",
            "ms",
            Some(Target::AtMost(1.0)),
            "the same walk with the scene in direct mode, run after the global one",
        ),
    ),
    (
        "tracking_to_swap_ms_p99",
        fig(
            "Tracking to swap, p99",
            "ms",
            None,
            "global mode: from the newest tracking sample to the frame's swap",
        ),
    ),
    (
        "tracking_to_swap_ms_p99_direct_mode",
        fig(
            "Tracking to swap, p99, direct mode",
            "ms",
            None,
            "the same walk with the scene in direct mode",
        ),
    ),
    (
        "illumination_updates",
        fig(
            "Illumination updates",
            "count",
            None,
            "global-illumination solutions the master published during the walk (after the first, before frame 0)",
        ),
    ),
    (
        "illumination_update_ms_p50",
        fig(
            "Illumination update, p50",
            "ms",
            None,
            "from the frame whose light or heads moved to the master publishing its solution",
        ),
    ),
    (
        "illumination_update_ms_p99",
        fig(
            "Illumination update, p99",
            "ms",
            Some(Target::AtMost(8.0)),
            "the same, p99",
        ),
    ),
    (
        "illumination_frames_stale_max",
        fig(
            "Frames stale, max",
            "frames",
            Some(Target::AtMost(1.0)),
            "from a moved frame to the first frame drawn with its solution",
        ),
    ),
    (
        "dropped_frames",
        fig(
            "Dropped frames",
            "frames",
            Some(Target::Equal(0.0)),
            "frame-clock ticks with no frame sent",
        ),
    ),
    (
        "interactive_consistency_rel_rmse",
        fig(
            "Consistency (camera)",
            "ratio",
            Some(Target::AtMost(0.01)),
            "physically complete, global mode: both projectors' values through the simulated projectors, every bounce between the real surfaces, seen by the cabinet's camera, against the scene path-traced as if the virtual lights and objects were real",
        ),
    ),
    (
        "interactive_compared_fraction",
        fig(
            "Camera pixels compared",
            "ratio",
            None,
            "fraction of the camera's real pixels the consistency check compares",
        ),
    ),
    (
        "interactive_consistency_rel_rmse_per_object",
        fig(
            "Consistency (camera) per object",
            "ratio",
            None,
            "the camera's consistency figure per real object",
        ),
    ),
    (
        "observer_consistency_rel_rmse",
        fig(
            "Consistency (observers)",
            "ratio",
            None,
            "physically complete, global mode: worst observer's whole view against its target, CRT image through the mirror included",
        ),
    ),
    (
        "observer_consistency_rel_rmse_real_comparable",
        fig(
            "Consistency (observers, real surfaces)",
            "ratio",
            Some(Target::AtMost(0.01)),
            "physically complete: observers' real surfaces where the method can be right by design",
        ),
    ),
    (
        "delta_e2000_median",
        fig(
            "CIEDE2000, median",
            "ΔE00",
            Some(Target::AtMost(1.0)),
            "physically complete, global mode: perceived colour difference of the observers' views against their targets",
        ),
    ),
    (
        "delta_e2000_p95",
        fig(
            "CIEDE2000, p95",
            "ΔE00",
            Some(Target::AtMost(3.0)),
            "95th percentile of the same",
        ),
    ),
    (
        "observers",
        fig(
            "Per observer",
            "ratio",
            None,
            "physically complete: each observer's figures (ΔE00 and relative RMSE)",
        ),
    ),
    (
        "ground_truth_noise_rel_rmse",
        fig(
            "Ground truth noise",
            "ratio",
            None,
            "the path-traced target's own noise over the compared pixels (worst view, measured from two independent halves of the paths)",
        ),
    ),
    (
        "compared_noise_rel_rmse",
        fig(
            "Noise in what is compared",
            "ratio",
            None,
            "the noise of the measured view minus the target (worst view): both are traced with common random numbers, so it is far below either image's own",
        ),
    ),
    (
        "ground_truth_leaves_out",
        fig(
            "Ground truth leaves out",
            "text",
            None,
            "what the path tracer of the complete world cannot find, so no complete figure includes it",
        ),
    ),
    (
        "camera_interreflection_rel_rmse",
        fig(
            "Interreflection (camera)",
            "ratio",
            None,
            "how far the light the camera measures reflected once is from all of it: what a direct-only world leaves out",
        ),
    ),
    (
        "interactive_consistency_rel_rmse_direct_mode",
        fig(
            "Consistency (camera), direct mode",
            "ratio",
            None,
            "physically complete, the projectors drawing direct light only (the scene in direct mode): what global mode improves on",
        ),
    ),
    (
        "interactive_compared_fraction_direct_mode",
        fig(
            "Camera pixels compared, direct mode",
            "ratio",
            None,
            "the same pixels as global mode's",
        ),
    ),
    (
        "interactive_consistency_rel_rmse_per_object_direct_mode",
        fig(
            "Consistency (camera) per object, direct mode",
            "ratio",
            None,
            "the direct-mode camera figure per real object",
        ),
    ),
    (
        "observer_consistency_rel_rmse_direct_mode",
        fig(
            "Consistency (observers), direct mode",
            "ratio",
            None,
            "physically complete, projectors and faces in direct mode: worst observer's whole view",
        ),
    ),
    (
        "observer_consistency_rel_rmse_real_comparable_direct_mode",
        fig(
            "Consistency (observers, real surfaces), direct mode",
            "ratio",
            None,
            "physically complete, direct mode: observers' real surfaces where the method can be right by design",
        ),
    ),
    (
        "delta_e2000_median_direct_mode",
        fig(
            "CIEDE2000, median, direct mode",
            "ΔE00",
            None,
            "physically complete, direct mode: the observers' colour difference",
        ),
    ),
    (
        "delta_e2000_p95_direct_mode",
        fig(
            "CIEDE2000, p95, direct mode",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "observers_direct_mode",
        fig(
            "Per observer, direct mode",
            "ratio",
            None,
            "physically complete, direct mode: each observer's figures",
        ),
    ),
    (
        "interactive_consistency_rel_rmse_direct",
        fig(
            "Consistency (camera), direct light only",
            "ratio",
            Some(Target::AtMost(0.01)),
            "the camera's check in a world without interreflection, against a direct-light target (what paper section 5 assumes)",
        ),
    ),
    (
        "interactive_compared_fraction_direct",
        fig(
            "Camera pixels compared, direct light only",
            "ratio",
            None,
            "the same pixels as the complete check's",
        ),
    ),
    (
        "interactive_consistency_rel_rmse_per_object_direct",
        fig(
            "Consistency (camera) per object, direct light only",
            "ratio",
            None,
            "the direct-light camera figure per real object",
        ),
    ),
    (
        "observer_consistency_rel_rmse_direct",
        fig(
            "Consistency (observers), direct light only",
            "ratio",
            None,
            "worst observer's whole view in a world without interreflection",
        ),
    ),
    (
        "observer_consistency_rel_rmse_real_comparable_direct",
        fig(
            "Consistency (observers, real surfaces), direct light only",
            "ratio",
            Some(Target::AtMost(0.01)),
            "observers' real surfaces where the method can be right by design, without interreflection",
        ),
    ),
    (
        "delta_e2000_median_direct",
        fig(
            "CIEDE2000, median, direct light only",
            "ΔE00",
            None,
            "the observers' colour difference in a world without interreflection",
        ),
    ),
    (
        "delta_e2000_p95_direct",
        fig(
            "CIEDE2000, p95, direct light only",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "observers_direct",
        fig(
            "Per observer, direct light only",
            "ratio",
            None,
            "each observer's figures without interreflection",
        ),
    ),
    (
        "photometric_seam_delta_e_median",
        fig(
            "CIEDE2000 across the seams, calibrated, median",
            "ΔE00",
            Some(Target::AtMost(1.0)),
            "frame 60, global mode, the measured profiles: the observers' colour difference 2 to 4 pixels either side of each occluding-occlusion seam, where the face draws a real surface next to the real surface itself",
        ),
    ),
    (
        "photometric_seam_delta_e_p95",
        fig(
            "CIEDE2000 across the seams, calibrated, p95",
            "ΔE00",
            Some(Target::AtMost(2.5)),
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_observer_delta_e_median",
        fig(
            "CIEDE2000, whole views, calibrated, median",
            "ΔE00",
            Some(Target::AtMost(1.0)),
            "frame 60, global mode, the photometric chain on and the measured profiles: every covered pixel",
        ),
    ),
    (
        "photometric_observer_delta_e_p95",
        fig(
            "CIEDE2000, whole views, calibrated, p95",
            "ΔE00",
            Some(Target::AtMost(3.0)),
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_seam_delta_e_median_uncalibrated",
        fig(
            "CIEDE2000 across the seams, uncalibrated, median",
            "ΔE00",
            None,
            "the nodes assuming a nominal CRT (gamma 2.2) behind an ideal combiner",
        ),
    ),
    (
        "photometric_seam_delta_e_p95_uncalibrated",
        fig(
            "CIEDE2000 across the seams, uncalibrated, p95",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_observer_delta_e_median_uncalibrated",
        fig(
            "CIEDE2000, whole views, uncalibrated, median",
            "ΔE00",
            None,
            "the nodes assuming a nominal CRT behind an ideal combiner",
        ),
    ),
    (
        "photometric_observer_delta_e_p95_uncalibrated",
        fig(
            "CIEDE2000, whole views, uncalibrated, p95",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_seam_delta_e_median_true",
        fig(
            "CIEDE2000 across the seams, true devices, median",
            "ΔE00",
            None,
            "the nodes encoding with the simulated devices themselves: the floor of any profile",
        ),
    ),
    (
        "photometric_seam_delta_e_p95_true",
        fig(
            "CIEDE2000 across the seams, true devices, p95",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_observer_delta_e_median_true",
        fig(
            "CIEDE2000, whole views, true devices, median",
            "ΔE00",
            None,
            "the nodes encoding with the simulated devices themselves",
        ),
    ),
    (
        "photometric_observer_delta_e_p95_true",
        fig(
            "CIEDE2000, whole views, true devices, p95",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_seam_delta_e_median_ideal_photometry",
        fig(
            "CIEDE2000 across the seams, no photometric chain, median",
            "ΔE00",
            None,
            "a world with an ideal combiner and a nominal CRT: what the figures were before the chain was modelled",
        ),
    ),
    (
        "photometric_seam_delta_e_p95_ideal_photometry",
        fig(
            "CIEDE2000 across the seams, no photometric chain, p95",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_observer_delta_e_median_ideal_photometry",
        fig(
            "CIEDE2000, whole views, no photometric chain, median",
            "ΔE00",
            None,
            "a world with an ideal combiner and a nominal CRT",
        ),
    ),
    (
        "photometric_observer_delta_e_p95_ideal_photometry",
        fig(
            "CIEDE2000, whole views, no photometric chain, p95",
            "ΔE00",
            None,
            "95th percentile of the same",
        ),
    ),
    (
        "photometric_camera_response_error",
        fig(
            "Camera response error",
            "ratio",
            Some(Target::AtMost(0.02)),
            "the response recovered from the exposure bracket against the camera's true one, over the middle 90 % of its signal range (worst face and channel)",
        ),
    ),
    (
        "photometric_crt_curve_error",
        fig(
            "CRT response error",
            "ratio",
            Some(Target::AtMost(0.01)),
            "the profile's light through the mirror (R / T times the CRT's) against the true devices', drive 0.1 to 1 (worst face and channel)",
        ),
    ),
    (
        "photometric_projector_curve_error",
        fig(
            "Projector response error",
            "ratio",
            Some(Target::AtMost(0.01)),
            "the projector profile's light against the true device's, device value 0.1 to 1, relative to the product's calibrated full white (worst projector and channel)",
        ),
    ),
    (
        "photometric_projector_curve_error_uncalibrated",
        fig(
            "Projector response error, uncalibrated",
            "ratio",
            None,
            "the same of the product's model alone (one gamma, eta and black level for every channel)",
        ),
    ),
    (
        "photometric_projector_gamma_error",
        fig(
            "Projector gamma error",
            "gamma",
            None,
            "the profile's gamma less the true device's (worst projector and channel, absolute)",
        ),
    ),
    (
        "photometric_projector_black_error",
        fig(
            "Projector black-level error",
            "ratio",
            None,
            "the profile's black level over the true device's, less 1 (worst projector and channel, absolute)",
        ),
    ),
    (
        "photometric_balance_error",
        fig(
            "T/R balance error",
            "ratio",
            None,
            "the profile's R / T times peak against the true devices' (worst face and channel)",
        ),
    ),
    (
        "photometric_held_out_error",
        fig(
            "Held-out error, calibrated",
            "ratio",
            None,
            "the fitted profile against the measured light at drive levels left out of the fit (worst)",
        ),
    ),
    (
        "photometric_held_out_error_uncalibrated",
        fig(
            "Held-out error, uncalibrated",
            "ratio",
            None,
            "the nominal profile against the same measurements",
        ),
    ),
    (
        "photometric_calibration_s",
        fig(
            "Photometric calibration time",
            "s",
            Some(Target::AtMost(60.0)),
            "every face and projector, in the simulated showcase (path tracing the real light included)",
        ),
    ),
    (
        "renderer",
        fig(
            "Renderer",
            "text",
            None,
            "the adapter the node renderers ran on",
        ),
    ),
];

/// The page's knowledge of figure `name`, if it has any.
pub(in crate::demo) fn figure(name: &str) -> Option<&'static Figure> {
    FIGURES.iter().find(|(n, _)| *n == name).map(|(_, f)| f)
}

/// Position of `name` in the page's order (unknown names last).
pub(in crate::demo) fn order(name: &str) -> usize {
    FIGURES
        .iter()
        .position(|(n, _)| *n == name)
        .unwrap_or(FIGURES.len())
}

/// The target as text, "—" for none.
pub(in crate::demo) fn target_text(f: &Figure) -> String {
    f.target.map_or("—".into(), |t| t.text(f.unit))
}

/// `v` to three significant digits: integers as they are, very large or
/// small magnitudes in scientific notation, "n/a" when not finite.
pub(in crate::demo) fn format_number(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    if v == v.trunc() && v.abs() < 1e15 {
        return format!("{v:.0}");
    }
    let magnitude = v.abs().log10().floor();
    if !(-3.0..5.0).contains(&magnitude) {
        return format!("{v:.2e}");
    }
    let decimals = (2.0 - magnitude).max(0.0) as usize;
    format!("{v:.decimals$}")
}

/// `text` followed by `unit`, except for plain ratios and text.
fn with_unit(text: &str, unit: &str) -> String {
    match unit {
        "ratio" | "text" | "" => text.into(),
        u => format!("{text} {u}"),
    }
}

/// A number with its unit, as the page shows it.
pub(in crate::demo) fn format_value(v: f64, unit: &str) -> String {
    with_unit(&format_number(v), unit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[track_caller]
    fn check(v: f64, expected: &str) {
        assert_eq!(format_number(v), expected);
    }

    #[test]
    fn numbers_get_three_significant_digits() {
        check(0.007_123_456_789, "0.00712");
        check(59.987_654_321, "60.0");
        check(0.25, "0.250");
        check(1234.4, "1234");
        check(3.0, "3");
        check(0.0, "0");
        check(-0.5, "-0.500");
        check(1.234e-5, "1.23e-5");
        check(123_456.7, "1.23e5");
        check(f64::NAN, "n/a");
        check(f64::INFINITY, "n/a");
        assert_eq!(format_value(0.2, "ms"), "0.200 ms");
        assert_eq!(format_value(0.2, "ratio"), "0.200");
    }

    #[test]
    fn targets_mark_pass_or_miss() {
        assert_eq!(Target::AtMost(1.0).met_by(1.0), Some(true));
        assert_eq!(Target::AtMost(1.0).met_by(1.01), Some(false));
        assert_eq!(Target::Equal(0.0).met_by(0.0), Some(true));
        assert_eq!(Target::Equal(0.0).met_by(1.0), Some(false));
        assert_eq!(Target::AtMost(1.0).met_by(f64::NAN), None);
        let skew = figure("swap_skew_ms_p99").unwrap();
        assert_eq!(target_text(skew), "≤ 1 ms");
        assert_eq!(target_text(figure("frame_rate_hz").unwrap()), "—");
        assert_eq!(
            target_text(figure("reflectance_rel_rmse").unwrap()),
            "≤ 0.02"
        );
    }

    #[test]
    fn every_figure_is_named_once_with_a_unit() {
        for (i, (name, f)) in FIGURES.iter().enumerate() {
            assert_eq!(order(name), i, "{name} listed twice");
            assert!(!f.unit.is_empty() && !f.meaning.is_empty(), "{name}");
        }
        assert!(figure("no_such_figure").is_none());
        assert_eq!(order("no_such_figure"), FIGURES.len());
    }
}
