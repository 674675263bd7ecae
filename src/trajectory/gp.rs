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
use super::lie::{Se3, curly, se3_right_jacobian, se3_right_jacobian_inv};

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

/// Step of the central differences in [`d_jr_inv_times`] and [`d_jr_times`].
const DIFF_STEP: f64 = 1e-6;

/// Derivative with respect to `xi` of `J_r^-1(xi) c`.
pub fn d_jr_inv_times(xi: &Vector6<f64>, c: &[&Vector6<f64>]) -> Vec<Matrix6<f64>> {
    central_difference(xi, c, se3_right_jacobian_inv)
}

/// Derivative with respect to `xi` of `J_r(xi) c`.
pub fn d_jr_times(xi: &Vector6<f64>, c: &[&Vector6<f64>]) -> Vec<Matrix6<f64>> {
    central_difference(xi, c, se3_right_jacobian)
}

fn central_difference(
    xi: &Vector6<f64>,
    c: &[&Vector6<f64>],
    f: fn(&Vector6<f64>) -> Matrix6<f64>,
) -> Vec<Matrix6<f64>> {
    let mut out = vec![Matrix6::zeros(); c.len()];
    for i in 0..6 {
        let mut xp = *xi;
        let mut xm = *xi;
        xp[i] += DIFF_STEP;
        xm[i] -= DIFF_STEP;
        let diff = (f(&xp) - f(&xm)) / (2.0 * DIFF_STEP);
        for (o, ci) in out.iter_mut().zip(c) {
            o.set_column(i, &(diff * **ci));
        }
    }
    out
}

/// The local state of the second knot relative to the first, with its Jacobians.
pub struct LocalState {
    /// `gamma_2 = [xi21; xi'; xi'']`.
    pub gamma: V18,
    /// Derivative of `gamma_2` with respect to the right perturbation of `T_1` (18x6).
    pub d_pose1: SMatrix<f64, 18, 6>,
    /// Derivative of `gamma_2` with respect to knot 2's variables `[dT_2; dw_2; ddw_2]`.
    pub d_knot2: M18,
}

/// `gamma_2` of knot `k2` in the local frame of `k1`, and its Jacobians.
pub fn local_state(k1: &Knot, k2: &Knot) -> LocalState {
    let xi = (k1.pose.inverse() * k2.pose).log();
    let jri = se3_right_jacobian_inv(&xi);
    let jli = se3_right_jacobian_inv(&-xi); // J_l^-1(xi) = J_r^-1(-xi)
    let w2 = k2.twist;
    let dw2 = k2.rate;
    let u = jri * w2;
    let a = jri * dw2 + curly(&u) * w2 * 0.5;
    let d = d_jr_inv_times(&xi, &[&w2, &dw2]);
    let (du_dxi, ddw_dxi) = (d[0], d[1]);
    // d(curly(u) w2)/du = -curly(w2)
    let cw2 = curly(&w2);
    let da_dxi = ddw_dxi - cw2 * du_dxi * 0.5;
    let da_dw2 = (curly(&u) - cw2 * jri) * 0.5;

    let mut d_pose1 = SMatrix::<f64, 18, 6>::zeros();
    d_pose1.fixed_view_mut::<6, 6>(0, 0).copy_from(&-jli);
    d_pose1
        .fixed_view_mut::<6, 6>(6, 0)
        .copy_from(&(-(du_dxi * jli)));
    d_pose1
        .fixed_view_mut::<6, 6>(12, 0)
        .copy_from(&(-(da_dxi * jli)));

    let mut d_knot2 = M18::zeros();
    d_knot2.fixed_view_mut::<6, 6>(0, 0).copy_from(&jri);
    d_knot2
        .fixed_view_mut::<6, 6>(6, 0)
        .copy_from(&(du_dxi * jri));
    d_knot2.fixed_view_mut::<6, 6>(6, 6).copy_from(&jri);
    d_knot2
        .fixed_view_mut::<6, 6>(12, 0)
        .copy_from(&(da_dxi * jri));
    d_knot2.fixed_view_mut::<6, 6>(12, 6).copy_from(&da_dw2);
    d_knot2.fixed_view_mut::<6, 6>(12, 12).copy_from(&jri);

    LocalState {
        gamma: stack(&xi, &u, &a),
        d_pose1,
        d_knot2,
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

/// Prior residual between consecutive knots, `e = gamma_2 - Phi(dt) gamma_1`, and its Jacobians
/// with respect to the variables `[dT; dw; ddw]` of each knot.
pub struct PriorFactor {
    pub e: V18,
    pub j1: M18,
    pub j2: M18,
}

pub fn prior_factor(k1: &Knot, k2: &Knot, dt: f64) -> PriorFactor {
    let ls = local_state(k1, k2);
    let phi = phi_scalar(dt);
    let e = ls.gamma - apply_scalar(&phi, &first_local_state(k1));
    // gamma_1 depends on (w1, dw1) through a selector; on T1 only via gamma_2.
    let mut j1 = -kron_identity(&phi);
    j1.fixed_view_mut::<18, 6>(0, 0).copy_from(&ls.d_pose1);
    PriorFactor {
        e,
        j1,
        j2: ls.d_knot2,
    }
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

/// Knot state at an interpolated local state `gamma` relative to `pose1`: inverts the mapping
/// used for `gamma_2`.
pub fn knot_from_local(pose1: &Se3, gamma: &V18) -> Knot {
    let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
    let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
    let xidd: Vector6<f64> = gamma.fixed_rows::<6>(12).into_owned();
    let jr = se3_right_jacobian(&xi);
    let twist = jr * xid;
    let rate = jr * (xidd - curly(&xid) * twist * 0.5);
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
            assert!((n1 - f.j1.column(i)).abs().max() < 1e-6, "j1 col {i}");
            assert!((n2 - f.j2.column(i)).abs().max() < 1e-6, "j2 col {i}");
        }
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
            let dr = super::super::lie::so3::log(&(k.pose.rot.transpose() * expect.rot));
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
