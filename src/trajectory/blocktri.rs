//! Symmetric positive-definite block-tridiagonal systems with 18x18 blocks.
//!
//! The normal equations of the trajectory fit couple each knot only with its neighbours, so the
//! information matrix is block tridiagonal. [`BlockTridiagonal::factor`] eliminates the blocks in
//! order (a block Cholesky, O(N) time and memory); the factor then solves for a step, gives the
//! log-determinant, and yields the blocks of the inverse (the posterior covariance) that lie on
//! and next to the diagonal.

use nalgebra::{SMatrix, SVector};

use crate::error::{Error, Result};

/// 18x18 block.
pub type M18 = SMatrix<f64, 18, 18>;
/// 18-vector.
pub type V18 = SVector<f64, 18>;

/// `A` with diagonal blocks `diag[k]` and upper blocks `upper[k] = A[k, k+1]`; the lower blocks
/// are their transposes. `rhs` is the right-hand side of `A x = rhs`.
#[derive(Clone, Debug)]
pub struct BlockTridiagonal {
    pub diag: Vec<M18>,
    pub upper: Vec<M18>,
    pub rhs: Vec<V18>,
}

/// The eliminated system: Schur complements `S_k` (as Cholesky factors) and `G_k = S_k^-1 B_k`.
pub struct Factored {
    chol: Vec<nalgebra::Cholesky<f64, nalgebra::Const<18>>>,
    gain: Vec<M18>,
    z: Vec<V18>,
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
    pub fn factor(self) -> Result<Factored> {
        let n = self.diag.len();
        let mut chol = Vec::with_capacity(n);
        let mut gain = Vec::with_capacity(n.saturating_sub(1));
        let mut z = Vec::with_capacity(n);
        let mut s = match self.diag.first() {
            Some(d) => *d,
            None => return Err(Error::Numerical("empty system".into())),
        };
        let mut zk = self.rhs[0];
        for k in 0..n {
            let c = s.cholesky().ok_or_else(|| {
                Error::Numerical(format!(
                    "information matrix not positive definite at knot {k} (too few or degenerate measurements)"
                ))
            })?;
            if k + 1 < n {
                let g = c.solve(&self.upper[k]);
                s = self.diag[k + 1] - self.upper[k].transpose() * g;
                // Keep the complement exactly symmetric.
                s = (s + s.transpose()) * 0.5;
                let zn = self.rhs[k + 1] - g.transpose() * zk;
                gain.push(g);
                z.push(zk);
                zk = zn;
            } else {
                z.push(zk);
            }
            chol.push(c);
        }
        Ok(Factored { chol, gain, z })
    }
}

impl Factored {
    /// The solution `x` of `A x = rhs`.
    pub fn solve(&self) -> Vec<V18> {
        let n = self.chol.len();
        let mut x = vec![V18::zeros(); n];
        x[n - 1] = self.chol[n - 1].solve(&self.z[n - 1]);
        for k in (0..n - 1).rev() {
            x[k] = self.chol[k].solve(&self.z[k]) - self.gain[k] * x[k + 1];
        }
        x
    }

    /// `log det A`.
    pub fn log_det(&self) -> f64 {
        self.chol
            .iter()
            .map(|c| 2.0 * c.l_dirty().diagonal().iter().map(|d| d.ln()).sum::<f64>())
            .sum()
    }

    /// Blocks of `A^-1` on and next to the diagonal, by the backward recursion
    /// `Sigma_k = S_k^-1 + G_k Sigma_{k+1} G_k^T`, `Sigma_{k,k+1} = -G_k Sigma_{k+1}`.
    pub fn banded_inverse(&self) -> BandedInverse {
        let n = self.chol.len();
        let mut diag = vec![M18::zeros(); n];
        let mut upper = vec![M18::zeros(); n.saturating_sub(1)];
        diag[n - 1] = self.chol[n - 1].inverse();
        for k in (0..n - 1).rev() {
            let off = -(self.gain[k] * diag[k + 1]);
            let d = self.chol[k].inverse() - off * self.gain[k].transpose();
            diag[k] = (d + d.transpose()) * 0.5;
            upper[k] = off;
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

    #[test]
    fn indefinite_system_is_an_error_not_a_panic() {
        let mut sys = BlockTridiagonal::zeros(3);
        sys.diag[1] = -M18::identity();
        sys.diag[0] = M18::identity();
        sys.diag[2] = M18::identity();
        assert!(sys.factor().is_err());
    }
}
