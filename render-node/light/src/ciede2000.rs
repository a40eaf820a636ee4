//! CIEDE2000 colour difference (Sharma, Wu and Dalal 2005) and the colour
//! conversions it needs: linear RGB with sRGB primaries and a D65 white to
//! CIE XYZ to CIELAB. Linear RGB `(1, 1, 1)` is the reference white
//! (`L = 100`); scale radiance images into that range before comparing.

use super::metrics::MetricError;
use glam::{DMat3, DVec3};

/// A CIELAB colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lab {
    /// Lightness L*, 0 to 100 for colours up to the white.
    pub l: f64,
    /// Green-red axis a*.
    pub a: f64,
    /// Blue-yellow axis b*.
    pub b: f64,
}

impl Lab {
    /// A Lab colour from its three coordinates.
    pub const fn new(l: f64, a: f64, b: f64) -> Self {
        Self { l, a, b }
    }
}

/// Linear sRGB (D65) to XYZ, IEC 61966-2-1 (columns are R, G, B).
const SRGB_TO_XYZ: DMat3 = DMat3::from_cols(
    DVec3::new(0.4124564, 0.2126729, 0.0193339),
    DVec3::new(0.3575761, 0.7151522, 0.1191920),
    DVec3::new(0.1804375, 0.0721750, 0.9503041),
);

/// Linear RGB (sRGB primaries, D65 white) to CIE XYZ; RGB white has `Y = 1`.
pub fn linear_srgb_to_xyz(rgb: DVec3) -> DVec3 {
    SRGB_TO_XYZ * rgb
}

/// CIE XYZ to CIELAB relative to the D65 white of [`linear_srgb_to_xyz`]
/// (the XYZ of RGB `(1, 1, 1)`, so RGB greys have `a = b = 0`).
pub fn xyz_to_lab(xyz: DVec3) -> Lab {
    let white = SRGB_TO_XYZ * DVec3::ONE;
    let f = |t: f64| {
        const D: f64 = 6.0 / 29.0;
        if t > D * D * D {
            t.cbrt()
        } else {
            t / (3.0 * D * D) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (f(xyz.x / white.x), f(xyz.y / white.y), f(xyz.z / white.z));
    Lab::new(116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz))
}

/// Linear RGB (sRGB primaries, D65) straight to CIELAB.
pub fn linear_srgb_to_lab(rgb: DVec3) -> Lab {
    xyz_to_lab(linear_srgb_to_xyz(rgb))
}

/// The CIEDE2000 difference of two Lab colours with `kL = kC = kH = 1`.
pub fn delta_e_2000(c1: Lab, c2: Lab) -> Result<f64, MetricError> {
    if ![c1.l, c1.a, c1.b, c2.l, c2.a, c2.b]
        .iter()
        .all(|v| v.is_finite())
    {
        return Err(MetricError::NonFinite { index: 0 });
    }
    let pow7 = |x: f64| x.powi(7);
    let c_bar = 0.5 * (c1.a.hypot(c1.b) + c2.a.hypot(c2.b));
    let g = 0.5 * (1.0 - (pow7(c_bar) / (pow7(c_bar) + pow7(25.0))).sqrt());
    let (a1, a2) = ((1.0 + g) * c1.a, (1.0 + g) * c2.a);
    let (cp1, cp2) = (a1.hypot(c1.b), a2.hypot(c2.b));
    let hue = |b: f64, a: f64| {
        if a == 0.0 && b == 0.0 {
            0.0
        } else {
            b.atan2(a).to_degrees().rem_euclid(360.0)
        }
    };
    let (h1, h2) = (hue(c1.b, a1), hue(c2.b, a2));
    let dl = c2.l - c1.l;
    let dc = cp2 - cp1;
    let chroma_product = cp1 * cp2;
    let dh = if chroma_product == 0.0 {
        0.0
    } else {
        let d = h2 - h1;
        if d > 180.0 {
            d - 360.0
        } else if d < -180.0 {
            d + 360.0
        } else {
            d
        }
    };
    let dh_big = 2.0 * chroma_product.sqrt() * (0.5 * dh).to_radians().sin();
    let l_bar = 0.5 * (c1.l + c2.l);
    let cp_bar = 0.5 * (cp1 + cp2);
    let h_bar = if chroma_product == 0.0 {
        h1 + h2
    } else if (h1 - h2).abs() <= 180.0 {
        0.5 * (h1 + h2)
    } else if h1 + h2 < 360.0 {
        0.5 * (h1 + h2 + 360.0)
    } else {
        0.5 * (h1 + h2 - 360.0)
    };
    let cosd = |deg: f64| deg.to_radians().cos();
    let t =
        1.0 - 0.17 * cosd(h_bar - 30.0) + 0.24 * cosd(2.0 * h_bar) + 0.32 * cosd(3.0 * h_bar + 6.0)
            - 0.20 * cosd(4.0 * h_bar - 63.0);
    let d_theta = 30.0 * (-((h_bar - 275.0) / 25.0).powi(2)).exp();
    let rc = 2.0 * (pow7(cp_bar) / (pow7(cp_bar) + pow7(25.0))).sqrt();
    let l50 = (l_bar - 50.0).powi(2);
    let sl = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    let sc = 1.0 + 0.045 * cp_bar;
    let sh = 1.0 + 0.015 * cp_bar * t;
    let rt = -(2.0 * d_theta).to_radians().sin() * rc;
    let (tl, tc, th) = (dl / sl, dc / sc, dh_big / sh);
    let e = (tl * tl + tc * tc + th * th + rt * tc * th).max(0.0).sqrt();
    if e.is_finite() {
        Ok(e)
    } else {
        Err(MetricError::NonFinite { index: 0 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sharma, Wu and Dalal (2005), "The CIEDE2000 color-difference formula:
    /// implementation notes, supplementary test data, and mathematical
    /// observations", Table 1: all 34 pairs with their published dE00.
    const SHARMA: [([f64; 3], [f64; 3], f64); 34] = [
        (
            [50.0000, 2.6772, -79.7751],
            [50.0000, 0.0000, -82.7485],
            2.0425,
        ),
        (
            [50.0000, 3.1571, -77.2803],
            [50.0000, 0.0000, -82.7485],
            2.8615,
        ),
        (
            [50.0000, 2.8361, -74.0200],
            [50.0000, 0.0000, -82.7485],
            3.4412,
        ),
        (
            [50.0000, -1.3802, -84.2814],
            [50.0000, 0.0000, -82.7485],
            1.0000,
        ),
        (
            [50.0000, -1.1848, -84.8006],
            [50.0000, 0.0000, -82.7485],
            1.0000,
        ),
        (
            [50.0000, -0.9009, -85.5211],
            [50.0000, 0.0000, -82.7485],
            1.0000,
        ),
        (
            [50.0000, 0.0000, 0.0000],
            [50.0000, -1.0000, 2.0000],
            2.3669,
        ),
        (
            [50.0000, -1.0000, 2.0000],
            [50.0000, 0.0000, 0.0000],
            2.3669,
        ),
        (
            [50.0000, 2.4900, -0.0010],
            [50.0000, -2.4900, 0.0009],
            7.1792,
        ),
        (
            [50.0000, 2.4900, -0.0010],
            [50.0000, -2.4900, 0.0010],
            7.1792,
        ),
        (
            [50.0000, 2.4900, -0.0010],
            [50.0000, -2.4900, 0.0011],
            7.2195,
        ),
        (
            [50.0000, 2.4900, -0.0010],
            [50.0000, -2.4900, 0.0012],
            7.2195,
        ),
        (
            [50.0000, -0.0010, 2.4900],
            [50.0000, 0.0009, -2.4900],
            4.8045,
        ),
        (
            [50.0000, -0.0010, 2.4900],
            [50.0000, 0.0010, -2.4900],
            4.8045,
        ),
        (
            [50.0000, -0.0010, 2.4900],
            [50.0000, 0.0011, -2.4900],
            4.7461,
        ),
        (
            [50.0000, 2.5000, 0.0000],
            [50.0000, 0.0000, -2.5000],
            4.3065,
        ),
        (
            [50.0000, 2.5000, 0.0000],
            [73.0000, 25.0000, -18.0000],
            27.1492,
        ),
        (
            [50.0000, 2.5000, 0.0000],
            [61.0000, -5.0000, 29.0000],
            22.8977,
        ),
        (
            [50.0000, 2.5000, 0.0000],
            [56.0000, -27.0000, -3.0000],
            31.9030,
        ),
        (
            [50.0000, 2.5000, 0.0000],
            [58.0000, 24.0000, 15.0000],
            19.4535,
        ),
        ([50.0000, 2.5000, 0.0000], [50.0000, 3.1736, 0.5854], 1.0000),
        ([50.0000, 2.5000, 0.0000], [50.0000, 3.2972, 0.0000], 1.0000),
        ([50.0000, 2.5000, 0.0000], [50.0000, 1.8634, 0.5757], 1.0000),
        ([50.0000, 2.5000, 0.0000], [50.0000, 3.2592, 0.3350], 1.0000),
        (
            [60.2574, -34.0099, 36.2677],
            [60.4626, -34.1751, 39.4387],
            1.2644,
        ),
        (
            [63.0109, -31.0961, -5.8663],
            [62.8187, -29.7946, -4.0864],
            1.2630,
        ),
        (
            [61.2901, 3.7196, -5.3901],
            [61.4292, 2.2480, -4.9620],
            1.8731,
        ),
        (
            [35.0831, -44.1164, 3.7933],
            [35.0232, -40.0716, 1.5901],
            1.8645,
        ),
        (
            [22.7233, 20.0904, -46.6940],
            [23.0331, 14.9730, -42.5619],
            2.0373,
        ),
        (
            [36.4612, 47.8580, 18.3852],
            [36.2715, 50.5065, 21.2231],
            1.4146,
        ),
        (
            [90.8027, -2.0831, 1.4410],
            [91.1528, -1.6435, 0.0447],
            1.4441,
        ),
        (
            [90.9257, -0.5406, -0.9208],
            [88.6381, -0.8985, -0.7239],
            1.5381,
        ),
        (
            [6.7747, -0.2908, -2.4247],
            [5.8714, -0.0985, -2.2286],
            0.6377,
        ),
        (
            [2.0776, 0.0795, -1.1350],
            [0.9033, -0.0636, -0.5514],
            0.9082,
        ),
    ];

    #[test]
    fn sharma_test_pairs() {
        for (i, (p, q, expected)) in SHARMA.iter().enumerate() {
            let (a, b) = (Lab::new(p[0], p[1], p[2]), Lab::new(q[0], q[1], q[2]));
            let e = delta_e_2000(a, b).unwrap();
            assert!(
                (e - expected).abs() < 5e-5,
                "pair {}: {e} != {expected}",
                i + 1
            );
            // The formula is symmetric.
            assert!(
                (delta_e_2000(b, a).unwrap() - e).abs() < 1e-12,
                "pair {}",
                i + 1
            );
        }
    }

    #[test]
    fn known_lab_values() {
        let white = linear_srgb_to_lab(DVec3::ONE);
        assert!((white.l - 100.0).abs() < 1e-9 && white.a.abs() < 1e-9 && white.b.abs() < 1e-9);
        assert_eq!(linear_srgb_to_lab(DVec3::ZERO), Lab::new(0.0, 0.0, 0.0));
        // Pure sRGB red is about (53.24, 80.09, 67.20).
        let red = linear_srgb_to_lab(DVec3::X);
        assert!(
            (red.l - 53.24).abs() < 0.01
                && (red.a - 80.09).abs() < 0.02
                && (red.b - 67.20).abs() < 0.02
        );
        // Linear 0.18 grey is L* = 49.5.
        assert!((linear_srgb_to_lab(DVec3::splat(0.18)).l - 49.50).abs() < 0.01);
    }

    #[test]
    fn non_finite_is_an_error() {
        let ok = Lab::new(50.0, 0.0, 0.0);
        assert!(delta_e_2000(ok, Lab::new(f64::NAN, 0.0, 0.0)).is_err());
        assert_eq!(delta_e_2000(ok, ok), Ok(0.0));
    }
}
