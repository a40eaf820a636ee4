//! The `calibrate` command's files as an outsider (a peer
//! implementation) writes and reads them: the input typed out key by key in
//! the documented layout, the output checked from its JSON alone.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;
use showcase_master::calibrate::{
    Calibration, Method, fiducial_plate, fiducial_rig, projector_in_showcase, run_calibrate_file,
    simulate_fiducials,
};
use std::path::PathBuf;

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("showcase-calib-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The documented input layout, written as text (not through our types).
fn issue_text(
    width: u32,
    height: u32,
    points: &[([f64; 3], [f64; 2])],
    k: Option<[[f64; 3]; 3]>,
) -> String {
    let points: Vec<String> = points
        .iter()
        .map(|([x, y, z], [u, v])| {
            format!(r#"{{"world": [{x:?}, {y:?}, {z:?}], "pixel": [{u:?}, {v:?}]}}"#)
        })
        .collect();
    let intrinsics = k.map_or(String::new(), |k| {
        let rows: Vec<String> = k
            .iter()
            .map(|r| format!("[{:?}, {:?}, {:?}]", r[0], r[1], r[2]))
            .collect();
        format!(
            r#", "intrinsics": {{"camera_matrix": [{}]}}"#,
            rows.join(", ")
        )
    });
    format!(
        "{{\"device\": \"projector-0\", \"width\": {width}, \"height\": {height},\n \"points\": [{}]{intrinsics}}}\n",
        points.join(",\n  ")
    )
}

fn number(v: &Value) -> f64 {
    v.as_f64().expect("a number")
}

fn matrix<const R: usize, const C: usize>(v: &Value) -> [[f64; C]; R] {
    std::array::from_fn(|r| std::array::from_fn(|c| number(&v[r][c])))
}

/// Check an output file from its JSON alone: the documented keys, P = K [R | t],
/// and every input point reprojected through P onto its pixel.
fn check_output(text: &str, points: &[([f64; 3], [f64; 2])], tol_px: f64) {
    let out: Value = serde_json::from_str(text).unwrap();
    let k: [[f64; 3]; 3] = matrix(&out["camera_matrix"]);
    let r: [[f64; 3]; 3] = matrix(&out["rotation"]);
    let p: [[f64; 4]; 3] = matrix(&out["projection"]);
    let t: Vec<f64> = out["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(number)
        .collect();
    assert_eq!(out["dist_coeffs"].as_array().unwrap().len(), 5);
    assert_eq!(out["residuals_px"].as_array().unwrap().len(), points.len());
    assert!(out["width"].is_u64() && out["height"].is_u64() && out["rms_px"].is_f64());
    for row in 0..3 {
        for col in 0..4 {
            let want: f64 = (0..3)
                .map(|i| k[row][i] * if col < 3 { r[i][col] } else { t[i] })
                .sum();
            assert!((p[row][col] - want).abs() <= 1e-9 * want.abs().max(1.0));
        }
    }
    for (world, pixel) in points {
        let h: [f64; 3] = std::array::from_fn(|row| {
            (0..3).map(|i| p[row][i] * world[i]).sum::<f64>() + p[row][3]
        });
        assert!(h[2] > 0.0, "point behind the device");
        let (du, dv) = (h[0] / h[2] - pixel[0], h[1] / h[2] - pixel[1]);
        assert!(du.hypot(dv) < tol_px, "reprojection off by {du}, {dv}");
    }
}

fn pairs(input: &showcase_master::calibrate::CalibrationInput) -> Vec<([f64; 3], [f64; 2])> {
    input.points.iter().map(|p| (p.world, p.pixel)).collect()
}

#[test]
fn a_file_typed_in_the_issue_layout_calibrates() {
    let dir = scratch("issue-layout");
    let (inp, out) = (dir.join("points.json"), dir.join("out.json"));
    for seed in 0..3 {
        let truth = projector_in_showcase(seed);
        // Non-coplanar rig, unknown intrinsics.
        let rig = pairs(&simulate_fiducials(
            &truth,
            &fiducial_rig(12, seed),
            0.0,
            seed,
        ));
        std::fs::write(&inp, issue_text(truth.width, truth.height, &rig, None)).unwrap();
        for method in [Method::Lm, Method::Powell] {
            let cal = run_calibrate_file(&inp, &out, method).unwrap();
            assert!(!cal.intrinsics_known);
            check_output(&std::fs::read_to_string(&out).unwrap(), &rig, 1e-4);
        }
        // Coplanar plate with the known camera_matrix: only the pose is solved.
        let plate = pairs(&simulate_fiducials(
            &truth,
            &fiducial_plate(8, seed),
            0.0,
            seed,
        ));
        let k = truth.k.transpose().to_cols_array_2d();
        std::fs::write(&inp, issue_text(truth.width, truth.height, &plate, Some(k))).unwrap();
        let cal = run_calibrate_file(&inp, &out, Method::Lm).unwrap();
        assert!(cal.intrinsics_known);
        assert_eq!(cal.camera_matrix, k);
        check_output(&std::fs::read_to_string(&out).unwrap(), &plate, 1e-6);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn malformed_files_get_errors_that_name_the_file_and_the_fault() {
    let dir = scratch("malformed");
    let (inp, out) = (dir.join("points.json"), dir.join("out.json"));
    let truth = projector_in_showcase(4);
    let plate = pairs(&simulate_fiducials(&truth, &fiducial_plate(8, 4), 0.0, 4));
    let good = issue_text(truth.width, truth.height, &plate, None);
    let cases = [
        (good.replace("\"width\": ", "\"wide\": "), "unknown field `wide`"),
        // A misspelled key is an error, not a silently ignored one: the
        // intrinsics would otherwise be solved instead of given.
        (
            good.replace("]}\n", r#"], "intrinsic": {"camera_matrix": [[800, 0, 512], [0, 800, 384], [0, 0, 1]]}}"#),
            "unknown field `intrinsic`",
        ),
        (
            good.replace("]}\n", r#"], "intrinsics": {"camera_matrx": [[800, 0, 512], [0, 800, 384], [0, 0, 1]]}}"#),
            "unknown field `camera_matrx`",
        ),
        (good.replace("\"pixel\": [", "\"pixel\": [1.0, "), "points[0].pixel must be [u, v] (2 numbers), got [1.0,"),
        (good.replacen("\"world\": [", "\"world\": [\"a\", ", 2), "points[0].world must be [x, y, z]"),
        // Coplanar points without intrinsics: the error says what to add.
        (good.clone(), "\"intrinsics\": {\"camera_matrix\""),
        (
            good.replace("]}\n", r#"], "intrinsics": {"camera_matrix": [[800, 0, 512], [0, 800, 384]]}}"#),
            "invalid camera_matrix: expected 3 rows of 3",
        ),
        (
            good.replace("]}\n", r#"], "intrinsics": {"camera_matrix": [[800, 0, 512], [0, -800, 384], [0, 0, 1]]}}"#),
            "focal lengths",
        ),
    ];
    for (text, expected) in cases {
        std::fs::write(&inp, &text).unwrap();
        let err = format!(
            "{:#}",
            run_calibrate_file(&inp, &out, Method::Lm).unwrap_err()
        );
        assert!(
            err.contains("points.json") && err.contains(expected),
            "{err}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn output_floats_parse_back_to_the_same_bits() {
    // serde_json's float_roundtrip feature: without it, parsing is off by
    // one ulp for some values (and a calibration read back would differ).
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for _ in 0..20_000 {
        let x = f64::from_bits(rng.random::<u64>());
        if !x.is_finite() {
            continue;
        }
        let y: f64 = serde_json::from_str(&serde_json::to_string(&x).unwrap()).unwrap();
        assert_eq!(x.to_bits(), y.to_bits(), "{x:e}");
    }
    let mut cal = Calibration::from_device("p", &projector_in_showcase(2), &[]);
    cal.rms_px = 0.1 + 0.2;
    cal.residuals_px = (0..50).map(|_| rng.random_range(0.0..3.0)).collect();
    let back: Calibration =
        serde_json::from_str(&serde_json::to_string_pretty(&cal).unwrap()).unwrap();
    assert_eq!(back, cal);
}
