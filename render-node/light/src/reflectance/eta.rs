//! Estimating the projector's intensity eta and black level (paper
//! section 3.5) with Brent's method.
//!
//! A reference surface of known reflectance `rho` is captured at several
//! projector pixel values `v_j`. Its re-rendered radiance map is
//! `I_radv_j = rho * G * (eta * v_j^gamma + black)`, with `G` the intensity
//! image for a unit light (`D_l = 1`); the fit minimises the mean-square
//! difference to the captured `I_rad_j` over the reference pixels: Brent
//! over eta, with Brent over the black level inside. Two or more distinct
//! levels separate eta from the black level; a reference of known
//! reflectance fixes the scale (with reflectance and eta both unknown, only
//! their product is observable).

use super::{ReflectanceError, brent, check_size};
use crate::{Image, RgbImage};

/// One captured level of the calibration.
#[derive(Clone, Debug)]
pub struct CalibrationLevel {
    /// The projector response at the shown value, `v^gamma`.
    pub response: f64,
    /// The captured radiance map (`pi * L`).
    pub i_rad: RgbImage,
}

/// The fitted projector photometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectorFit {
    /// Peak intensity eta (W/sr).
    pub eta: f64,
    /// Black level (W/sr).
    pub black_level: f64,
    /// Mean-square difference at the fit.
    pub mse: f64,
}

/// Fit eta and the black level (module docs). `unit_intensity` is `G`,
/// `reflectance` the known reflectance, `mask` the reference pixels, and
/// `eta_guess` a positive starting guess.
pub fn estimate_projector(
    levels: &[CalibrationLevel],
    unit_intensity: &RgbImage,
    reflectance: &RgbImage,
    mask: &Image<bool>,
    eta_guess: f64,
) -> Result<ProjectorFit, ReflectanceError> {
    if !(eta_guess.is_finite() && eta_guess > 0.0) {
        return Err(ReflectanceError::BadParameter {
            what: "eta_guess",
            value: eta_guess,
        });
    }
    check_size("reflectance", reflectance, unit_intensity)?;
    check_size("mask", mask, unit_intensity)?;
    // Sufficient statistics per level: sum I^2, sum I*M, sum M^2, count.
    let mut stats = Vec::new();
    for level in levels {
        check_size("i_rad", &level.i_rad, unit_intensity)?;
        if !level.response.is_finite() {
            return Err(ReflectanceError::BadParameter {
                what: "response",
                value: level.response,
            });
        }
        let (mut ii, mut im, mut mm, mut n) = (0.0, 0.0, 0.0, 0.0);
        for (k, valid) in mask.data.iter().enumerate() {
            if !valid {
                continue;
            }
            let m = reflectance.data[k].as_dvec3() * unit_intensity.data[k].as_dvec3();
            let i = level.i_rad.data[k].as_dvec3();
            if !(m.is_finite() && i.is_finite()) {
                continue;
            }
            ii += i.length_squared();
            im += i.dot(m);
            mm += m.length_squared();
            n += 3.0;
        }
        if n > 0.0 {
            stats.push((level.response, ii, im, mm, n));
        }
    }
    let total: f64 = stats.iter().map(|s| s.4).sum();
    if !(total > 0.0) || stats.iter().all(|s| !(s.3 > 0.0)) {
        return Err(ReflectanceError::NoValidPixels("projector fit"));
    }
    let mse = |eta: f64, black: f64| {
        stats
            .iter()
            .map(|&(r, ii, im, mm, _)| {
                let s = eta * r + black;
                ii - 2.0 * s * im + s * s * mm
            })
            .sum::<f64>()
            / total
    };
    let best_black = |eta: f64| -> Result<(f64, f64), ReflectanceError> {
        Ok(brent::minimize(
            |b| mse(eta, b),
            0.0,
            0.05 * eta_guess,
            1e-10,
        )?)
    };
    let (eta, _) = brent::minimize(
        |eta| best_black(eta).map_or(f64::INFINITY, |(_, f)| f),
        eta_guess,
        1.2 * eta_guess,
        1e-10,
    )?;
    let (black_level, mse) = best_black(eta)?;
    if !(eta.is_finite() && black_level.is_finite() && mse.is_finite()) {
        return Err(ReflectanceError::NoValidPixels(
            "projector fit (no finite optimum)",
        ));
    }
    Ok(ProjectorFit {
        eta,
        black_level,
        mse: mse.max(0.0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn recovers_eta_and_black_level_from_two_levels() {
        let g = Image::from_fn(8, 8, |x, y| Vec3::splat(0.5 + 0.05 * (x + y) as f32));
        let rho = Image::from_fn(8, 8, |x, _| Vec3::new(0.8, 0.5, 0.2 + 0.01 * x as f32));
        let mask = Image::from_fn(8, 8, |x, _| x != 3);
        let (eta, black) = (3.7, 0.11);
        let levels: Vec<CalibrationLevel> = [1.0, 0.2176]
            .iter()
            .map(|&r| CalibrationLevel {
                response: r,
                i_rad: Image::from_fn(8, 8, |x, y| {
                    let k = (y * 8 + x) as usize;
                    rho.data[k] * g.data[k] * (eta * r + black) as f32
                }),
            })
            .collect();
        let fit = estimate_projector(&levels, &g, &rho, &mask, 1.0).unwrap();
        assert!((fit.eta - eta).abs() < 1e-4 * eta, "{fit:?}");
        assert!((fit.black_level - black).abs() < 1e-4, "{fit:?}");
        let none = Image::new(8, 8, false);
        assert_eq!(
            estimate_projector(&levels, &g, &rho, &none, 1.0),
            Err(ReflectanceError::NoValidPixels("projector fit"))
        );
        assert!(estimate_projector(&levels, &g, &rho, &mask, f64::NAN).is_err());
    }
}
