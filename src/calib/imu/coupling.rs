//! The calibration's coupling with the knots, `H_x theta`, stored per knot on the columns its
//! factors touch, and the calibration's Schur complement computed from it without forming
//! `A^-1 H_x theta`.
//!
//! A bin touches the fixed parameters and its two bias nodes (21 columns), a DVL velocity the
//! DVL's 8; a knot collects the bins of the two intervals around it, so its rows of `H_x theta`
//! are the 9 fixed columns, two or three bias nodes and the DVL's columns, whatever the number
//! of bias nodes. Dense, the coupling took `18 N p` numbers and its solution as many again.
//!
//! The Schur complement `S = H_theta - H_x theta^T A^-1 H_x theta` and the reduced right-hand
//! side need `H_x theta^T A^-1 H_x theta` and `H_x theta^T A^-1 r`: the block-tridiagonal
//! elimination's sweeps carry the forward-substituted columns from knot to knot and sum their
//! products as they go ([`streamed_quadratic_forms`]), so nothing of the recording's length is
//! stored beyond the system and the coupling.

use nalgebra::{DMatrix, DVector, SMatrix};

use super::state::NFIXED;
use crate::calib::model::NPARAM;
use crate::error::Result;
use crate::trajectory::blocktri::{
    BlockSource, BlockTridiagonal, M18, V18, streamed_quadratic_forms,
};

/// Knot rows.
const R: usize = 18;

/// `H_x theta`, knot by knot, on the columns the knot's factors touch.
#[derive(Clone, Debug)]
pub struct Coupling {
    /// The number of columns of `theta`.
    p: usize,
    /// Per knot: the fixed parameters' columns.
    fixed: Vec<SMatrix<f64, R, NFIXED>>,
    /// Per knot: the bias nodes touched and their 6 columns.
    bias: Vec<Vec<(usize, SMatrix<f64, R, 6>)>>,
    /// With a DVL: its first column and, per knot, its columns.
    dvl: Option<(usize, Vec<SMatrix<f64, R, NPARAM>>)>,
}

impl Coupling {
    /// A zero coupling of `n` knots with `theta` of `p` columns, the DVL's from `dvl_start` on.
    pub fn zeros(n: usize, p: usize, dvl_start: Option<usize>) -> Coupling {
        Coupling {
            p,
            fixed: vec![SMatrix::zeros(); n],
            bias: vec![Vec::new(); n],
            dvl: dvl_start.map(|c| (c, vec![SMatrix::zeros(); n])),
        }
    }

    /// The number of columns of `theta`.
    pub fn columns(&self) -> usize {
        self.p
    }

    /// Adds a bin's block on knot `k` (the 21 columns of `theta_columns(node)`: the fixed
    /// parameters, then nodes `node` and `node + 1`).
    pub fn add_bin(&mut self, k: usize, node: usize, block: &SMatrix<f64, R, 21>) {
        self.fixed[k] += block.fixed_columns::<NFIXED>(0);
        for (i, c) in [(node, NFIXED), (node + 1, NFIXED + 6)] {
            let part = block.fixed_columns::<6>(c);
            let list = &mut self.bias[k];
            match list.iter_mut().find(|(j, _)| *j == i) {
                Some((_, m)) => *m += part,
                None => list.push((i, part.into_owned())),
            }
        }
    }

    /// Adds a DVL velocity's block on knot `k` (without a DVL in `theta`: nothing).
    pub fn add_dvl(&mut self, k: usize, block: &SMatrix<f64, R, NPARAM>) {
        if let Some((_, d)) = &mut self.dvl {
            d[k] += block;
        }
    }

    /// Zeroes column `c` of `theta` on every knot.
    pub fn hold(&mut self, c: usize) {
        if c < NFIXED {
            self.fixed
                .iter_mut()
                .for_each(|m| m.column_mut(c).fill(0.0));
        }
        if let Some((c0, d)) = &mut self.dvl
            && (*c0..*c0 + NPARAM).contains(&c)
        {
            d.iter_mut().for_each(|m| m.column_mut(c - *c0).fill(0.0));
            return;
        }
        if c >= NFIXED {
            let (node, col) = ((c - NFIXED) / 6, (c - NFIXED) % 6);
            for list in &mut self.bias {
                for (_, m) in list.iter_mut().filter(|(j, _)| *j == node) {
                    m.column_mut(col).fill(0.0);
                }
            }
        }
    }

    /// Calls `f(column of theta, its 18 rows)` for every stored column of knot `k`.
    fn for_each_column(&self, k: usize, mut f: impl FnMut(usize, &[f64])) {
        for (c, col) in self.fixed[k].as_slice().chunks_exact(R).enumerate() {
            f(c, col);
        }
        for (node, m) in &self.bias[k] {
            for (c, col) in m.as_slice().chunks_exact(R).enumerate() {
                f(NFIXED + 6 * node + c, col);
            }
        }
        if let Some((c0, d)) = &self.dvl {
            for (c, col) in d[k].as_slice().chunks_exact(R).enumerate() {
                f(c0 + c, col);
            }
        }
    }

    /// Knot `k`'s rows on the columns `from..from + width` of `theta`, written to the columns
    /// `to..to + width` of `out` (columns beyond `theta` are left alone).
    pub fn put<const C: usize>(
        &self,
        k: usize,
        from: usize,
        width: usize,
        to: usize,
        out: &mut SMatrix<f64, R, C>,
    ) {
        self.for_each_column(k, |c, col| {
            if (from..from + width).contains(&c) {
                out.column_mut(to + c - from).copy_from_slice(col);
            }
        });
    }

    /// `H_k d`: knot `k`'s rows times a step of `theta`.
    pub fn times(&self, k: usize, d: &DVector<f64>) -> V18 {
        let mut out = V18::zeros();
        self.for_each_column(k, |c, col| {
            out += V18::from_column_slice(col) * d[c];
        });
        out
    }

    /// `(H_k G)[:, from..from + C]` for a `p x p` matrix `G` (columns beyond `theta` zero).
    pub fn times_matrix<const C: usize>(
        &self,
        k: usize,
        g: &DMatrix<f64>,
        from: usize,
    ) -> SMatrix<f64, R, C> {
        let width = C.min(self.p.saturating_sub(from));
        let mut out = SMatrix::<f64, R, C>::zeros();
        self.for_each_column(k, |c, col| {
            for j in 0..width {
                let gcj = g[(c, from + j)];
                if gcj != 0.0 {
                    for (o, v) in out.column_mut(j).iter_mut().zip(col) {
                        *o += v * gcj;
                    }
                }
            }
        });
        out
    }

    /// The dense `18 N x p` matrix (for tests).
    #[cfg(test)]
    pub fn dense(&self) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(R * self.fixed.len(), self.p);
        for k in 0..self.fixed.len() {
            self.for_each_column(k, |c, col| {
                out.view_mut((R * k, c), (R, 1)).copy_from_slice(col);
            });
        }
        out
    }
}

/// The system and up to two ranges of the coupling's columns side by side, as a
/// [`BlockSource`].
struct Source<'a, const C: usize> {
    sys: &'a BlockTridiagonal,
    cross: &'a Coupling,
    /// `(first column of theta, width, first column of the block)`.
    ranges: &'a [(usize, usize, usize)],
}

impl<const C: usize> BlockSource<C> for Source<'_, C> {
    fn len(&self) -> usize {
        self.sys.len()
    }
    fn diag(&self, k: usize) -> M18 {
        self.sys.diag[k]
    }
    fn upper(&self, k: usize) -> M18 {
        self.sys.upper[k]
    }
    fn rhs(&self, k: usize) -> V18 {
        self.sys.rhs[k]
    }
    fn columns(&self, k: usize) -> SMatrix<f64, R, C> {
        let mut out = SMatrix::zeros();
        for &(from, width, to) in self.ranges {
            self.cross.put(k, from, width, to, &mut out);
        }
        out
    }
}

/// `H^T A^-1 H` and `H^T A^-1 r` for the system `sys` (`A`, `r`) and the coupling `H`, in one
/// streamed elimination when `theta` has at most 72 columns, else in one per pair of 36-column
/// ranges.
pub fn schur_forms(
    sys: &BlockTridiagonal,
    cross: &Coupling,
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let p = cross.columns();
    let mut hah = DMatrix::zeros(p, p);
    let mut har = DVector::zeros(p);
    // Runs one elimination on the column ranges and writes the blocks they give.
    fn run<const C: usize>(
        sys: &BlockTridiagonal,
        cross: &Coupling,
        ranges: &[(usize, usize, usize)],
        hah: &mut DMatrix<f64>,
        har: &mut DVector<f64>,
    ) -> Result<()> {
        let (q, g) = streamed_quadratic_forms::<C>(&Source { sys, cross, ranges })?;
        for &(fa, wa, ta) in ranges {
            for &(fb, wb, tb) in ranges {
                for i in 0..wa {
                    for j in 0..wb {
                        hah[(fa + i, fb + j)] = q[(ta + i, tb + j)];
                    }
                }
            }
            for i in 0..wa {
                har[fa + i] = g[ta + i];
            }
        }
        Ok(())
    }
    let all = [(0, p, 0)];
    match p {
        0..=24 => run::<24>(sys, cross, &all, &mut hah, &mut har)?,
        25..=48 => run::<48>(sys, cross, &all, &mut hah, &mut har)?,
        49..=64 => run::<64>(sys, cross, &all, &mut hah, &mut har)?,
        65..=72 => run::<72>(sys, cross, &all, &mut hah, &mut har)?,
        _ => {
            let starts: Vec<usize> = (0..p).step_by(36).collect();
            for (i, &a) in starts.iter().enumerate() {
                for &b in &starts[i + 1..] {
                    let ranges = [(a, 36.min(p - a), 0), (b, 36.min(p - b), 36)];
                    run::<72>(sys, cross, &ranges, &mut hah, &mut har)?;
                }
            }
        }
    }
    Ok((hah, har))
}
