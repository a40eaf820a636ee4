//! The error metrics every benchmark uses (DESIGN section 3), one
//! implementation each: relative RMSE over valid pixels
//! (`rmse / mean(reference)`), PSNR, and the mean CIEDE2000 difference.
//! RGB images count each channel of a valid pixel as one value. Also the
//! one definition of a percentile (nearest rank) that every median, p95
//! and p99 in the reports and benches is taken with.

pub use super::ciede2000::{Lab, delta_e_2000, linear_srgb_to_lab, linear_srgb_to_xyz, xyz_to_lab};
use super::image::{Image, RgbImage};
use glam::Vec3;

/// PSNR reported for identical inputs (a zero error), in dB.
pub const PSNR_CAP_DB: f64 = 300.0;

/// Why a metric could not be computed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MetricError {
    /// The inputs (or the mask) differ in size.
    #[error("size mismatch: test has {test} values, reference {reference}, mask {mask}")]
    SizeMismatch {
        /// Values in the test input.
        test: usize,
        /// Values in the reference.
        reference: usize,
        /// Values in the mask (equal to `test` when there is none).
        mask: usize,
    },
    /// No value is valid (empty input or an all-false mask).
    #[error("no valid values to compare")]
    NoValidValues,
    /// A valid value is NaN or infinite.
    #[error("non-finite value at index {index}")]
    NonFinite {
        /// Index of the offending value.
        index: usize,
    },
    /// Relative RMSE needs a positive reference mean.
    #[error("reference mean {mean} is not positive")]
    NonPositiveReferenceMean {
        /// The mean of the valid reference values.
        mean: f64,
    },
    /// PSNR needs a positive, finite peak.
    #[error("peak value {peak} is not positive and finite")]
    BadPeak {
        /// The offending peak.
        peak: f64,
    },
}

/// Root mean square difference and mean reference over the valid values.
fn error_stats(
    test: &[f64],
    reference: &[f64],
    mask: Option<&[bool]>,
) -> Result<(f64, f64), MetricError> {
    let mask_len = mask.map_or(test.len(), <[bool]>::len);
    if test.len() != reference.len() || mask_len != test.len() {
        return Err(MetricError::SizeMismatch {
            test: test.len(),
            reference: reference.len(),
            mask: mask_len,
        });
    }
    let (mut sq, mut sum, mut n) = (0.0, 0.0, 0usize);
    for (i, (&t, &r)) in test.iter().zip(reference).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        if !(t.is_finite() && r.is_finite()) {
            return Err(MetricError::NonFinite { index: i });
        }
        sq += (t - r) * (t - r);
        sum += r;
        n += 1;
    }
    if n == 0 {
        return Err(MetricError::NoValidValues);
    }
    Ok(((sq / n as f64).sqrt(), sum / n as f64))
}

/// Relative RMSE `rmse / mean(reference)` over the values where `mask` is
/// true (all values when `None`).
pub fn relative_rmse_values(
    test: &[f64],
    reference: &[f64],
    mask: Option<&[bool]>,
) -> Result<f64, MetricError> {
    let (rmse, mean) = error_stats(test, reference, mask)?;
    if !(mean > 0.0) {
        return Err(MetricError::NonPositiveReferenceMean { mean });
    }
    let e = rmse / mean;
    if e.is_finite() {
        Ok(e)
    } else {
        Err(MetricError::NonPositiveReferenceMean { mean })
    }
}

/// PSNR `10 log10(peak^2 / mse)` in dB over the valid values, at most
/// [`PSNR_CAP_DB`].
pub fn psnr_values(
    test: &[f64],
    reference: &[f64],
    peak: f64,
    mask: Option<&[bool]>,
) -> Result<f64, MetricError> {
    if !(peak > 0.0 && peak.is_finite()) {
        return Err(MetricError::BadPeak { peak });
    }
    let (rmse, _) = error_stats(test, reference, mask)?;
    let db = 20.0 * (peak / rmse).log10();
    Ok(if db.is_finite() {
        db.min(PSNR_CAP_DB)
    } else {
        PSNR_CAP_DB
    })
}

/// Channels of an RGB image as f64, and the mask repeated per channel.
fn channels(img: &RgbImage) -> Vec<f64> {
    img.data
        .iter()
        .flat_map(|p| p.to_array().map(f64::from))
        .collect()
}

fn channel_mask(
    test: &RgbImage,
    reference: &RgbImage,
    mask: Option<&Image<bool>>,
) -> Result<Option<Vec<bool>>, MetricError> {
    let Some(m) = mask else { return Ok(None) };
    if !m.same_size(test) || !test.same_size(reference) {
        return Err(MetricError::SizeMismatch {
            test: test.data.len(),
            reference: reference.data.len(),
            mask: m.data.len(),
        });
    }
    Ok(Some(m.data.iter().flat_map(|&v| [v; 3]).collect()))
}

fn check_sizes(test: &RgbImage, reference: &RgbImage) -> Result<(), MetricError> {
    if test.same_size(reference) {
        Ok(())
    } else {
        Err(MetricError::SizeMismatch {
            test: test.data.len(),
            reference: reference.data.len(),
            mask: test.data.len(),
        })
    }
}

/// Relative RMSE of two linear RGB images over the pixels where `mask` is
/// true (all when `None`); every channel of a valid pixel counts.
pub fn relative_rmse(
    test: &RgbImage,
    reference: &RgbImage,
    mask: Option<&Image<bool>>,
) -> Result<f64, MetricError> {
    check_sizes(test, reference)?;
    let m = channel_mask(test, reference, mask)?;
    relative_rmse_values(&channels(test), &channels(reference), m.as_deref())
}

/// RMSE of `test` against `reference` and the mean of `reference`, over
/// the channels of the pixels where `mask` is true (all when `None`): the
/// two halves of [`relative_rmse`], for a difference whose reference is
/// not the image it is relative to.
pub fn rmse_and_reference_mean(
    test: &RgbImage,
    reference: &RgbImage,
    mask: Option<&Image<bool>>,
) -> Result<(f64, f64), MetricError> {
    check_sizes(test, reference)?;
    let m = channel_mask(test, reference, mask)?;
    error_stats(&channels(test), &channels(reference), m.as_deref())
}

/// PSNR of two linear RGB images, in dB, for signal peak `peak`.
pub fn psnr(
    test: &RgbImage,
    reference: &RgbImage,
    peak: f64,
    mask: Option<&Image<bool>>,
) -> Result<f64, MetricError> {
    check_sizes(test, reference)?;
    let m = channel_mask(test, reference, mask)?;
    psnr_values(&channels(test), &channels(reference), peak, m.as_deref())
}

/// Mean CIEDE2000 difference of two linear RGB images (sRGB primaries, D65,
/// `(1, 1, 1)` = reference white) over the valid pixels.
pub fn mean_delta_e_2000(
    test: &RgbImage,
    reference: &RgbImage,
    mask: Option<&Image<bool>>,
) -> Result<f64, MetricError> {
    check_sizes(test, reference)?;
    if let Some(m) = mask
        && !m.same_size(test)
    {
        return Err(MetricError::SizeMismatch {
            test: test.data.len(),
            reference: reference.data.len(),
            mask: m.data.len(),
        });
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (i, (t, r)) in test.data.iter().zip(&reference.data).enumerate() {
        if mask.is_some_and(|m| !m.data[i]) {
            continue;
        }
        if !(t.is_finite() && r.is_finite()) {
            return Err(MetricError::NonFinite { index: i });
        }
        let lab = |c: &Vec3| linear_srgb_to_lab(c.as_dvec3());
        sum += delta_e_2000(lab(t), lab(r)).map_err(|_| MetricError::NonFinite { index: i })?;
        n += 1;
    }
    if n == 0 {
        return Err(MetricError::NoValidValues);
    }
    Ok(sum / n as f64)
}

/// The `p`-th percentile (`0..=100`) of the finite `values` by nearest
/// rank: the smallest value with at least `p` % of the values at or below
/// it, so the median of `[1, 2, 3, 4]` is 2. It is always an observed
/// value (as latency monitors and hdrhistogram report). Non-finite values
/// are left out; `None` when none is finite. The one definition of a
/// quantile in Showcase: medians, p95 and p99 everywhere use it.
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * v.len() as f64).ceil().max(1.0) as usize;
    Some(v[rank.min(v.len()) - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 50.0), Some(50.0));
        assert_eq!(percentile(&v, 99.0), Some(99.0));
        assert_eq!(percentile(&v, 100.0), Some(100.0));
        assert_eq!(percentile(&[3.0], 99.0), Some(3.0));
        assert_eq!(percentile(&[], 50.0), None);
        assert_eq!(percentile(&[f64::NAN, 2.0], 50.0), Some(2.0));
    }

    #[test]
    fn relative_rmse_by_hand() {
        // rmse = sqrt((1 + 0 + 4 + 0) / 4) = sqrt(5)/2, mean = 10/4.
        let e = relative_rmse_values(&[2.0, 2.0, 5.0, 4.0], &[1.0, 2.0, 3.0, 4.0], None).unwrap();
        assert!((e - 5f64.sqrt() / 2.0 / 2.5).abs() < 1e-15);
        // Masking out the differing values leaves zero error.
        let m = [false, true, false, true];
        assert_eq!(
            relative_rmse_values(&[2.0, 2.0, 5.0, 4.0], &[1.0, 2.0, 3.0, 4.0], Some(&m)),
            Ok(0.0)
        );
    }

    #[test]
    fn errors_are_reported_not_nan() {
        assert_eq!(
            relative_rmse_values(&[], &[], None),
            Err(MetricError::NoValidValues)
        );
        assert_eq!(
            relative_rmse_values(&[1.0], &[0.0], None),
            Err(MetricError::NonPositiveReferenceMean { mean: 0.0 })
        );
        assert_eq!(
            relative_rmse_values(&[f64::NAN], &[1.0], None),
            Err(MetricError::NonFinite { index: 0 })
        );
        // A non-finite value under a false mask is ignored.
        assert_eq!(
            relative_rmse_values(&[f64::NAN, 1.0], &[1.0, 1.0], Some(&[false, true])),
            Ok(0.0)
        );
        assert!(matches!(
            relative_rmse_values(&[1.0], &[1.0, 2.0], None),
            Err(MetricError::SizeMismatch { .. })
        ));
        assert_eq!(
            psnr_values(&[1.0], &[1.0], 0.0, None),
            Err(MetricError::BadPeak { peak: 0.0 })
        );
    }

    #[test]
    fn psnr_by_hand_and_capped() {
        // mse = 0.01 with peak 1: 20 dB.
        let db = psnr_values(&[0.1, 0.5], &[0.0, 0.6], 1.0, None).unwrap();
        assert!((db - 20.0).abs() < 1e-12);
        assert_eq!(psnr_values(&[0.3], &[0.3], 1.0, None), Ok(PSNR_CAP_DB));
    }

    #[test]
    fn image_metrics_use_every_channel_of_valid_pixels() {
        let reference = Image::from_fn(2, 1, |x, _| Vec3::splat(1.0 + x as f32));
        let mut test = reference.clone();
        test.data[1].x += 3.0;
        let mask = Image::from_fn(2, 1, |x, _| x == 0);
        assert_eq!(relative_rmse(&test, &reference, Some(&mask)), Ok(0.0));
        // Unmasked: rmse = sqrt(9/6), mean = 1.5.
        let e = relative_rmse(&test, &reference, None).unwrap();
        assert!((e - (1.5f64).sqrt() / 1.5).abs() < 1e-12);
        assert!(psnr(&test, &reference, 1.0, Some(&mask)).unwrap() == PSNR_CAP_DB);
        assert_eq!(mean_delta_e_2000(&reference, &reference, None), Ok(0.0));
        let small = Image::new(1, 1, Vec3::ONE);
        assert!(matches!(
            relative_rmse(&small, &reference, None),
            Err(MetricError::SizeMismatch { .. })
        ));
    }

    #[test]
    fn delta_e_of_a_grey_step_matches_lightness_difference() {
        // For neutral greys dE00 reduces to dL / S_L.
        let a = Image::new(1, 1, Vec3::splat(0.18));
        let b = Image::new(1, 1, Vec3::splat(0.2));
        let (la, lb) = (
            linear_srgb_to_lab(a.data[0].as_dvec3()).l,
            linear_srgb_to_lab(b.data[0].as_dvec3()).l,
        );
        let lbar = 0.5 * (la + lb) - 50.0;
        let sl = 1.0 + 0.015 * lbar * lbar / (20.0 + lbar * lbar).sqrt();
        let e = mean_delta_e_2000(&a, &b, None).unwrap();
        assert!((e - (lb - la) / sl).abs() < 1e-4, "{e}");
    }

    proptest::proptest! {
        /// Any input, NaN and infinities included, gives a finite value or
        /// an error.
        #[test]
        fn metrics_are_finite_or_errors(
            values in proptest::collection::vec(
                proptest::prop_oneof![
                    -1e30f32..1e30f32,
                    proptest::strategy::Just(f32::NAN),
                    proptest::strategy::Just(f32::INFINITY),
                    proptest::strategy::Just(0.0f32),
                ],
                0..24,
            ),
            mask_bits in proptest::num::u32::ANY,
            peak in -1.0f64..1e3,
        ) {
            let n = values.len() / 6;
            let img = |off: usize| Image::from_fn(n as u32, 1, |x, _| {
                let i = off + 3 * x as usize;
                Vec3::new(values[i], values[i + 1], values[i + 2])
            });
            let (a, b) = (img(0), img(3 * n));
            let mask = Image::from_fn(n as u32, 1, |x, _| mask_bits >> x & 1 == 1);
            for m in [None, Some(&mask)] {
                let results = [relative_rmse(&a, &b, m), psnr(&a, &b, peak, m), mean_delta_e_2000(&a, &b, m)];
                for v in results.into_iter().flatten() {
                    proptest::prop_assert!(v.is_finite());
                }
            }
        }
    }
}
