//! The least-squares null vector of a Hartley-normalised linear system from
//! its normal matrix `A^T A`: inverse iteration on a fixed-size LDL^T
//! factorisation, with a full symmetric eigen-decomposition only when the
//! null space may not be one-dimensional.
//!
//! The DLT (12 unknowns), the homography (9) and EPnP (12) all need the
//! eigenvector of the smallest eigenvalue of a small symmetric positive
//! semi-definite matrix. A full eigen-decomposition costs tens of
//! microseconds, most of a linear start at six points; the smallest
//! eigenpair alone costs two small factorisations and a few triangular
//! solves, and nothing here allocates.

use nalgebra::{DMatrix, SMatrix, SVector, SymmetricEigen};

/// Below this ratio of the second-smallest to the largest singular value
/// of `A` (square roots of the eigenvalues of `A^T A`) the null space is
/// not one-dimensional: the linear system has no unique solution.
pub(crate) const NULL_SPACE_RATIO: f64 = 1e-7;

/// Inverse iterations before falling back to the full decomposition
/// (each gains a factor `lambda_2 / lambda_1`, so a handful suffice unless the
/// two smallest eigenvalues are close).
const MAX_INVERSE_ITERATIONS: usize = 40;

/// The iteration has converged when the unit vector moves less than this
/// (max-norm) in one step.
const CONVERGED_STEP: f64 = 1e-14;

/// Why no unique null vector came out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum NullSpaceError {
    /// The matrix has non-finite entries or the decomposition failed.
    NoDecomposition,
    /// The second-smallest singular value relative to the largest is below
    /// [`NULL_SPACE_RATIO`] (the ratio is given).
    NotUnique(f64),
}

/// `L D L^T` of a symmetric matrix without pivoting (`L` unit lower
/// triangular, stored below the diagonal).
struct Ldlt<const N: usize> {
    l: SMatrix<f64, N, N>,
    d: SVector<f64, N>,
}

impl<const N: usize> Ldlt<N> {
    /// Factor `m - shift I`. Each pivot passes through `pivot` first, which
    /// may replace it (a guard against zero pivots) or reject it (`None`).
    fn factor(
        m: &SMatrix<f64, N, N>,
        shift: f64,
        mut pivot: impl FnMut(f64) -> Option<f64>,
    ) -> Option<Self> {
        let mut l = SMatrix::<f64, N, N>::zeros();
        let mut d = SVector::<f64, N>::zeros();
        // ld[k] = L[j][k] d[k] for the current column j.
        let mut ld = [0.0; N];
        for j in 0..N {
            let mut dj = m[(j, j)] - shift;
            for k in 0..j {
                ld[k] = l[(j, k)] * d[k];
                dj -= l[(j, k)] * ld[k];
            }
            let dj = pivot(dj)?;
            d[j] = dj;
            for i in j + 1..N {
                let mut v = m[(i, j)];
                for k in 0..j {
                    v -= l[(i, k)] * ld[k];
                }
                l[(i, j)] = v / dj;
            }
        }
        Some(Self { l, d })
    }

    /// `x` with `(L D L^T) x = b`.
    fn solve(&self, b: &SVector<f64, N>) -> SVector<f64, N> {
        let mut x = *b;
        for i in 0..N {
            for k in 0..i {
                x[i] -= self.l[(i, k)] * x[k];
            }
        }
        for i in 0..N {
            x[i] /= self.d[i];
        }
        for i in (0..N).rev() {
            for k in i + 1..N {
                x[i] -= self.l[(k, i)] * x[k];
            }
        }
        x
    }
}

/// The unit eigenvector of the smallest eigenvalue of the symmetric
/// positive semi-definite `ata` (the normal matrix `A^T A` of a
/// homogeneous system `A x = 0`), or why there is none that is unique.
///
/// Fast path: when `ata - tau I`, with `tau = NULL_SPACE_RATIO^2 trace`,
/// has at most one negative pivot, the second eigenvalue exceeds
/// `NULL_SPACE_RATIO^2` times the largest (Sylvester's law of inertia;
/// `trace >= lambda_max`), and inverse iteration with that shift converges
/// to the smallest eigenvector. Otherwise, or when the iteration does not
/// settle, the full eigen-decomposition decides, as precisely as before.
pub(crate) fn null_vector<const N: usize>(
    ata: &SMatrix<f64, N, N>,
) -> Result<SVector<f64, N>, NullSpaceError> {
    if !ata.iter().all(|v| v.is_finite()) {
        return Err(NullSpaceError::NoDecomposition);
    }
    inverse_iteration(ata).map_or_else(|| by_eigen_decomposition(ata), Ok)
}

/// The fast path of [`null_vector`]; `None` sends the caller to the full
/// decomposition.
fn inverse_iteration<const N: usize>(ata: &SMatrix<f64, N, N>) -> Option<SVector<f64, N>> {
    let trace = ata.trace();
    if trace.is_nan() || trace <= 0.0 {
        return None;
    }
    let floor = f64::EPSILON * trace;
    let tau = NULL_SPACE_RATIO * NULL_SPACE_RATIO * trace;
    // The shifted matrix is near singular when lambda_1 is near 0: that
    // is what inverse iteration wants, but a pivot at the rounding level
    // would say nothing reliable about the inertia.
    let mut negative = 0;
    let f = Ldlt::factor(ata, tau, |d| {
        negative += usize::from(d < 0.0);
        (d.abs() > floor && negative <= 1).then_some(d)
    })?;
    // A start with no special relation to the systems' structure.
    let mut x = SVector::<f64, N>::from_fn(|i, _| 1.0 + (i as f64 + 1.0).sqrt()).normalize();
    for _ in 0..MAX_INVERSE_ITERATIONS {
        let y = f.solve(&x);
        let norm = y.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return None;
        }
        let y = y * (y.dot(&x).signum() / norm);
        let step = (y - x).amax();
        x = y;
        if step <= CONVERGED_STEP {
            // The eigenvalue nearest the shift: with one eigenvalue below
            // tau it must be that one (and not lambda_2 above); with none,
            // lambda_1 is the nearest.
            let below = x.dot(&(ata * x)) < tau;
            return (negative == 0 || below).then_some(x);
        }
    }
    None
}

/// The full symmetric eigen-decomposition: the smallest eigenvector, or the
/// exact singular-value ratio when it is below [`NULL_SPACE_RATIO`].
fn by_eigen_decomposition<const N: usize>(
    ata: &SMatrix<f64, N, N>,
) -> Result<SVector<f64, N>, NullSpaceError> {
    // The rare path: the dynamic decomposition serves every size.
    let m = DMatrix::from_column_slice(N, N, ata.as_slice());
    let eig =
        SymmetricEigen::try_new(m, f64::EPSILON, 200).ok_or(NullSpaceError::NoDecomposition)?;
    let mut order: [usize; N] = std::array::from_fn(|i| i);
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let (smallest, second, largest) = (order[0], order[1], order[N - 1]);
    let ratio =
        (eig.eigenvalues[second].max(0.0) / eig.eigenvalues[largest].max(f64::MIN_POSITIVE)).sqrt();
    if ratio < NULL_SPACE_RATIO {
        return Err(NullSpaceError::NotUnique(ratio));
    }
    Ok(SVector::from_iterator(
        eig.eigenvectors.column(smallest).iter().copied(),
    ))
}

/// The smallest `K` (at most 12) eigenvectors of a symmetric 12x12 matrix,
/// smallest first (EPnP's kernel); `None` when the decomposition fails.
pub(crate) fn smallest_eigenvectors<const K: usize>(
    m: &SMatrix<f64, 12, 12>,
) -> Option<[SVector<f64, 12>; K]> {
    if K > 12 || !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let eig = SymmetricEigen::try_new(*m, f64::EPSILON, 200)?;
    let mut order: [usize; 12] = std::array::from_fn(|i| i);
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    Some(std::array::from_fn(|k| {
        eig.eigenvectors.column(order[k]).into_owned()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `Q diag(values) Q^T` with a random orthogonal `Q`.
    fn with_spectrum<const N: usize>(values: [f64; N], seed: u64) -> SMatrix<f64, N, N> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = DMatrix::<f64>::from_fn(N, N, |_, _| rng.random_range(-1.0..1.0));
        let q = g.qr().q();
        let m = &q
            * DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&values))
            * q.transpose();
        SMatrix::from_column_slice(m.as_slice())
    }

    fn assert_parallel<const N: usize>(a: &SVector<f64, N>, b: &SVector<f64, N>, tol: f64) {
        let d = (a - b).amax().min((a + b).amax());
        assert!(d < tol, "vectors differ by {d:.3e}");
    }

    #[test]
    fn fast_path_matches_the_full_decomposition() {
        for seed in 0..20 {
            // A spread of well-separated spectra, from an exact null space
            // to a noisy one, as in a Hartley-normalised DLT.
            let smallest = [0.0, 1e-30, 1e-12, 1e-6, 1e-3][seed as usize % 5];
            let mut values = [0.0; 12];
            for (i, v) in values.iter_mut().enumerate() {
                *v = 0.05 * (i as f64 + 1.0).powi(2);
            }
            values[7] = smallest;
            let m = with_spectrum(values, seed);
            let fast = inverse_iteration(&m).expect("fast path");
            let full = by_eigen_decomposition(&m).unwrap();
            assert_parallel(&fast, &full, 1e-12);
            // It is the eigenvector of the smallest eigenvalue.
            let residual = (m * fast - fast * smallest).amax();
            assert!(residual < 1e-13, "seed {seed}: residual {residual:.3e}");
        }
    }

    #[test]
    fn a_two_dimensional_null_space_is_not_unique() {
        let mut values = [1.0; 9];
        values[2] = 0.0;
        values[5] = 1e-20;
        let m = with_spectrum(values, 3);
        match null_vector(&m) {
            Err(NullSpaceError::NotUnique(ratio)) => assert!(ratio < NULL_SPACE_RATIO),
            other => panic!("expected NotUnique, got {other:?}"),
        }
        // Just above the threshold it is unique, and found.
        values[5] = 1e-12;
        let m = with_spectrum(values, 3);
        let v = null_vector(&m).unwrap();
        assert!((m * v).amax() < 1e-12);
    }

    #[test]
    fn close_smallest_eigenvalues_fall_back_and_still_answer() {
        // lambda_1 / lambda_2 = 0.99: inverse iteration would crawl.
        let mut values = [2.0; 9];
        values[0] = 0.99e-3;
        values[1] = 1e-3;
        let m = with_spectrum(values, 7);
        assert!(inverse_iteration(&m).is_none());
        let v = null_vector(&m).unwrap();
        assert!((m * v - v * 0.99e-3).amax() < 1e-12);
    }

    #[test]
    fn non_finite_and_zero_matrices_are_errors() {
        let mut m = SMatrix::<f64, 9, 9>::identity();
        m[(3, 4)] = f64::NAN;
        assert_eq!(null_vector(&m), Err(NullSpaceError::NoDecomposition));
        let z = SMatrix::<f64, 9, 9>::zeros();
        assert!(matches!(null_vector(&z), Err(NullSpaceError::NotUnique(_))));
    }

    #[test]
    fn smallest_eigenvectors_are_sorted() {
        let values = [5.0, 0.5, 3.0, 0.1, 4.0, 0.3, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0];
        let m = with_spectrum(values, 1);
        let k: [SVector<f64, 12>; 4] = smallest_eigenvectors(&m).unwrap();
        for (v, lambda) in k.iter().zip([0.1, 0.3, 0.5, 3.0]) {
            assert!((m * v - v * lambda).amax() < 1e-12);
        }
    }
}
