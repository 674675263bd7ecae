//! Symmetric positive-definite block-tridiagonal systems with 18x18 blocks.
//!
//! The normal equations of the trajectory fit couple each knot only with its neighbours, so the
//! information matrix is block tridiagonal. [`BlockTridiagonal::factor`] eliminates the blocks in
//! order (a block Cholesky, O(N) time and memory); the factor then solves for a step, gives the
//! log-determinant, and yields the blocks of the inverse (the posterior covariance) that lie on
//! and next to the diagonal.
//!
//! The elimination works in place on the system's storage with small dense kernels on the
//! column-major arrays of the blocks (18 is too small for blocked algorithms and too large for
//! full unrolling; the kernels keep every inner loop a contiguous `y += a x` that vectorises).

use nalgebra::{SMatrix, SVector};

use crate::error::{Error, Result};

/// Block size.
const N: usize = 18;

/// 18x18 block.
pub type M18 = SMatrix<f64, 18, 18>;
/// 18-vector.
pub type V18 = SVector<f64, 18>;

/// Column-major storage of a block: `cols(m)[c][r] == m[(r, c)]`.
type Cols = [[f64; N]; N];

#[inline]
fn cols(m: &M18) -> &Cols {
    &m.data.0
}

#[inline]
fn cols_mut(m: &mut M18) -> &mut Cols {
    &mut m.data.0
}

/// In-place Cholesky factorisation `S = L L^T` of a symmetric matrix (only its lower triangle is
/// read). On success the lower triangle holds `L`, the strict upper triangle is zeroed, and the
/// result is `log det S`; `None` when `S` is not (numerically) positive definite.
pub fn cholesky_in_place(s: &mut M18) -> Option<f64> {
    let a = cols_mut(s);
    let mut log_det = 0.0;
    for j in 0..N {
        let d = a[j][j];
        if d.is_nan() || d <= 0.0 || d.is_infinite() {
            return None;
        }
        let d = d.sqrt();
        log_det += 2.0 * d.ln();
        a[j][j] = d;
        a[j][j + 1..].iter_mut().for_each(|v| *v /= d);
        a[j][..j].fill(0.0);
        // Right-looking update of the trailing lower triangle.
        let lj = a[j];
        for (k, col) in a.iter_mut().enumerate().skip(j + 1) {
            let l_kj = lj[k];
            for r in k..N {
                col[r] -= lj[r] * l_kj;
            }
        }
    }
    Some(log_det)
}

/// `x <- L^-1 x` for the lower-triangular `L` of [`cholesky_in_place`].
#[inline]
fn forward_substitute(l: &Cols, x: &mut [f64; N]) {
    for j in 0..N {
        x[j] /= l[j][j];
        let xj = x[j];
        for r in j + 1..N {
            x[r] -= l[j][r] * xj;
        }
    }
}

/// `x <- L^-T x`, with `lt` the columns of `L^T` (the rows of `L`).
#[inline]
fn backward_substitute(lt: &Cols, x: &mut [f64; N]) {
    for j in (0..N).rev() {
        x[j] /= lt[j][j];
        let xj = x[j];
        for r in 0..j {
            x[r] -= lt[j][r] * xj;
        }
    }
}

/// Transpose of a block.
#[inline]
fn transpose(m: &Cols) -> Cols {
    let mut t = [[0.0; N]; N];
    for (c, col) in m.iter().enumerate() {
        for (r, v) in col.iter().enumerate() {
            t[r][c] = *v;
        }
    }
    t
}

/// `out = a b`.
pub fn mul(a: &M18, b: &M18) -> M18 {
    let (a, b) = (cols(a), cols(b));
    let mut out = M18::zeros();
    for (o, bc) in cols_mut(&mut out).iter_mut().zip(b) {
        for (ak, bkj) in a.iter().zip(bc) {
            for r in 0..N {
                o[r] += ak[r] * bkj;
            }
        }
    }
    out
}

/// `out += sign a b^T` on the lower triangle of `out`, then mirrored to the upper triangle (for
/// products known to be symmetric).
fn add_symmetric_abt(out: &mut M18, a: &Cols, b: &Cols, sign: f64) {
    let o = cols_mut(out);
    let mut acc = [[0.0; N]; N];
    for (m, am) in a.iter().enumerate() {
        for (j, accj) in acc.iter_mut().enumerate() {
            let bjm = b[m][j];
            for r in j..N {
                accj[r] += am[r] * bjm;
            }
        }
    }
    for j in 0..N {
        for (v, s) in o[j][j..].iter_mut().zip(&acc[j][j..]) {
            *v += sign * s;
        }
        let (left, right) = o.split_at_mut(j);
        for (r, col) in left.iter().enumerate() {
            right[0][r] = col[j];
        }
    }
}

/// `S^-1` from the Cholesky factor `L` of `S` (lower triangle of `l`).
pub fn inverse_from_cholesky(l: &M18) -> M18 {
    // V = L^-T (upper triangular); S^-1 = V V^T, the sum of outer products of V's columns.
    let lt = transpose(cols(l));
    let mut v = [[0.0; N]; N];
    for (c, vc) in v.iter_mut().enumerate() {
        vc[c] = 1.0;
        backward_substitute(&lt, vc);
    }
    let mut out = M18::zeros();
    let o = cols_mut(&mut out);
    for (k, vk) in v.iter().enumerate() {
        for j in 0..=k {
            let s = vk[j];
            for r in 0..=k {
                o[j][r] += vk[r] * s;
            }
        }
    }
    out
}

/// `A` with diagonal blocks `diag[k]` and upper blocks `upper[k] = A[k, k+1]`; the lower blocks
/// are their transposes. `rhs` is the right-hand side of `A x = rhs`.
#[derive(Clone, Debug)]
pub struct BlockTridiagonal {
    pub diag: Vec<M18>,
    pub upper: Vec<M18>,
    pub rhs: Vec<V18>,
}

/// The eliminated system, in the storage of the [`BlockTridiagonal`] it came from: the Cholesky
/// factors `L_k` of the Schur complements `S_k`, the gains `G_k = S_k^-1 B_k` and the forward
/// solution `w_k = L_k^-1 z_k` of the eliminated right-hand side.
pub struct Factored {
    chol: Vec<M18>,
    gain: Vec<M18>,
    w: Vec<V18>,
    log_det: f64,
}

/// Diagonal and first off-diagonal blocks of `A^-1`.
#[derive(Clone, Debug, Default)]
pub struct BandedInverse {
    /// `Sigma[k, k]`.
    pub diag: Vec<M18>,
    /// `Sigma[k, k+1]`.
    pub upper: Vec<M18>,
}

impl BlockTridiagonal {
    /// A zero system of `n` blocks.
    pub fn zeros(n: usize) -> Self {
        BlockTridiagonal {
            diag: vec![M18::zeros(); n],
            upper: vec![M18::zeros(); n.saturating_sub(1)],
            rhs: vec![V18::zeros(); n],
        }
    }

    pub fn len(&self) -> usize {
        self.diag.len()
    }

    pub fn is_empty(&self) -> bool {
        self.diag.is_empty()
    }

    /// Block elimination; fails when a Schur complement is not positive definite.
    ///
    /// With `S_0 = D_0`, `z_0 = r_0` and `S_k = L_k L_k^T`: `Y_k = L_k^-1 B_k`,
    /// `S_{k+1} = D_{k+1} - Y_k^T Y_k`, `G_k = L_k^-T Y_k`, `w_k = L_k^-1 z_k`,
    /// `z_{k+1} = r_{k+1} - Y_k^T w_k`.
    pub fn factor(self) -> Result<Factored> {
        let BlockTridiagonal {
            diag: mut chol,
            upper: mut gain,
            rhs: mut w,
        } = self;
        let n = chol.len();
        if n == 0 {
            return Err(Error::Numerical("empty system".into()));
        }
        let mut log_det = 0.0;
        for k in 0..n {
            log_det += cholesky_in_place(&mut chol[k]).ok_or_else(|| {
                Error::Numerical(format!(
                    "information matrix not positive definite at knot {k} (too few or degenerate measurements)"
                ))
            })?;
            let l = *cols(&chol[k]);
            let mut wk: [f64; N] = w[k].into();
            forward_substitute(&l, &mut wk);
            w[k] = wk.into();
            if k + 1 < n {
                // Rows of Y = L^-1 B by forward substitution on the rows of B, so that every
                // inner loop runs over a full row of 18.
                let mut y = transpose(cols(&gain[k]));
                for j in 0..N {
                    let (done, rest) = y.split_at_mut(j);
                    let yj = &mut rest[0];
                    for (yk, lk) in done.iter().zip(&l) {
                        let l_jk = lk[j];
                        for (a, b) in yj.iter_mut().zip(yk) {
                            *a -= l_jk * b;
                        }
                    }
                    let d = l[j][j];
                    yj.iter_mut().for_each(|a| *a /= d);
                }
                // S_{k+1} = D_{k+1} - Y^T Y (a sum of outer products of the rows of Y; both
                // triangles are formed, with identical roundings, so it stays symmetric).
                let s = cols_mut(&mut chol[k + 1]);
                let mut yty = [[0.0; N]; N];
                for yj in &y {
                    for (col, yjc) in yty.iter_mut().zip(yj) {
                        for (a, b) in col.iter_mut().zip(yj) {
                            *a += b * yjc;
                        }
                    }
                }
                for (sc, pc) in s.iter_mut().zip(&yty) {
                    for (a, b) in sc.iter_mut().zip(pc) {
                        *a -= b;
                    }
                }
                // z_{k+1} = r_{k+1} - Y^T w_k.
                let mut ytw = [0.0; N];
                for (yj, wj) in y.iter().zip(&wk) {
                    for (a, b) in ytw.iter_mut().zip(yj) {
                        *a += b * wj;
                    }
                }
                w[k + 1] -= V18::from(ytw);
                // Rows of G = L^-T Y by backward substitution (column j of L below the diagonal
                // holds the multipliers of row j).
                for j in (0..N).rev() {
                    let (head, done) = y.split_at_mut(j + 1);
                    let gj = &mut head[j];
                    for (gk, l_kj) in done.iter().zip(&l[j][j + 1..]) {
                        for (a, b) in gj.iter_mut().zip(gk) {
                            *a -= l_kj * b;
                        }
                    }
                    let d = l[j][j];
                    gj.iter_mut().for_each(|a| *a /= d);
                }
                *cols_mut(&mut gain[k]) = transpose(&y);
            }
        }
        Ok(Factored {
            chol,
            gain,
            w,
            log_det,
        })
    }
}

impl Factored {
    /// The solution `x` of `A x = rhs`: `x_k = L_k^-T w_k - G_k x_{k+1}`.
    pub fn solve(&self) -> Vec<V18> {
        let n = self.chol.len();
        let mut x = vec![V18::zeros(); n];
        for k in (0..n).rev() {
            let mut xk: [f64; N] = self.w[k].into();
            backward_substitute(&transpose(cols(&self.chol[k])), &mut xk);
            if k + 1 < n {
                let g = cols(&self.gain[k]);
                for (gc, xc) in g.iter().zip(x[k + 1].iter()) {
                    for r in 0..N {
                        xk[r] -= gc[r] * xc;
                    }
                }
            }
            x[k] = xk.into();
        }
        x
    }

    /// The solution `x` of `A x = rhs` for another right-hand side (one block per knot).
    ///
    /// Forward: `z_0 = r_0`, `z_{k+1} = r_{k+1} - G_k^T z_k` (since `Y_k^T L_k^-1 = G_k^T`),
    /// `w_k = L_k^-1 z_k`; backward as in [`Factored::solve`].
    pub fn solve_rhs(&self, rhs: &[V18]) -> Vec<V18> {
        let n = self.chol.len();
        let mut w = Vec::with_capacity(n);
        let mut z = rhs.first().copied().unwrap_or_else(V18::zeros);
        for k in 0..n {
            let mut wk: [f64; N] = z.into();
            forward_substitute(cols(&self.chol[k]), &mut wk);
            w.push(V18::from(wk));
            if k + 1 < n {
                z = rhs.get(k + 1).copied().unwrap_or_else(V18::zeros)
                    - self.gain[k].transpose() * z;
            }
        }
        let mut x = vec![V18::zeros(); n];
        for k in (0..n).rev() {
            let mut xk: [f64; N] = w[k].into();
            backward_substitute(&transpose(cols(&self.chol[k])), &mut xk);
            let mut xv = V18::from(xk);
            if k + 1 < n {
                xv -= self.gain[k] * x[k + 1];
            }
            x[k] = xv;
        }
        x
    }

    /// The storage of the factor, as a system to assemble into (its contents are meaningless).
    pub fn into_system(self) -> BlockTridiagonal {
        BlockTridiagonal {
            diag: self.chol,
            upper: self.gain,
            rhs: self.w,
        }
    }

    /// `log det A`.
    pub fn log_det(&self) -> f64 {
        self.log_det
    }

    /// Blocks of `A^-1` on and next to the diagonal, by the backward recursion
    /// `Sigma_k = S_k^-1 + G_k Sigma_{k+1} G_k^T`, `Sigma_{k,k+1} = -G_k Sigma_{k+1}`. Reuses the
    /// factor's storage.
    pub fn banded_inverse(self) -> BandedInverse {
        let Factored {
            chol: mut diag,
            gain: mut upper,
            ..
        } = self;
        let n = diag.len();
        for k in (0..n).rev() {
            let mut d = inverse_from_cholesky(&diag[k]);
            if k + 1 < n {
                let off = -mul(&upper[k], &diag[k + 1]);
                add_symmetric_abt(&mut d, cols(&off), cols(&upper[k]), -1.0);
                upper[k] = off;
            }
            diag[k] = d;
        }
        BandedInverse { diag, upper }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn pseudo_random(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
    }

    fn random_system(n: usize, seed: &mut u64) -> BlockTridiagonal {
        // Build A = J^T J from a random banded J so that A is SPD and block tridiagonal.
        let mut sys = BlockTridiagonal::zeros(n);
        for k in 0..n {
            let mut j = M18::zeros();
            j.iter_mut().for_each(|v| *v = pseudo_random(seed));
            sys.diag[k] += j.transpose() * j + M18::identity() * 0.5;
            sys.rhs[k] = V18::from_fn(|_, _| pseudo_random(seed));
        }
        for k in 0..n - 1 {
            let mut j1 = M18::zeros();
            let mut j2 = M18::zeros();
            j1.iter_mut().for_each(|v| *v = pseudo_random(seed));
            j2.iter_mut().for_each(|v| *v = pseudo_random(seed));
            sys.diag[k] += j1.transpose() * j1;
            sys.diag[k + 1] += j2.transpose() * j2;
            sys.upper[k] += j1.transpose() * j2;
        }
        sys
    }

    fn dense(sys: &BlockTridiagonal) -> DMatrix<f64> {
        let n = sys.len();
        let mut a = DMatrix::zeros(18 * n, 18 * n);
        for k in 0..n {
            a.view_mut((18 * k, 18 * k), (18, 18))
                .copy_from(&sys.diag[k]);
            if k + 1 < n {
                a.view_mut((18 * k, 18 * (k + 1)), (18, 18))
                    .copy_from(&sys.upper[k]);
                a.view_mut((18 * (k + 1), 18 * k), (18, 18))
                    .copy_from(&sys.upper[k].transpose());
            }
        }
        a
    }

    #[test]
    fn matches_dense_solution_inverse_and_determinant() {
        let mut seed = 7;
        for n in [1usize, 2, 5, 9] {
            let sys = random_system(n, &mut seed);
            let a = dense(&sys);
            let b = DMatrix::from_fn(18 * n, 1, |i, _| sys.rhs[i / 18][i % 18]);
            let f = sys.clone().factor().unwrap();
            let x = f.solve();
            let x2 = f.solve_rhs(&sys.rhs);
            for (a, b) in x.iter().zip(&x2) {
                assert!((a - b).abs().max() < 1e-9 * (1.0 + a.abs().max()));
            }
            let xd = a.clone().lu().solve(&b).unwrap();
            for i in 0..18 * n {
                assert!((x[i / 18][i % 18] - xd[i]).abs() < 1e-9 * (1.0 + xd[i].abs()));
            }
            let ld = a
                .clone()
                .cholesky()
                .unwrap()
                .l()
                .diagonal()
                .map(|d| d.ln())
                .sum()
                * 2.0;
            assert!((f.log_det() - ld).abs() < 1e-8 * ld.abs().max(1.0));
            let inv = a.try_inverse().unwrap();
            let bi = f.banded_inverse();
            for k in 0..n {
                let d = inv.view((18 * k, 18 * k), (18, 18));
                assert!((bi.diag[k] - d).abs().max() < 1e-10);
                if k + 1 < n {
                    let u = inv.view((18 * k, 18 * (k + 1)), (18, 18));
                    assert!((bi.upper[k] - u).abs().max() < 1e-10);
                }
            }
        }
    }

    fn random_spd(seed: &mut u64) -> M18 {
        let mut j = M18::zeros();
        j.iter_mut().for_each(|v| *v = pseudo_random(seed));
        // Widely spread scales, as in the trajectory's normal equations.
        let scale = M18::from_diagonal(&V18::from_fn(|i, _| 10f64.powi(i as i32 % 6 - 2)));
        scale * (j.transpose() * j + M18::identity() * 0.1) * scale
    }

    #[test]
    fn cholesky_and_inverse_match_nalgebra() {
        let mut seed = 11;
        for _ in 0..20 {
            let s = random_spd(&mut seed);
            let reference = s.cholesky().unwrap();
            let mut l = s;
            let log_det = cholesky_in_place(&mut l).unwrap();
            let lr = reference.l();
            assert!((l - lr).abs().max() <= 1e-13 * lr.abs().max(), "{}", l - lr);
            let ld: f64 = lr.diagonal().iter().map(|d| 2.0 * d.ln()).sum();
            assert!((log_det - ld).abs() < 1e-12 * ld.abs().max(1.0));
            let inv = inverse_from_cholesky(&l);
            let ir = reference.inverse();
            assert!((inv - ir).abs().max() <= 1e-10 * ir.abs().max());
            assert_eq!(inv, inv.transpose());
            let a = random_spd(&mut seed);
            let p = mul(&s, &a);
            assert!((p - s * a).abs().max() <= 1e-13 * (s * a).abs().max());
        }
        let mut indefinite = M18::identity();
        indefinite[(7, 7)] = -1.0;
        assert!(cholesky_in_place(&mut indefinite).is_none());
        let mut nan = M18::identity();
        nan[(3, 3)] = f64::NAN;
        assert!(cholesky_in_place(&mut nan).is_none());
    }

    #[test]
    fn indefinite_system_is_an_error_not_a_panic() {
        let mut sys = BlockTridiagonal::zeros(3);
        sys.diag[1] = -M18::identity();
        sys.diag[0] = M18::identity();
        sys.diag[2] = M18::identity();
        assert!(sys.factor().is_err());
    }
}
