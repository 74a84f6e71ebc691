//! The small dense solvers the IK methods need, written for fixed sizes so that nothing allocates
//! and every failure is a value: Cholesky for the damped normal equations, and a cyclic Jacobi
//! eigen-decomposition for the true pseudoinverse.

use crate::Real;
use nalgebra::{SMatrix, SVector};

/// Solves `a x = b` for a symmetric positive definite `a` by Cholesky (`a = L L^T`), reading only
/// the lower triangle of `a`. Returns `None` if `a` is not numerically positive definite or the
/// result is not finite.
pub fn cholesky_solve<T: Real, const K: usize>(a: &SMatrix<T, K, K>, b: &SVector<T, K>) -> Option<SVector<T, K>> {
    cholesky_solve_leading(a, b, K)
}

/// [`cholesky_solve`] of the leading `k x k` block of `a` with the first `k` entries of `b`; the
/// rest of the result is zero. One solver serves systems of several sizes held in one storage,
/// with the arithmetic of a solver of size `k`.
///
/// Plain arrays rather than nalgebra indexing: this runs every IK iteration, and the fixed-size
/// array loops compile without bounds checks. Index loops mirror the textbook algorithm.
#[allow(clippy::needless_range_loop)]
pub fn cholesky_solve_leading<T: Real, const K: usize>(
    a: &SMatrix<T, K, K>,
    b: &SVector<T, K>,
    k: usize,
) -> Option<SVector<T, K>> {
    let size = k.min(K);
    let mut l = [[T::zero(); K]; K];
    let mut inv_diag = [T::zero(); K];
    for j in 0..size {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        // Written so that NaN also fails: a NaN pivot is not positive definite.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        if !(d > T::zero()) {
            return None;
        }
        let d = d.sqrt();
        l[j][j] = d;
        inv_diag[j] = T::one() / d;
        for i in j + 1..size {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s * inv_diag[j];
        }
    }
    // Forward then backward substitution.
    let mut y = [T::zero(); K];
    for i in 0..size {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s * inv_diag[i];
    }
    for i in (0..size).rev() {
        let mut s = y[i];
        for k in i + 1..size {
            s -= l[k][i] * y[k];
        }
        y[i] = s * inv_diag[i];
    }
    y.iter().all(|v| v.finite()).then(|| SVector::from(y))
}

/// Eigen-decomposition of a symmetric matrix by cyclic Jacobi rotations: returns the eigenvalues
/// and the orthogonal matrix whose columns are the eigenvectors. Converges quadratically; the sweep
/// count is bounded so that the function always returns.
pub fn symmetric_eigen<T: Real, const K: usize>(a: &SMatrix<T, K, K>) -> (SVector<T, K>, SMatrix<T, K, K>) {
    let mut a = *a;
    let mut v = SMatrix::<T, K, K>::identity();
    for _sweep in 0..50 {
        let mut off = T::zero();
        for p in 0..K {
            for q in p + 1..K {
                off += a[(p, q)] * a[(p, q)];
            }
        }
        let scale = a.norm_squared();
        // NaN stops the sweeps too (no comparison with NaN is true).
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        if !(off > T::EPSILON * T::EPSILON * scale) {
            break;
        }
        for p in 0..K {
            for q in p + 1..K {
                let apq = a[(p, q)];
                if apq == T::zero() {
                    continue;
                }
                // Rotation that zeroes a[p][q] (Golub & Van Loan, symmetric Schur decomposition).
                let theta = (a[(q, q)] - a[(p, p)]) / (T::of(2.0) * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + T::one()).sqrt());
                let t = if theta == T::zero() { T::one() } else { t };
                let c = T::one() / (t * t + T::one()).sqrt();
                let s = t * c;
                for k in 0..K {
                    let akp = a[(k, p)];
                    let akq = a[(k, q)];
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..K {
                    let apk = a[(p, k)];
                    let aqk = a[(q, k)];
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
                for k in 0..K {
                    let vkp = v[(k, p)];
                    let vkq = v[(k, q)];
                    v[(k, p)] = c * vkp - s * vkq;
                    v[(k, q)] = s * vkp + c * vkq;
                }
            }
        }
    }
    (SVector::from_fn(|i, _| a[(i, i)]), v)
}

/// Minimum-norm least-squares solution `x = J^+ e` of `J x = e` for an `M x N` matrix, through the
/// eigen-decomposition of `J^T J`; singular values below `rcond * max` count as zero.
pub fn pseudoinverse_solve<T: Real, const M: usize, const N: usize>(
    j: &SMatrix<T, M, N>,
    e: &SVector<T, M>,
    rcond: T,
) -> SVector<T, N> {
    let (eigenvalues, v) = symmetric_eigen(&(j.transpose() * j));
    let largest = eigenvalues.iter().fold(T::zero(), |m, &x| m.max(x));
    // Eigenvalues of J^T J are squared singular values.
    let cutoff = largest * rcond * rcond;
    let projected = v.transpose() * (j.transpose() * e);
    let scaled = SVector::<T, N>::from_fn(|i, _| {
        let l = eigenvalues[i];
        if l > cutoff && l > T::zero() {
            projected[i] / l
        } else {
            T::zero()
        }
    });
    v * scaled
}
