//! Extracting reflectance, `I_ref = I_rad / E` (equation 3.2, with `E`
//! the direct irradiance `I_int` or, corrected, `I_int + E_indirect`), and
//! the blend weight of each extracted pixel.
//!
//! # Floor and cuts (DESIGN section 8)
//! A pixel is valid only when it sees a surface the light reaches, its
//! angle `phi` to the camera is at most `phi_max` (default 60 degrees,
//! section 3.5), and every channel of `E` exceeds the floor
//! `floor_relative * max(I_int)` (default `1e-3`: below it, 8-bit camera
//! noise would be amplified a thousandfold). Everything else is 0.

use super::{ReflectanceError, check_size};
use crate::finite::finite_or_zero;
use crate::{Image, IntensityImage, RgbImage, SurfaceSample};
use glam::{DVec3, Vec3};

/// Parameters of the extraction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExtractParams {
    /// Floor on the irradiance, relative to the brightest `I_int` pixel.
    pub floor_relative: f64,
    /// The grazing-angle cut phi_max in degrees.
    pub phi_max_deg: f64,
}

impl Default for ExtractParams {
    fn default() -> Self {
        Self {
            floor_relative: 1e-3,
            phi_max_deg: 60.0,
        }
    }
}

/// The absolute floor: `floor_relative` times the largest channel of
/// `I_int` (0 for an all-dark or non-finite image).
pub fn intensity_floor(intensity: &RgbImage, floor_relative: f64) -> f64 {
    let max = intensity
        .data
        .iter()
        .map(|v| v.max_element() as f64)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let f = max * floor_relative;
    finite_or_zero(f).max(0.0)
}

/// `I_ref = I_rad / irradiance` where valid (module docs), 0 elsewhere, and
/// the validity mask. `intensity` supplies the surfaces, `lit` flags and
/// the floor's reference; `irradiance` is `intensity.intensity` for the
/// paper's method or that plus the indirect irradiance for the corrected
/// one.
pub fn extract_reflectance(
    i_rad: &RgbImage,
    irradiance: &RgbImage,
    intensity: &IntensityImage,
    params: &ExtractParams,
) -> Result<(RgbImage, Image<bool>), ReflectanceError> {
    check_size("i_rad", i_rad, &intensity.intensity)?;
    check_size("irradiance", irradiance, &intensity.intensity)?;
    let floor = intensity_floor(&intensity.intensity, params.floor_relative).max(f64::MIN_POSITIVE);
    let phi_max = params.phi_max_deg.to_radians();
    let mut out = Image::new(i_rad.width, i_rad.height, Vec3::ZERO);
    let mut valid = Image::new(i_rad.width, i_rad.height, false);
    for i in 0..out.data.len() {
        let Some(s) = intensity.surface.data[i] else {
            continue;
        };
        let e = irradiance.data[i].as_dvec3();
        let direct = intensity.intensity.data[i].as_dvec3();
        let measured = e.is_finite() && direct.is_finite();
        if !(measured
            && s.lit
            && s.phi <= phi_max
            && e.min_element() > floor
            && direct.min_element() > floor)
        {
            continue;
        }
        // Finite in f64 is not enough: a huge radiance over a tiny
        // irradiance overflows the f32 map.
        let r = (i_rad.data[i].as_dvec3() / e).max(DVec3::ZERO).as_vec3();
        if r.is_finite() {
            out.data[i] = r;
            valid.data[i] = true;
        }
    }
    Ok((out, valid))
}

/// Blend weight (alpha) of each extracted pixel for merging maps: the
/// product of a grazing-angle ramp `(cos phi - cos phi_max) / (1 - cos
/// phi_max)` and a border ramp `min(1, d / border_px)` with `d` the
/// chamfer distance (pixels) to the nearest invalid pixel, so the weight
/// falls to 0 at every blank border and at phi_max, and overlapping maps
/// blend without seams. In `[0, 1]`; 0 where invalid.
pub fn blend_weights(
    valid: &Image<bool>,
    surface: &Image<Option<SurfaceSample>>,
    phi_max_deg: f64,
    border_px: f64,
) -> Result<Image<f32>, ReflectanceError> {
    check_size("surface", surface, valid)?;
    let (w, h) = (valid.width as usize, valid.height as usize);
    let big = 1e9f64;
    let mut d: Vec<f64> = valid
        .data
        .iter()
        .map(|v| if *v { big } else { 0.0 })
        .collect();
    let (a, b) = (1.0, std::f64::consts::SQRT_2);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            // Pixels outside the image count as invalid (distance 1).
            let mut m = d[i].min(if x == 0 || y == 0 { 1.0 } else { big });
            if x > 0 {
                m = m.min(d[i - 1] + a);
            }
            if y > 0 {
                m = m.min(d[i - w] + a);
                if x > 0 {
                    m = m.min(d[i - w - 1] + b);
                }
                if x + 1 < w {
                    m = m.min(d[i - w + 1] + b);
                }
            }
            d[i] = m;
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let i = y * w + x;
            let mut m = d[i].min(if x + 1 == w || y + 1 == h { 1.0 } else { big });
            if x + 1 < w {
                m = m.min(d[i + 1] + a);
            }
            if y + 1 < h {
                m = m.min(d[i + w] + a);
                if x + 1 < w {
                    m = m.min(d[i + w + 1] + b);
                }
                if x > 0 {
                    m = m.min(d[i + w - 1] + b);
                }
            }
            d[i] = m;
        }
    }
    let cos_max = phi_max_deg.to_radians().cos();
    let border = if border_px.is_finite() && border_px > 0.0 {
        border_px
    } else {
        1.0
    };
    let data = (0..w * h)
        .map(|i| {
            let (Some(s), true) = (surface.data[i], valid.data[i]) else {
                return 0.0;
            };
            let ramp = ((s.phi.cos() - cos_max) / (1.0 - cos_max).max(1e-9)).clamp(0.0, 1.0);
            let edge = (d[i] / border).clamp(0.0, 1.0);
            let v = (ramp * edge) as f32;
            finite_or_zero(v)
        })
        .collect();
    Ok(Image {
        width: valid.width,
        height: valid.height,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_pixel(rad: Vec3, irradiance: Vec3) -> (RgbImage, Image<bool>) {
        let sample = SurfaceSample {
            object: 0,
            triangle: 0,
            point: DVec3::Z,
            normal: DVec3::Z,
            phi: 0.0,
            uv: None,
            lit: true,
        };
        let intensity = IntensityImage {
            intensity: Image::new(1, 1, irradiance),
            surface: Image::new(1, 1, Some(sample)),
        };
        let irr = Image::new(1, 1, irradiance);
        extract_reflectance(
            &Image::new(1, 1, rad),
            &irr,
            &intensity,
            &ExtractParams::default(),
        )
        .unwrap()
    }

    #[test]
    fn a_ratio_past_f32_range_or_an_infinite_irradiance_is_invalid_not_infinite() {
        // Found by the capture proptest: 1.9e35 / 3e-7 is finite in f64.
        let (rho, valid) = one_pixel(Vec3::new(0.0, 1.86e35, 0.0), Vec3::new(1e-8, 3e-7, 1e-7));
        assert!(
            !valid.data[0] && rho.data[0] == Vec3::ZERO,
            "{:?}",
            rho.data[0]
        );
        let (rho, valid) = one_pixel(Vec3::splat(0.5), Vec3::new(1.0, 1.0, f32::INFINITY));
        assert!(
            !valid.data[0] && rho.data[0] == Vec3::ZERO,
            "{:?}",
            rho.data[0]
        );
        // An ordinary pixel still extracts.
        let (rho, valid) = one_pixel(Vec3::new(0.25, 0.5, 0.1), Vec3::new(0.5, 1.0, 0.5));
        assert!(valid.data[0]);
        assert!((rho.data[0] - Vec3::new(0.5, 0.5, 0.2)).abs().max_element() < 1e-6);
    }
}
