use super::*;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const WIDTH: usize = 64;
const HEIGHT: usize = 48;
const LEVELS: u32 = 256;
/// Decades of radiance in the scene, per channel.
const DECADES: [f64; 3] = [2.5, 2.0, 3.0];
/// Slope of the response above the knee, relative to below it.
const KNEE_SLOPE: f64 = 0.4;
/// The codes over which the recovered curves are checked.
const CHECKED: std::ops::RangeInclusive<u32> = 13..=242;

/// A synthetic camera: `v = s^(1/gamma)`, compressed above the knee,
/// clipped to `[0, 1]`, read noise in units of the full range, 8 bits.
#[derive(Clone, Copy, Debug)]
struct Camera {
    gamma: [f64; 3],
    knee: Option<f64>,
    noise: f64,
}

const KNEE_CAMERA: Camera = Camera {
    gamma: [2.0, 2.3, 1.8],
    knee: Some(0.8),
    noise: 0.5 / 255.0,
};

const POWER_CAMERA: Camera = Camera {
    gamma: [2.2; 3],
    knee: None,
    noise: 0.0,
};

impl Camera {
    /// Normalised value of signal `s` in `channel`, before noise.
    fn value(&self, channel: usize, s: f64) -> f64 {
        let v = s.max(0.0).powf(1.0 / self.gamma[channel]);
        let v = match self.knee {
            Some(k) if v > k => k + (v - k) * KNEE_SLOPE,
            _ => v,
        };
        v.clamp(0.0, 1.0)
    }

    /// The true inverse response: the signal of `code`.
    fn signal(&self, channel: usize, code: u32) -> f64 {
        let v = f64::from(code) / f64::from(LEVELS - 1);
        let v = match self.knee {
            Some(k) if v > k => k + (v - k) / KNEE_SLOPE,
            _ => v,
        };
        v.powf(self.gamma[channel])
    }
}

/// Radiances of a smooth 64x48 scene spanning `DECADES` per channel.
fn scene() -> Vec<[f64; 3]> {
    (0..WIDTH * HEIGHT)
        .map(|p| {
            let u = (p % WIDTH) as f64 / (WIDTH - 1) as f64;
            let v = (p / WIDTH) as f64 / (HEIGHT - 1) as f64;
            std::array::from_fn(|c| {
                let wave = 0.5 + 0.5 * (3.0 * u + 5.0 * v + c as f64).sin();
                let f = 0.55 * u + 0.35 * v + 0.1 * wave;
                10f64.powf(DECADES[c] * f)
            })
        })
        .collect()
}

/// Eight exposure times a factor 2 apart, the first `first_s`.
fn exposures(first_s: f64) -> Vec<f64> {
    (0..8).map(|j| first_s * f64::from(1 << j)).collect()
}

/// Gain per channel that centres the bracket of `exposures(1e-3)` over
/// the scene on the codes of `camera`: the geometric mean signal is that
/// of the codes 6 and 250.
fn gains(camera: &Camera) -> [f64; 3] {
    std::array::from_fn(|c| {
        let centre = (camera.signal(c, 6) * camera.signal(c, 250)).sqrt();
        centre / (1e-3 * 128f64.sqrt() * 10f64.powf(DECADES[c] / 2.0))
    })
}

/// The frames `camera` takes of `scene` at `exposures_s`, with the fixed
/// noise seed.
fn capture(camera: &Camera, scene: &[[f64; 3]], exposures_s: &[f64]) -> Vec<Vec<[u16; 3]>> {
    capture_seeded(camera, scene, exposures_s, 0x5eed_da7a)
}

/// The frames `camera` takes of `scene` at `exposures_s`, noise seeded.
fn capture_seeded(
    camera: &Camera,
    scene: &[[f64; 3]],
    exposures_s: &[f64],
    seed: u64,
) -> Vec<Vec<[u16; 3]>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let gain = gains(camera);
    let top = f64::from(LEVELS - 1);
    exposures_s
        .iter()
        .map(|&t| {
            scene
                .iter()
                .map(|radiance| {
                    std::array::from_fn(|c| {
                        let v = camera.value(c, gain[c] * t * radiance[c]);
                        let v = v + camera.noise * noise.sample(&mut rng);
                        (v * top).round().clamp(0.0, top) as u16
                    })
                })
                .collect()
        })
        .collect()
}

fn bracket<'a>(exposures_s: &'a [f64], frames: &'a [Vec<[u16; 3]>]) -> ExposureBracket<'a> {
    ExposureBracket {
        exposures_s,
        frames,
        levels: LEVELS,
    }
}

/// Worst relative error of the recovered exposure against `camera`'s
/// inverse over `CHECKED`, after fitting the channel's scale by least
/// squares in log space over the trusted range; and the code where it is.
#[track_caller]
fn worst_error(response: &RecoveredResponse, camera: &Camera, channel: usize) -> (f64, u32) {
    let (low, high) = response.trusted_range(channel);
    assert!(
        low <= *CHECKED.start() && high >= *CHECKED.end(),
        "channel {channel}: trusted range {low}..={high} does not cover {CHECKED:?}"
    );
    let log_ratio =
        |z: u32| camera.signal(channel, z).ln() - response.log_exposure(channel, f64::from(z));
    let scale = (low..=high).map(log_ratio).sum::<f64>() / f64::from(high - low + 1);
    CHECKED
        .map(|z| (((scale - log_ratio(z)).exp() - 1.0).abs(), z))
        .fold((0.0, 0), |worst, e| if e.0 > worst.0 { e } else { worst })
}

#[test]
fn recovers_gamma_with_a_knee_within_2_percent() {
    let exposures_s = exposures(1e-3);
    let frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    let response = recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default())
        .expect("a clean bracket recovers");
    assert_eq!(response.levels(), LEVELS);
    for channel in 0..3 {
        let (error, code) = worst_error(&response, &KNEE_CAMERA, channel);
        assert!(
            error < 0.02,
            "channel {channel} (gamma {}): worst error {:.3}% at code {code}, trusted {:?}, residual {:.4}",
            KNEE_CAMERA.gamma[channel],
            100.0 * error,
            response.trusted_range(channel),
            response.residual_rms(channel),
        );
        assert!(response.residual_rms(channel) < 0.5 * ResponseOptions::default().max_residual);
    }
}

#[test]
fn the_2_percent_holds_for_other_noise_seeds() {
    let exposures_s = exposures(1e-3);
    let scene = scene();
    let mut worst = [(0.0, 0, 0); 3];
    for seed in 0..10 {
        let frames = capture_seeded(&KNEE_CAMERA, &scene, &exposures_s, seed);
        let response =
            recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default())
                .expect("a clean bracket recovers");
        for (channel, w) in worst.iter_mut().enumerate() {
            let (error, code) = worst_error(&response, &KNEE_CAMERA, channel);
            if error > w.0 {
                *w = (error, code, seed);
            }
        }
    }
    for (channel, (error, code, seed)) in worst.into_iter().enumerate() {
        assert!(
            error < 0.02,
            "channel {channel}: worst error {:.3}% at code {code}, seed {seed}",
            100.0 * error
        );
    }
}

#[test]
fn recovers_a_noiseless_power_curve_within_1_percent() {
    let exposures_s = exposures(1e-3);
    let frames = capture(&POWER_CAMERA, &scene(), &exposures_s);
    let response = recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default())
        .expect("a clean bracket recovers");
    for channel in 0..3 {
        let (error, code) = worst_error(&response, &POWER_CAMERA, channel);
        assert!(
            error < 0.01,
            "channel {channel}: worst error {:.3}% at code {code}",
            100.0 * error
        );
    }
}

#[test]
fn the_middle_code_maps_to_one_and_values_stay_finite() {
    let exposures_s = exposures(1e-3);
    let frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    let response =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap();
    for channel in 0..3 {
        assert!((response.exposure(channel, 128.0) - 1.0).abs() < 1e-12);
        for code in [
            f64::NAN,
            f64::NEG_INFINITY,
            -3.0,
            0.0,
            254.5,
            255.0,
            1e9,
            f64::INFINITY,
        ] {
            let e = response.exposure(channel, code);
            assert!(e.is_finite() && e > 0.0, "exposure({code}) = {e}");
        }
        // Interpolation halfway between codes is the geometric mean.
        let mid = response.exposure(channel, 100.5);
        let geometric =
            (response.exposure(channel, 100.0) * response.exposure(channel, 101.0)).sqrt();
        assert!((mid / geometric - 1.0).abs() < 1e-12);
        for t in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(response.radiance(channel, 128.0, t), 0.0);
        }
        let tiny = response.radiance(channel, 255.0, f64::MIN_POSITIVE);
        assert!(tiny.is_finite() && tiny > 0.0);
        assert!((response.radiance(channel, 128.0, 0.5) - 2.0).abs() < 1e-12);
    }
}

#[test]
fn exposure_order_does_not_matter() {
    let exposures_s = exposures(1e-3);
    let frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    let sorted =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap();
    let order = [3, 0, 7, 5, 1, 6, 2, 4];
    let shuffled_s: Vec<f64> = order.iter().map(|&j| exposures_s[j]).collect();
    let shuffled_frames: Vec<_> = order.iter().map(|&j| frames[j].clone()).collect();
    let shuffled = recover_response(
        &bracket(&shuffled_s, &shuffled_frames),
        &ResponseOptions::default(),
    )
    .unwrap();
    for channel in 0..3 {
        assert_eq!(
            sorted.trusted_range(channel),
            shuffled.trusted_range(channel)
        );
        for code in 0..LEVELS {
            let (a, b) = (
                sorted.log_exposure(channel, f64::from(code)),
                shuffled.log_exposure(channel, f64::from(code)),
            );
            assert!(
                (a - b).abs() < 1e-9,
                "channel {channel} code {code}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn a_saturated_bracket_asks_for_shorter_exposures() {
    let exposures_s = exposures(100.0);
    let frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    let err =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap_err();
    assert!(
        matches!(err, ResponseError::Saturated { channel: 0, usable, .. } if usable < MIN_USABLE_SITES),
        "{err:?}"
    );
    assert!(err.to_string().contains("add shorter exposures"), "{err}");
}

#[test]
fn an_underexposed_bracket_asks_for_longer_exposures() {
    let exposures_s = exposures(1e-8);
    let frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    let err =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap_err();
    assert!(
        matches!(err, ResponseError::Underexposed { channel: 0, clipped_percent, .. } if clipped_percent > 90.0),
        "{err:?}"
    );
    assert!(err.to_string().contains("add longer exposures"), "{err}");
}

#[test]
fn frames_out_of_the_order_of_their_exposures_are_refused() {
    let exposures_s = exposures(1e-3);
    let mut frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    frames.reverse();
    let err =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap_err();
    assert!(
        matches!(err, ResponseError::NotMonotonic { channel: 0, .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("not monotonic"), "{err}");
    eprintln!("{err}");
}

#[test]
fn a_scene_that_changes_between_frames_is_refused() {
    let exposures_s = exposures(1e-3);
    let mut frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for frame in frames.iter_mut().skip(1) {
        frame.shuffle(&mut rng);
    }
    let err =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap_err();
    assert!(
        matches!(
            err,
            ResponseError::NotMonotonic { channel: 0, .. }
                | ResponseError::InconsistentFrames { channel: 0, .. }
        ),
        "{err:?}"
    );
}

#[test]
fn lighting_that_flickers_between_frames_is_refused() {
    // Every other frame is lit 1.6 times brighter: the curve still rises,
    // but the samples sit far from it.
    let exposures_s = exposures(1e-3);
    let scene = scene();
    let frames: Vec<_> = exposures_s
        .iter()
        .enumerate()
        .map(|(j, &t)| {
            let lit = if j % 2 == 1 { 1.6 } else { 1.0 };
            capture(&KNEE_CAMERA, &scene, &[lit * t]).remove(0)
        })
        .collect();
    let err =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap_err();
    assert!(
        matches!(err, ResponseError::InconsistentFrames { channel: 0, rms, .. } if rms > 0.15),
        "{err:?}"
    );
}

#[test]
fn a_uniform_grey_scene_does_not_fit_one_curve() {
    let exposures_s = exposures(1e-3);
    let frames = vec![vec![[128u16; 3]; WIDTH * HEIGHT]; exposures_s.len()];
    let err =
        recover_response(&bracket(&exposures_s, &frames), &ResponseOptions::default()).unwrap_err();
    assert!(
        matches!(err, ResponseError::InconsistentFrames { channel: 0, rms, .. } if rms > 1.0),
        "{err:?}"
    );
}

/// Recovering from the clean bracket, changed by `edit`, gives the error
/// that `expected` accepts.
#[track_caller]
fn check_bad_input(
    edit: impl FnOnce(&mut Vec<f64>, &mut Vec<Vec<[u16; 3]>>, &mut u32),
    expected: impl FnOnce(&ResponseError) -> bool,
) {
    let mut exposures_s = exposures(1e-3);
    let mut frames = capture(&POWER_CAMERA, &scene(), &exposures_s);
    let mut levels = LEVELS;
    edit(&mut exposures_s, &mut frames, &mut levels);
    let result = recover_response(
        &ExposureBracket {
            exposures_s: &exposures_s,
            frames: &frames,
            levels,
        },
        &ResponseOptions::default(),
    );
    match result {
        Err(err) => assert!(expected(&err), "unexpected error: {err}"),
        Ok(_) => panic!("expected an error, got a response"),
    }
}

#[test]
fn bad_brackets_give_their_errors() {
    use ResponseError as E;
    check_bad_input(
        |t, f, _| {
            t.truncate(1);
            f.truncate(1);
        },
        |e| matches!(e, E::TooFewExposures { found: 1 }),
    );
    check_bad_input(
        |t, f, _| {
            t.clear();
            f.clear();
        },
        |e| matches!(e, E::TooFewExposures { found: 0 }),
    );
    check_bad_input(
        |_, f, _| {
            f.pop();
        },
        |e| {
            matches!(
                e,
                E::FrameCountMismatch {
                    frames: 7,
                    exposures: 8
                }
            )
        },
    );
    check_bad_input(
        |_, f, _| f[3].pop().map(drop).unwrap_or(()),
        |e| {
            matches!(
                e,
                E::FrameSizeMismatch {
                    index: 3,
                    len: 3071,
                    expected: 3072
                }
            )
        },
    );
    check_bad_input(
        |_, f, _| f.iter_mut().for_each(Vec::clear),
        |e| matches!(e, E::EmptyFrame { index: 0 }),
    );
    check_bad_input(
        |_, f, _| f[5].clear(),
        |e| matches!(e, E::EmptyFrame { index: 5 }),
    );
    for bad in [0.0, -0.01, f64::NAN, f64::INFINITY] {
        check_bad_input(
            |t, _, _| t[2] = bad,
            |e| matches!(e, E::InvalidExposure { index: 2, value } if value.to_bits() == bad.to_bits()),
        );
    }
    check_bad_input(
        |t, _, _| t[6] = t[1],
        |e| matches!(e, E::DuplicateExposure { first: 1, second: 6, value } if *value == 2e-3),
    );
    check_bad_input(
        |_, f, _| f[4][100][2] = 256,
        |e| {
            matches!(
                e,
                E::CodeOutOfRange {
                    frame: 4,
                    pixel: 100,
                    channel: 2,
                    code: 256,
                    levels: 256
                }
            )
        },
    );
    check_bad_input(
        |_, _, l| *l = 200,
        |e| matches!(e, E::CodeOutOfRange { code, levels: 200, .. } if *code >= 200),
    );
    for bad in [0, MIN_LEVELS - 1, MAX_LEVELS + 1] {
        check_bad_input(
            |_, _, l| *l = bad,
            |e| matches!(e, E::InvalidLevels { levels } if *levels == bad),
        );
    }
}

#[test]
fn bad_options_give_their_errors() {
    let exposures_s = exposures(1e-3);
    let frames = capture(&POWER_CAMERA, &scene(), &exposures_s);
    let defaults = ResponseOptions::default();
    for (options, word) in [
        (
            ResponseOptions {
                samples: MIN_USABLE_SITES - 1,
                ..defaults
            },
            "samples",
        ),
        (
            ResponseOptions {
                smoothness: 0.0,
                ..defaults
            },
            "smoothness",
        ),
        (
            ResponseOptions {
                smoothness: f64::NAN,
                ..defaults
            },
            "smoothness",
        ),
        (
            ResponseOptions {
                smoothness: f64::INFINITY,
                ..defaults
            },
            "smoothness",
        ),
        (
            ResponseOptions {
                max_residual: 0.0,
                ..defaults
            },
            "max_residual",
        ),
        (
            ResponseOptions {
                samples: 1,
                ..defaults
            },
            "samples",
        ),
        (
            ResponseOptions {
                max_residual: f64::NAN,
                ..defaults
            },
            "max_residual",
        ),
    ] {
        match recover_response(&bracket(&exposures_s, &frames), &options) {
            Err(ResponseError::InvalidOptions { reason }) => {
                assert!(reason.starts_with(word), "{options:?}: {reason}")
            }
            other => panic!("{options:?}: expected invalid options, got {other:?}"),
        }
    }
    let unchecked = ResponseOptions {
        max_residual: f64::INFINITY,
        ..defaults
    };
    assert!(recover_response(&bracket(&exposures_s, &frames), &unchecked).is_ok());
    // A finite but overflowing smoothness fails cleanly.
    let huge = ResponseOptions {
        smoothness: 1e200,
        ..defaults
    };
    assert!(matches!(
        recover_response(&bracket(&exposures_s, &frames), &huge),
        Err(ResponseError::SolveFailed { channel: 0 })
    ));
}

#[test]
fn sites_spread_over_the_codes_and_are_distinct() {
    let exposures_s = exposures(1e-3);
    let frames = capture(&KNEE_CAMERA, &scene(), &exposures_s);
    let b = bracket(&exposures_s, &frames);
    for channel in [0, 1, 2] {
        let usable = usable_sites(&b, channel, 0);
        let sites = select_sites(&b, channel, &usable, 200);
        assert_eq!(sites.len(), 200);
        let mut unique = sites.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), 200, "channel {channel}: repeated sites");
        assert_eq!(
            sites,
            select_sites(&b, channel, &usable, 200),
            "not deterministic"
        );
        // Codes of the middle exposure: the sites reach both ends of the
        // usable sites' codes, and every tenth of that range.
        let code = |p: usize| u32::from(frames[4][p][channel]);
        let usable_codes = usable.iter().map(|&p| code(p));
        let (first, last) = (
            usable_codes.clone().min().unwrap(),
            usable_codes.max().unwrap(),
        );
        let site_codes = sites.iter().map(|&p| code(p));
        assert!(
            site_codes.clone().min().unwrap() <= first + 2,
            "channel {channel}"
        );
        assert!(
            site_codes.clone().max().unwrap() + 2 >= last,
            "channel {channel}"
        );
        let mut deciles = [false; 10];
        for z in site_codes {
            deciles[(10 * (z - first) / (last - first + 1)) as usize] = true;
        }
        assert!(deciles.iter().all(|&d| d), "channel {channel}: {deciles:?}");
        // And the frame: every quadrant holds some sites.
        let mut quadrants = [0usize; 4];
        for &p in &sites {
            quadrants
                [usize::from(p % WIDTH >= WIDTH / 2) + 2 * usize::from(p / WIDTH >= HEIGHT / 2)] +=
                1;
        }
        assert!(
            quadrants.iter().all(|&q| q >= 10),
            "channel {channel}: {quadrants:?}"
        );
    }
}

#[test]
fn inside_codes_leave_two_percent_at_each_end() {
    assert_eq!(inside_codes(256, 0), (6, 249));
    assert_eq!(inside_codes(16, 0), (1, 14));
    assert_eq!(inside_codes(1024, 0), (21, 1002));
    // A noise floor above the margin moves the low end.
    assert_eq!(inside_codes(256, 20), (21, 249));
    assert_eq!(hat_weight(0, 256), 0.0);
    assert_eq!(hat_weight(255, 256), 0.0);
    assert!((hat_weight(127, 256) - 127.0 / 127.5).abs() < 1e-15);
}
