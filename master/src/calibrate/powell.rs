//! The paper's baseline: Powell's direction-set minimisation with Brent
//! line searches (Numerical Recipes, sections 10.2 and 10.5) of the same
//! reprojection error, over the same parameters as Levenberg-Marquardt.

use super::camera::{CameraModel, Layout, Observation};
use super::lm::Refined;
use nalgebra::DVector;
use showcase_light::reflectance::{bracket, brent_minimize};

/// Cost standing in for a pose that puts a point behind the device.
const BEHIND: f64 = 1e300;
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
/// (Numerical Recipes `linmin`, with the shared Brent search of
/// [`showcase_light::reflectance`]); returns the cost there. A direction
/// along which no minimum is bracketed (the cost falls without bound) is
/// not taken: `p` stays and `dir` becomes zero.
fn line_minimise(
    cost_at: &mut impl FnMut(&DVector<f64>) -> f64,
    p: &mut DVector<f64>,
    dir: &mut DVector<f64>,
    tol: f64,
) -> f64 {
    let mut along = |s: f64| cost_at(&(&*p + &*dir * s));
    let Ok((a, b, c, fb)) = bracket(&mut along, 0.0, 1.0) else {
        let here = along(0.0);
        dir.fill(0.0);
        return here;
    };
    let (s, fmin) = brent_minimize(&mut along, a, b, c, fb, tol);
    *dir *= s;
    *p += &*dir;
    fmin
}
