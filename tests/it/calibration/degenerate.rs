//! Degenerate calibration inputs: each gives the right error, never an
//! answer.

use super::*;

#[track_caller]
fn check_err(input: &CalibrationInput, expected: fn(&CalibrationError) -> bool, what: &str) {
    match calibrate(input, &lm()) {
        Ok(c) => panic!("{what}: expected an error, got rms {}", c.rms_px),
        Err(e) => assert!(expected(&e), "{what}: wrong error {e:?}"),
    }
}

#[test]
fn degenerate_inputs_give_the_right_error() {
    use CalibrationError as E;
    let (truth, rig) = clean_rig(20);

    let mut few = rig.clone();
    few.points.truncate(5);
    check_err(
        &few,
        |e| {
            matches!(
                e,
                E::TooFewPoints {
                    found: 5,
                    needed: 6,
                    ..
                }
            )
        },
        "5 points",
    );
    let mut few_known = few.clone();
    few_known.points.truncate(3);
    few_known.intrinsics = Some(Intrinsics {
        camera_matrix: k_rows(&truth),
        dist_coeffs: None,
    });
    check_err(
        &few_known,
        |e| {
            matches!(
                e,
                E::TooFewPoints {
                    found: 3,
                    needed: 4,
                    ..
                }
            )
        },
        "3 points, known K",
    );

    let line: Vec<DVec3> = (-5..5)
        .map(|i| RIG_CENTER + 0.02 * i as f64 * DVec3::new(1.0, 0.3, 0.5))
        .collect();
    let collinear = simulate_fiducials(&truth, &line, 0.0, 0);
    assert_eq!(collinear.points.len(), 10);
    check_err(
        &collinear,
        |e| matches!(e, E::Collinear { .. }),
        "collinear",
    );

    let plate = simulate_fiducials(&truth, &fiducial_plate(30, 1), 0.0, 0);
    check_err(
        &plate,
        |e| matches!(e, E::CoplanarWithoutIntrinsics { .. }),
        "coplanar",
    );
    let msg = calibrate(&plate, &lm()).unwrap_err().to_string();
    assert!(msg.contains("intrinsics"), "{msg}");

    for (i, bad) in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY]
        .into_iter()
        .enumerate()
    {
        let mut nf = rig.clone();
        nf.points[i].world[1] = bad;
        check_err(
            &nf,
            |e| matches!(e, E::NonFinite { what } if what.contains("world")),
            "non-finite world",
        );
        let mut nf = rig.clone();
        nf.points[i].pixel[0] = bad;
        check_err(
            &nf,
            |e| matches!(e, E::NonFinite { what } if what.contains("pixel")),
            "non-finite pixel",
        );
    }

    let bad_k = [
        vec![vec![800.0, 0.0, 512.0], vec![0.0, 800.0, 384.0]],
        vec![
            vec![800.0, 0.0, 512.0, 0.0],
            vec![0.0, 800.0, 384.0],
            vec![0.0, 0.0, 1.0],
        ],
        vec![
            vec![0.0, 0.0, 512.0],
            vec![0.0, 800.0, 384.0],
            vec![0.0, 0.0, 1.0],
        ],
        vec![
            vec![800.0, 0.0, 512.0],
            vec![0.0, 800.0, 384.0],
            vec![0.0, 0.0, 0.0],
        ],
        vec![
            vec![800.0, 0.0, 512.0],
            vec![0.0, -800.0, 384.0],
            vec![0.0, 0.0, 1.0],
        ],
        vec![
            vec![800.0, 0.0, 512.0],
            vec![5.0, 800.0, 384.0],
            vec![0.0, 0.0, 1.0],
        ],
    ];
    for k in bad_k {
        let mut known = rig.clone();
        known.intrinsics = Some(Intrinsics {
            camera_matrix: k.clone(),
            dist_coeffs: None,
        });
        check_err(
            &known,
            |e| matches!(e, E::InvalidCameraMatrix { .. }),
            &format!("camera_matrix {k:?}"),
        );
    }
    let mut known = rig.clone();
    known.intrinsics = Some(Intrinsics {
        camera_matrix: vec![
            vec![800.0, 0.0, f64::NAN],
            vec![0.0, 800.0, 384.0],
            vec![0.0, 0.0, 1.0],
        ],
        dist_coeffs: None,
    });
    check_err(
        &known,
        |e| matches!(e, E::NonFinite { .. }),
        "NaN camera_matrix",
    );

    let mut empty = rig.clone();
    empty.width = 0;
    check_err(
        &empty,
        |e| matches!(e, E::InvalidImageSize { .. }),
        "zero width",
    );

    // Mirroring one fiducial through the centre of projection keeps its pixel:
    // the data fit the true device exactly, with that point behind it.
    let mut behind = rig.clone();
    let c = truth.center();
    let w = DVec3::from_array(behind.points[7].world);
    behind.points[7].world = (2.0 * c - w).to_array();
    check_err(
        &behind,
        |e| matches!(e, E::PointBehindDevice { index: 7, .. }),
        "point behind",
    );
}
