//! Linear starts: Hartley-normalised DLT of the 3x4 projection, its RQ
//! decomposition into K, R, t, the planar homography, and the spread test
//! that tells collinear and coplanar fiducials apart.

use super::CalibrationError;
use super::camera::{CameraModel, Observation};
use super::nullspace::{NullSpaceError, null_vector};
use nalgebra::{Matrix3, Matrix3x4, SMatrix, SVector, SymmetricEigen, Vector2, Vector3};

/// Singular values of the centred world points, largest first, relative to
/// the largest: `[1, s2/s1, s3/s1]`, with the principal axes as columns.
pub(crate) struct Spread {
    /// Centroid of the points.
    pub(crate) centroid: Vector3<f64>,
    /// `s2 / s1`: near zero for collinear points.
    pub(crate) line_ratio: f64,
    /// `s3 / s1`: near zero for coplanar points.
    pub(crate) plane_ratio: f64,
    /// Principal axes, largest spread first; the third is the plane normal.
    pub(crate) axes: Matrix3<f64>,
    /// Variances along the axes (eigenvalues of the covariance).
    pub(crate) variances: Vector3<f64>,
}

/// Below this `s2/s1` the fiducials count as collinear.
pub(crate) const COLLINEAR_RATIO: f64 = 1e-6;
/// Below this `s3/s1` (thickness under 0.1% of the extent) the fiducials
/// count as coplanar: the intrinsics cannot be separated from the pose.
pub(crate) const COPLANAR_RATIO: f64 = 1e-3;

/// The principal spread of the world points.
pub(crate) fn spread(obs: &[Observation]) -> Spread {
    let n = obs.len() as f64;
    let centroid = obs.iter().map(|o| o.world).sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    for o in obs {
        let d = o.world - centroid;
        cov += d * d.transpose();
    }
    cov /= n;
    let eig = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let variances = Vector3::from_fn(|i, _| eig.eigenvalues[order[i]].max(0.0));
    let mut axes = Matrix3::from_fn(|r, c| eig.eigenvectors[(r, order[c])]);
    if axes.determinant() < 0.0 {
        axes.set_column(2, &(-axes.column(2)));
    }
    let s1 = variances[0].sqrt();
    let ratio = |v: f64| if s1 > 0.0 { v.sqrt() / s1 } else { 0.0 };
    Spread {
        centroid,
        line_ratio: ratio(variances[1]),
        plane_ratio: ratio(variances[2]),
        axes,
        variances,
    }
}

/// Similarity that moves 2D points to their centroid with mean distance
/// sqrt(2) (Hartley); `None` when all points coincide.
fn normalise_2d(points: impl Iterator<Item = Vector2<f64>> + Clone) -> Option<Matrix3<f64>> {
    let n = points.clone().count() as f64;
    let c = points.clone().sum::<Vector2<f64>>() / n;
    let mean = points.map(|p| (p - c).norm()).sum::<f64>() / n;
    if mean.is_nan() || mean <= 0.0 {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean;
    Some(Matrix3::new(
        s,
        0.0,
        -s * c.x,
        0.0,
        s,
        -s * c.y,
        0.0,
        0.0,
        1.0,
    ))
}

/// The normal matrix `A^T A` (`N = 3 K` unknowns) of the homogeneous DLT
/// system with the rows `[0, -x, v x]` and `[x, 0, -u x]` for each
/// normalised pair of a point `x` (homogeneous, `K` entries) and a pixel
/// `(u, v)`. With `S = sum x x^T` and its weighted sums `S_u` (by u), `S_v`
/// (by v), `S_w` (by `u^2 + v^2`) it is
/// `[[S, 0, -S_u], [0, S, -S_v], [-S_u, -S_v, S_w]]`: four K x K sums per
/// point instead of two N x N outer products, and the 2n x N `A` is never formed.
fn dlt_normal_matrix<const K: usize, const N: usize>(
    pairs: impl Iterator<Item = (SVector<f64, K>, Vector2<f64>)>,
) -> SMatrix<f64, N, N> {
    const { assert!(N == 3 * K) };
    let mut s = [SMatrix::<f64, K, K>::zeros(); 4];
    for (x, p) in pairs {
        let xx = x * x.transpose();
        s[0] += xx;
        s[1] += xx * p.x;
        s[2] += xx * p.y;
        s[3] += xx * (p.x * p.x + p.y * p.y);
    }
    let mut m = SMatrix::<f64, N, N>::zeros();
    let mut put = |r: usize, c: usize, block: &SMatrix<f64, K, K>| {
        m.fixed_view_mut::<K, K>(r * K, c * K).copy_from(block);
    };
    let (su, sv) = (-s[1], -s[2]);
    put(0, 0, &s[0]);
    put(1, 1, &s[0]);
    put(0, 2, &su);
    put(2, 0, &su);
    put(1, 2, &sv);
    put(2, 1, &sv);
    put(2, 2, &s[3]);
    m
}

/// Normalised DLT: the projection matrix P (up to scale) from at least six
/// non-coplanar correspondences with their [`spread`].
///
/// The 12x12 normal matrix `A^T A` of the Hartley-normalised system is
/// accumulated point by point (the 2n x 12 `A` is never formed) and its
/// smallest eigenvector taken; normalisation keeps it well conditioned.
pub(crate) fn projection_dlt(
    obs: &[Observation],
    sp: &Spread,
) -> Result<Matrix3x4<f64>, CalibrationError> {
    let degenerate = |reason: &str| CalibrationError::Degenerate {
        reason: reason.to_string(),
    };
    let t2 = normalise_2d(obs.iter().map(|o| o.pixel))
        .ok_or_else(|| degenerate("all pixels coincide"))?;
    let n = obs.len() as f64;
    let mean3 = obs
        .iter()
        .map(|o| (o.world - sp.centroid).norm())
        .sum::<f64>()
        / n;
    let s3 = 3f64.sqrt() / mean3;
    let ata: SMatrix<f64, 12, 12> = dlt_normal_matrix(obs.iter().map(|o| {
        let x = (o.world - sp.centroid) * s3;
        let p = t2 * o.pixel.push(1.0);
        (x.push(1.0), p.xy())
    }));
    let v = null_vector(&ata).map_err(|e| match e {
        NullSpaceError::NoDecomposition => degenerate("the DLT system has no eigen-decomposition"),
        NullSpaceError::NotUnique(ratio) => degenerate(&format!(
            "the DLT solution is not unique (singular value ratio {ratio:.3e})"
        )),
    })?;
    let pn = Matrix3x4::from_row_slice(v.as_slice());
    // Undo the normalisations: P = T2^-1 Pn T3.
    let c = sp.centroid;
    let t3 = nalgebra::Matrix4::new(
        s3,
        0.0,
        0.0,
        -s3 * c.x,
        0.0,
        s3,
        0.0,
        -s3 * c.y,
        0.0,
        0.0,
        s3,
        -s3 * c.z,
        0.0,
        0.0,
        0.0,
        1.0,
    );
    let t2_inv = t2
        .try_inverse()
        .ok_or_else(|| degenerate("singular pixel normalisation"))?;
    Ok(t2_inv * pn * t3)
}

/// RQ decomposition of a 3x3 matrix: `m = k * r` with `k` upper
/// triangular with a positive diagonal and `r` orthogonal.
pub(crate) fn rq(m: &Matrix3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    // With the row-reversal permutation E and the QR (E m)^T = Q U:
    // m = E U^T Q^T = (E U^T E) (E Q^T), upper triangular times orthogonal.
    let e = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
    let qr = (e * m).transpose().qr();
    let (q, u) = (qr.q(), qr.r());
    let mut k = e * u.transpose() * e;
    let mut r = e * q.transpose();
    for i in 0..3 {
        if k[(i, i)] < 0.0 {
            // K D and D R with D = diag(.., -1, ..) leave the product alone.
            k.set_column(i, &(-k.column(i)));
            r.set_row(i, &(-r.row(i)));
        }
    }
    (k, r)
}

/// K, R, t from a projection matrix: sign fixed so most points lie in
/// front, K scaled to `K[2][2] = 1`, R a proper rotation.
pub(crate) fn decompose_projection(
    p: &Matrix3x4<f64>,
    obs: &[Observation],
) -> Result<CameraModel, CalibrationError> {
    let in_front = obs
        .iter()
        .filter(|o| (p.row(2) * o.world.push(1.0))[0] > 0.0)
        .count();
    let p = if 2 * in_front >= obs.len() { *p } else { -p };
    let m: Matrix3<f64> = p.fixed_view::<3, 3>(0, 0).into_owned();
    if m.determinant() <= 0.0 {
        return Err(CalibrationError::Degenerate {
            reason: format!(
                "the DLT projection is a reflection (det {:.3e}); the points may be mislabelled",
                m.determinant()
            ),
        });
    }
    let (k_raw, r) = rq(&m);
    let scale = k_raw[(2, 2)];
    let k = k_raw / scale;
    let k_inv = k_raw
        .try_inverse()
        .ok_or_else(|| CalibrationError::Degenerate {
            reason: "the DLT camera matrix is singular".to_string(),
        })?;
    let t = k_inv * p.column(3);
    Ok(CameraModel::from_k(&k, r, t))
}

/// Normalised DLT homography `H` with `pixel ~ H [a, b, 1]` from planar
/// coordinates to image points, given as `(plane, image)` pairs (at least
/// four). Like [`projection_dlt`], through the 9x9 normal matrix.
pub(crate) fn homography(
    pairs: &[(Vector2<f64>, Vector2<f64>)],
) -> Result<Matrix3<f64>, CalibrationError> {
    let degenerate = |reason: String| CalibrationError::Degenerate { reason };
    let ta = normalise_2d(pairs.iter().map(|(x, _)| *x))
        .ok_or_else(|| degenerate("all plane points coincide".into()))?;
    let tb = normalise_2d(pairs.iter().map(|(_, u)| *u))
        .ok_or_else(|| degenerate("all image points coincide".into()))?;
    let ata: SMatrix<f64, 9, 9> = dlt_normal_matrix(pairs.iter().map(|(x, u)| {
        let u = tb * u.push(1.0);
        (ta * x.push(1.0), u.xy())
    }));
    let v = null_vector(&ata).map_err(|e| match e {
        NullSpaceError::NoDecomposition => {
            degenerate("the homography system has no eigen-decomposition".into())
        }
        NullSpaceError::NotUnique(ratio) => degenerate(format!(
            "the homography is not unique (singular value ratio {ratio:.3e})"
        )),
    })?;
    let hn = Matrix3::from_row_slice(v.as_slice());
    let tb_inv = tb
        .try_inverse()
        .ok_or_else(|| degenerate("singular image normalisation".into()))?;
    Ok(tb_inv * hn * ta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn rq_gives_positive_upper_triangular_and_rotation() {
        let k = Matrix3::new(800.0, 3.0, 320.0, 0.0, 820.0, 240.0, 0.0, 0.0, 1.0);
        let r = Rotation3::new(Vector3::new(0.4, -1.2, 2.5)).into_inner();
        for scale in [1.0, 2.5] {
            let (k2, r2) = rq(&(k * r * scale));
            assert!((k2 / k2[(2, 2)] - k).abs().max() < 1e-9);
            assert!((r2 - r).abs().max() < 1e-12);
            assert!((r2.determinant() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn spread_tells_lines_and_planes() {
        let obs = |pts: &[[f64; 3]]| {
            pts.iter()
                .map(|p| Observation {
                    world: Vector3::from(*p),
                    pixel: Vector2::zeros(),
                })
                .collect::<Vec<_>>()
        };
        let line = obs(&[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]);
        assert!(spread(&line).line_ratio < COLLINEAR_RATIO);
        let plane = obs(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ]);
        let s = spread(&plane);
        assert!(s.line_ratio > 0.5 && s.plane_ratio < COPLANAR_RATIO);
        assert!((s.axes.column(2).z.abs() - 1.0).abs() < 1e-12);
        let solid = obs(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]);
        assert!(spread(&solid).plane_ratio > 0.5);
    }
}
