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
fn normal_equations(model: &CameraModel, obs: &[Observation], layout: Layout) -> Option<(DMatrix<f64>, DVector<f64>, f64)> {
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

/// Minimise the summed squared pixel error over the free parameters of
/// `layout`, starting at `start`. Stops when a step no longer lowers the
/// cost by more than a relative 1e-15, or after `max_iterations` steps.
pub(crate) fn refine(start: &CameraModel, obs: &[Observation], layout: Layout, max_iterations: usize) -> Refined {
    let mut model = start.clone();
    let mut evaluations = 1;
    let Some((mut jtj, mut jtr, mut cost)) = normal_equations(&model, obs, layout) else {
        return Refined {
            model,
            iterations: 0,
            evaluations,
            converged: false,
        };
    };
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        if cost <= f64::MIN_POSITIVE {
            return Refined {
                model,
                iterations,
                evaluations,
                converged: true,
            };
        }
        let mut a = jtj.clone();
        for i in 0..a.nrows() {
            a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
        }
        let step = a.cholesky().map(|c| c.solve(&(-&jtr)));
        let trial = step
            .filter(|d| d.iter().all(|v| v.is_finite()))
            .map(|d| model.apply(&d, layout))
            .and_then(|m| {
                evaluations += 1;
                normal_equations(&m, obs, layout).map(|ne| (m, ne))
            });
        match trial {
            Some((m, (j2, r2, c2))) if c2 < cost => {
                let gain = cost - c2;
                model = m;
                (jtj, jtr, cost) = (j2, r2, c2);
                lambda = (lambda * 0.1).max(1e-12);
                if gain <= 1e-15 * cost {
                    return Refined {
                        model,
                        iterations,
                        evaluations,
                        converged: true,
                    };
                }
            }
            _ => {
                lambda *= 10.0;
                if lambda > 1e12 {
                    // No direction lowers the cost at machine precision.
                    return Refined {
                        model,
                        iterations,
                        evaluations,
                        converged: true,
                    };
                }
            }
        }
    }
    Refined {
        model,
        iterations,
        evaluations,
        converged: false,
    }
}
