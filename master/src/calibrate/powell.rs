//! The paper's baseline: Powell's direction-set minimisation with Brent
//! line searches (Numerical Recipes, sections 10.2 and 10.5) of the same
//! reprojection error, over the same parameters as Levenberg-Marquardt.

use super::camera::{CameraModel, Layout, Observation};
use super::lm::Refined;
use nalgebra::DVector;

/// Cost standing in for a pose that puts a point behind the device.
const BEHIND: f64 = 1e300;
const GOLD: f64 = 1.618_033_988_749_895;
const CGOLD: f64 = 0.381_966_011_250_105;

/// Bracket a minimum of `f` starting from `a`, `b`: returns `(a, b, c)`
/// with `f(b) <= f(a), f(c)` (Numerical Recipes `mnbrak`).
fn bracket(f: &mut impl FnMut(f64) -> f64, mut a: f64, mut b: f64) -> (f64, f64, f64, f64) {
    let (mut fa, mut fb) = (f(a), f(b));
    if fb > fa {
        std::mem::swap(&mut a, &mut b);
        std::mem::swap(&mut fa, &mut fb);
    }
    let mut c = b + GOLD * (b - a);
    let mut fc = f(c);
    for _ in 0..200 {
        if fb <= fc {
            break;
        }
        let r = (b - a) * (fb - fc);
        let q = (b - c) * (fb - fa);
        let denom = 2.0 * (q - r).abs().max(1e-20).copysign(q - r);
        let mut u = b - ((b - c) * q - (b - a) * r) / denom;
        let ulim = b + 100.0 * (c - b);
        let mut fu;
        if (b - u) * (u - c) > 0.0 {
            fu = f(u);
            if fu < fc {
                return (b, u, c, fu);
            } else if fu > fb {
                return (a, b, u, fb);
            }
            u = c + GOLD * (c - b);
            fu = f(u);
        } else if (c - u) * (u - ulim) > 0.0 {
            fu = f(u);
            if fu < fc {
                b = c;
                c = u;
                u = c + GOLD * (c - b);
                fb = fc;
                fc = fu;
                fu = f(u);
            }
        } else if (u - ulim) * (ulim - c) >= 0.0 {
            u = ulim;
            fu = f(u);
        } else {
            u = c + GOLD * (c - b);
            fu = f(u);
        }
        a = b;
        b = c;
        c = u;
        fa = fb;
        fb = fc;
        fc = fu;
    }
    let _ = fa;
    (a, b, c, fb)
}

/// Brent's parabolic-interpolation line minimisation inside the bracket
/// `(a, b, c)` to relative tolerance `tol`; returns `(x_min, f_min)`.
fn brent(
    f: &mut impl FnMut(f64) -> f64,
    ax: f64,
    bx: f64,
    cx: f64,
    fbx: f64,
    tol: f64,
) -> (f64, f64) {
    const ZEPS: f64 = 1e-12;
    let (mut a, mut b) = (ax.min(cx), ax.max(cx));
    let (mut x, mut w, mut v) = (bx, bx, bx);
    let (mut fx, mut fw, mut fv) = (fbx, fbx, fbx);
    let (mut d, mut e) = (0.0f64, 0.0f64);
    for _ in 0..200 {
        let xm = 0.5 * (a + b);
        let tol1 = tol * x.abs() + ZEPS;
        let tol2 = 2.0 * tol1;
        if (x - xm).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let golden = |x: f64| if x >= xm { a - x } else { b - x };
        if e.abs() > tol1 {
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
            if p.abs() >= (0.5 * q * etemp).abs() || p <= q * (a - x) || p >= q * (b - x) {
                e = golden(x);
                d = CGOLD * e;
            } else {
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = tol1.copysign(xm - x);
                }
            }
        } else {
            e = golden(x);
            d = CGOLD * e;
        }
        let u = if d.abs() >= tol1 {
            x + d
        } else {
            x + tol1.copysign(d)
        };
        let fu = f(u);
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, w, x) = (w, x, u);
            (fv, fw, fx) = (fw, fx, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
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

/// Settings of the baseline.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PowellSettings {
    /// Relative decrease of the cost per sweep below which it stops.
    pub(crate) ftol: f64,
    /// Relative tolerance of each Brent line search.
    pub(crate) line_tol: f64,
    /// Sweeps at most.
    pub(crate) max_sweeps: usize,
}

/// Typical magnitude of one unit of each parameter, so that the initial
/// directions and brackets are sensible: 0.01 rad, 1 cm, 10 px, 0.01.
fn scales(layout: Layout) -> DVector<f64> {
    let mut s = vec![0.01, 0.01, 0.01, 0.01, 0.01, 0.01];
    if layout.intrinsics {
        s.extend([10.0; 4]);
        if layout.skew {
            s.push(1.0);
        }
        if layout.distortion {
            s.extend([0.01, 0.01]);
        }
    }
    DVector::from_vec(s)
}

/// Minimise the summed squared pixel error with Powell's method from
/// `start` (parameters are offsets from `start`, scaled by [`scales`]).
pub(crate) fn refine(
    start: &CameraModel,
    obs: &[Observation],
    layout: Layout,
    settings: PowellSettings,
) -> Refined {
    let n = layout.len();
    let scale = scales(layout);
    let mut evaluations = 0usize;
    let mut cost_at = |x: &DVector<f64>| {
        evaluations += 1;
        start
            .apply(x.component_mul(&scale).as_slice(), layout)
            .cost(obs)
            .unwrap_or(BEHIND)
    };
    let mut p = DVector::zeros(n);
    let mut dirs: Vec<DVector<f64>> = (0..n)
        .map(|i| {
            let mut d = DVector::zeros(n);
            d[i] = 1.0;
            d
        })
        .collect();
    let mut fret = cost_at(&p);
    let mut pt = p.clone();
    let mut converged = false;
    let mut sweeps = 0;
    while sweeps < settings.max_sweeps {
        sweeps += 1;
        let fp = fret;
        let (mut ibig, mut del) = (0, 0.0);
        for (i, dir) in dirs.iter_mut().enumerate() {
            let before = fret;
            fret = line_minimise(&mut cost_at, &mut p, dir, settings.line_tol);
            if before - fret > del {
                del = before - fret;
                ibig = i;
            }
        }
        if 2.0 * (fp - fret) <= settings.ftol * (fp.abs() + fret.abs()) + 1e-30 {
            converged = true;
            break;
        }
        let extrapolated = 2.0 * &p - &pt;
        let mut xit = &p - &pt;
        pt = p.clone();
        let fptt = cost_at(&extrapolated);
        if fptt < fp {
            let t = 2.0 * (fp - 2.0 * fret + fptt) * (fp - fret - del).powi(2)
                - del * (fp - fptt).powi(2);
            if t < 0.0 {
                fret = line_minimise(&mut cost_at, &mut p, &mut xit, settings.line_tol);
                dirs[ibig] = dirs[n - 1].clone();
                dirs[n - 1] = xit;
            }
        }
    }
    let model = start.apply(p.component_mul(&scale).as_slice(), layout);
    Refined {
        model,
        iterations: sweeps,
        evaluations,
        converged,
    }
}

/// Move `p` to the minimum along `dir` and scale `dir` to the step taken
/// (Numerical Recipes `linmin`); returns the cost there.
fn line_minimise(
    cost_at: &mut impl FnMut(&DVector<f64>) -> f64,
    p: &mut DVector<f64>,
    dir: &mut DVector<f64>,
    tol: f64,
) -> f64 {
    let mut along = |s: f64| cost_at(&(&*p + &*dir * s));
    let (a, b, c, fb) = bracket(&mut along, 0.0, 1.0);
    let (s, fmin) = brent(&mut along, a, b, c, fb, tol);
    *dir *= s;
    *p += &*dir;
    fmin
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn brent_finds_a_parabola_minimum() {
        let mut f = |x: f64| (x - 2.5).powi(2) + 1.0;
        let (a, b, c, fb) = bracket(&mut f, 0.0, 1.0);
        let (x, fx) = brent(&mut f, a, b, c, fb, 1e-8);
        assert!((x - 2.5).abs() < 1e-6, "{x}");
        assert!((fx - 1.0).abs() < 1e-12);
    }
}
