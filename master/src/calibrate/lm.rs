//! Levenberg-Marquardt refinement of the reprojection error, with the
//! analytic Jacobian of [`CameraModel::project_with_jacobian`] and
//! Marquardt's diagonal scaling (parameters mix pixels, radians, metres).

use super::camera::{CameraModel, Layout, Observation};
use nalgebra::{DMatrix, DVector};

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

/// Normal equations `J^T J` and `J^T r` at `model`, and the cost `r^T r`.
fn normal_equations(
    model: &CameraModel,
    obs: &[Observation],
    layout: Layout,
) -> Option<(DMatrix<f64>, DVector<f64>, f64)> {
    let p = layout.len();
    let mut jtj = DMatrix::zeros(p, p);
    let mut jtr = DVector::zeros(p);
    let mut cost = 0.0;
    let mut jac = vec![[0.0; 2]; p];
    for o in obs {
        let px = model.project_with_jacobian(&o.world, layout, &mut jac)?;
        let r = px - o.pixel;
        cost += r.norm_squared();
        for a in 0..p {
            jtr[a] += jac[a][0] * r.x + jac[a][1] * r.y;
            for b in 0..=a {
                jtj[(a, b)] += jac[a][0] * jac[b][0] + jac[a][1] * jac[b][1];
            }
        }
    }
    jtj.fill_upper_triangle_with_lower_triangle();
    cost.is_finite().then_some((jtj, jtr, cost))
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
    let mut model = start.clone();
    let mut evaluations = 1;
    let mut iterations = 0;
    let done = |model, iterations, evaluations, converged| Refined {
        model,
        iterations,
        evaluations,
        converged,
    };
    let Some((mut jtj, mut jtr, mut cost)) = normal_equations(&model, obs, layout) else {
        return done(model, iterations, evaluations, false);
    };
    let mut lambda = 1e-3;
    while iterations < max_iterations {
        let cosine = (0..jtr.len())
            .map(|i| jtr[i].abs() / (jtj[(i, i)] * cost).sqrt().max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max);
        if cost <= f64::MIN_POSITIVE || cosine <= GRADIENT_COSINE {
            return done(model, iterations, evaluations, true);
        }
        iterations += 1;
        let mut a = jtj.clone();
        for i in 0..a.nrows() {
            a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
        }
        let step = a
            .cholesky()
            .map(|c| c.solve(&(-&jtr)))
            .filter(|d| d.iter().all(|v| v.is_finite()));
        let mut trial = None;
        if let Some(d) = step {
            // cost(x + d) ~ cost + 2 d.J^T r + d.J^T J d (linearised model).
            let predicted = -(2.0 * d.dot(&jtr) + d.dot(&(&jtj * &d)));
            if predicted <= PREDICTED_DECREASE * cost {
                // Nothing left to gain beyond rounding.
                return done(model, iterations, evaluations, true);
            }
            evaluations += 1;
            let m = model.apply(&d, layout);
            trial = normal_equations(&m, obs, layout).map(|ne| (m, ne));
        }
        match trial {
            Some((m, (j2, r2, c2))) if c2 < cost => {
                let gain = cost - c2;
                model = m;
                (jtj, jtr, cost) = (j2, r2, c2);
                lambda = (lambda * 0.1).max(1e-12);
                if gain <= PREDICTED_DECREASE * cost {
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
