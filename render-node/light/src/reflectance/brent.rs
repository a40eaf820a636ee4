//! Brent's one-dimensional minimisation: downhill bracketing by golden
//! steps with parabolic extrapolation, then inverse parabolic
//! interpolation safeguarded by golden-section steps (Numerical Recipes'
//! `mnbrak` and `brent`). Non-finite function values count as `+inf`.

const GOLD: f64 = 1.618_033_988_749_895;
const CGOLD: f64 = 0.381_966_011_250_105;
const GLIMIT: f64 = 100.0;
const TINY: f64 = 1e-20;

/// Why a minimisation failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BrentError {
    /// A start point is not finite, or the two start points are equal.
    #[error("start points {a} and {b} must be finite and distinct")]
    BadStart {
        /// First start point.
        a: f64,
        /// Second start point.
        b: f64,
    },
    /// No bracket was found within the iteration budget.
    #[error("no minimum bracketed after {0} steps (function unbounded below or flat)")]
    NoBracket(u32),
}

fn eval(f: &mut impl FnMut(f64) -> f64, x: f64) -> f64 {
    let v = f(x);
    if v.is_nan() { f64::INFINITY } else { v }
}

/// Find `a < b < c` (or `a > b > c`) with `f(b) <= f(a)` and `f(b) <= f(c)`,
/// searching downhill from the start points `a`, `b`. Returns
/// `(a, b, c, f(b))`.
pub fn bracket(
    f: &mut impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
) -> Result<(f64, f64, f64, f64), BrentError> {
    if !(a.is_finite() && b.is_finite()) || a == b {
        return Err(BrentError::BadStart { a, b });
    }
    let (mut ax, mut bx) = (a, b);
    let (mut fa, mut fb) = (eval(f, ax), eval(f, bx));
    if fb > fa {
        std::mem::swap(&mut ax, &mut bx);
        std::mem::swap(&mut fa, &mut fb);
    }
    let mut cx = bx + GOLD * (bx - ax);
    let mut fc = eval(f, cx);
    let mut steps = 0;
    while fb > fc || (fb == fc && fb == f64::INFINITY) {
        steps += 1;
        if steps > 200 || !cx.is_finite() {
            return Err(BrentError::NoBracket(steps));
        }
        let r = (bx - ax) * (fb - fc);
        let q = (bx - cx) * (fb - fa);
        let denom = 2.0 * (q - r).abs().max(TINY).copysign(q - r);
        let mut u = bx - ((bx - cx) * q - (bx - ax) * r) / denom;
        let ulim = bx + GLIMIT * (cx - bx);
        let mut fu;
        if !u.is_finite() {
            u = cx + GOLD * (cx - bx);
            fu = eval(f, u);
        } else if (bx - u) * (u - cx) > 0.0 {
            fu = eval(f, u);
            if fu < fc {
                return Ok(order(bx, u, cx, fu));
            } else if fu > fb {
                return Ok(order(ax, bx, u, fb));
            }
            u = cx + GOLD * (cx - bx);
            fu = eval(f, u);
        } else if (cx - u) * (u - ulim) > 0.0 {
            fu = eval(f, u);
            if fu < fc {
                bx = cx;
                cx = u;
                u = cx + GOLD * (cx - bx);
                fb = fc;
                fc = fu;
                fu = eval(f, u);
            }
        } else if (u - ulim) * (ulim - cx) >= 0.0 {
            u = ulim;
            fu = eval(f, u);
        } else {
            u = cx + GOLD * (cx - bx);
            fu = eval(f, u);
        }
        ax = bx;
        bx = cx;
        cx = u;
        fa = fb;
        fb = fc;
        fc = fu;
    }
    let _ = fa;
    Ok(order(ax, bx, cx, fb))
}

fn order(a: f64, b: f64, c: f64, fb: f64) -> (f64, f64, f64, f64) {
    if a < c { (a, b, c, fb) } else { (c, b, a, fb) }
}

/// Brent's method on a bracket `a < b < c` with `f(b) = fb` below both
/// ends, to a relative tolerance `tol` (at least `1e-10`). Returns
/// `(x_min, f(x_min))`.
pub fn brent_minimize(
    f: &mut impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
    c: f64,
    fb: f64,
    tol: f64,
) -> (f64, f64) {
    let tol = if tol.is_finite() {
        tol.max(1e-10)
    } else {
        1e-8
    };
    let (mut lo, mut hi) = (a.min(c), a.max(c));
    let (mut x, mut w, mut v) = (b, b, b);
    let (mut fx, mut fw, mut fv) = (fb, fb, fb);
    let mut d: f64 = 0.0;
    let mut e: f64 = 0.0;
    for _ in 0..200 {
        let xm = 0.5 * (lo + hi);
        let tol1 = tol * x.abs() + 1e-12;
        let tol2 = 2.0 * tol1;
        if (x - xm).abs() <= tol2 - 0.5 * (hi - lo) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            // Inverse parabolic interpolation through x, w, v.
            let r = (x - w) * (fx - fv);
            let mut q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            let etemp = e;
            e = d;
            if p.abs() < (0.5 * q * etemp).abs() && p > q * (lo - x) && p < q * (hi - x) {
                d = p / q;
                let u = x + d;
                if u - lo < tol2 || hi - u < tol2 {
                    d = tol1.copysign(xm - x);
                }
                golden = false;
            }
        }
        if golden {
            e = if x >= xm { lo - x } else { hi - x };
            d = CGOLD * e;
        }
        let u = if d.abs() >= tol1 {
            x + d
        } else {
            x + tol1.copysign(d)
        };
        let fu = eval(f, u);
        if fu <= fx {
            if u >= x {
                lo = x;
            } else {
                hi = x;
            }
            (v, w, x) = (w, x, u);
            (fv, fw, fx) = (fw, fx, fu);
        } else {
            if u < x {
                lo = u;
            } else {
                hi = u;
            }
            if fu <= fw || w == x {
                (v, w) = (w, u);
                (fv, fw) = (fw, fu);
            } else if fu <= fv || v == x || v == w {
                v = u;
                fv = fu;
            }
        }
    }
    (x, fx)
}

/// Bracket from `a`, `b` and minimise with Brent's method to relative
/// tolerance `tol`.
pub fn minimize(
    mut f: impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
    tol: f64,
) -> Result<(f64, f64), BrentError> {
    let (lo, mid, hi, fmid) = bracket(&mut f, a, b)?;
    Ok(brent_minimize(&mut f, lo, mid, hi, fmid, tol))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_minima_of_smooth_functions() {
        let (x, fx) = minimize(|x| (x - 3.7).powi(2) + 1.0, 0.0, 1.0, 1e-10).unwrap();
        assert!(
            (x - 3.7).abs() < 1e-6 && (fx - 1.0).abs() < 1e-12,
            "{x} {fx}"
        );
        let (x, _) = minimize(|x: f64| x.cos(), 2.0, 2.5, 1e-10).unwrap();
        assert!((x - std::f64::consts::PI).abs() < 1e-6, "{x}");
        // Far from the start, and below it.
        let (x, _) = minimize(|x| (x + 1234.5).powi(2), 1.0, 2.0, 1e-12).unwrap();
        assert!((x + 1234.5).abs() < 1e-4, "{x}");
    }

    #[test]
    fn counts_evaluations_and_refuses_bad_input() {
        let mut n = 0;
        minimize(
            |x| {
                n += 1;
                (x - 0.3).powi(4) + (x - 0.3).powi(2)
            },
            0.0,
            0.1,
            1e-8,
        )
        .unwrap();
        assert!(n < 60, "{n} evaluations");
        assert!(matches!(
            minimize(|x| x, f64::NAN, 1.0, 1e-8),
            Err(BrentError::BadStart { .. })
        ));
        assert!(matches!(
            minimize(|x| -x, 0.0, 1.0, 1e-8),
            Err(BrentError::NoBracket(_))
        ));
        // NaN regions count as +inf and are avoided.
        let (x, _) = minimize(
            |x: f64| if x < 0.0 { f64::NAN } else { (x - 2.0).powi(2) },
            0.5,
            1.0,
            1e-10,
        )
        .unwrap();
        assert!((x - 2.0).abs() < 1e-6);
    }
}
