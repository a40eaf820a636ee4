//! Pose from known intrinsics: a homography start for coplanar fiducials
//! (Zhang's decomposition) and EPnP (Lepetit, Moreno-Noguer, Fua 2009) for
//! the rest. Both are linear starts; Levenberg-Marquardt refines them.

use super::CalibrationError;
use super::camera::{CameraModel, Observation};
use super::dlt::{Spread, homography};
use super::nullspace::smallest_eigenvectors;
use nalgebra::{DMatrix, DVector, Matrix3, Matrix4, SMatrix, SVector, Vector2, Vector3, Vector4};

/// The rotation nearest to `m` in the Frobenius norm: the orthogonal polar
/// factor when `det m > 0`, by Newton's iteration `X <- (g X + X^-T / g) / 2`
/// with Higham's scaling `g` (a handful of 3x3 inverses, several times
/// cheaper than an SVD); otherwise, or if it does not settle, by the SVD.
pub(crate) fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    if m.determinant() > 0.0 {
        let mut x = *m;
        for _ in 0..30 {
            let Some(inv) = x.try_inverse() else { break };
            let g = (inv.norm() / x.norm()).sqrt();
            let next = (x * g + inv.transpose() / g) * 0.5;
            let change = (next - x).amax();
            x = next;
            if !change.is_finite() {
                break;
            }
            if change < 1e-9 {
                // Quadratic convergence: one more step reaches rounding level.
                if let Some(inv) = x.try_inverse() {
                    return (x + inv.transpose()) * 0.5;
                }
                break;
            }
        }
    }
    nearest_rotation_by_svd(m)
}

/// [`nearest_rotation`] through the SVD `m = U S V^T`: `U diag(1, 1, det) V^T`.
fn nearest_rotation_by_svd(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (u, v_t) = (
        svd.u.unwrap_or_else(Matrix3::identity),
        svd.v_t.unwrap_or_else(Matrix3::identity),
    );
    let d = (u * v_t).determinant().signum();
    u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t
}

/// Rigid transform `(R, t)` with `cam ~ R world + t` in the least-squares
/// sense (Kabsch / Umeyama without scale).
fn absolute_orientation(
    world: &[Vector3<f64>],
    cam: &[Vector3<f64>],
) -> (Matrix3<f64>, Vector3<f64>) {
    let n = world.len() as f64;
    let mw = world.iter().sum::<Vector3<f64>>() / n;
    let mc = cam.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (w, c) in world.iter().zip(cam) {
        h += (c - mc) * (w - mw).transpose();
    }
    let r = nearest_rotation(&h);
    (r, mc - r * mw)
}

/// `K^-1` of the known intrinsics.
fn inverse_k(intrinsics: &CameraModel) -> Result<Matrix3<f64>, CalibrationError> {
    intrinsics
        .k()
        .try_inverse()
        .ok_or_else(|| CalibrationError::InvalidCameraMatrix {
            reason: "the matrix is singular".to_string(),
        })
}

/// Undistortion-free normalised image coordinates `K^-1 [u, v, 1]`.
fn normalised_point(k_inv: &Matrix3<f64>, pixel: &Vector2<f64>) -> Vector2<f64> {
    let m = k_inv * pixel.push(1.0);
    Vector2::new(m.x / m.z, m.y / m.z)
}

fn with_pose(
    intrinsics: &CameraModel,
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
) -> CameraModel {
    CameraModel {
        rotation,
        translation,
        ..intrinsics.clone()
    }
}

/// Pose of a device with known intrinsics from coplanar fiducials: the
/// homography from the best-fit plane to normalised image coordinates,
/// split into the plane's rotation and translation.
pub(crate) fn pose_from_homography(
    intrinsics: &CameraModel,
    obs: &[Observation],
    spread: &Spread,
) -> Result<CameraModel, CalibrationError> {
    let basis = spread.axes;
    let k_inv = inverse_k(intrinsics)?;
    let pairs: Vec<(Vector2<f64>, Vector2<f64>)> = obs
        .iter()
        .map(|o| {
            let d = basis.transpose() * (o.world - spread.centroid);
            (d.xy(), normalised_point(&k_inv, &o.pixel))
        })
        .collect();
    let mut h = homography(&pairs)?;
    // The plane's centroid maps to h3; it must lie in front (z > 0).
    if h[(2, 2)] < 0.0 {
        h = -h;
    }
    let lambda = 0.5 * (h.column(0).norm() + h.column(1).norm());
    let r1 = h.column(0) / lambda;
    let r2 = h.column(1) / lambda;
    let rp = nearest_rotation(&Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]));
    let tp = h.column(2) / lambda;
    // x_cam = Rp B^T (X - c) + tp.
    let rotation = rp * basis.transpose();
    let translation = tp - rotation * spread.centroid;
    Ok(with_pose(intrinsics, rotation, translation))
}

/// Gauss-Newton on the four kernel weights so that the control points keep
/// their world distances (EPnP's final step).
fn refine_betas(mut beta: [f64; 4], deltas: &[Vec<Vector3<f64>>], dist2: &[f64]) -> [f64; 4] {
    for _ in 0..10 {
        let mut jtj = Matrix4::zeros();
        let mut jtr = Vector4::zeros();
        for (dp, d2) in deltas.iter().zip(dist2) {
            let x: Vector3<f64> = (0..4).map(|k| beta[k] * dp[k]).sum();
            let r = x.norm_squared() - d2;
            let j = Vector4::from_fn(|k, _| 2.0 * x.dot(&dp[k]));
            jtj += j * j.transpose();
            jtr += j * r;
        }
        let Ok(step) = jtj.svd(true, true).solve(&(-jtr), 1e-12) else {
            break;
        };
        if !step.iter().all(|v| v.is_finite()) {
            break;
        }
        for k in 0..4 {
            beta[k] += step[k];
        }
    }
    beta
}

/// EPnP: the pose of a device with known intrinsics from at least four
/// non-coplanar fiducials, expressed through four control points.
pub(crate) fn epnp(
    intrinsics: &CameraModel,
    obs: &[Observation],
    spread: &Spread,
) -> Result<CameraModel, CalibrationError> {
    let c0 = spread.centroid;
    let mut ctrl = [c0; 4];
    for i in 0..3 {
        ctrl[i + 1] = c0 + spread.variances[i].sqrt() * spread.axes.column(i);
    }
    let basis = Matrix3::from_columns(&[ctrl[1] - c0, ctrl[2] - c0, ctrl[3] - c0]);
    let basis_inv = basis
        .try_inverse()
        .ok_or_else(|| CalibrationError::Degenerate {
            reason: "the EPnP control points are coplanar".to_string(),
        })?;
    let alphas: Vec<[f64; 4]> = obs
        .iter()
        .map(|o| {
            let a = basis_inv * (o.world - c0);
            [1.0 - a.x - a.y - a.z, a.x, a.y, a.z]
        })
        .collect();
    let k_inv = inverse_k(intrinsics)?;
    // M^T M accumulated point by point (M, 2n x 12, is never formed).
    let mut mtm = SMatrix::<f64, 12, 12>::zeros();
    for (a, o) in alphas.iter().zip(obs) {
        let p = normalised_point(&k_inv, &o.pixel);
        let mut r1 = SVector::<f64, 12>::zeros();
        let mut r2 = SVector::<f64, 12>::zeros();
        for j in 0..4 {
            r1[3 * j] = a[j];
            r1[3 * j + 2] = -a[j] * p.x;
            r2[3 * j + 1] = a[j];
            r2[3 * j + 2] = -a[j] * p.y;
        }
        mtm.syger(1.0, &r1, &r1, 1.0);
        mtm.syger(1.0, &r2, &r2, 1.0);
    }
    mtm.fill_upper_triangle_with_lower_triangle();
    let kernel: [SVector<f64, 12>; 4] =
        smallest_eigenvectors(&mtm).ok_or_else(|| CalibrationError::Degenerate {
            reason: "the EPnP system has no eigen-decomposition".to_string(),
        })?;

    let pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
    let dist2: Vec<f64> = pairs
        .iter()
        .map(|&(i, j)| (ctrl[i] - ctrl[j]).norm_squared())
        .collect();
    // deltas[p][k]: control-point difference of pair p in kernel vector k.
    let deltas: Vec<Vec<Vector3<f64>>> = pairs
        .iter()
        .map(|&(i, j)| {
            kernel
                .iter()
                .map(|v| {
                    Vector3::new(
                        v[3 * i] - v[3 * j],
                        v[3 * i + 1] - v[3 * j + 1],
                        v[3 * i + 2] - v[3 * j + 2],
                    )
                })
                .collect()
        })
        .collect();

    let mut starts: Vec<[f64; 4]> = Vec::new();
    // N = 1: x = b v_k with b from the control-point distances; v1 is
    // EPnP's choice, the others are extra starts for four or five points,
    // where the kernel has more than one dimension.
    for k in 0..4 {
        let (num, den) = deltas
            .iter()
            .zip(&dist2)
            .fold((0.0, 0.0), |(n, d), (dp, d2)| {
                let len = dp[k].norm();
                (n + len * d2.sqrt(), d + len * len)
            });
        if den > 0.0 {
            starts.push(std::array::from_fn(
                |j| if j == k { num / den } else { 0.0 },
            ));
        }
    }
    // N = 2, 3: linearised products b_i b_j from the six distances.
    for n in 2..=3 {
        let terms: Vec<(usize, usize)> = (0..n).flat_map(|a| (a..n).map(move |b| (a, b))).collect();
        let l = DMatrix::from_fn(6, terms.len(), |p, c| {
            let (a, b) = terms[c];
            let d = &deltas[p];
            if a == b {
                d[a].dot(&d[a])
            } else {
                2.0 * d[a].dot(&d[b])
            }
        });
        let rho = DVector::from_vec(dist2.clone());
        let Ok(b) = l.svd(true, true).solve(&rho, 1e-12) else {
            continue;
        };
        if b[0].is_nan() || b[0] <= 0.0 {
            continue;
        }
        let b1 = b[0].sqrt();
        starts.push(std::array::from_fn(|k| match k {
            0 => b1,
            k if k < n => b[k] / b1,
            _ => 0.0,
        }));
    }
    let candidates: Vec<Vec<f64>> = starts
        .iter()
        .flat_map(|beta| [*beta, refine_betas(*beta, &deltas, &dist2)])
        .map(|beta| {
            (0..12)
                .map(|r| (0..4).map(|k| beta[k] * kernel[k][r]).sum())
                .collect()
        })
        .collect();

    let world: Vec<Vector3<f64>> = obs.iter().map(|o| o.world).collect();
    let mut best: Option<(f64, CameraModel)> = None;
    for x in candidates {
        let mut cam: Vec<Vector3<f64>> = alphas
            .iter()
            .map(|a| {
                (0..4)
                    .map(|j| a[j] * Vector3::new(x[3 * j], x[3 * j + 1], x[3 * j + 2]))
                    .sum()
            })
            .collect();
        if cam.iter().map(|c| c.z).sum::<f64>() < 0.0 {
            cam.iter_mut().for_each(|c| *c = -*c);
        }
        let (r, t) = absolute_orientation(&world, &cam);
        let model = with_pose(intrinsics, r, t);
        if let Some(cost) = model.cost(obs)
            && best.as_ref().is_none_or(|(c, _)| cost < *c)
        {
            best = Some((cost, model));
        }
    }
    best.map(|(_, m)| m)
        .ok_or_else(|| CalibrationError::Degenerate {
            reason: "EPnP found no pose with every point in front".to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::dlt::spread;
    use crate::calibrate::io::model_of_device;
    use crate::calibrate::{fiducial_rig, projector_in_showcase, simulate_fiducials};

    #[test]
    fn newton_polar_rotation_matches_the_svd() {
        use nalgebra::Rotation3;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for i in 0..200 {
            let m = match i % 3 {
                // Near a rotation (a homography's columns).
                0 => {
                    Rotation3::new(Vector3::new(0.3, -1.1, 2.0 + i as f64)).into_inner()
                        + Matrix3::from_fn(|_, _| rng.random_range(-0.05..0.05))
                }
                // Anything, including reflections (det < 0: the SVD path).
                _ => Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0)),
            };
            let (fast, svd) = (nearest_rotation(&m), nearest_rotation_by_svd(&m));
            assert!((fast - svd).amax() < 1e-11, "{m} {fast} {svd}");
            assert!((fast.transpose() * fast - Matrix3::identity()).amax() < 1e-14);
            assert!((fast.determinant() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn epnp_is_exact_on_noise_free_points_down_to_four() {
        for seed in 0..8 {
            for n in [4, 5, 6, 20] {
                let truth = projector_in_showcase(seed);
                let input = simulate_fiducials(&truth, &fiducial_rig(n * 3, seed), 0.0, 1);
                let obs: Vec<Observation> = input.points[..n]
                    .iter()
                    .map(|p| Observation {
                        world: Vector3::from(p.world),
                        pixel: Vector2::from(p.pixel),
                    })
                    .collect();
                let tm = model_of_device(&truth);
                let m = epnp(&tm, &obs, &spread(&obs)).unwrap();
                let dr = (m.rotation - tm.rotation).abs().max();
                let dt = (m.translation - tm.translation).norm();
                assert!(
                    dr < 1e-9 && dt < 1e-9,
                    "seed {seed}, {n} points: R {dr:.2e}, t {dt:.2e}"
                );
            }
        }
    }
}
