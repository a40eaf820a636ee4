//! Levenberg-Marquardt refinement of the reprojection error, with the
//! analytic Jacobian of [`CameraModel::project_with_jacobian`] and
//! Marquardt's diagonal scaling (parameters mix pixels, radians, metres).

use super::camera::{CameraModel, Layout, Observation};

/// The outcome of a refinement.
#[derive(Clone, Debug)]
pub(crate) struct Refined {
    /// The refined model.
    pub(crate) model: CameraModel,
    /// Iterations (LM: accepted and rejected steps; Powell: direction-set sweeps).
    pub(crate) iterations: usize,
    /// Evaluations of the reprojection error.
    pub(crate) evaluations: usize,
    /// The stopping test was met (not the iteration limit).
    pub(crate) converged: bool,
}

/// The Gauss-Newton normal equations at one model for `P` free parameters,
/// in fixed-size arrays (this is the refinement's hot path; nothing here
/// allocates, and with `P` known the loops unroll).
#[derive(Clone, Copy)]
struct NormalEquations<const P: usize> {
    /// `J^T J`, full symmetric.
    jtj: [[f64; P]; P],
    /// `J^T r`.
    jtr: [f64; P],
    /// `r^T r`.
    cost: f64,
}

/// Normal equations at `model`; `None` when a point is behind the device.
fn normal_equations<const P: usize>(
    model: &CameraModel,
    obs: &[Observation],
    layout: Layout,
) -> Option<NormalEquations<P>> {
    let mut ne = NormalEquations {
        jtj: [[0.0; P]; P],
        jtr: [0.0; P],
        cost: 0.0,
    };
    let mut jac = [[0.0f64; 2]; P];
    for o in obs {
        let px = model.project_with_jacobian(&o.world, layout, &mut jac)?;
        let r = px - o.pixel;
        ne.cost += r.norm_squared();
        // The two Jacobian rows apart, so that the updates below run over
        // contiguous rows.
        let ju: [f64; P] = std::array::from_fn(|a| jac[a][0]);
        let jv: [f64; P] = std::array::from_fn(|a| jac[a][1]);
        for a in 0..P {
            let (ua, va) = (ju[a], jv[a]);
            ne.jtr[a] += ua * r.x + va * r.y;
            let row = &mut ne.jtj[a][..=a];
            for ((t, ub), vb) in row.iter_mut().zip(&ju).zip(&jv) {
                *t += ua * ub + va * vb;
            }
        }
    }
    for a in 0..P {
        for b in 0..a {
            ne.jtj[b][a] = ne.jtj[a][b];
        }
    }
    ne.cost.is_finite().then_some(ne)
}

/// Solve `(J^T J + lambda diag(J^T J)) d = -J^T r` by Cholesky; `None`
/// when the damped matrix is not positive definite.
fn damped_step<const P: usize>(ne: &NormalEquations<P>, lambda: f64) -> Option<[f64; P]> {
    let mut l = ne.jtj;
    for (i, row) in l.iter_mut().enumerate() {
        row[i] += lambda * ne.jtj[i][i].max(1e-12);
    }
    for j in 0..P {
        let d = l[j][j] - l[j][..j].iter().map(|v| v * v).sum::<f64>();
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        l[j][j] = d;
        for i in j + 1..P {
            let dot: f64 = l[i][..j].iter().zip(&l[j][..j]).map(|(a, b)| a * b).sum();
            l[i][j] = (l[i][j] - dot) / d;
        }
    }
    let mut x = [0.0; P];
    for i in 0..P {
        let mut v = -ne.jtr[i];
        for k in 0..i {
            v -= l[i][k] * x[k];
        }
        x[i] = v / l[i][i];
    }
    for i in (0..P).rev() {
        let mut v = x[i];
        for k in i + 1..P {
            v -= l[k][i] * x[k];
        }
        x[i] = v / l[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Stop when every Jacobian column is this close to orthogonal to the
/// residual (the cosine; MINPACK's `gtol`).
const GRADIENT_COSINE: f64 = 1e-11;
/// Stop when the linear model predicts a relative decrease below this.
const PREDICTED_DECREASE: f64 = 1e-15;

/// Minimise the summed squared pixel error over the free parameters of
/// `layout`, starting at `start`. Stops at a stationary point (gradient
/// test), when a step can no longer lower the cost beyond rounding, or
/// after `max_iterations` steps.
pub(crate) fn refine(
    start: &CameraModel,
    obs: &[Observation],
    layout: Layout,
    max_iterations: usize,
) -> Refined {
    // One instance per parameter count (`Layout::len`).
    let refine = match (layout.intrinsics, layout.skew, layout.distortion) {
        (false, _, _) => refine_fixed::<6>,
        (true, false, false) => refine_fixed::<10>,
        (true, true, false) => refine_fixed::<11>,
        (true, false, true) => refine_fixed::<12>,
        (true, true, true) => refine_fixed::<13>,
    };
    refine(start, obs, layout, max_iterations)
}

/// [`refine`] with `P = layout.len()` free parameters.
fn refine_fixed<const P: usize>(
    start: &CameraModel,
    obs: &[Observation],
    layout: Layout,
    max_iterations: usize,
) -> Refined {
    debug_assert_eq!(P, layout.len());
    let mut model = start.clone();
    let mut evaluations = 1;
    let mut iterations = 0;
    let done = |model, iterations, evaluations, converged| Refined {
        model,
        iterations,
        evaluations,
        converged,
    };
    let Some(mut ne) = normal_equations::<P>(&model, obs, layout) else {
        return done(model, iterations, evaluations, false);
    };
    let mut lambda = 1e-3;
    while iterations < max_iterations {
        let cosine = (0..P)
            .map(|i| ne.jtr[i].abs() / (ne.jtj[i][i] * ne.cost).sqrt().max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max);
        if ne.cost <= f64::MIN_POSITIVE || cosine <= GRADIENT_COSINE {
            return done(model, iterations, evaluations, true);
        }
        iterations += 1;
        let mut trial = None;
        if let Some(d) = damped_step(&ne, lambda) {
            // cost(x + d) ~ cost + 2 d.J^T r + d.J^T J d (linearised model).
            let mut predicted = 0.0;
            for a in 0..P {
                let jd: f64 = (0..P).map(|b| ne.jtj[a][b] * d[b]).sum();
                predicted -= d[a] * (2.0 * ne.jtr[a] + jd);
            }
            if predicted <= PREDICTED_DECREASE * ne.cost {
                // Nothing left to gain beyond rounding.
                return done(model, iterations, evaluations, true);
            }
            evaluations += 1;
            let m = model.apply(&d, layout);
            trial = normal_equations::<P>(&m, obs, layout).map(|n| (m, n));
        }
        match trial {
            Some((m, n)) if n.cost < ne.cost => {
                let gain = ne.cost - n.cost;
                model = m;
                ne = n;
                lambda = (lambda * 0.1).max(1e-12);
                if gain <= PREDICTED_DECREASE * ne.cost {
                    return done(model, iterations, evaluations, true);
                }
            }
            _ => {
                lambda *= 10.0;
                if lambda > 1e12 {
                    // No direction lowers the cost at machine precision.
                    return done(model, iterations, evaluations, true);
                }
            }
        }
    }
    done(model, iterations, evaluations, false)
}
