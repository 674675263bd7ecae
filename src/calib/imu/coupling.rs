//! The calibration's coupling with the knots, `H_x theta`, stored per knot on the columns its
//! factors touch, and the calibration's Schur complement computed from it without forming
//! `A^-1 H_x theta`.
//!
//! A bin or window touches the fixed parameters (9 columns), a DVL velocity the DVL's 8: a
//! knot's rows of `H_x theta` (24: the knot's state and its biases) are at most 17 columns.
//!
//! The Schur complement `S = H_theta - H_x theta^T A^-1 H_x theta` and the reduced right-hand
//! side need `H_x theta^T A^-1 H_x theta` and `H_x theta^T A^-1 r`: both come from the forward
//! half of a solve, carried knot by knot ([`schur_forms`]), so nothing of the recording's
//! length is stored beyond the system, its factor and the coupling.

use nalgebra::{DMatrix, DVector, SMatrix};
use rayon::prelude::*;

use super::block::{KB, VK};
use super::state::NFIXED;
use crate::calib::model::NPARAM;
use crate::trajectory::blocktri::{Factored, ForwardParts, forward_in_place, lower_inverse};

/// Knot rows.
const R: usize = KB;

/// `H_x theta`, knot by knot, on the columns the knot's factors touch.
#[derive(Clone, Debug)]
pub struct Coupling {
    /// The number of columns of `theta`.
    p: usize,
    /// Per knot: the fixed parameters' columns.
    fixed: Vec<SMatrix<f64, R, NFIXED>>,
    /// With a DVL: its first column and, per knot, its columns.
    dvl: Option<(usize, Vec<SMatrix<f64, R, NPARAM>>)>,
}

impl Coupling {
    /// A zero coupling of `n` knots with `theta` of `p` columns, the DVL's from `dvl_start` on.
    pub fn zeros(n: usize, p: usize, dvl_start: Option<usize>) -> Coupling {
        Coupling {
            p,
            fixed: vec![SMatrix::zeros(); n],
            dvl: dvl_start.map(|c| (c, vec![SMatrix::zeros(); n])),
        }
    }

    /// The number of columns of `theta`.
    pub fn columns(&self) -> usize {
        self.p
    }

    /// Adds a bin's or window's block on knot `k` (the fixed parameters' columns).
    pub fn add_bin(&mut self, k: usize, block: &SMatrix<f64, R, NFIXED>) {
        self.fixed[k] += block;
    }

    /// The knots' rows of the fixed parameters in runs of `len` knots, each borrowed apart from
    /// the others, so that runs can be filled in parallel.
    pub fn runs_mut(
        &mut self,
        len: usize,
    ) -> impl IndexedParallelIterator<Item = &mut [SMatrix<f64, R, NFIXED>]> {
        self.fixed.par_chunks_mut(len)
    }

    /// Adds a DVL velocity's block on knot `k`'s trajectory rows (without a DVL in `theta`:
    /// nothing).
    pub fn add_dvl(&mut self, k: usize, block: &SMatrix<f64, 18, NPARAM>) {
        if let Some((_, d)) = &mut self.dvl {
            let mut rows = d[k].fixed_rows_mut::<18>(0);
            rows += block;
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
        }
    }

    /// Calls `f(column of theta, its rows)` for every stored column of knot `k`.
    fn for_each_column(&self, k: usize, mut f: impl FnMut(usize, &[f64])) {
        for (c, col) in self.fixed[k].as_slice().chunks_exact(R).enumerate() {
            f(c, col);
        }
        if let Some((c0, d)) = &self.dvl {
            for (c, col) in d[k].as_slice().chunks_exact(R).enumerate() {
                f(c0 + c, col);
            }
        }
    }

    /// `H_k d`: knot `k`'s rows times a step of `theta`.
    pub fn times(&self, k: usize, d: &DVector<f64>) -> VK {
        let mut out = VK::zeros();
        self.for_each_column(k, |c, col| {
            out += VK::from_column_slice(col) * d[c];
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

    /// The dense `24 N x p` matrix (for tests).
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

/// One sweep's share of [`schur_forms`], on the columns of `theta`: `(L^-1 H)^T (L^-1 H)` over
/// its knots and `(L^-1 H)^T w`, and what its last knot hands to the middle block
/// (`-Y^T (L^-1 H)`) on the columns still carried (`order`, one each).
struct SweepForms {
    order: Vec<usize>,
    gram: DMatrix<f64>,
    rhs: DVector<f64>,
    to_mid: Vec<VK>,
}

/// Knots whose blocks of `L^-1 H` are stacked before their products are summed: one matrix
/// product of `24 BATCH` rows per batch rather than a dot product per pair of columns and knot.
const BATCH: usize = 16;

/// A carried column of `L^-1 H` is dropped once its squared norm falls below this fraction of
/// the largest it had (see [`sweep`]).
const RETIRE_BELOW: f64 = 1e-40;

/// The columns of `theta` one sweep carries, in its slots: `order[slot]` is the column,
/// `at[column]` its slot (`usize::MAX`: not carried), `peak[slot]` its largest squared norm.
struct Slots {
    order: Vec<usize>,
    at: Vec<usize>,
    peak: Vec<f64>,
}

impl Slots {
    /// The slot of column `c`, a new one (its entries zero) when it is not carried.
    fn of(&mut self, c: usize) -> usize {
        if self.at[c] == usize::MAX {
            self.at[c] = self.order.len();
            self.order.push(c);
            self.peak.push(0.0);
        }
        self.at[c]
    }

    /// Drops the slots whose column of `y` has decayed below [`RETIRE_BELOW`] of its peak,
    /// moving the last carried column into each one's place.
    fn retire(&mut self, y: &mut DMatrix<f64>) {
        let mut j = 0;
        while j < self.order.len() {
            let norm2 = y.column(j).norm_squared();
            self.peak[j] = self.peak[j].max(norm2);
            if norm2 >= RETIRE_BELOW * self.peak[j] {
                j += 1;
                continue;
            }
            let last = self.order.len() - 1;
            self.at[self.order[j]] = usize::MAX;
            if j != last {
                y.swap_columns(j, last);
                self.order.swap(j, last);
                self.peak.swap(j, last);
                self.at[self.order[j]] = j;
            }
            y.column_mut(last).fill(0.0);
            self.order.pop();
            self.peak.pop();
        }
    }
}

/// The knots' stacked blocks of `L^-1 H` and `w`, waiting for their products.
struct Stack {
    z: DMatrix<f64>,
    w: DVector<f64>,
    filled: usize,
}

impl Stack {
    /// Adds the stacked knots' `Z^T Z` and `Z^T w` on the carried columns (`order`) to `gram`
    /// and `rhs` (in `theta`'s columns) and empties the stack.
    fn flush(&mut self, order: &[usize], gram: &mut DMatrix<f64>, rhs: &mut DVector<f64>) {
        let m = order.len();
        if self.filled == 0 || m == 0 {
            self.filled = 0;
            return;
        }
        let z = self.z.columns(0, m);
        // An explicit transpose: `gemm` on dynamic shapes is the blocked product, `gemm_tr` a
        // dot product per entry.
        let zt = z.transpose();
        let mut block = DMatrix::<f64>::zeros(m, m);
        block.gemm(1.0, &zt, &z, 0.0);
        let mut zw = DVector::<f64>::zeros(m);
        zw.gemv(1.0, &zt, &self.w, 0.0);
        for (a, &ca) in order.iter().enumerate() {
            rhs[ca] += zw[a];
            for (b, &cb) in order.iter().enumerate() {
                gram[(ca, cb)] += block[(a, b)];
            }
        }
        self.z.columns_mut(0, m).fill(0.0);
        self.w.fill(0.0);
        self.filled = 0;
    }
}

/// The forward substitution of `H` along one sweep of the factor: `knots` in the sweep's order
/// and, for each, the gain it hands on through. Only the columns the sweep carries take work: a
/// column is zero before the first knot that touches it (the DVL's before its first velocity),
/// and once the sweep has passed the last it decays knot by knot (through the gains); below
/// [`RETIRE_BELOW`] of its peak (checked every [`BATCH`] knots) it is dropped, which changes no
/// sum by more than a part in 1e20 of the column's own. The carried blocks are one `24 x p` matrix, the first columns the carried
/// ones; their products are summed every [`BATCH`] knots.
fn sweep(
    parts: &ForwardParts<KB>,
    cross: &Coupling,
    knots: impl Iterator<Item = (usize, usize)>,
) -> SweepForms {
    let p = cross.columns();
    let mut slots = Slots {
        order: Vec::with_capacity(p),
        at: vec![usize::MAX; p],
        peak: Vec::with_capacity(p),
    };
    // z holds minus what the previous knot handed on: adding this knot's rows gives
    // `H_k - Y^T z_prev`; y is `L_k^-1` of that.
    let mut z = DMatrix::<f64>::zeros(R, p);
    let mut y = DMatrix::<f64>::zeros(R, p);
    let mut stack = Stack {
        z: DMatrix::zeros(R * BATCH, p),
        w: DVector::zeros(R * BATCH),
        filled: 0,
    };
    let mut gram = DMatrix::zeros(p, p);
    let mut rhs = DVector::zeros(p);
    for (k, gain) in knots {
        cross.for_each_column(k, |c, col| {
            let j = slots.of(c);
            for (a, v) in z.column_mut(j).iter_mut().zip(col) {
                *a += v;
            }
        });
        let m = slots.order.len();
        // `L_k^-1` once, then one product for all columns (a substitution per column costs
        // 24 divisions each).
        let l_inv = lower_inverse(&parts.chol[k]);
        y.columns_mut(0, m).gemm(1.0, &l_inv, &z.columns(0, m), 0.0);
        let row = R * stack.filled;
        stack
            .z
            .view_mut((row, 0), (R, m))
            .copy_from(&y.columns(0, m));
        stack.w.rows_mut(row, R).copy_from(&parts.w[k]);
        stack.filled += 1;
        if stack.filled == BATCH {
            stack.flush(&slots.order, &mut gram, &mut rhs);
            slots.retire(&mut y);
        }
        let m = slots.order.len();
        z.columns_mut(0, m)
            .gemm(-1.0, &parts.gain[gain], &y.columns(0, m), 0.0);
        // Retired slots past the carried ones start from zero when reused.
        z.columns_mut(m, p - m).fill(0.0);
    }
    stack.flush(&slots.order, &mut gram, &mut rhs);
    let to_mid = (0..slots.order.len())
        .map(|j| VK::from_column_slice(z.column(j).as_slice()))
        .collect();
    SweepForms {
        order: slots.order,
        gram,
        rhs,
        to_mid,
    }
}

/// `H^T A^-1 H` and `H^T A^-1 r` for the factored system `factor` (`A`, `r`) and the coupling
/// `H`, with `A^-1 r` (knot by knot). A Schur complement needs only the forward half of a
/// solve: with `A = L L^T` in the factor's elimination order, `H^T A^-1 H = (L^-1 H)^T (L^-1 H)`
/// and `H^T A^-1 r = (L^-1 H)^T (L^-1 r)`. Each of the factor's two sweeps carries one knot's
/// block of `L^-1 H` to the next and adds its products as it goes (the two on two cores), and
/// the middle block takes both; the sums are the top sweep's, the bottom sweep's, then the
/// middle's, an order fixed by the system's length. Nothing of the recording's length is
/// stored.
pub fn schur_forms(
    factor: &Factored<KB>,
    cross: &Coupling,
) -> (DMatrix<f64>, DVector<f64>, Vec<VK>) {
    let p = cross.columns();
    let xr = factor.solve();
    let n = xr.len();
    let parts = factor.forward_parts();
    let m = parts.middle;
    let (top, bottom) = rayon::join(
        || sweep(&parts, cross, (0..m).map(|k| (k, k))),
        || sweep(&parts, cross, (m + 1..n).rev().map(|k| (k, k - 1))),
    );
    // The middle block: its own rows less both sweeps' hand-overs, in `theta`'s order.
    let mut zm = vec![VK::zeros(); p];
    cross.for_each_column(m, |c, col| zm[c] = VK::from_column_slice(col));
    for half in [&top, &bottom] {
        for (c, z) in half.order.iter().zip(&half.to_mid) {
            zm[*c] += z;
        }
    }
    for col in zm.iter_mut() {
        forward_in_place(&parts.chol[m], col);
    }
    let mut hah = DMatrix::zeros(p, p);
    let mut har = DVector::zeros(p);
    for half in [&top, &bottom] {
        hah += &half.gram;
        har += &half.rhs;
    }
    let mut add = |ca: usize, cb: usize, v: f64| {
        hah[(ca, cb)] += v;
        if ca != cb {
            hah[(cb, ca)] += v;
        }
    };
    for a in 0..p {
        har[a] += zm[a].dot(&parts.w[m]);
        for b in 0..=a {
            add(a, b, zm[a].dot(&zm[b]));
        }
    }
    (hah, har, xr)
}
