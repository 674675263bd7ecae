//! The IMU's factors: each bin's predicted gyro and accelerometer means at the trajectory's
//! state at the bin's camera time, and their Jacobians with respect to the two knots around it
//! and to the calibration.
//!
//! The prediction depends on the knots through the interpolated local state `gamma(tau) =
//! Lambda gamma_1 + Omega gamma_2` (twist, twist rate and the rotation for gravity) and, for
//! gravity, on the first knot's rotation directly. The derivative with respect to `gamma` is
//! exact on its rates and taken by central differences on its pose part (6 pairs of cheap
//! evaluations per bin); everything after it (the interpolation weights, the local state's
//! Jacobians) is exact, as is the derivative with respect to the calibration except for the
//! clock offset's (a central difference in time).

use std::ops::Range;

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

use super::bins::ImuBin;
use super::state::ImuState;
use crate::lie::{Se3, curly, hat, se3_right_jacobian, se3_right_jacobian_inv, so3};
use crate::trajectory::KnotView;
use crate::trajectory::blocktri::{M18, V18};
use crate::trajectory::factors::{CoSensorFactors, IntervalNormal};
use crate::trajectory::gp::{
    Knot, LocalState, apply_scalar, first_local_state, interpolation_weights,
    motion_from_local_with,
};
use crate::types::imu::{ImuNoise, imu_measurement};

/// 6 x 18.
pub type M6x18 = SMatrix<f64, 6, 18>;
/// 6 x 9: the calibration's fixed parameters.
pub type M6x9 = SMatrix<f64, 6, 9>;

/// One bin's residual and Jacobians.
pub struct BinTerms {
    /// `h - z`: predicted minus measured, gyro then accelerometer.
    pub e: Vector6<f64>,
    /// d e / d knot k (`[dT; dw; ddw]`).
    pub j1: M6x18,
    /// d e / d knot k + 1.
    pub j2: M6x18,
    /// d e / d the fixed parameters (`theta[0..9]`).
    pub jth: M6x9,
    /// The weight `u` of the next knot's biases in the bin's (`d e / d b_k` is `(1 - u) I`,
    /// `d e / d b_{k+1}` is `u I`).
    pub u: f64,
}

/// The information of a bin, gyro then accelerometer (diagonal).
pub fn bin_information(bin: &ImuBin, noise: &ImuNoise) -> Vector6<f64> {
    let (wg, wa) = bin.information(noise);
    Vector6::new(wg, wg, wg, wa, wa, wa)
}

/// The prediction without bias at the local state `gamma` relative to `pose1`.
fn predict(pose1: &Se3, gamma: &V18, st: &ImuState, g: &Vector3<f64>) -> Vector6<f64> {
    let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
    let jr = se3_right_jacobian(&xi);
    let m = motion_from_local_with(&jr, gamma);
    let rot = pose1.rot * so3::exp(&xi.fixed_rows::<3>(3).into_owned());
    let pose = Se3::new(rot, Vector3::zeros());
    let (gy, ac) = imu_measurement(&pose, &m.twist, &m.rate, &st.t_cam_imu, g);
    Vector6::new(gy.x, gy.y, gy.z, ac.x, ac.y, ac.z)
}

/// `d h / d [xi'; xi'']` at the local state `gamma` (`jr = J_r(xi)`), gyro rows then
/// accelerometer rows. With `u = xi'` and `a = xi''` the twist is `J u` and its rate
/// `J (a - 1/2 curly(u) J u)` ([`motion_from_local_with`]), so `d twist / d u = J`,
/// `d rate / d a = J` and `d rate / d u = -1/2 J (curly(u) J - curly(J u))` (`curly(u) y =
/// -curly(y) u`); the gyro reads `R^T w` and the accelerometer `R^T (v' + w x v + w' x p +
/// w x (w x p))` less gravity, which depends on the pose alone ([`imu_measurement`]).
fn d_predict_d_rates(gamma: &V18, jr: &Matrix6<f64>, st: &ImuState) -> SMatrix<f64, 6, 12> {
    let u: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
    let twist = jr * u;
    let v: Vector3<f64> = twist.fixed_rows::<3>(0).into_owned();
    let w: Vector3<f64> = twist.fixed_rows::<3>(3).into_owned();
    let p = &st.t_cam_imu.trans;
    let rt = st.t_cam_imu.rot.transpose();
    let mut dh_dtwist = Matrix6::zeros();
    dh_dtwist.fixed_view_mut::<3, 3>(0, 3).copy_from(&rt);
    dh_dtwist
        .fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(rt * hat(&w)));
    dh_dtwist
        .fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(-rt * (hat(&v) + hat(&w.cross(p)) + hat(&w) * hat(p))));
    let mut dh_drate = Matrix6::zeros();
    dh_drate.fixed_view_mut::<3, 3>(3, 0).copy_from(&rt);
    dh_drate
        .fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(-rt * hat(p)));
    let drate_du = jr * (curly(&u) * jr - curly(&twist)) * -0.5;
    let mut out = SMatrix::<f64, 6, 12>::zeros();
    out.fixed_columns_mut::<6>(0)
        .copy_from(&(dh_dtwist * jr + dh_drate * drate_du));
    out.fixed_columns_mut::<6>(6).copy_from(&(dh_drate * jr));
    out
}

/// The interpolated local state at `s` after knot `k1` in an interval of `dt`, given the next
/// knot's local state `gamma2` (no clamping: a little outside the interval it extrapolates).
fn local_at(k1: &Knot, gamma2: &V18, s: f64, dt: f64) -> V18 {
    let (lambda, omega, _) = interpolation_weights(s, dt);
    interpolated(&lambda, &omega, k1, gamma2)
}

/// `Lambda gamma_1 + Omega gamma_2`: the local state between knot `k1` and the next (local state
/// `gamma2`) at the interpolation weights `lambda`, `omega`.
fn interpolated(lambda: &Matrix3<f64>, omega: &Matrix3<f64>, k1: &Knot, gamma2: &V18) -> V18 {
    apply_scalar(lambda, &first_local_state(k1)) + apply_scalar(omega, gamma2)
}

/// The weight of knot `k + 1`'s biases at `s` into an interval of `dt`.
fn bias_weight(s: f64, dt: f64) -> f64 {
    (s / dt).clamp(0.0, 1.0)
}

/// The residual of `bin` alone (for costs), the bin's camera time at `s` after knot `k1`
/// (knot `k` of the state's biases).
pub fn bin_residual(
    (k, k1): (usize, &Knot),
    gamma2: &V18,
    s: f64,
    dt: f64,
    bin: &ImuBin,
    st: &ImuState,
) -> Vector6<f64> {
    let g = st.gravity_world();
    let b = st.bias.between(k, bias_weight(s, dt));
    let h = predict(&k1.pose, &local_at(k1, gamma2, s, dt), st, &g);
    h - measured(bin, &b)
}

fn measured(bin: &ImuBin, b: &crate::types::imu::ImuBias) -> Vector6<f64> {
    let gy = bin.gyro - b.gyro;
    let ac = bin.accel - b.accel;
    Vector6::new(gy.x, gy.y, gy.z, ac.x, ac.y, ac.z)
}

/// The residual and Jacobians of `bin`, at `s` after knot `k1` (interval of `dt`; knot `k` of
/// the state's biases), with `ls` the local state of the next knot and its Jacobians.
pub fn bin_terms(
    (k, k1): (usize, &Knot),
    ls: &LocalState,
    s: f64,
    dt: f64,
    bin: &ImuBin,
    st: &ImuState,
) -> BinTerms {
    let g = st.gravity_world();
    let (lambda, omega, _) = interpolation_weights(s, dt);
    let gamma = interpolated(&lambda, &omega, k1, &ls.gamma);
    let h = predict(&k1.pose, &gamma, st, &g);
    let u = bias_weight(s, dt);
    let e = h - measured(bin, &st.bias.between(k, u));

    // d h / d gamma: exact on the rates (the prediction is a closed form in them), by central
    // differences on the pose part (which enters through `J_r(xi)` and gravity's rotation).
    let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
    let jr = se3_right_jacobian(&xi);
    let mut dh_dgamma = M6x18::zeros();
    dh_dgamma
        .fixed_columns_mut::<12>(6)
        .copy_from(&d_predict_d_rates(&gamma, &jr, st));
    for i in 0..6 {
        let step = 1e-6 * (1.0 + gamma[i].abs());
        let mut gp = gamma;
        let mut gm = gamma;
        gp[i] += step;
        gm[i] -= step;
        let d = (predict(&k1.pose, &gp, st, &g) - predict(&k1.pose, &gm, st, &g)) / (2.0 * step);
        dh_dgamma.set_column(i, &d);
    }
    // Through Lambda (x) I6 (gamma_1 = [0; w_1; dw_1]) and Omega (x) I6 (gamma_2).
    let through = |w: &Matrix3<f64>| {
        let mut m = M6x18::zeros();
        for j in 0..3 {
            let block: Matrix6<f64> = (0..3)
                .map(|i| dh_dgamma.fixed_view::<6, 6>(0, 6 * i) * w[(i, j)])
                .sum();
            m.fixed_view_mut::<6, 6>(0, 6 * j).copy_from(&block);
        }
        m
    };
    let (via1, via2) = (through(&lambda), through(&omega));
    let mut j1 = via1;
    j1.fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&(via2 * ls.d_pose1()));
    let j2 = via2 * ls.d_knot2();

    // Gravity through the first knot's rotation: R(tau)^T g = Exp(phi)^T R_1^T g, and a right
    // perturbation of R_1 adds hat(R_1^T g) d to R_1^T g.
    let phi: Vector3<f64> = gamma.fixed_rows::<3>(3).into_owned();
    let r_imu_cam = st.t_cam_imu.rot.transpose();
    let g1 = k1.pose.rot.transpose() * g;
    let d_acc_drot1 = -(r_imu_cam * so3::exp(&phi).transpose() * hat(&g1));
    let mut add = j1.fixed_view_mut::<3, 3>(3, 3);
    add += d_acc_drot1;

    // The calibration.
    let mut jth = M6x9::zeros();
    // Rotation: R^T y -> Exp(-d) R^T y = R^T y + hat(R^T y) d.
    let hg: Vector3<f64> = h.fixed_rows::<3>(0).into_owned();
    let ha: Vector3<f64> = h.fixed_rows::<3>(3).into_owned();
    jth.fixed_view_mut::<3, 3>(0, 0).copy_from(&hat(&hg));
    jth.fixed_view_mut::<3, 3>(3, 0).copy_from(&hat(&ha));
    // Lever arm: R^T (hat(w') + hat(w)^2) p.
    let m = motion_from_local_with(&jr, &gamma);
    let w: Vector3<f64> = m.twist.fixed_rows::<3>(3).into_owned();
    let dw: Vector3<f64> = m.rate.fixed_rows::<3>(3).into_owned();
    jth.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(r_imu_cam * (hat(&dw) + hat(&w) * hat(&w))));
    // Clock offset: the prediction's time derivative.
    let ds = 1e-5;
    let hp = predict(&k1.pose, &local_at(k1, &ls.gamma, s + ds, dt), st, &g);
    let hm = predict(&k1.pose, &local_at(k1, &ls.gamma, s - ds, dt), st, &g);
    jth.set_column(6, &((hp - hm) / (2.0 * ds)));
    // Gravity: g = R_g g0 with R_g <- R_g Exp(d): dg = -R_g hat(g0) d; the accelerometer reads
    // -R^T R(tau)^T g.
    let g0 = Vector3::new(0.0, 0.0, -st.gravity_magnitude);
    let r_tau = k1.pose.rot * so3::exp(&phi);
    let dg = -(st.gravity_rotation * hat(&g0));
    let d_acc_dg = -(r_imu_cam * r_tau.transpose() * dg);
    jth.fixed_view_mut::<3, 2>(3, 7)
        .copy_from(&d_acc_dg.fixed_view::<3, 2>(0, 0));
    // The clock offset also moves the bin along the biases' line between the knots.
    if u > 0.0 && u < 1.0 {
        let (b0, b1) = (&st.bias.values[k], &st.bias.values[k + 1]);
        for r in 0..3 {
            jth[(r, 6)] += (b1.gyro[r] - b0.gyro[r]) / dt;
            jth[(r + 3, 6)] += (b1.accel[r] - b0.accel[r]) / dt;
        }
    }
    BinTerms { e, j1, j2, jth, u }
}

/// Camera poses on some of the knots (the others lie between pose times, where the IMU
/// alone drives the trajectory), each a factor `log(T_meas^-1 T_knot)` weighted by its
/// information; and camera poses between knots (when the knots are sparser than the poses),
/// each the same factor on the pose the GP interpolates there from the two knots around it.
#[derive(Clone, Debug, Default)]
pub struct SparsePoseFactors {
    /// Per knot: the measured pose and its information, or `None`.
    pub poses: Vec<Option<(Se3, Matrix6<f64>)>>,
    /// Per interval (empty: none anywhere): the poses inside it, each with its time after the
    /// interval's first knot.
    pub between: Vec<Vec<BetweenPose>>,
}

/// A camera pose between two knots.
#[derive(Clone, Debug)]
pub struct BetweenPose {
    /// Its time after the interval's first knot, s.
    pub s: f64,
    /// The measured pose.
    pub meas: Se3,
    /// Its information.
    pub info: Matrix6<f64>,
}

/// The residual `log(T_meas^-1 T(s))` of a pose between knots `k1` and the next (whose local
/// state is `gamma2`), `dt` apart.
pub fn between_residual(k1: &Knot, gamma2: &V18, dt: f64, p: &BetweenPose) -> Vector6<f64> {
    let xi: Vector6<f64> = local_at(k1, gamma2, p.s, dt)
        .fixed_rows::<6>(0)
        .into_owned();
    (p.meas.inverse() * k1.pose * Se3::exp(&xi)).log()
}

/// [`between_residual`] and its Jacobians with respect to both knots' variables. With
/// `T(s) = T_1 Exp(xi(s))`, a right perturbation `d` of `T_1` and a change `dxi` move `T(s)` by
/// `Ad(Exp(-xi)) d + J_r(xi) dxi` on the right, and the residual by `J_r^-1(e)` of that.
pub fn between_terms(
    k1: &Knot,
    ls: &LocalState,
    dt: f64,
    p: &BetweenPose,
) -> (Vector6<f64>, M6x18, M6x18) {
    let (lambda, omega, _) = interpolation_weights(p.s, dt);
    let gamma = interpolated(&lambda, &omega, k1, &ls.gamma);
    let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
    let e = (p.meas.inverse() * k1.pose * Se3::exp(&xi)).log();
    let outer = se3_right_jacobian_inv(&e);
    let via = outer * se3_right_jacobian(&xi);
    // d xi / d gamma_2 = [Omega00 I, Omega01 I, Omega02 I].
    let mut d_xi_d_gamma2 = M6x18::zeros();
    for j in 0..3 {
        d_xi_d_gamma2
            .fixed_view_mut::<6, 6>(0, 6 * j)
            .copy_from(&(via * omega[(0, j)]));
    }
    let mut j1 = M6x18::zeros();
    j1.fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&(outer * Se3::exp(&-xi).adjoint() + d_xi_d_gamma2 * ls.d_pose1()));
    j1.fixed_view_mut::<6, 6>(0, 6)
        .copy_from(&(via * lambda[(0, 1)]));
    j1.fixed_view_mut::<6, 6>(0, 12)
        .copy_from(&(via * lambda[(0, 2)]));
    let j2 = d_xi_d_gamma2 * ls.d_knot2();
    (e, j1, j2)
}

impl CoSensorFactors for SparsePoseFactors {
    fn knot_terms(&self, knots: &[Knot], k: usize, diag: &mut M18, rhs: &mut V18) -> f64 {
        *diag = M18::zeros();
        *rhs = V18::zeros();
        let Some((meas, info)) = &self.poses[k] else {
            return 0.0;
        };
        let e = (meas.inverse() * knots[k].pose).log();
        let j = se3_right_jacobian_inv(&e);
        let wj = info * j;
        diag.fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&(j.transpose() * wj));
        rhs.fixed_rows_mut::<6>(0).copy_from(&-(wj.transpose() * e));
        (e.transpose() * info * e)[0]
    }

    fn knot_cost(&self, knots: &[Knot], k: usize) -> f64 {
        self.poses[k].as_ref().map_or(0.0, |(meas, info)| {
            let e = (meas.inverse() * knots[k].pose).log();
            (e.transpose() * info * e)[0]
        })
    }

    fn has_interval_terms(&self) -> bool {
        !self.between.is_empty()
    }

    fn interval_terms(
        &self,
        view: KnotView,
        k: usize,
        ls: &LocalState,
        out: &mut IntervalNormal,
    ) -> bool {
        let Some(list) = self.between.get(k).filter(|l| !l.is_empty()) else {
            return false;
        };
        let dt = view.times[k + 1] - view.times[k];
        *out = IntervalNormal::zeros();
        for p in list {
            let (e, j1, j2) = between_terms(&view.knots[k], ls, dt, p);
            let (wj1, wj2) = (p.info * j1, p.info * j2);
            out.d1 += j1.transpose() * wj1;
            out.d2 += j2.transpose() * wj2;
            out.upper += j1.transpose() * wj2;
            out.r1 -= wj1.transpose() * e;
            out.r2 -= wj2.transpose() * e;
            out.cost += (e.transpose() * p.info * e)[0];
        }
        true
    }

    fn interval_cost(&self, view: KnotView, k: usize, gamma2: &V18) -> f64 {
        let Some(list) = self.between.get(k) else {
            return 0.0;
        };
        let dt = view.times[k + 1] - view.times[k];
        list.iter()
            .map(|p| {
                let e = between_residual(&view.knots[k], gamma2, dt, p);
                (e.transpose() * p.info * e)[0]
            })
            .sum()
    }

    fn dimension(&self) -> usize {
        6 * (self.poses.iter().filter(|p| p.is_some()).count()
            + self.between.iter().map(Vec::len).sum::<usize>())
    }

    fn restricted(&self, range: Range<usize>) -> Box<dyn CoSensorFactors + '_> {
        let between = if self.between.is_empty() {
            Vec::new()
        } else {
            // The intervals inside the range: all but its last knot's.
            let end = range.end.saturating_sub(1).min(self.between.len());
            self.between[range.start.min(end)..end].to_vec()
        };
        Box::new(SparsePoseFactors {
            poses: self.poses[range].to_vec(),
            between,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::gp::{knot_from_local, local_gamma, local_state};
    use crate::types::imu::{ImuBias, STANDARD_GRAVITY};

    fn knot(a: f64) -> Knot {
        Knot {
            pose: Se3::exp(&Vector6::new(0.3, -0.2, 0.5, 0.4 * a, -0.3, 0.2)),
            twist: Vector6::new(0.2, 0.1, -0.3, 0.5, -0.8 * a, 0.3),
            rate: Vector6::new(-0.1, 0.3, 0.05, 0.2, 0.1, -0.4 * a),
        }
    }

    fn perturb(k: &Knot, d: &V18) -> Knot {
        Knot {
            pose: k.pose * Se3::exp(&d.fixed_rows::<6>(0).into_owned()),
            twist: k.twist + d.fixed_rows::<6>(6),
            rate: k.rate + d.fixed_rows::<6>(12),
        }
    }

    fn state() -> ImuState {
        let mut bias = super::super::state::BiasNodes::spanning(
            0.0,
            1.0,
            0.5,
            ImuBias {
                gyro: Vector3::new(0.01, 0.02, -0.01),
                accel: Vector3::new(0.1, -0.2, 0.05),
            },
        );
        bias.values[1].gyro.x = 0.03;
        ImuState {
            t_cam_imu: Se3::new(
                so3::exp(&Vector3::new(0.4, 1.1, -0.3)),
                Vector3::new(0.1, -0.05, 0.2),
            ),
            time_offset_s: 0.01,
            gravity_rotation: so3::exp(&Vector3::new(0.2, -0.1, 0.4)),
            gravity_magnitude: STANDARD_GRAVITY,
            bias,
            dvl: None,
        }
    }

    /// The residual as a function of both knots and the calibration, evaluated from scratch.
    fn residual(
        k1: &Knot,
        k2: &Knot,
        s: f64,
        dt: f64,
        bin: &ImuBin,
        st: &ImuState,
    ) -> Vector6<f64> {
        bin_residual((0, k1), &local_gamma(k1, k2), s, dt, bin, st)
    }

    #[test]
    fn a_pose_between_knots_has_the_jacobians_of_its_differences() {
        let (k1, k2) = (knot(1.0), knot(-0.6));
        let k2 = Knot {
            pose: k1.pose * Se3::exp(&Vector6::new(0.05, 0.02, -0.03, 0.04, -0.02, 0.03)),
            ..k2
        };
        let dt = 0.4;
        let p = BetweenPose {
            s: 0.13,
            meas: k1.pose * Se3::exp(&Vector6::new(0.02, 0.01, -0.01, 0.01, 0.02, -0.02)),
            info: Matrix6::identity(),
        };
        let ls = local_state(&k1, &k2);
        let (e, j1, j2) = between_terms(&k1, &ls, dt, &p);
        let res = |a: &Knot, b: &Knot| between_residual(a, &local_gamma(a, b), dt, &p);
        assert!((e - res(&k1, &k2)).norm() < 1e-14);
        // The interpolated pose is the trajectory's own interpolation.
        let (lambda, omega, _) = interpolation_weights(p.s, dt);
        let gamma =
            apply_scalar(&lambda, &first_local_state(&k1)) + apply_scalar(&omega, &ls.gamma);
        let want = (p.meas.inverse() * knot_from_local(&k1.pose, &gamma).pose).log();
        assert!((e - want).norm() < 1e-12, "{e} vs {want}");
        let h = 1e-6;
        for i in 0..18 {
            let mut d = V18::zeros();
            d[i] = h;
            let n1 = (res(&perturb(&k1, &d), &k2) - res(&perturb(&k1, &(-d)), &k2)) / (2.0 * h);
            let n2 = (res(&k1, &perturb(&k2, &d)) - res(&k1, &perturb(&k2, &(-d)))) / (2.0 * h);
            let (a1, a2) = (j1.column(i), j2.column(i));
            assert!((a1 - n1).amax() < 1e-7, "knot 1 col {i}: {a1} vs {n1}");
            assert!((a2 - n2).amax() < 1e-7, "knot 2 col {i}: {a2} vs {n2}");
        }
    }

    #[test]
    fn the_exact_rate_columns_match_differences_of_the_prediction() {
        let st = state();
        let g = st.gravity_world();
        let pose1 = knot(1.0).pose;
        let gamma = V18::from_fn(|i, _| 0.3 * ((i * 7 % 11) as f64 - 5.0) / 5.0);
        let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
        let exact = d_predict_d_rates(&gamma, &se3_right_jacobian(&xi), &st);
        for i in 0..12 {
            let h = 1e-6;
            let (mut gp, mut gm) = (gamma, gamma);
            gp[6 + i] += h;
            gm[6 + i] -= h;
            let num = (predict(&pose1, &gp, &st, &g) - predict(&pose1, &gm, &st, &g)) / (2.0 * h);
            let err = (exact.column(i) - num).amax();
            assert!(err < 1e-8 * (1.0 + num.amax()), "column {i}: off by {err}");
        }
    }

    #[test]
    fn the_bin_jacobians_match_differences_of_the_whole_residual() {
        let (k1, k2) = (knot(1.0), knot(-0.6));
        let k2 = Knot {
            pose: k1.pose * Se3::exp(&Vector6::new(0.05, 0.02, -0.03, 0.04, -0.02, 0.03)),
            ..k2
        };
        let dt = 0.1;
        let s = 0.037;
        let st = state();
        let bin = ImuBin {
            t: 0.3,
            gyro: Vector3::new(0.1, 0.2, 0.3),
            accel: Vector3::new(1.0, -2.0, 9.0),
            n: 5,
        };
        let ls = local_state(&k1, &k2);
        let t = bin_terms((0, &k1), &ls, s, dt, &bin, &st);
        let e0 = residual(&k1, &k2, s, dt, &bin, &st);
        assert!((t.e - e0).norm() < 1e-12);
        let h = 1e-6;
        for i in 0..18 {
            let mut d = V18::zeros();
            d[i] = h;
            let num1 = (residual(&perturb(&k1, &d), &k2, s, dt, &bin, &st)
                - residual(&perturb(&k1, &(-d)), &k2, s, dt, &bin, &st))
                / (2.0 * h);
            let num2 = (residual(&k1, &perturb(&k2, &d), s, dt, &bin, &st)
                - residual(&k1, &perturb(&k2, &(-d)), s, dt, &bin, &st))
                / (2.0 * h);
            let (a1, a2) = (t.j1.column(i), t.j2.column(i));
            assert!(
                (a1 - num1).amax() < 1e-5 * (1.0 + num1.amax()),
                "knot 1 col {i}: {a1} vs {num1}"
            );
            assert!(
                (a2 - num2).amax() < 1e-5 * (1.0 + num2.amax()),
                "knot 2 col {i}: {a2} vs {num2}"
            );
        }
        for i in 0..9 {
            let mut d = nalgebra::DVector::zeros(st.dim());
            d[i] = h;
            let sp = st.retract(&d);
            let sm = st.retract(&(-d.clone()));
            // The offset moves the bin's camera time.
            let (s_p, s_m) = if i == 6 { (s + h, s - h) } else { (s, s) };
            let num = (residual(&k1, &k2, s_p, dt, &bin, &sp)
                - residual(&k1, &k2, s_m, dt, &bin, &sm))
                / (2.0 * h);
            let a = t.jth.column(i);
            assert!(
                (a - num).amax() < 1e-5 * (1.0 + num.amax()),
                "theta {i}: {a} vs {num}"
            );
        }
        // The interpolated pose agrees with the trajectory's own interpolation.
        let (lambda, omega, _) = interpolation_weights(s, dt);
        let gamma =
            apply_scalar(&lambda, &first_local_state(&k1)) + apply_scalar(&omega, &ls.gamma);
        let kk = knot_from_local(&k1.pose, &gamma);
        assert!(kk.pose.rot.iter().all(|x| x.is_finite()));
    }
}
