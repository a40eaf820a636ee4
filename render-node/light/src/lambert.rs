//! Lambert's closed-form irradiance at a point from a uniformly emitting
//! planar polygon (the point-to-polygon form factor), the analytic ground
//! truth for the simulated showcase and the radiosity solver.
//!
//! With `r_i = p_i - x` for the polygon's vertices `p_i`, `Theta_i` the
//! angle between `r_i` and `r_{i+1}` and `Gamma_i` the unit normal of
//! `r_i x r_{i+1}`, the form factor from a differential area at `x` with
//! normal `n` is `F = -1/(2 pi) * sum_i Theta_i (n . Gamma_i)` for vertices
//! wound counter-clockwise seen from the emitting side, and the irradiance
//! is `E = pi * L * F`. The polygon is first clipped to the half-space
//! above the receiver's tangent plane, so parts below the horizon add
//! nothing, as they must.

use crate::finite::finite_or_zero;
use glam::DVec3;

/// Why an irradiance could not be computed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LambertError {
    /// A coordinate, the normal or the radiance is NaN or infinite.
    #[error("non-finite input to the polygon irradiance: {what}")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// The receiver normal has zero length.
    #[error("receiver normal has zero length")]
    ZeroNormal,
}

/// Irradiance (W/m^2) at `point` with surface normal `normal` from the
/// planar polygon `polygon` emitting radiance `radiance` (W/m^2/sr) from its
/// front side only (vertices counter-clockwise seen from the front). No
/// occlusion. A point behind the emitter or a degenerate polygon gets 0.
pub fn polygon_irradiance(
    point: DVec3,
    normal: DVec3,
    polygon: &[DVec3],
    radiance: f64,
) -> Result<f64, LambertError> {
    if !radiance.is_finite() {
        return Err(LambertError::NonFinite { what: "radiance" });
    }
    Ok(std::f64::consts::PI * radiance * form_factor_point_polygon(point, normal, polygon)?)
}

/// The form factor from a differential area at `point` (normal `normal`) to
/// the front side of planar polygon `polygon`, in `[0, 1]`. See
/// [`polygon_irradiance`].
pub fn form_factor_point_polygon(
    point: DVec3,
    normal: DVec3,
    polygon: &[DVec3],
) -> Result<f64, LambertError> {
    if !point.is_finite() {
        return Err(LambertError::NonFinite { what: "point" });
    }
    if !normal.is_finite() {
        return Err(LambertError::NonFinite { what: "normal" });
    }
    if polygon.iter().any(|p| !p.is_finite()) {
        return Err(LambertError::NonFinite { what: "polygon" });
    }
    let n = normal.normalize_or_zero();
    if n == DVec3::ZERO {
        return Err(LambertError::ZeroNormal);
    }
    if polygon.len() < 3 {
        return Ok(0.0);
    }
    let emitter_normal = newell_normal(polygon);
    let centroid = polygon.iter().sum::<DVec3>() / polygon.len() as f64;
    if !(emitter_normal.dot(point - centroid) > 0.0) {
        return Ok(0.0);
    }
    // The polygon relative to the point, clipped to the point's upper
    // half-space (at most two corners per edge), on the stack for the
    // triangles and quads of the radiosity mesh.
    let m = polygon.len();
    let f = if m <= STACK_CORNERS {
        let mut buffer = [DVec3::ZERO; 2 * STACK_CORNERS];
        relative_form_factor(polygon, point, n, &mut buffer[..2 * m])
    } else {
        relative_form_factor(polygon, point, n, &mut vec![DVec3::ZERO; 2 * m])
    };
    Ok(finite_or_zero(f).clamp(0.0, 1.0))
}

/// Polygons with at most this many corners (the mesh's triangles, quads)
/// are clipped on the stack.
const STACK_CORNERS: usize = 4;

/// The form factor from `point` (unit normal `n`) to `polygon`, unclamped;
/// `buffer` holds at least two corners per polygon corner.
fn relative_form_factor(polygon: &[DVec3], point: DVec3, n: DVec3, buffer: &mut [DVec3]) -> f64 {
    let m = clip_above(polygon, point, n, buffer);
    if m < 3 {
        return 0.0;
    }
    let clipped = &buffer[..m];
    let mut sum = 0.0;
    for i in 0..m {
        let (a, b) = (clipped[i], clipped[(i + 1) % m]);
        let cross = a.cross(b);
        let len = cross.length();
        if !(len > 0.0) {
            continue;
        }
        let theta = len.atan2(a.dot(b));
        sum += theta * n.dot(cross / len);
    }
    -sum / (2.0 * std::f64::consts::PI)
}

/// Unit normal of a (possibly slightly non-planar) polygon by Newell's
/// method, following the counter-clockwise rule; zero if degenerate.
fn newell_normal(polygon: &[DVec3]) -> DVec3 {
    let m = polygon.len();
    let mut n = DVec3::ZERO;
    for i in 0..m {
        n += polygon[i].cross(polygon[(i + 1) % m]);
    }
    n.normalize_or_zero()
}

/// Sutherland-Hodgman clip of a polygon, taken relative to `origin`, to
/// the half-space `p . n >= 0`, into `out` (at least two corners per
/// polygon corner); returns the clipped polygon's corner count.
fn clip_above(polygon: &[DVec3], origin: DVec3, n: DVec3, out: &mut [DVec3]) -> usize {
    let m = polygon.len();
    let mut k = 0;
    for i in 0..m {
        let (a, b) = (polygon[i] - origin, polygon[(i + 1) % m] - origin);
        let (da, db) = (a.dot(n), b.dot(n));
        if da >= 0.0 {
            out[k] = a;
            k += 1;
        }
        if (da >= 0.0) != (db >= 0.0) {
            let s = da / (da - db);
            let p = a + s * (b - a);
            // Exactly on the plane: drop the (rounding) height.
            out[k] = p - p.dot(n) * n;
            k += 1;
        }
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// A square of half-side `a` at height `h` above the origin, facing down.
    fn square(a: f64, h: f64) -> Vec<DVec3> {
        vec![
            DVec3::new(-a, -a, h),
            DVec3::new(-a, a, h),
            DVec3::new(a, a, h),
            DVec3::new(a, -a, h),
        ]
    }

    #[test]
    fn facing_away_and_degenerate_give_zero() {
        let mut sq = square(1.0, 1.0);
        sq.reverse(); // now emits upwards, away from the origin
        assert_eq!(
            form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &sq),
            Ok(0.0)
        );
        let line = [DVec3::Z, DVec3::Z * 2.0, DVec3::Z * 3.0];
        assert_eq!(
            form_factor_point_polygon(DVec3::ZERO, DVec3::X, &line),
            Ok(0.0)
        );
        assert_eq!(
            form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &sq[..2]),
            Ok(0.0)
        );
        // Receiver facing away from the emitter.
        let sq = square(1.0, 1.0);
        assert_eq!(
            form_factor_point_polygon(DVec3::ZERO, -DVec3::Z, &sq),
            Ok(0.0)
        );
    }

    #[test]
    fn rejects_bad_input() {
        let sq = square(1.0, 1.0);
        assert_eq!(
            form_factor_point_polygon(DVec3::ZERO, DVec3::ZERO, &sq),
            Err(LambertError::ZeroNormal)
        );
        assert!(polygon_irradiance(DVec3::NAN, DVec3::Z, &sq, 1.0).is_err());
        assert!(polygon_irradiance(DVec3::ZERO, DVec3::Z, &sq, f64::INFINITY).is_err());
    }

    #[test]
    fn huge_emitter_fills_the_hemisphere() {
        // A plane-filling emitter gives F -> 1 and E -> pi L.
        let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &square(1e7, 1.0)).unwrap();
        assert!((f - 1.0).abs() < 1e-6, "{f}");
    }

    /// Irradiance by midpoint quadrature over the parallelogram
    /// `corner + s u + t v` (emitting along `u x v`), for receiver `x`, `n`.
    fn irradiance_numeric(
        x: DVec3,
        n: DVec3,
        corner: DVec3,
        u: DVec3,
        v: DVec3,
        radiance: f64,
        steps: usize,
    ) -> f64 {
        let ne = u.cross(v);
        let da = ne.length() / (steps * steps) as f64;
        let ne = ne.normalize();
        let mut sum = 0.0;
        for i in 0..steps {
            for j in 0..steps {
                let y = corner
                    + (i as f64 + 0.5) / steps as f64 * u
                    + (j as f64 + 0.5) / steps as f64 * v;
                let d = y - x;
                let r2 = d.length_squared();
                let cos_x = (n.dot(d) / r2.sqrt()).max(0.0);
                let cos_y = (ne.dot(-d) / r2.sqrt()).max(0.0);
                sum += cos_x * cos_y / r2 * da;
            }
        }
        radiance * sum
    }

    #[test]
    fn lambert_matches_numeric_integration_including_below_the_horizon() {
        let corner = DVec3::new(-0.3, 1.0, -0.2);
        let (u, v) = (DVec3::new(0.2, 0.5, 1.1), DVec3::new(0.9, 0.3, 0.0));
        // Emit towards the receivers (below).
        let (u, v) = if u.cross(v).y < 0.0 { (u, v) } else { (v, u) };
        let polygon = [corner, corner + u, corner + u + v, corner + v];
        let cases = [
            (DVec3::ZERO, DVec3::Y),
            (
                DVec3::new(0.1, 0.2, 0.3),
                DVec3::new(0.3, 1.0, -0.2).normalize(),
            ),
            // Tilted so the emitter straddles the receiver's horizon.
            (
                DVec3::new(0.2, 0.0, 0.4),
                DVec3::new(1.0, 0.15, 0.0).normalize(),
            ),
            (
                DVec3::new(0.2, 0.0, 0.4),
                DVec3::new(-1.0, 0.3, 0.2).normalize(),
            ),
        ];
        for (x, n) in cases {
            let exact = polygon_irradiance(x, n, &polygon, 3.0).unwrap();
            let numeric = irradiance_numeric(x, n, corner, u, v, 3.0, 600);
            assert!(exact > 0.0);
            assert!(
                (exact - numeric).abs() < 1e-4 * numeric,
                "{exact} vs {numeric} at {x}, {n}"
            );
            // A triangle half of the quad plus the other half is the whole.
            let half1 = polygon_irradiance(x, n, &polygon[..3], 3.0).unwrap();
            let half2 =
                polygon_irradiance(x, n, &[polygon[0], polygon[2], polygon[3]], 3.0).unwrap();
            assert!((half1 + half2 - exact).abs() < 1e-12 * exact.max(1.0));
        }
    }

    #[test]
    fn lambert_matches_closed_forms_on_the_axis_of_a_square_and_a_disk() {
        for (a, h) in [(0.5, 1.0), (0.1, 2.0), (3.0, 0.2), (1.0, 1.0)] {
            // Square of side 2a, facing down, at height h over the origin.
            let square = [
                DVec3::new(-a, h, -a),
                DVec3::new(a, h, -a),
                DVec3::new(a, h, a),
                DVec3::new(-a, h, a),
            ];
            let square = if (square[1] - square[0]).cross(square[2] - square[0]).y < 0.0 {
                square
            } else {
                [square[0], square[3], square[2], square[1]]
            };
            let x: f64 = a / h;
            let s = (1.0 + x * x).sqrt();
            let expected = 4.0 / PI * x / s * (x / s).atan();
            let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Y, &square).unwrap();
            assert!(
                (f - expected).abs() < 1e-12,
                "square a={a} h={h}: {f} vs {expected}"
            );
            // Disk of radius a as a fine regular polygon: F = a^2 / (a^2 + h^2).
            let n = 4096;
            let mut disk: Vec<DVec3> = (0..n)
                .map(|k| {
                    let phi = 2.0 * PI * k as f64 / n as f64;
                    DVec3::new(a * phi.cos(), h, a * phi.sin())
                })
                .collect();
            if (disk[1] - disk[0]).cross(disk[2] - disk[0]).y > 0.0 {
                disk.reverse(); // face down
            }
            let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Y, &disk).unwrap();
            let expected = a * a / (a * a + h * h);
            assert!(
                (f - expected).abs() < 1e-5 * expected,
                "disk a={a} h={h}: {f} vs {expected}"
            );
            let e = polygon_irradiance(DVec3::ZERO, DVec3::Y, &disk, 2.0).unwrap();
            assert!((e - PI * 2.0 * f).abs() < 1e-12);
        }
    }

    proptest::proptest! {
        #[test]
        fn lambert_is_finite_and_bounded(
            x in proptest::array::uniform3(-2.0f64..2.0),
            n in proptest::array::uniform3(-1.0f64..1.0),
            polygon in proptest::collection::vec(proptest::array::uniform3(-2.0f64..2.0), 0..7),
        ) {
            let polygon: Vec<DVec3> = polygon.into_iter().map(DVec3::from_array).collect();
            let (x, n) = (DVec3::from_array(x), DVec3::from_array(n));
            if let Ok(f) = form_factor_point_polygon(x, n, &polygon) {
                proptest::prop_assert!(f.is_finite() && (0.0..=1.0).contains(&f));
            }
            if let Ok(e) = polygon_irradiance(x, n, &polygon, 0.0) {
                proptest::prop_assert_eq!(e, 0.0);
            }
        }
    }
}
