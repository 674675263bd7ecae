//! Symmetric positive-definite block-tridiagonal systems with `B x B` blocks: 18 by default (the
//! trajectory's knot state); a larger `B` serves knots that carry states of their own beside it.
//!
//! The normal equations of the trajectory fit couple each knot only with its neighbours, so the
//! information matrix is block tridiagonal. [`BlockTridiagonal::factor`] eliminates the blocks in
//! order (a block Cholesky, O(N) time and memory); the factor then solves for a step, gives the
//! log-determinant, and yields the blocks of the inverse (the posterior covariance) that lie on
//! and next to the diagonal.
//!
//! The elimination works in place on the system's storage with small dense kernels on the
//! column-major arrays of the blocks (18 or 24 is too small for blocked algorithms and too large for
//! full unrolling; the kernels keep every inner loop a contiguous `y += a x` that vectorises).

use nalgebra::{SMatrix, SVector};

use crate::error::{Error, Result};

/// 18x18 block.
pub type M18 = SMatrix<f64, 18, 18>;
/// 18-vector.
pub type V18 = SVector<f64, 18>;
/// A `B x B` block.
pub type Blk<const B: usize> = SMatrix<f64, B, B>;
/// A `B`-vector.
pub type Vb<const B: usize> = SVector<f64, B>;

/// Column-major storage of a block: `cols(m)[c][r] == m[(r, c)]`.
type Cols<const B: usize> = [[f64; B]; B];

#[inline]
fn cols<const B: usize>(m: &Blk<B>) -> &Cols<B> {
    &m.data.0
}

#[inline]
fn cols_mut<const B: usize>(m: &mut Blk<B>) -> &mut Cols<B> {
    &mut m.data.0
}

/// `log det (L L^T)` from the factor `L` of [`cholesky_factor`], its diagonal's logarithms
/// summed in order.
fn log_det_of_factor<const B: usize>(l: &Blk<B>) -> f64 {
    let a = cols(l);
    let mut log_det = 0.0;
    for (j, col) in a.iter().enumerate() {
        log_det += 2.0 * col[j].ln();
    }
    log_det
}

/// In-place Cholesky factorisation `S = L L^T` of a symmetric matrix (only its lower triangle is
/// read). On success the lower triangle holds `L` and the strict upper triangle is zeroed;
/// `false` when `S` is not (numerically) positive definite. The log-determinant (`B` logarithms,
/// which only the likelihoods need) is left to [`log_det_of_factor`].
fn cholesky_factor<const B: usize>(s: &mut Blk<B>) -> bool {
    let a = cols_mut(s);
    // Left-looking: column `k` is brought up to date in registers, with the updates of the
    // columns before it subtracted in their order (the order a right-looking loop applies
    // them in, so the factor is the same to the bit), then scaled and stored once.
    for k in 0..B {
        let mut col = [0.0; B];
        copy_in_halves(&mut col, &a[k]);
        for lj in &a[..k] {
            let l_kj = lj[k];
            // Rows above `k` of a finished column are zero: the whole column is updated so
            // that the loop has a fixed length; rows above `k` are cleared below.
            for (c, l) in col.iter_mut().zip(lj) {
                *c -= l * l_kj;
            }
        }
        let d = col[k];
        if d.is_nan() || d <= 0.0 || d.is_infinite() {
            return false;
        }
        let d = d.sqrt();
        col[..k].fill(0.0);
        col[k] = d;
        col[k + 1..].iter_mut().for_each(|v| *v /= d);
        copy_in_halves(&mut a[k], &col);
    }
    true
}

/// `dst = src` for a column, as two copies of nine rows: the compiler moves copies of that size
/// through registers, where it makes one of a whole column a call into libc.
#[inline(always)]
fn copy_in_halves<const B: usize>(dst: &mut [f64; B], src: &[f64; B]) {
    let h = B / 2;
    dst[..h].copy_from_slice(&src[..h]);
    dst[h..].copy_from_slice(&src[h..]);
}

/// `x <- L^-1 x` for the lower-triangular `L` of [`cholesky_factor`].
#[inline]
fn forward_substitute<const B: usize>(l: &Cols<B>, x: &mut [f64; B]) {
    for j in 0..B {
        x[j] /= l[j][j];
        let xj = x[j];
        for r in j + 1..B {
            x[r] -= l[j][r] * xj;
        }
    }
}

/// `x <- L^-T x`, with `lt` the columns of `L^T` (the rows of `L`).
#[inline]
fn backward_substitute<const B: usize>(lt: &Cols<B>, x: &mut [f64; B]) {
    for j in (0..B).rev() {
        x[j] /= lt[j][j];
        let xj = x[j];
        for r in 0..j {
            x[r] -= lt[j][r] * xj;
        }
    }
}

/// Transpose of a block.
#[inline]
fn transpose<const B: usize>(m: &Cols<B>) -> Cols<B> {
    let mut t = [[0.0; B]; B];
    for (c, col) in m.iter().enumerate() {
        for (r, v) in col.iter().enumerate() {
            t[r][c] = *v;
        }
    }
    t
}

/// Transposes a block in place.
fn transpose_in_place<const B: usize>(m: &mut Cols<B>) {
    for c in 0..B {
        let (left, right) = m.split_at_mut(c + 1);
        let col_c = &mut left[c];
        for (r, col_r) in (c + 1..B).zip(right.iter_mut()) {
            std::mem::swap(&mut col_c[r], &mut col_r[c]);
        }
    }
}

/// `out = a b`.
pub fn mul<const B: usize>(a: &Blk<B>, b: &Blk<B>) -> Blk<B> {
    let (a, b) = (cols(a), cols(b));
    let mut out = Blk::<B>::zeros();
    for (o, bc) in cols_mut(&mut out).iter_mut().zip(b) {
        *o = combine_columns::<B, B>(a, |m, _| bc[m]);
    }
    out
}

/// `out += sign a b^T` on the lower triangle of `out`, then mirrored to the upper triangle (for
/// products known to be symmetric).
fn add_symmetric_abt<const B: usize>(out: &mut Blk<B>, a: &Cols<B>, b: &Cols<B>, sign: f64) {
    let o = cols_mut(out);
    for j in 0..B {
        add_lower_column(a, |m, _| b[m][j], j, sign, &mut o[j]);
        let (left, right) = o.split_at_mut(j);
        for (r, col) in left.iter().enumerate() {
            right[0][r] = col[j];
        }
    }
}

/// `out[j..] += sign (sum_m coef(m, a_m) a_m)[j..]`: the lower part of column `j` of a sum of
/// the columns `a_m` of `a`, through [`combine_columns`] over the shortest of 6, 12, 18 or `B` rows
/// that covers it. (`x - s` and `x + (-1) s` round alike, so `sign = -1` subtracts.)
#[inline(always)]
fn add_lower_column<const B: usize>(
    a: &Cols<B>,
    coef: impl Fn(usize, &[f64; B]) -> f64,
    j: usize,
    sign: f64,
    out: &mut [f64; B],
) {
    let add = |out: &mut [f64], s: &[f64]| {
        for (v, s) in out.iter_mut().zip(s) {
            *v += sign * s;
        }
    };
    // The last `need` rows, from the shortest of 6, 12, 18 or all `B` rows that holds them.
    let need = B - j;
    if need <= 6 {
        add(
            &mut out[j..],
            &combine_columns::<B, 6>(a, &coef)[6 - need..],
        );
    } else if need <= 12 {
        add(
            &mut out[j..],
            &combine_columns::<B, 12>(a, &coef)[12 - need..],
        );
    } else if need <= 18 {
        add(
            &mut out[j..],
            &combine_columns::<B, 18>(a, &coef)[18 - need..],
        );
    } else {
        add(
            &mut out[j..],
            &combine_columns::<B, B>(a, &coef)[B - need..],
        );
    }
}

/// The last `R` rows of `sum_m coef(m, a_m) a_m` (`a_m` the columns of `a`), kept in
/// registers: each element's terms `a_m[r] * coef(m, a_m)` are added in the order of `m`,
/// starting from zero. The kernels below are written with it so that each element of their
/// results gets the operations, and the order, of a plain triple loop.
#[inline(always)]
fn combine_columns<const B: usize, const R: usize>(
    a: &Cols<B>,
    coef: impl Fn(usize, &[f64; B]) -> f64,
) -> [f64; R] {
    let first = B - R;
    let mut acc = [0.0; R];
    for (m, am) in a.iter().enumerate() {
        let c = coef(m, am);
        for (s, v) in acc.iter_mut().zip(&am[first..]) {
            *s += v * c;
        }
    }
    acc
}

/// `S^-1` from the Cholesky factor `L` of `S` (lower triangle of `l`).
pub fn inverse_from_cholesky<const B: usize>(l: &Blk<B>) -> Blk<B> {
    // V = L^-T (upper triangular); S^-1 = V V^T, the sum of outer products of V's columns.
    let lt = transpose(cols(l));
    let mut v = [[0.0; B]; B];
    for (c, vc) in v.iter_mut().enumerate() {
        vc[c] = 1.0;
        backward_substitute(&lt, vc);
    }
    // Column j of V V^T is sum_k V[j, k] v_k. Only k >= j contribute: V[j, k] is zero below the
    // diagonal, and so are the rows of v_k below k, so the zero products the full sums add
    // change no bit of the result.
    let mut out = Blk::<B>::zeros();
    for (j, o) in cols_mut(&mut out).iter_mut().enumerate() {
        *o = combine_columns::<B, B>(&v, |_, vk| vk[j]);
    }
    out
}

/// `A` with diagonal blocks `diag[k]` and upper blocks `upper[k] = A[k, k+1]`; the lower blocks
/// are their transposes. `rhs` is the right-hand side of `A x = rhs`.
#[derive(Clone, Debug)]
pub struct BlockTridiagonal<const B: usize = 18> {
    pub diag: Vec<Blk<B>>,
    pub upper: Vec<Blk<B>>,
    pub rhs: Vec<Vb<B>>,
}

/// The eliminated system, in the storage of the [`BlockTridiagonal`] it came from.
///
/// The blocks are eliminated from both ends towards the middle block `m = n / 2` (a "twisted"
/// factorisation): blocks `0..m` from the top, with Schur complements `S_k`, and blocks
/// `m+1..n` from the bottom, with Schur complements `R_k`; the middle block's complement takes
/// both sides' contributions. The two sweeps are independent, so they run on two cores, and the
/// order of every operation is fixed by `n` alone: the result does not depend on the number of
/// threads.
///
/// Storage: `chol[k]` holds the Cholesky factor `L_k` of the complement eliminated at `k`;
/// `gain[k]` (the slot of `A[k, k+1]`) holds `Y_k^T` with `Y_k = L_k^-1 A[k, k+1]` for `k < m`,
/// and `Y_{k+1}^T` with `Y_{k+1} = L_{k+1}^-1 A[k+1, k]` for `k >= m`; `w[k] = L_k^-1 z_k` is the
/// eliminated right-hand side. The gains `G = L^-T Y` of the textbook recursion are applied as
/// `L^-T (Y x)` and `Y^T (L^-1 z)`, which cost the same as `G x` and `G^T z`.
pub struct Factored<const B: usize = 18> {
    chol: Vec<Blk<B>>,
    gain: Vec<Blk<B>>,
    w: Vec<Vb<B>>,
}

/// A [`Factored`]'s blocks, read by forward substitutions written outside this module: the
/// top sweep eliminates blocks `0..middle` (knot `k` hands on through `gain[k]`), the bottom
/// sweep blocks `n - 1` down to `middle + 1` (knot `k` through `gain[k - 1]`), and the middle
/// block takes both. `w` is `L^-1` of the system's right-hand side.
pub(crate) struct ForwardParts<'a, const B: usize = 18> {
    pub middle: usize,
    pub chol: &'a [Blk<B>],
    pub gain: &'a [Blk<B>],
    pub w: &'a [Vb<B>],
}

/// `x <- L^-1 x` for one column and a block's factor `l` from [`ForwardParts::chol`].
#[inline]
pub(crate) fn forward_in_place<const B: usize>(l: &Blk<B>, x: &mut Vb<B>) {
    forward_substitute(cols(l), &mut x.data.0[0]);
}

/// `L^-1` of a block's factor `l` from [`ForwardParts::chol`] (lower triangular), with one
/// division per row: for many columns, one product with it costs less than a substitution
/// each.
pub(crate) fn lower_inverse<const B: usize>(l: &Blk<B>) -> Blk<B> {
    let a = cols(l);
    let d: [f64; B] = std::array::from_fn(|j| 1.0 / a[j][j]);
    let mut out = Blk::<B>::zeros();
    for (j, x) in cols_mut(&mut out).iter_mut().enumerate() {
        x[j] = 1.0;
        for jj in j..B {
            x[jj] *= d[jj];
            let xj = x[jj];
            for r in jj + 1..B {
                x[r] -= a[jj][r] * xj;
            }
        }
    }
    out
}

/// Diagonal and first off-diagonal blocks of `A^-1`.
#[derive(Clone, Debug, Default)]
pub struct BandedInverse<const B: usize = 18> {
    /// `Sigma[k, k]`.
    pub diag: Vec<Blk<B>>,
    /// `Sigma[k, k+1]`.
    pub upper: Vec<Blk<B>>,
}

/// Systems smaller than this are eliminated on one thread (the two sweeps are the same).
const PARALLEL_MIN: usize = 2048;

/// Runs `a` and `b`, on two threads when `parallel` and more than one core is available.
fn both<A: Send, B: Send>(
    parallel: bool,
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    let cores = std::thread::available_parallelism().map_or(1, |t| t.get());
    if parallel && cores > 1 {
        std::thread::scope(|scope| {
            let hb = scope.spawn(b);
            let ra = a();
            // A panic in `b` is a bug; re-raise it here rather than lose it.
            let rb = hb.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
            (ra, rb)
        })
    } else {
        (a(), b())
    }
}

/// The middle block of a twisted elimination of `n` blocks.
fn middle(n: usize) -> usize {
    n / 2
}

/// One elimination step. `l` is the Cholesky factor of the block being eliminated and `y` holds
/// the rows of its coupling block `C` to the next block in the sweep. With `Y = L^-1 C`:
/// subtracts `Y^T Y` from `next` and `Y^T w` from `next_w` (`w = L^-1 z` of the block), and
/// replaces `y` by the rows of `Y`, which are the columns of `Y^T`: the column-major storage of
/// `Y^T`. (Solves and the banded inverse need `G = L^-T Y` only applied to vectors or once per
/// knot, so it is not formed here: that would be a third of the step's work.)
fn eliminate<const B: usize>(
    l: &Cols<B>,
    y: &mut Cols<B>,
    w: &[f64; B],
    next: &mut Blk<B>,
    next_w: &mut Vb<B>,
) {
    // Rows of Y = L^-1 C by forward substitution on the rows of C, so that every inner loop
    // runs over a full row of `B`; each row is kept in registers until it is done.
    for j in 0..B {
        let mut row = y[j];
        for (yk, lk) in y[..j].iter().zip(l) {
            let l_jk = lk[j];
            for (a, b) in row.iter_mut().zip(yk) {
                *a -= l_jk * b;
            }
        }
        let d = l[j][j];
        row.iter_mut().for_each(|a| *a /= d);
        y[j] = row;
    }
    // next -= Y^T Y on the lower triangle only (the Cholesky factorisation of `next` reads
    // nothing else), one column at a time.
    for (c, sc) in cols_mut(next).iter_mut().enumerate() {
        add_lower_column(y, |_, yj| yj[c], c, -1.0, sc);
    }
    // next_w -= Y^T w.
    let mut ytw = [0.0; B];
    for (yj, wj) in y.iter().zip(w) {
        for (a, b) in ytw.iter_mut().zip(yj) {
            *a += b * wj;
        }
    }
    *next_w -= Vb::<B>::from(ytw);
}

/// Factorises a block in place and forward-substitutes its right-hand side.
fn factor_block<const B: usize>(k: usize, chol: &mut Blk<B>, w: &mut Vb<B>) -> Result<()> {
    if !cholesky_factor(chol) {
        return Err(Error::Numerical(format!(
            "information matrix not positive definite at knot {k} (too few or degenerate measurements)"
        )));
    }
    let mut wk: [f64; B] = (*w).into();
    forward_substitute(cols(chol), &mut wk);
    *w = wk.into();
    Ok(())
}

impl<const B: usize> BlockTridiagonal<B> {
    /// A zero system of `n` blocks.
    pub fn zeros(n: usize) -> Self {
        // Large systems take hundreds of megabytes: their pages are first touched on all cores.
        use rayon::prelude::*;
        let zeros = |len: usize| -> Vec<Blk<B>> {
            if len >= PARALLEL_MIN {
                (0..len)
                    .into_par_iter()
                    .map(|_| Blk::<B>::zeros())
                    .collect()
            } else {
                vec![Blk::<B>::zeros(); len]
            }
        };
        BlockTridiagonal {
            diag: zeros(n),
            upper: zeros(n.saturating_sub(1)),
            rhs: vec![Vb::<B>::zeros(); n],
        }
    }

    pub fn len(&self) -> usize {
        self.diag.len()
    }

    /// The same storage for a system of `n` blocks (contents meaningless, as for assembly):
    /// shortening keeps the memory, lengthening adds zero blocks.
    pub fn resized(mut self, n: usize) -> Self {
        self.diag.resize(n, Blk::<B>::zeros());
        self.upper.resize(n.saturating_sub(1), Blk::<B>::zeros());
        self.rhs.resize(n, Vb::<B>::zeros());
        self
    }

    /// Block elimination from both ends (see [`Factored`]); fails when a Schur complement is not
    /// positive definite.
    ///
    /// Top sweep, `k = 0..m`: with `S_0 = D_0`, `z_0 = r_0` and `S_k = L_k L_k^T`:
    /// `Y_k = L_k^-1 B_k`, `S_{k+1} = D_{k+1} - Y_k^T Y_k`, `G_k = L_k^-T Y_k`,
    /// `w_k = L_k^-1 z_k`, `z_{k+1} = r_{k+1} - Y_k^T w_k`. The bottom sweep is the same on the
    /// reversed chain (`B_{k-1}^T` couples block `k` to block `k - 1`).
    pub fn factor(self) -> Result<Factored<B>> {
        let BlockTridiagonal {
            diag: mut chol,
            upper: mut gain,
            rhs: mut w,
        } = self;
        let n = chol.len();
        if n == 0 {
            return Err(Error::Numerical("empty system".into()));
        }
        let m = middle(n);
        let (top_chol, bottom_chol) = chol.split_at_mut(m + 1);
        let (top_w, bottom_w) = w.split_at_mut(m + 1);
        let (top_gain, bottom_gain) = gain.split_at_mut(m);
        // The bottom sweep's contribution to the middle block is kept apart and subtracted after
        // the top sweep's, so both orders of completion give the same middle block.
        let (top, bottom) = both(
            n >= PARALLEL_MIN,
            || -> Result<()> {
                for k in 0..m {
                    let (cur, next) = top_chol.split_at_mut(k + 1);
                    let (wc, wn) = top_w.split_at_mut(k + 1);
                    factor_block(k, &mut cur[k], &mut wc[k])?;
                    let wk: [f64; B] = wc[k].into();
                    let y = cols_mut(&mut top_gain[k]);
                    transpose_in_place(y);
                    eliminate(cols(&cur[k]), y, &wk, &mut next[0], &mut wn[0]);
                }
                Ok(())
            },
            || -> Result<(Blk<B>, Vb<B>)> {
                let (mut to_mid, mut to_mid_w) = (Blk::<B>::zeros(), Vb::<B>::zeros());
                // Bottom block j is knot m + 1 + j; its coupling to knot m + j sits in gain slot
                // m + j, i.e. bottom_gain[j].
                for j in (0..bottom_chol.len()).rev() {
                    let (prev, cur) = bottom_chol.split_at_mut(j);
                    let (wp, wc) = bottom_w.split_at_mut(j);
                    factor_block(m + 1 + j, &mut cur[0], &mut wc[0])?;
                    let wk: [f64; B] = wc[0].into();
                    let (next, next_w) = if j > 0 {
                        (&mut prev[j - 1], &mut wp[j - 1])
                    } else {
                        (&mut to_mid, &mut to_mid_w)
                    };
                    eliminate(
                        cols(&cur[0]),
                        cols_mut(&mut bottom_gain[j]),
                        &wk,
                        next,
                        next_w,
                    );
                }
                Ok((to_mid, to_mid_w))
            },
        );
        top?;
        let (to_mid, to_mid_w) = bottom?;
        // `to_mid` holds `-C^T C` and `to_mid_w` `-C^T w` (subtracted from zero).
        chol[m] += to_mid;
        w[m] += to_mid_w;
        factor_block(m, &mut chol[m], &mut w[m])?;
        Ok(Factored { chol, gain, w })
    }
}

/// The gain `G = L^-T Y` of an eliminated block from its factor `L` and the stored `Y^T`.
fn gain_from<const B: usize>(l: &Blk<B>, yt: &Blk<B>) -> Blk<B> {
    let mut g = yt.transpose();
    backward_columns(cols(l), &mut g);
    g
}

/// `x <- L^-1 x` on every column of a `B x C` block. Several columns are substituted side by
/// side, on a row-major copy, so that each division and each update runs across the columns
/// at once; every element gets the operations of [`forward_substitute`] in the same order.
fn forward_columns<const B: usize, const C: usize>(l: &Cols<B>, x: &mut SMatrix<f64, B, C>) {
    if C == 1 {
        for col in x.data.0.iter_mut() {
            forward_substitute(l, col);
        }
        return;
    }
    let mut rows = [[0.0; C]; B];
    for (c, col) in x.data.0.iter().enumerate() {
        for (row, v) in rows.iter_mut().zip(col) {
            row[c] = *v;
        }
    }
    for j in 0..B {
        let d = l[j][j];
        let (done, rest) = rows.split_at_mut(j + 1);
        let xj = &mut done[j];
        xj.iter_mut().for_each(|v| *v /= d);
        for (row, l_rj) in rest.iter_mut().zip(&l[j][j + 1..]) {
            for (a, b) in row.iter_mut().zip(xj.iter()) {
                *a -= l_rj * b;
            }
        }
    }
    for (c, col) in x.data.0.iter_mut().enumerate() {
        for (v, row) in col.iter_mut().zip(&rows) {
            *v = row[c];
        }
    }
}

/// `x <- L^-T x` on every column of a `B x C` block. The rows of `L` are copied out once
/// for several columns; a single column reads them in place.
fn backward_columns<const B: usize, const C: usize>(l: &Cols<B>, x: &mut SMatrix<f64, B, C>) {
    if C == 1 {
        for col in x.data.0.iter_mut() {
            backward_substitute_in_place(l, col);
        }
        return;
    }
    let lt = transpose(l);
    for col in x.data.0.iter_mut() {
        backward_substitute(&lt, col);
    }
}

/// [`backward_substitute`] reading `L` itself (the same operations in the same order).
fn backward_substitute_in_place<const B: usize>(l: &Cols<B>, x: &mut [f64; B]) {
    for j in (0..B).rev() {
        x[j] /= l[j][j];
        let xj = x[j];
        for r in 0..j {
            x[r] -= l[r][j] * xj;
        }
    }
}

/// Sums `R^T A^-1 R` and `R^T A^-1 rhs` of [`Factored::quadratic_forms`].
type Sums<const C: usize> = (SMatrix<f64, C, C>, SMatrix<f64, C, 1>);

/// Zero [`Sums`].
fn zero_sums<const C: usize>() -> Sums<C> {
    (SMatrix::zeros(), SMatrix::zeros())
}

/// One knot's terms of [`Factored::quadratic_forms`]: forward-substitutes the carried block
/// `z` with the knot's factor `l`, adds `z^T z` and `z^T w` (`w` the knot's eliminated
/// right-hand side) to `sums`, and returns `z`.
#[inline]
fn add_forms<const B: usize, const C: usize>(
    l: &Blk<B>,
    w: &Vb<B>,
    mut z: SMatrix<f64, B, C>,
    sums: &mut Sums<C>,
) -> SMatrix<f64, B, C> {
    forward_columns(cols(l), &mut z);
    sums.0 += z.tr_mul(&z);
    sums.1 += z.tr_mul(w);
    z
}

/// The blocks of a system held elsewhere, for [`streamed_quadratic_forms`], with `C` further
/// columns `R` per knot.
pub trait BlockSource<const C: usize, const B: usize = 18>: Sync {
    /// Number of blocks.
    fn len(&self) -> usize;
    /// `A[k, k]`.
    fn diag(&self, k: usize) -> Blk<B>;
    /// `A[k, k + 1]`.
    fn upper(&self, k: usize) -> Blk<B>;
    /// The right-hand side of block `k`.
    fn rhs(&self, k: usize) -> Vb<B>;
    /// The rows of `R` of block `k`.
    fn columns(&self, k: usize) -> SMatrix<f64, B, C>;
}

/// What one sweep of [`streamed_quadratic_forms`] hands to the middle block.
struct SweepEnd<const C: usize, const B: usize> {
    /// The middle block's complement and eliminated right-hand side so far.
    diag: Blk<B>,
    w: Vb<B>,
    /// The sweep's sums and its contribution to the middle block's carried columns.
    sums: Sums<C>,
    to_mid: SMatrix<f64, B, C>,
}

/// [`BlockTridiagonal::factor`] followed by [`Factored::quadratic_forms`] for a system read
/// block by block from `src`, without storing the factor: each sweep carries one block of the
/// complement, one right-hand side and one block of columns from knot to knot. Every operation
/// is the one those two functions apply, in the same order, so the sums are the same to the
/// bit as factorising a copy of the system; the memory is that of a few blocks, whatever the
/// system's length.
pub fn streamed_quadratic_forms<const C: usize, const B: usize>(
    src: &impl BlockSource<C, B>,
) -> Result<(SMatrix<f64, C, C>, SMatrix<f64, C, 1>)> {
    let n = src.len();
    if n == 0 {
        return Err(Error::Numerical("empty system".into()));
    }
    let m = middle(n);
    let (top, bottom) = both(
        n >= PARALLEL_MIN,
        || -> Result<SweepEnd<C, B>> {
            let (mut cur, mut w, mut z) = (src.diag(0), src.rhs(0), src.columns(0));
            let (mut sums, mut to_mid) = (zero_sums::<C>(), SMatrix::zeros());
            for k in 0..m {
                factor_block(k, &mut cur, &mut w)?;
                let zl = add_forms(&cur, &w, z, &mut sums);
                let mut y = src.upper(k);
                transpose_in_place(cols_mut(&mut y));
                let (mut next, mut next_w) = (src.diag(k + 1), src.rhs(k + 1));
                eliminate(
                    cols(&cur),
                    cols_mut(&mut y),
                    &w.into(),
                    &mut next,
                    &mut next_w,
                );
                let contribution = y * zl;
                if k + 1 < m {
                    z = src.columns(k + 1) - contribution;
                } else {
                    to_mid = contribution;
                }
                (cur, w) = (next, next_w);
            }
            Ok(SweepEnd {
                diag: cur,
                w,
                sums,
                to_mid,
            })
        },
        || -> Result<SweepEnd<C, B>> {
            let (mut diag, mut w) = (Blk::<B>::zeros(), Vb::<B>::zeros());
            let (mut sums, mut to_mid) = (zero_sums::<C>(), SMatrix::zeros());
            if m + 1 < n {
                let (mut cur, mut wc, mut z) =
                    (src.diag(n - 1), src.rhs(n - 1), src.columns(n - 1));
                for knot in (m + 1..n).rev() {
                    factor_block(knot, &mut cur, &mut wc)?;
                    let zl = add_forms(&cur, &wc, z, &mut sums);
                    let mut y = src.upper(knot - 1);
                    let (mut next, mut next_w) = if knot - 1 > m {
                        (src.diag(knot - 1), src.rhs(knot - 1))
                    } else {
                        (Blk::<B>::zeros(), Vb::<B>::zeros())
                    };
                    eliminate(
                        cols(&cur),
                        cols_mut(&mut y),
                        &wc.into(),
                        &mut next,
                        &mut next_w,
                    );
                    let contribution = y * zl;
                    if knot - 1 > m {
                        z = src.columns(knot - 1) - contribution;
                    } else {
                        to_mid = contribution;
                    }
                    (cur, wc) = (next, next_w);
                }
                (diag, w) = (cur, wc);
            }
            Ok(SweepEnd {
                diag,
                w,
                sums,
                to_mid,
            })
        },
    );
    let (top, bottom) = (top?, bottom?);
    let (mut chol, mut w) = (top.diag, top.w);
    chol += bottom.diag;
    w += bottom.w;
    factor_block(m, &mut chol, &mut w)?;
    let mut sums = (top.sums.0 + bottom.sums.0, top.sums.1 + bottom.sums.1);
    add_forms(
        &chol,
        &w,
        src.columns(m) - top.to_mid - bottom.to_mid,
        &mut sums,
    );
    Ok(sums)
}

impl<const B: usize> Factored<B> {
    fn middle(&self) -> usize {
        middle(self.chol.len())
    }

    /// What a forward substitution written elsewhere needs, laid out as the type's doc says.
    pub(crate) fn forward_parts(&self) -> ForwardParts<'_, B> {
        ForwardParts {
            middle: self.middle(),
            chol: &self.chol,
            gain: &self.gain,
            w: &self.w,
        }
    }

    /// `L^-1 R` for other right-hand sides (one `B x C` block per knot, missing blocks are zero):
    /// the forward half of a solve, in the elimination order of the factor.
    fn forward_many<const C: usize>(&self, rhs: &[SMatrix<f64, B, C>]) -> Vec<SMatrix<f64, B, C>> {
        let n = self.chol.len();
        let block = |k: usize| rhs.get(k).copied().unwrap_or_else(SMatrix::zeros);
        let mut w: Vec<SMatrix<f64, B, C>> = (0..n).map(block).collect();
        self.forward_in_place(&mut w);
        w
    }

    /// [`Factored::forward_many`] on one block per knot, in place.
    fn forward_in_place<const C: usize>(&self, w: &mut [SMatrix<f64, B, C>]) {
        let n = self.chol.len();
        let m = self.middle();
        let (top, bottom) = w.split_at_mut(m + 1);
        let (mid_top, mid_bottom) = both(
            n >= PARALLEL_MIN,
            || {
                // w_k = L_k^-1 z_k, z_{k+1} = r_{k+1} - Y_k^T w_k.
                let mut to_mid = SMatrix::<f64, B, C>::zeros();
                for k in 0..m {
                    forward_columns(cols(&self.chol[k]), &mut top[k]);
                    let contribution = self.gain[k] * top[k];
                    if k + 1 < m {
                        top[k + 1] -= contribution;
                    } else {
                        to_mid = contribution;
                    }
                }
                to_mid
            },
            || {
                let mut to_mid = SMatrix::<f64, B, C>::zeros();
                for j in (0..bottom.len()).rev() {
                    forward_columns(cols(&self.chol[m + 1 + j]), &mut bottom[j]);
                    let contribution = self.gain[m + j] * bottom[j];
                    if j > 0 {
                        bottom[j - 1] -= contribution;
                    } else {
                        to_mid = contribution;
                    }
                }
                to_mid
            },
        );
        w[m] -= mid_top;
        w[m] -= mid_bottom;
        forward_columns(cols(&self.chol[m]), &mut w[m]);
    }

    /// `L^-T W` in place: the backward half of a solve, from the middle block outwards
    /// (`x_k = L_k^-T (w_k - Y_k x_{k+1})`).
    fn backward_many<const C: usize>(&self, x: &mut [SMatrix<f64, B, C>]) {
        let n = self.chol.len();
        let m = self.middle();
        backward_columns(cols(&self.chol[m]), &mut x[m]);
        let (top, bottom) = x.split_at_mut(m);
        let (mid, bottom) = bottom.split_at_mut(1);
        let xm = mid[0];
        both(
            n >= PARALLEL_MIN,
            || {
                let mut next = xm;
                for k in (0..top.len()).rev() {
                    top[k] -= self.gain[k].tr_mul(&next);
                    backward_columns(cols(&self.chol[k]), &mut top[k]);
                    next = top[k];
                }
            },
            || {
                let mut prev = xm;
                for (j, xk) in bottom.iter_mut().enumerate() {
                    *xk -= self.gain[m + j].tr_mul(&prev);
                    backward_columns(cols(&self.chol[m + 1 + j]), xk);
                    prev = *xk;
                }
            },
        );
    }

    /// The solution `x` of `A x = rhs`.
    pub fn solve(&self) -> Vec<Vb<B>> {
        let mut x: Vec<SMatrix<f64, B, 1>> = self.w.clone();
        self.backward_many(&mut x);
        x
    }

    /// [`Factored::solve_many`] in the storage of its right-hand sides (one block per knot, all
    /// of them), which hold the solutions after: half the memory of a solve that keeps both.
    pub fn solve_many_in_place<const C: usize>(&self, x: &mut [SMatrix<f64, B, C>]) {
        debug_assert_eq!(x.len(), self.chol.len(), "one block per knot");
        self.forward_in_place(x);
        self.backward_many(x);
    }

    /// The solutions of `A X = R` for `C` right-hand sides at once (one `B x C` block per knot).
    pub fn solve_many<const C: usize>(
        &self,
        rhs: &[SMatrix<f64, B, C>],
    ) -> Vec<SMatrix<f64, B, C>> {
        let mut x = self.forward_many(rhs);
        self.backward_many(&mut x);
        x
    }

    /// `R^T A^-1 R` and `R^T A^-1 rhs` (with `rhs` the system's own right-hand side) for
    /// `C` columns `R` (one `B x C` block per knot, missing blocks are zero): Schur complements
    /// need only the forward half of a solve, `R^T A^-1 R = (L^-1 R)^T (L^-1 R)`. Each sweep
    /// carries one block from knot to knot and adds its knots' terms as it goes, so nothing of
    /// the system's length is stored; the sums are the top sweep's, then the bottom sweep's,
    /// then the middle block's, an order fixed by the system's length.
    pub fn quadratic_forms<const C: usize>(
        &self,
        r: &[SMatrix<f64, B, C>],
    ) -> (SMatrix<f64, C, C>, SMatrix<f64, C, 1>) {
        let n = self.chol.len();
        let m = self.middle();
        let block = |k: usize| r.get(k).copied().unwrap_or_else(SMatrix::zeros);
        let add = |k: usize, z, sums: &mut Sums<C>| add_forms(&self.chol[k], &self.w[k], z, sums);
        let zero = zero_sums::<C>;
        let (top, bottom) = both(
            n >= PARALLEL_MIN,
            || {
                let mut sums = zero();
                let mut to_mid = SMatrix::<f64, B, C>::zeros();
                let mut z = block(0);
                for k in 0..m {
                    let w = add(k, z, &mut sums);
                    let contribution = self.gain[k] * w;
                    if k + 1 < m {
                        z = block(k + 1) - contribution;
                    } else {
                        to_mid = contribution;
                    }
                }
                (sums, to_mid)
            },
            || {
                let mut sums = zero();
                let mut to_mid = SMatrix::<f64, B, C>::zeros();
                let mut z = block(n - 1);
                for knot in (m + 1..n).rev() {
                    let w = add(knot, z, &mut sums);
                    let contribution = self.gain[knot - 1] * w;
                    if knot - 1 > m {
                        z = block(knot - 1) - contribution;
                    } else {
                        to_mid = contribution;
                    }
                }
                (sums, to_mid)
            },
        );
        let ((top_sums, top_mid), (bottom_sums, bottom_mid)) = (top, bottom);
        let mut sums = (top_sums.0 + bottom_sums.0, top_sums.1 + bottom_sums.1);
        add(m, block(m) - top_mid - bottom_mid, &mut sums);
        sums
    }

    /// The storage of the factor, as a system to assemble into (its contents are meaningless).
    pub fn into_system(self) -> BlockTridiagonal<B> {
        BlockTridiagonal {
            diag: self.chol,
            upper: self.gain,
            rhs: self.w,
        }
    }

    /// `rhs^T A^-1 rhs`, the squared length of the solution `x` in the metric of `A`
    /// (`x^T A x`): for normal equations, the cost decrease a Gauss-Newton step predicts, and
    /// how far the step moves in units of the posterior spread (no linear function of the
    /// variables moves by more than `sqrt` of this many of its standard deviations).
    pub fn decrement(&self) -> f64 {
        self.w.iter().map(|w| w.norm_squared()).sum()
    }

    /// `log det A`, from the factor's diagonals, summed in the order of the elimination: the
    /// top sweep's blocks, the bottom sweep's, then the middle block.
    pub fn log_det(&self) -> f64 {
        let m = self.middle();
        let (top, rest) = self.chol.split_at(m);
        let top: f64 = top.iter().fold(0.0, |s, l| s + log_det_of_factor(l));
        let bottom: f64 = rest[1..]
            .iter()
            .rev()
            .fold(0.0, |s, l| s + log_det_of_factor(l));
        top + bottom + log_det_of_factor(&rest[0])
    }

    /// Blocks of `A^-1` on and next to the diagonal, from the middle block outwards:
    /// `Sigma_k = S_k^-1 + G_k Sigma_{k+1} G_k^T`, `Sigma_{k,k+1} = -G_k Sigma_{k+1}` above it and
    /// the mirror image below. Reuses the factor's storage.
    pub fn banded_inverse(self) -> BandedInverse<B> {
        let Factored {
            chol: mut diag,
            gain: mut upper,
            ..
        } = self;
        let n = diag.len();
        let m = middle(n);
        diag[m] = inverse_from_cholesky(&diag[m]);
        let (top, rest) = diag.split_at_mut(m);
        let (mid, bottom) = rest.split_at_mut(1);
        let sigma_m = mid[0];
        let (top_gain, bottom_gain) = upper.split_at_mut(m);
        both(
            n >= PARALLEL_MIN,
            || {
                let mut next = sigma_m;
                for k in (0..top.len()).rev() {
                    let gain = gain_from(&top[k], &top_gain[k]);
                    let mut d = inverse_from_cholesky(&top[k]);
                    let off = -mul(&gain, &next);
                    add_symmetric_abt(&mut d, cols(&off), cols(&gain), -1.0);
                    top_gain[k] = off;
                    top[k] = d;
                    next = d;
                }
            },
            || {
                let mut prev = sigma_m;
                for (j, dk) in bottom.iter_mut().enumerate() {
                    let gain = gain_from(dk, &bottom_gain[j]);
                    let mut d = inverse_from_cholesky(dk);
                    // Sigma_{k,k-1} = -G'_k Sigma_{k-1}; the slot holds Sigma_{k-1,k}.
                    let off = -mul(&gain, &prev);
                    add_symmetric_abt(&mut d, cols(&off), cols(&gain), -1.0);
                    bottom_gain[j] = off.transpose();
                    *dk = d;
                    prev = d;
                }
            },
        );
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

    fn random_system<const B: usize>(n: usize, seed: &mut u64) -> BlockTridiagonal<B> {
        // Build A = J^T J from a random banded J so that A is SPD and block tridiagonal.
        let mut sys = BlockTridiagonal::<B>::zeros(n);
        for k in 0..n {
            let mut j = Blk::<B>::zeros();
            j.iter_mut().for_each(|v| *v = pseudo_random(seed));
            sys.diag[k] += j.transpose() * j + Blk::<B>::identity() * 0.5;
            sys.rhs[k] = Vb::<B>::from_fn(|_, _| pseudo_random(seed));
        }
        for k in 0..n - 1 {
            let mut j1 = Blk::<B>::zeros();
            let mut j2 = Blk::<B>::zeros();
            j1.iter_mut().for_each(|v| *v = pseudo_random(seed));
            j2.iter_mut().for_each(|v| *v = pseudo_random(seed));
            sys.diag[k] += j1.transpose() * j1;
            sys.diag[k + 1] += j2.transpose() * j2;
            sys.upper[k] += j1.transpose() * j2;
        }
        sys
    }

    fn dense<const B: usize>(sys: &BlockTridiagonal<B>) -> DMatrix<f64> {
        let n = sys.len();
        let mut a = DMatrix::zeros(B * n, B * n);
        for k in 0..n {
            a.view_mut((B * k, B * k), (B, B)).copy_from(&sys.diag[k]);
            if k + 1 < n {
                a.view_mut((B * k, B * (k + 1)), (B, B))
                    .copy_from(&sys.upper[k]);
                a.view_mut((B * (k + 1), B * k), (B, B))
                    .copy_from(&sys.upper[k].transpose());
            }
        }
        a
    }

    #[test]
    fn matches_dense_solution_inverse_and_determinant() {
        matches_dense::<18>();
        matches_dense::<24>();
    }

    fn matches_dense<const B: usize>() {
        let mut seed = 7;
        for n in [1usize, 2, 3, 4, 5, 9, 10] {
            let sys = random_system::<B>(n, &mut seed);
            let a = dense(&sys);
            let b = DMatrix::from_fn(B * n, 1, |i, _| sys.rhs[i / B][i % B]);
            let f = sys.clone().factor().unwrap();
            let x = f.solve();
            let x2 = f.solve_many(&sys.rhs);
            for (a, b) in x.iter().zip(&x2) {
                assert!((a - b).abs().max() < 1e-9 * (1.0 + a.abs().max()));
            }
            // Two right-hand sides at once: the system's own and its double.
            let both: Vec<SMatrix<f64, B, 2>> = sys
                .rhs
                .iter()
                .map(|r| SMatrix::<f64, B, 2>::from_columns(&[*r, *r * 2.0]))
                .collect();
            for (a, b) in x.iter().zip(f.solve_many(&both)) {
                assert!((a - b.column(0)).abs().max() < 1e-9 * (1.0 + a.abs().max()));
                assert!((a * 2.0 - b.column(1)).abs().max() < 1e-9 * (1.0 + a.abs().max()));
            }
            // b^T A^-1 b and b^T A^-1 (2 b) from the forward half alone.
            let (rr, rw) = f.quadratic_forms(&both[..]);
            let q: f64 = x.iter().zip(&sys.rhs).map(|(x, r)| x.dot(r)).sum();
            assert!((f.decrement() - q).abs() < 1e-9 * q.abs().max(1.0));
            assert!((rr[(0, 0)] - q).abs() < 1e-9 * q.abs().max(1.0));
            assert!((rr[(1, 1)] - 4.0 * q).abs() < 1e-9 * q.abs().max(1.0));
            assert!((rr[(0, 1)] - 2.0 * q).abs() < 1e-9 * q.abs().max(1.0));
            assert!((rw[1] - 2.0 * q).abs() < 1e-9 * q.abs().max(1.0));
            let xd = a.clone().lu().solve(&b).unwrap();
            for i in 0..B * n {
                assert!((x[i / B][i % B] - xd[i]).abs() < 1e-9 * (1.0 + xd[i].abs()));
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
                let d = inv.view((B * k, B * k), (B, B));
                assert!((bi.diag[k] - d).abs().max() < 1e-10);
                if k + 1 < n {
                    let u = inv.view((B * k, B * (k + 1)), (B, B));
                    assert!((bi.upper[k] - u).abs().max() < 1e-10);
                }
            }
        }
    }

    #[test]
    fn long_system_is_solved_and_inverted() {
        long_system::<18>();
        long_system::<24>();
    }

    fn long_system<const B: usize>() {
        // Long enough for the two sweeps to run on separate threads where there are two cores.
        let mut seed = 3;
        let n = PARALLEL_MIN + 101;
        let sys = random_system::<B>(n, &mut seed);
        let f = sys.clone().factor().unwrap();
        let x = f.solve();
        let max_rhs = sys.rhs.iter().map(|r| r.abs().max()).fold(0.0, f64::max);
        for k in 0..n {
            let mut ax = sys.diag[k] * x[k];
            if k > 0 {
                ax += sys.upper[k - 1].transpose() * x[k - 1];
            }
            if k + 1 < n {
                ax += sys.upper[k] * x[k + 1];
            }
            assert!((ax - sys.rhs[k]).abs().max() < 1e-9 * max_rhs, "block {k}");
        }
        // A Sigma = I on the band: block row k of A times block column k of Sigma.
        let inv = f.banded_inverse();
        for k in [0, 1, n / 2 - 1, n / 2, n / 2 + 1, n - 2, n - 1] {
            let mut e = sys.diag[k] * inv.diag[k];
            if k > 0 {
                e += sys.upper[k - 1].transpose() * inv.upper[k - 1];
            }
            if k + 1 < n {
                e += sys.upper[k] * inv.upper[k].transpose();
            }
            assert!((e - Blk::<B>::identity()).abs().max() < 1e-9, "block {k}");
        }
    }

    fn random_spd<const B: usize>(seed: &mut u64) -> Blk<B> {
        let mut j = Blk::<B>::zeros();
        j.iter_mut().for_each(|v| *v = pseudo_random(seed));
        // Widely spread scales, as in the trajectory's normal equations.
        let scale = Blk::<B>::from_diagonal(&Vb::<B>::from_fn(|i, _| 10f64.powi(i as i32 % 6 - 2)));
        scale * (j.transpose() * j + Blk::<B>::identity() * 0.1) * scale
    }

    #[test]
    fn cholesky_and_inverse_match_nalgebra() {
        cholesky_and_inverse::<18>();
        cholesky_and_inverse::<24>();
    }

    fn cholesky_and_inverse<const B: usize>() {
        let mut seed = 11;
        for _ in 0..20 {
            let s = random_spd::<B>(&mut seed);
            let reference = s.cholesky().unwrap();
            let mut l = s;
            assert!(cholesky_factor(&mut l));
            let log_det = log_det_of_factor(&l);
            let lr = reference.l();
            assert!((l - lr).abs().max() <= 1e-13 * lr.abs().max(), "{}", l - lr);
            let ld: f64 = lr.diagonal().iter().map(|d| 2.0 * d.ln()).sum();
            assert!((log_det - ld).abs() < 1e-12 * ld.abs().max(1.0));
            let inv = inverse_from_cholesky(&l);
            let ir = reference.inverse();
            assert!((inv - ir).abs().max() <= 1e-10 * ir.abs().max());
            assert_eq!(inv, inv.transpose());
            let a = random_spd::<B>(&mut seed);
            let p = mul(&s, &a);
            assert!((p - s * a).abs().max() <= 1e-13 * (s * a).abs().max());
        }
        let mut indefinite = Blk::<B>::identity();
        indefinite[(7, 7)] = -1.0;
        assert!(!cholesky_factor(&mut indefinite));
        let mut nan = Blk::<B>::identity();
        nan[(3, 3)] = f64::NAN;
        assert!(!cholesky_factor(&mut nan));
    }

    /// A system with `C` columns per block, read through [`BlockSource`].
    struct Held<'a, const C: usize, const B: usize> {
        sys: &'a BlockTridiagonal<B>,
        columns: &'a [SMatrix<f64, B, C>],
    }

    impl<const C: usize, const B: usize> BlockSource<C, B> for Held<'_, C, B> {
        fn len(&self) -> usize {
            self.sys.len()
        }
        fn diag(&self, k: usize) -> Blk<B> {
            self.sys.diag[k]
        }
        fn upper(&self, k: usize) -> Blk<B> {
            self.sys.upper[k]
        }
        fn rhs(&self, k: usize) -> Vb<B> {
            self.sys.rhs[k]
        }
        fn columns(&self, k: usize) -> SMatrix<f64, B, C> {
            self.columns[k]
        }
    }

    #[test]
    fn streamed_forms_equal_the_stored_factors_to_the_bit() {
        streamed_forms::<18>();
        streamed_forms::<24>();
    }

    fn streamed_forms<const B: usize>() {
        // Short systems (one sweep empty, a single block), and one long enough for the sweeps
        // to run on two threads.
        let mut seed = 5;
        for n in [1usize, 2, 3, 6, 11, PARALLEL_MIN + 37] {
            let sys = random_system::<B>(n, &mut seed);
            let columns: Vec<SMatrix<f64, B, 3>> = (0..n)
                .map(|_| SMatrix::from_fn(|_, _| pseudo_random(&mut seed)))
                .collect();
            let stored = sys.clone().factor().unwrap().quadratic_forms(&columns);
            let held = Held {
                sys: &sys,
                columns: &columns,
            };
            assert_eq!(streamed_quadratic_forms(&held).unwrap(), stored, "n = {n}");
        }
        // A complement that is not positive definite is the same error.
        let mut sys = random_system::<B>(4, &mut seed);
        sys.diag[3] = -Blk::<B>::identity();
        let columns = vec![SMatrix::<f64, B, 1>::zeros(); 4];
        let held = Held {
            sys: &sys,
            columns: &columns,
        };
        assert!(streamed_quadratic_forms(&held).is_err());
    }

    #[test]
    fn columns_side_by_side_are_substituted_as_one_at_a_time() {
        side_by_side::<18>();
        side_by_side::<24>();
    }

    fn side_by_side<const B: usize>() {
        // `forward_columns` runs several columns at once on a row-major copy; each must get
        // the operations of `forward_substitute` on its own, to the bit.
        let mut seed = 13;
        for _ in 0..10 {
            let mut l = random_spd::<B>(&mut seed);
            assert!(cholesky_factor(&mut l));
            let x = SMatrix::<f64, B, 8>::from_fn(|_, _| pseudo_random(&mut seed));
            let mut together = x;
            forward_columns(cols(&l), &mut together);
            let mut alone = x;
            for col in alone.data.0.iter_mut() {
                forward_substitute(cols(&l), col);
            }
            assert_eq!(together, alone);
            let mut two = x.fixed_columns::<2>(3).into_owned();
            forward_columns(cols(&l), &mut two);
            assert_eq!(two, alone.fixed_columns::<2>(3).into_owned());
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
