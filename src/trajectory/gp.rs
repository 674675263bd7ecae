//! The white-noise-on-jerk (WNOJ) Gaussian-process prior on SE(3).
//!
//! Each knot `k` carries the pose `T_k = T_world_cam(t_k)`, the body twist `w_k = [v; w]`
//! (`T' = T hat(w)`) and its rate `dw_k`. Between two knots the trajectory is described in the
//! local variable `xi(t) = log(T_1^-1 T(t))` (a right perturbation of the first knot), whose
//! third derivative is white noise with power spectral density `Qc`. The local state
//! `gamma = [xi; xi'; xi'']` follows a linear SDE with transition `Phi` and covariance `Q`.
//!
//! Mapping between knot variables and the local state (right-perturbation form):
//! - `xi' = J_r^-1(xi) w`;
//! - `xi'' = J_r^-1(xi) dw + 1/2 curly(xi') w` (the first-order expansion of the derivative of
//!   `J_r^-1`, exact at the first knot where `xi = 0`, and inverted exactly when querying, so
//!   interpolation reproduces the knots).

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector6};

use super::blocktri::{M18, V18};
use crate::lie::{
    Se3, curly, se3_left_jacobian_inv_both, se3_right_jacobian, se3_right_jacobian_inv,
};

/// State of the trajectory at a knot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knot {
    /// `T_world_cam`.
    pub pose: Se3,
    /// Body twist `[v; w]`: velocity of the camera origin and angular velocity, camera frame.
    pub twist: Vector6<f64>,
    /// Time derivative of the body twist.
    pub rate: Vector6<f64>,
}

/// Scalar transition matrix of a triple integrator over `dt`.
pub fn phi_scalar(dt: f64) -> Matrix3<f64> {
    Matrix3::new(1.0, dt, 0.5 * dt * dt, 0.0, 1.0, dt, 0.0, 0.0, 1.0)
}

/// Scalar process covariance of a triple integrator over `dt` (multiply by `Qc`).
pub fn q_scalar(dt: f64) -> Matrix3<f64> {
    let d2 = dt * dt;
    let d3 = d2 * dt;
    Matrix3::new(
        d3 * d2 / 20.0,
        d2 * d2 / 8.0,
        d3 / 6.0,
        d2 * d2 / 8.0,
        d3 / 3.0,
        d2 / 2.0,
        d3 / 6.0,
        d2 / 2.0,
        dt,
    )
}

/// Inverse of [`q_scalar`] in closed form.
pub fn q_scalar_inv(dt: f64) -> Matrix3<f64> {
    let i1 = 1.0 / dt;
    let i2 = i1 * i1;
    let i3 = i2 * i1;
    Matrix3::new(
        720.0 * i3 * i2,
        -360.0 * i2 * i2,
        60.0 * i3,
        -360.0 * i2 * i2,
        192.0 * i3,
        -36.0 * i2,
        60.0 * i3,
        -36.0 * i2,
        9.0 * i1,
    )
}

/// `s (x) diag(d)`: an 18x18 matrix whose 6x6 block (i, j) is `s[i][j] diag(d)`.
pub fn kron_diag(s: &Matrix3<f64>, d: &Vector6<f64>) -> M18 {
    let mut m = M18::zeros();
    for i in 0..3 {
        for j in 0..3 {
            for c in 0..6 {
                m[(6 * i + c, 6 * j + c)] = s[(i, j)] * d[c];
            }
        }
    }
    m
}

/// `(s (x) diag(d)) m` without forming the 18x18 weight: each output row is a combination of at
/// most three rows of `m`.
pub fn kron_diag_mul<const C: usize>(
    s: &Matrix3<f64>,
    d: &Vector6<f64>,
    m: &SMatrix<f64, 18, C>,
) -> SMatrix<f64, 18, C> {
    let mut out = SMatrix::<f64, 18, C>::zeros();
    for i in 0..3 {
        for c in 0..6 {
            let r = 6 * i + c;
            for col in 0..C {
                out[(r, col)] = d[c]
                    * (s[(i, 0)] * m[(c, col)]
                        + s[(i, 1)] * m[(6 + c, col)]
                        + s[(i, 2)] * m[(12 + c, col)]);
            }
        }
    }
    out
}

/// Stacks the three 6-vectors of a local state.
fn stack(a: &Vector6<f64>, b: &Vector6<f64>, c: &Vector6<f64>) -> V18 {
    let mut v = V18::zeros();
    v.fixed_rows_mut::<6>(0).copy_from(a);
    v.fixed_rows_mut::<6>(6).copy_from(b);
    v.fixed_rows_mut::<6>(12).copy_from(c);
    v
}

/// `B_2k / (2k)!` for `k = 1..=40` (`B_n` the Bernoulli numbers): the coefficients of `ad^2k` in
/// `J_r^-1(xi) = I + ad/2 + sum_k B_2k/(2k)! ad^2k`, `ad = curly(xi)`.
const BERNOULLI_OVER_FACTORIAL: [f64; 40] = [
    0.08333333333333333,
    -0.001388888888888889,
    3.306878306878307e-05,
    -8.267195767195768e-07,
    2.08767569878681e-08,
    -5.284190138687493e-10,
    1.3382536530684679e-11,
    -3.3896802963225827e-13,
    8.586062056277845e-15,
    -2.174868698558062e-16,
    5.5090028283602295e-18,
    -1.3954464685812522e-19,
    3.534707039629467e-21,
    -8.953517427037546e-23,
    2.267952452337683e-24,
    -5.744790668872202e-26,
    1.455172475614865e-27,
    -3.6859949406653103e-29,
    9.336734257095045e-31,
    -2.36502241570063e-32,
    5.990671762482134e-34,
    -1.5174548844682903e-35,
    3.843758125454189e-37,
    -9.736353072646691e-39,
    2.466247044200681e-40,
    -6.247076741820743e-42,
    1.5824030244644914e-43,
    -4.008273685948936e-45,
    1.0153075855569557e-46,
    -2.5718041582418717e-48,
    6.514456035233815e-50,
    -1.6501309906896525e-51,
    4.179830628539476e-53,
    -1.058763466770291e-54,
    2.6818791912607708e-56,
    -6.793279351107421e-58,
    1.7207577616681404e-59,
    -4.358730329348894e-61,
    1.1040792903684666e-62,
    -2.7966655133781345e-64,
];

/// `a x b`.
#[inline(always)]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The translation and rotation parts of a twist.
#[inline(always)]
fn split(v: &[f64; 6]) -> ([f64; 3], [f64; 3]) {
    ([v[0], v[1], v[2]], [v[3], v[4], v[5]])
}

/// `curly(xi) v` without forming the matrix: `[phi x v_rho + rho x v_phi; phi x v_phi]`.
#[inline(always)]
fn curly_times(xi: &[f64; 6], v: &[f64; 6]) -> [f64; 6] {
    let ((rho, phi), (vr, vp)) = (split(xi), split(v));
    let (a, b, c) = (cross(phi, vr), cross(rho, vp), cross(phi, vp));
    [a[0] + b[0], a[1] + b[1], a[2] + b[2], c[0], c[1], c[2]]
}

/// `s += coef d` for a 3x3 block stored by columns, keeping in `largest` the largest magnitude of
/// a term added and of a sum (the series' convergence test).
#[inline(always)]
fn add_scaled_block(s: &mut [[f64; 3]; 3], d: &[[f64; 3]; 3], coef: f64, largest: &mut (f64, f64)) {
    for (sc, dc) in s.iter_mut().zip(d) {
        for (si, di) in sc.iter_mut().zip(dc) {
            let t = coef * di;
            *si += t;
            // Comparisons rather than `f64::max`, whose NaN rule costs several instructions;
            // neither running maximum can become NaN either way.
            let (t, s) = (t.abs(), si.abs());
            if t > largest.0 {
                largest.0 = t;
            }
            if s > largest.1 {
                largest.1 = s;
            }
        }
    }
}

/// Derivative with respect to `xi` of `(sum_n a_n ad^n) c`, `ad = curly(xi)`, for a power series
/// with coefficients `coef(n)` (`n >= 1`; the constant term does not depend on `xi`).
///
/// With `v_n = ad^n c`, `d v_n / d xi = D_n = ad D_{n-1} - curly(v_{n-1})` (`D_0 = 0`), because
/// `curly(a) b = -curly(b) a`. In 3x3 blocks `D_n = [A_n B_n; 0 A_n]`: the translation columns of
/// `-curly(v)` are `[e_j x v_phi; 0]` and its rotation columns `[e_i x v_rho; e_i x v_phi]`, and
/// `ad = [phi^ rho^; 0 phi^]` keeps a zero lower-left block zero, so
/// `A_n = phi^ A_{n-1} + [e_j x v_phi]_j` for both diagonal blocks (the same recursion from zero)
/// and `B_n = phi^ B_{n-1} + rho^ A_{n-1} + [e_i x v_rho]_i`. Only `A` and `B` are formed.
/// The sum stops at the first non-zero term (from `n = 4`) below 1e-16 of the sum, or after
/// `max_n` terms. The series used here shrink by at least a factor of four per non-zero term
/// (rotation angles up to pi), so the remainder is below 4e-17.
fn d_series_times(
    xi: &Vector6<f64>,
    c: &Vector6<f64>,
    coef: impl Fn(usize) -> f64,
    max_n: usize,
) -> Matrix6<f64> {
    let xi: [f64; 6] = (*xi).into();
    let (rho, phi) = split(&xi);
    let mut v: [f64; 6] = (*c).into();
    // Columns of A_n and B_n, and of their sums.
    let (mut a, mut b) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
    let (mut sa, mut sb) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
    for n in 1..=max_n {
        // e_i x u = [0, -u2, u1], [u2, 0, -u0], [-u1, u0, 0].
        let (vr, vp) = split(&v);
        let e_cross = |i: usize, u: [f64; 3]| match i {
            0 => [0.0, -u[2], u[1]],
            1 => [u[2], 0.0, -u[0]],
            _ => [-u[1], u[0], 0.0],
        };
        for i in 0..3 {
            let (pa, pb, ra) = (cross(phi, a[i]), cross(phi, b[i]), cross(rho, a[i]));
            let (ea, eb) = (e_cross(i, vp), e_cross(i, vr));
            a[i] = [pa[0] + ea[0], pa[1] + ea[1], pa[2] + ea[2]];
            b[i] = [
                pb[0] + ra[0] + eb[0],
                pb[1] + ra[1] + eb[1],
                pb[2] + ra[2] + eb[2],
            ];
        }
        v = curly_times(&xi, &v);
        let coef_n = coef(n);
        if coef_n != 0.0 {
            let mut largest = (0.0f64, 0.0f64);
            add_scaled_block(&mut sa, &a, coef_n, &mut largest);
            add_scaled_block(&mut sb, &b, coef_n, &mut largest);
            let (term, total) = largest;
            if n >= 4 && term <= 1e-16 * total {
                break;
            }
        }
    }
    Matrix6::from_fn(|r, c| match (r < 3, c < 3) {
        (true, true) => sa[c][r],
        (true, false) => sb[c - 3][r],
        (false, true) => 0.0,
        (false, false) => sa[c - 3][r - 3],
    })
}

/// Derivative with respect to `xi` of `J_r^-1(xi) c` for each `c`, from the Bernoulli series of
/// `J_r^-1` (which converges for rotation angles below 2 pi; the local states use angles up to
/// pi).
pub fn d_jr_inv_times<const N: usize>(
    xi: &Vector6<f64>,
    c: [&Vector6<f64>; N],
) -> [Matrix6<f64>; N] {
    let coef = |n: usize| match n {
        1 => 0.5,
        _ if n % 2 == 1 => 0.0,
        _ => BERNOULLI_OVER_FACTORIAL[n / 2 - 1],
    };
    c.map(|c| d_series_times(xi, c, coef, 2 * BERNOULLI_OVER_FACTORIAL.len()))
}

/// `(n+1)!` for `n = 0..=60`, each the product `2 * 3 * ... * (n+1)` in that order.
const FACTORIAL_OF_NEXT: [f64; 61] = {
    let mut f = [1.0; 61];
    let mut n = 1;
    while n < 61 {
        f[n] = f[n - 1] * (n + 1) as f64;
        n += 1;
    }
    f
};

/// Derivative with respect to `xi` of `J_r(xi) c` for each `c`, from
/// `J_r(xi) = sum_n (-ad)^n / (n+1)!`.
pub fn d_jr_times<const N: usize>(xi: &Vector6<f64>, c: [&Vector6<f64>; N]) -> [Matrix6<f64>; N] {
    // (-1)^n / (n+1)!; 60 terms reach 1e-17 for any angle below ~10 rad.
    let coef = |n: usize| {
        let f = FACTORIAL_OF_NEXT[n];
        if n % 2 == 0 { 1.0 / f } else { -1.0 / f }
    };
    c.map(|c| d_series_times(xi, c, coef, 60))
}

/// The local state of the second knot relative to the first, with the 6x6 pieces of its
/// Jacobians (see [`LocalState::d_pose1`] and [`LocalState::d_knot2`]).
pub struct LocalState {
    /// `gamma_2 = [xi21; xi'; xi'']`.
    pub gamma: V18,
    /// `J_r^-1(xi21)`.
    pub jri: Matrix6<f64>,
    /// `J_l^-1(xi21)`.
    pub jli: Matrix6<f64>,
    /// `d xi' / d xi21`.
    pub du_dxi: Matrix6<f64>,
    /// `d xi'' / d xi21`.
    pub da_dxi: Matrix6<f64>,
    /// `d xi'' / d w_2`.
    pub da_dw2: Matrix6<f64>,
}

impl LocalState {
    /// Derivative of `gamma_2` with respect to the right perturbation of `T_1` (18x6):
    /// `-[I; du_dxi; da_dxi] J_l^-1`.
    pub fn d_pose1(&self) -> SMatrix<f64, 18, 6> {
        let mut d = SMatrix::<f64, 18, 6>::zeros();
        for (i, b) in self.pose_blocks(&self.jli).iter().enumerate() {
            d.fixed_view_mut::<6, 6>(6 * i, 0).copy_from(&-b);
        }
        d
    }

    /// Derivative of `gamma_2` with respect to knot 2's variables `[dT_2; dw_2; ddw_2]`.
    pub fn d_knot2(&self) -> M18 {
        let mut d = M18::zeros();
        for (i, b) in self.pose_blocks(&self.jri).iter().enumerate() {
            d.fixed_view_mut::<6, 6>(6 * i, 0).copy_from(b);
        }
        d.fixed_view_mut::<6, 6>(6, 6).copy_from(&self.jri);
        d.fixed_view_mut::<6, 6>(12, 6).copy_from(&self.da_dw2);
        d.fixed_view_mut::<6, 6>(12, 12).copy_from(&self.jri);
        d
    }

    /// `[I; du_dxi; da_dxi] m` as three 6x6 blocks.
    fn pose_blocks(&self, m: &Matrix6<f64>) -> [Matrix6<f64>; 3] {
        [*m, self.du_dxi * m, self.da_dxi * m]
    }
}

/// `gamma_2` of knot `k2` in the local frame of `k1`, without Jacobians (for queries).
pub fn local_gamma(k1: &Knot, k2: &Knot) -> V18 {
    let xi = (k1.pose.inverse() * k2.pose).log();
    let jri = se3_right_jacobian_inv(&xi);
    let u = jri * k2.twist;
    let a = jri * k2.rate + curly(&u) * k2.twist * 0.5;
    stack(&xi, &u, &a)
}

/// `gamma_2` of knot `k2` in the local frame of `k1`, and its Jacobians.
pub fn local_state(k1: &Knot, k2: &Knot) -> LocalState {
    let xi = (k1.pose.inverse() * k2.pose).log();
    // J_r^-1(xi) = J_l^-1(-xi).
    let (jli, jri) = se3_left_jacobian_inv_both(&xi);
    let w2 = k2.twist;
    let dw2 = k2.rate;
    let u = jri * w2;
    let a = jri * dw2 + curly(&u) * w2 * 0.5;
    let [du_dxi, ddw_dxi] = d_jr_inv_times(&xi, [&w2, &dw2]);
    // d(curly(u) w2)/du = -curly(w2)
    let cw2 = curly(&w2);
    let da_dxi = ddw_dxi - cw2 * du_dxi * 0.5;
    let da_dw2 = (curly(&u) - cw2 * jri) * 0.5;
    LocalState {
        gamma: stack(&xi, &u, &a),
        jri,
        jli,
        du_dxi,
        da_dxi,
        da_dw2,
    }
}

/// `gamma_1 = [0; w_1; dw_1]`.
pub fn first_local_state(k1: &Knot) -> V18 {
    stack(&Vector6::zeros(), &k1.twist, &k1.rate)
}

/// `Phi (x) I6` applied to an 18-vector.
pub fn apply_scalar(s: &Matrix3<f64>, v: &V18) -> V18 {
    let mut out = V18::zeros();
    for i in 0..3 {
        let mut acc = Vector6::zeros();
        for j in 0..3 {
            acc += v.fixed_rows::<6>(6 * j) * s[(i, j)];
        }
        out.fixed_rows_mut::<6>(6 * i).copy_from(&acc);
    }
    out
}

/// `s (x) I6` as an 18x18 matrix.
pub fn kron_identity(s: &Matrix3<f64>) -> M18 {
    kron_diag(s, &Vector6::repeat(1.0))
}

/// Prior residual between consecutive knots, `e = gamma_2 - Phi(dt) gamma_1`, and the pieces of
/// its Jacobians with respect to the variables `[dT; dw; ddw]` of each knot: `j1` is
/// `-Phi (x) I6` with its first block column replaced by [`LocalState::d_pose1`]; `j2` is
/// [`LocalState::d_knot2`] (block lower triangular).
pub struct PriorFactor {
    /// The residual `gamma_2 - Phi(dt) gamma_1` (18-vector).
    pub e: V18,
    /// `Phi(dt)`.
    pub phi: Matrix3<f64>,
    /// Local state of the second knot relative to the first, with its Jacobians.
    pub local: LocalState,
}

impl PriorFactor {
    /// `d e / d x_1` (18x18).
    pub fn j1(&self) -> M18 {
        let mut j1 = -kron_identity(&self.phi);
        j1.fixed_view_mut::<18, 6>(0, 0)
            .copy_from(&self.local.d_pose1());
        j1
    }

    /// `d e / d x_2` (18x18).
    pub fn j2(&self) -> M18 {
        self.local.d_knot2()
    }
}

/// The prior factor between consecutive knots `k1` and `k2`, `dt` seconds apart.
pub fn prior_factor(k1: &Knot, k2: &Knot, dt: f64) -> PriorFactor {
    let local = local_state(k1, k2);
    let phi = phi_scalar(dt);
    let e = local.gamma - apply_scalar(&phi, &first_local_state(k1));
    PriorFactor { e, phi, local }
}

/// The contribution of a prior factor to the normal equations: with the weight
/// `W = Q(dt)^-1 (x) diag(qc_inv)`, `d1 = J1^T W J1`, `d2 = J2^T W J2`, `r1 = -J1^T W e`,
/// `r2 = -J2^T W e` and `cost = e^T W e`. The off-diagonal block `J1^T W J2` is written by
/// [`prior_normal`] straight into the slot the caller gives (the system's own, in an assembly).
pub struct PriorNormal {
    /// `J1^T W J1`: the first knot's diagonal block.
    pub d1: M18,
    /// `J2^T W J2`: the second knot's diagonal block.
    pub d2: M18,
    /// `-J1^T W e`: the first knot's right-hand side.
    pub r1: V18,
    /// `-J2^T W e`: the second knot's right-hand side.
    pub r2: V18,
    /// `e^T W e`: the factor's cost.
    pub cost: f64,
}

impl PriorNormal {
    /// All blocks zero: a scratch value for [`prior_normal`].
    pub fn zeros() -> PriorNormal {
        PriorNormal {
            d1: M18::zeros(),
            d2: M18::zeros(),
            r1: V18::zeros(),
            r2: V18::zeros(),
            cost: 0.0,
        }
    }
}

/// `diag(d) m`.
fn scale_rows(d: &Vector6<f64>, m: &Matrix6<f64>) -> Matrix6<f64> {
    Matrix6::from_fn(|r, c| d[r] * m[(r, c)])
}

/// `(qi (x) diag(d)) x` for a block column `x` of three 6x6 blocks.
fn weigh(qi: &Matrix3<f64>, d: &Vector6<f64>, x: &[Matrix6<f64>; 3]) -> [Matrix6<f64>; 3] {
    // Written out rather than with `array::from_fn`, which copies each block through a guard.
    let row = |i: usize| {
        scale_rows(
            d,
            &(x[0] * qi[(i, 0)] + x[1] * qi[(i, 1)] + x[2] * qi[(i, 2)]),
        )
    };
    [row(0), row(1), row(2)]
}

/// Writes the 6x6 block `(a, b)` of `out`, and its transpose at `(b, a)` when `mirror`.
fn put(out: &mut M18, a: usize, b: usize, m: &Matrix6<f64>, mirror: bool) {
    out.fixed_view_mut::<6, 6>(6 * a, 6 * b).copy_from(m);
    if mirror && a != b {
        out.fixed_view_mut::<6, 6>(6 * b, 6 * a)
            .copy_from(&m.transpose());
    }
}

/// [`PriorNormal`] of a prior factor. The Jacobians are mostly structure: the last two block
/// columns of `J1` are scalar multiples of the identity, and `J2` is block lower triangular with
/// `J_r^-1` on its diagonal, so the products are formed block by block from the 6x6 pieces
/// (about a third of the flops of dense 18x18 products). Every block of `out` and of `upper`
/// (`J1^T W J2`) is written, so neither needs clearing first.
pub fn prior_normal(
    f: &PriorFactor,
    qi: &Matrix3<f64>,
    d: &Vector6<f64>,
    out: &mut PriorNormal,
    upper: &mut M18,
) {
    let ls = &f.local;
    let (jri, dw) = (&ls.jri, &ls.da_dw2);
    let zero = Matrix6::zeros();
    // Block columns: J1 = [p1 | S_1 S_2] with (S_b)_i = -phi[i][b] I, J2 = [p2 | t1 t2].
    let p1 = ls.pose_blocks(&-ls.jli);
    let p2 = ls.pose_blocks(jri);
    let (wp1, wp2) = (weigh(qi, d, &p1), weigh(qi, d, &p2));
    let wt1 = weigh(qi, d, &[zero, *jri, *dw]);
    // (W S_b)_i = c[(i, b)] diag(d).
    let c = -(qi * f.phi);
    let s = |i: usize, b: usize| -f.phi[(i, b)];

    let d1 = &mut out.d1;
    put(d1, 0, 0, &(0..3).map(|i| p1[i].tr_mul(&wp1[i])).sum(), true);
    for b in 1..3 {
        let x: Matrix6<f64> = (0..3).map(|i| wp1[i] * s(i, b)).sum();
        put(d1, b, 0, &x, true);
        for a in 1..=b {
            let sab: f64 = (0..3).map(|i| s(i, a) * c[(i, b)]).sum();
            put(d1, a, b, &Matrix6::from_diagonal(&(d * sab)), true);
        }
    }

    let d2 = &mut out.d2;
    put(d2, 0, 0, &(0..3).map(|i| p2[i].tr_mul(&wp2[i])).sum(), true);
    put(d2, 0, 1, &(wp2[1].tr_mul(jri) + wp2[2].tr_mul(dw)), true);
    put(d2, 0, 2, &wp2[2].tr_mul(jri), true);
    put(d2, 1, 1, &(jri.tr_mul(&wt1[1]) + dw.tr_mul(&wt1[2])), true);
    put(d2, 1, 2, &wt1[2].tr_mul(jri), true);
    put(
        d2,
        2,
        2,
        &jri.tr_mul(&scale_rows(&(d * qi[(2, 2)]), jri)),
        true,
    );

    put(
        upper,
        0,
        0,
        &(0..3).map(|i| wp1[i].tr_mul(&p2[i])).sum(),
        false,
    );
    put(
        upper,
        0,
        1,
        &(wp1[1].tr_mul(jri) + wp1[2].tr_mul(dw)),
        false,
    );
    put(upper, 0, 2, &wp1[2].tr_mul(jri), false);
    for a in 1..3 {
        let col0: Matrix6<f64> = (0..3).map(|i| p2[i] * c[(i, a)]).sum();
        put(upper, a, 0, &scale_rows(d, &col0), false);
        put(
            upper,
            a,
            1,
            &scale_rows(d, &(jri * c[(1, a)] + dw * c[(2, a)])),
            false,
        );
        put(upper, a, 2, &scale_rows(d, &(jri * c[(2, a)])), false);
    }

    let we = kron_diag_mul(qi, d, &f.e);
    let wb = |i: usize| we.fixed_rows::<6>(6 * i).into_owned();
    let (r1, r2) = (&mut out.r1, &mut out.r2);
    let t: Vector6<f64> = (0..3).map(|i| p1[i].tr_mul(&wb(i))).sum();
    r1.fixed_rows_mut::<6>(0).copy_from(&-t);
    for b in 1..3 {
        let t: Vector6<f64> = (0..3).map(|i| wb(i) * s(i, b)).sum();
        r1.fixed_rows_mut::<6>(6 * b).copy_from(&-t);
    }
    let t: Vector6<f64> = (0..3).map(|i| p2[i].tr_mul(&wb(i))).sum();
    r2.fixed_rows_mut::<6>(0).copy_from(&-t);
    r2.fixed_rows_mut::<6>(6)
        .copy_from(&-(jri.tr_mul(&wb(1)) + dw.tr_mul(&wb(2))));
    r2.fixed_rows_mut::<6>(12).copy_from(&-jri.tr_mul(&wb(2)));
    out.cost = f.e.dot(&we);
}

/// Interpolation weights at `s = tau - t1` inside an interval of length `dt`:
/// `gamma(tau) = Lambda gamma_1 + Omega gamma_2` (scalar 3x3 parts; `Qc` cancels), and the scalar
/// part of the conditional covariance of `gamma(tau)` given both knots (multiply by `Qc`).
pub fn interpolation_weights(s: f64, dt: f64) -> (Matrix3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let qs = q_scalar(s);
    let phi_rest = phi_scalar(dt - s);
    let omega = qs * phi_rest.transpose() * q_scalar_inv(dt);
    let lambda = phi_scalar(s) - omega * phi_scalar(dt);
    let cond = qs - omega * phi_rest * qs;
    (lambda, omega, (cond + cond.transpose()) * 0.5)
}

/// The twist of [`knot_from_local`] alone: `J_r(xi) xi'`.
pub fn twist_from_local(gamma: &V18) -> Vector6<f64> {
    let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
    let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
    se3_right_jacobian(&xi) * xid
}

/// The twist and the twist rate of an interpolated state: a [`Knot`] without its pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Body twist `[v; w]` (m/s, rad/s).
    pub twist: Vector6<f64>,
    /// Its time derivative.
    pub rate: Vector6<f64>,
}

/// The twist and the twist rate at an interpolated local state `gamma` (what
/// [`knot_from_local`] gives, without the pose's exponential), with `jr = J_r(xi)` of its pose
/// part (for callers that need `J_r` themselves).
pub fn motion_from_local_with(jr: &Matrix6<f64>, gamma: &V18) -> Motion {
    let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
    let xidd: Vector6<f64> = gamma.fixed_rows::<6>(12).into_owned();
    let twist = jr * xid;
    let rate = jr * (xidd - curly(&xid) * twist * 0.5);
    Motion { twist, rate }
}

/// [`motion_from_local_with`], forming `J_r(xi)` itself.
pub fn motion_from_local(gamma: &V18) -> Motion {
    motion_from_local_with(
        &se3_right_jacobian(&gamma.fixed_rows::<6>(0).into_owned()),
        gamma,
    )
}

/// Knot state at an interpolated local state `gamma` relative to `pose1`: inverts the mapping
/// used for `gamma_2`.
pub fn knot_from_local(pose1: &Se3, gamma: &V18) -> Knot {
    let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
    let Motion { twist, rate } = motion_from_local_with(&se3_right_jacobian(&xi), gamma);
    Knot {
        pose: *pose1 * Se3::exp(&xi),
        twist,
        rate,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn knot(seed: f64) -> Knot {
        let xi = Vector6::new(0.3, -0.2, 0.5, 0.4 * seed, -0.3, 0.2);
        Knot {
            pose: Se3::exp(&xi),
            twist: Vector6::new(0.2, 0.1, -0.3, 0.5, -0.8 * seed, 0.3),
            rate: Vector6::new(-0.1, 0.3, 0.05, 0.2, 0.1, -0.4 * seed),
        }
    }

    fn perturb(k: &Knot, d: &V18) -> Knot {
        Knot {
            pose: k.pose * Se3::exp(&d.fixed_rows::<6>(0).into_owned()),
            twist: k.twist + d.fixed_rows::<6>(6),
            rate: k.rate + d.fixed_rows::<6>(12),
        }
    }

    /// Fourth-order central differences of `f(xi) c` (truncation ~h^4, rounding ~eps/h).
    fn numeric_derivative(
        xi: &Vector6<f64>,
        c: &Vector6<f64>,
        f: fn(&Vector6<f64>) -> Matrix6<f64>,
        h: f64,
    ) -> Matrix6<f64> {
        let mut out = Matrix6::zeros();
        for i in 0..6 {
            let at = |s: f64| {
                let mut x = *xi;
                x[i] += s * h;
                f(&x) * c
            };
            let col = ((at(1.0) - at(-1.0)) * 8.0 - (at(2.0) - at(-2.0))) / (12.0 * h);
            out.set_column(i, &col);
        }
        out
    }

    #[test]
    fn series_derivatives_match_numeric_differentiation() {
        use crate::lie::{se3_right_jacobian, se3_right_jacobian_inv};
        let c = Vector6::new(0.7, -1.3, 0.4, 2.1, -0.6, 1.1);
        let dirs = [
            Vector6::new(0.3, -0.2, 0.5, 0.4, -0.3, 0.2),
            Vector6::new(-1.5, 0.7, 2.0, 0.1, 0.9, -0.5),
            Vector6::new(0.01, 0.02, -0.03, 0.0, 0.0, 1e-7),
        ];
        for dir in &dirs {
            // Angles from zero to close to pi (the largest a logarithm returns).
            for scale in [0.0, 1e-6, 0.02, 0.3, 1.0, 2.5, 5.5] {
                let xi = dir * scale;
                if xi.fixed_rows::<3>(3).norm() > 3.1 {
                    continue;
                }
                for (series, f, h) in [
                    (
                        d_jr_inv_times(&xi, [&c])[0],
                        se3_right_jacobian_inv as fn(&_) -> _,
                        1e-3,
                    ),
                    (
                        d_jr_times(&xi, [&c])[0],
                        se3_right_jacobian as fn(&_) -> _,
                        1e-3,
                    ),
                ] {
                    let numeric = numeric_derivative(&xi, &c, f, h);
                    let err = (series - numeric).amax();
                    // The reference itself is good to a few 1e-13.
                    assert!(err < 1e-11 * numeric.amax().max(1.0), "xi {xi}: {err}");
                }
            }
        }
    }

    #[test]
    fn q_inverse_is_exact() {
        // Q(dt) spans dt^5 .. dt, so round-off grows as dt shrinks: check relative to that.
        for dt in [1e-3, 0.1, 1.0, 7.0] {
            let err = (q_scalar(dt) * q_scalar_inv(dt) - Matrix3::identity())
                .abs()
                .max();
            assert!(err < 1e-12 * (1.0 + dt.powi(-4)), "dt {dt}: {err}");
        }
    }

    #[test]
    fn prior_jacobians_match_numeric_differentiation() {
        let k1 = knot(1.0);
        let mut k2 = knot(-0.5);
        k2.pose = k1.pose * Se3::exp(&Vector6::new(0.05, 0.02, -0.03, 0.1, 0.2, -0.15));
        let dt = 0.1;
        let f = prior_factor(&k1, &k2, dt);
        let h = 1e-6;
        for i in 0..18 {
            let mut d = V18::zeros();
            d[i] = h;
            let ep1 = prior_factor(&perturb(&k1, &d), &k2, dt).e;
            let em1 = prior_factor(&perturb(&k1, &-d), &k2, dt).e;
            let ep2 = prior_factor(&k1, &perturb(&k2, &d), dt).e;
            let em2 = prior_factor(&k1, &perturb(&k2, &-d), dt).e;
            let n1 = (ep1 - em1) / (2.0 * h);
            let n2 = (ep2 - em2) / (2.0 * h);
            assert!((n1 - f.j1().column(i)).abs().max() < 1e-6, "j1 col {i}");
            assert!((n2 - f.j2().column(i)).abs().max() < 1e-6, "j2 col {i}");
        }
    }

    #[test]
    fn structured_normal_blocks_match_dense_products() {
        let k1 = knot(1.0);
        let mut k2 = knot(-0.5);
        k2.pose = k1.pose * Se3::exp(&Vector6::new(0.05, 0.02, -0.03, 0.1, 0.2, -0.15));
        let dt = 0.1;
        let f = prior_factor(&k1, &k2, dt);
        let qc_inv = Vector6::new(1.0, 2.0, 3.0, 40.0, 50.0, 60.0);
        let qi = q_scalar_inv(dt);
        let w = kron_diag(&qi, &qc_inv);
        let (j1, j2) = (f.j1(), f.j2());
        let mut p = PriorNormal::zeros();
        let mut upper = M18::zeros();
        prior_normal(&f, &qi, &qc_inv, &mut p, &mut upper);
        let close = |a: &M18, b: &M18| (a - b).abs().max() <= 1e-12 * b.abs().max();
        assert!(close(&p.d1, &(j1.transpose() * w * j1)));
        assert!(close(&p.d2, &(j2.transpose() * w * j2)));
        assert!(close(&upper, &(j1.transpose() * w * j2)));
        let (r1, r2) = (-(j1.transpose() * w * f.e), -(j2.transpose() * w * f.e));
        assert!((p.r1 - r1).abs().max() <= 1e-12 * r1.abs().max());
        assert!((p.r2 - r2).abs().max() <= 1e-12 * r2.abs().max());
        let cost = (f.e.transpose() * w * f.e)[0];
        assert!((p.cost - cost).abs() <= 1e-12 * cost);
    }

    #[test]
    fn interpolation_reproduces_knots_and_constant_twist() {
        let k1 = knot(1.0);
        let twist = Vector6::new(0.3, -0.1, 0.2, 0.6, -0.9, 1.2);
        let dt = 0.1;
        let k2 = Knot {
            pose: k1.pose * Se3::exp(&(twist * dt)),
            twist,
            rate: Vector6::zeros(),
        };
        let k1 = Knot {
            twist,
            rate: Vector6::zeros(),
            ..k1
        };
        let g1 = first_local_state(&k1);
        let g2 = local_state(&k1, &k2).gamma;
        for s in [0.0, 0.013, 0.05, 0.0999, 0.1] {
            let (l, o, _) = interpolation_weights(s, dt);
            let g = apply_scalar(&l, &g1) + apply_scalar(&o, &g2);
            let k = knot_from_local(&k1.pose, &g);
            let expect = k1.pose * Se3::exp(&(twist * s));
            assert!((k.twist - twist).abs().max() < 1e-9, "s {s}");
            assert!(k.rate.abs().max() < 1e-8, "s {s}: {}", k.rate);
            assert!((k.pose.trans - expect.trans).norm() < 1e-10);
            let dr = crate::lie::so3::log(&(k.pose.rot.transpose() * expect.rot));
            assert!(dr.norm() < 1e-10);
        }
        let _ = Vector3::<f64>::zeros();
    }

    #[test]
    fn conditional_covariance_vanishes_at_knots() {
        let (_, _, c0) = interpolation_weights(0.0, 0.1);
        let (_, _, c1) = interpolation_weights(0.1, 0.1);
        let (_, _, cm) = interpolation_weights(0.05, 0.1);
        assert!(c0.abs().max() < 1e-15);
        assert!(c1.abs().max() < 1e-12);
        assert!(cm.symmetric_eigenvalues().min() > 0.0);
    }
}
