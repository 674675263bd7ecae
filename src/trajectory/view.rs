//! Queries of a trajectory between its knots: GP interpolation and its Jacobians over knot
//! times and states borrowed from a fitted trajectory or from a solver's iterate
//! ([`KnotView`]), and what a query gives ([`TrajectoryState`], [`TwistJacobian`]).

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector6};

use super::blocktri::V18;
use super::gp::{
    Knot, LocalState, Motion, apply_scalar, d_jr_times, first_local_state, interpolation_weights,
    knot_from_local, local_gamma, local_state, motion_from_local, motion_from_local_with,
    twist_from_local,
};
use crate::error::{Error, Result};
use crate::lie::{Se3, se3_right_jacobian};

/// The trajectory at one time.
#[derive(Clone, Debug)]
pub struct TrajectoryState {
    /// Camera-clock time, seconds relative to the dataset epoch.
    pub t: f64,
    /// `T_world_cam`.
    pub pose: Se3,
    /// Body twist `[v; w]` (m/s, rad/s, camera frame).
    pub twist: Vector6<f64>,
    /// Its time derivative.
    pub rate: Vector6<f64>,
    /// Posterior covariance of `twist`, when the fit computed covariances.
    pub twist_cov: Option<Matrix6<f64>>,
}

impl TrajectoryState {
    /// The interpolated knot state `s` at `t`, without a covariance.
    pub(crate) fn of_knot(t: f64, s: Knot) -> TrajectoryState {
        TrajectoryState {
            t,
            pose: s.pose,
            twist: s.twist,
            rate: s.rate,
            twist_cov: None,
        }
    }
}

/// Interpolated twist with its Jacobian with respect to the variables of the two knots that
/// bracket the query time (for factors that involve the twist, e.g. DVL velocities).
pub struct TwistJacobian {
    /// Index of the first knot.
    pub knot: usize,
    /// The interpolated state (pose, twist, rate) at the query time.
    pub state: Knot,
    /// d twist / d [x_k; x_{k+1}], each `x = [dT; dw; ddw]`.
    pub jacobian: SMatrix<f64, 6, 36>,
    /// d twist / d local state (6x18), for the conditional covariance term.
    pub d_local: SMatrix<f64, 6, 18>,
    /// Scalar conditional covariance of the local state at the query time (times `Qc`).
    pub cond: Matrix3<f64>,
}

/// Knot times and states borrowed from a trajectory or from a Gauss-Newton iterate: GP
/// interpolation and its Jacobians without copying the knots. Needs at least two knots.
#[derive(Clone, Copy, Debug)]
pub struct KnotView<'a> {
    /// Knot times, seconds, strictly increasing.
    pub times: &'a [f64],
    /// Knot states, one per time.
    pub knots: &'a [Knot],
}

impl KnotView<'_> {
    /// First and last knot times.
    pub fn span(&self) -> (f64, f64) {
        (self.times[0], self.times[self.times.len() - 1])
    }

    /// Index `k` of the interval `[t_k, t_{k+1}]` holding `t`, or `None` outside the span.
    pub fn interval(&self, t: f64) -> Option<usize> {
        let (a, b) = self.span();
        let tol = 1e-9 * (1.0 + a.abs().max(b.abs()));
        if !(t >= a - tol && t <= b + tol) {
            return None;
        }
        let i = self.times.partition_point(|&x| x <= t);
        Some(i.saturating_sub(1).min(self.times.len() - 2))
    }

    /// The interval holding `t`, or an error naming the span.
    pub(crate) fn locate(&self, t: f64) -> Result<usize> {
        self.interval(t).ok_or_else(|| {
            let (a, b) = self.span();
            Error::Input(format!(
                "time {t} is outside the trajectory span [{a}, {b}]"
            ))
        })
    }

    /// Pose, twist and twist rate at `t`, without covariance or Jacobians (the cheap query).
    pub fn state(&self, t: f64) -> Result<TrajectoryState> {
        let k = self.locate(t)?;
        let s = self.state_in(k, t, &local_gamma(&self.knots[k], &self.knots[k + 1]));
        Ok(TrajectoryState::of_knot(t, s))
    }

    /// The twist and the rate at `t` (the values of [`KnotView::state`], without the pose).
    pub fn motion(&self, t: f64) -> Result<Motion> {
        let k = self.locate(t)?;
        Ok(self.motion_in(k, t, &local_gamma(&self.knots[k], &self.knots[k + 1])))
    }

    /// The twist and the rate at `t` in the interval `k`, given the local state `gamma_2` of
    /// knot `k + 1` (as [`KnotView::state_in`] gives them).
    pub(crate) fn motion_in(&self, k: usize, t: f64, gamma2: &V18) -> Motion {
        motion_from_local(&self.local_at(k, t, gamma2))
    }

    /// The twist at `t` in the interval `k`, given the local state `gamma_2` of knot `k + 1`
    /// (as [`KnotView::state_in`] gives it).
    pub(crate) fn twist_in(&self, k: usize, t: f64, gamma2: &V18) -> Vector6<f64> {
        twist_from_local(&self.local_at(k, t, gamma2))
    }

    /// The twist at `t` alone (the value of [`KnotView::state`]).
    pub fn twist(&self, t: f64) -> Result<Vector6<f64>> {
        let k = self.locate(t)?;
        Ok(self.twist_in(k, t, &local_gamma(&self.knots[k], &self.knots[k + 1])))
    }

    /// The time since knot `k` (clamped to the interval) and the interval's length.
    fn offset_in(&self, k: usize, t: f64) -> (f64, f64) {
        let dt = self.times[k + 1] - self.times[k];
        ((t - self.times[k]).clamp(0.0, dt), dt)
    }

    /// The state at `t` in the interval `k`, given the local state `gamma_2` of knot `k + 1`
    /// relative to knot `k` ([`local_gamma`]).
    pub(crate) fn state_in(&self, k: usize, t: f64, gamma2: &V18) -> Knot {
        knot_from_local(&self.knots[k].pose, &self.local_at(k, t, gamma2))
    }

    /// The interpolated local state at `t` in the interval `k` (relative to knot `k`), given
    /// knot `k + 1`'s local state `gamma2`.
    fn local_at(&self, k: usize, t: f64, gamma2: &V18) -> V18 {
        let (s, dt) = self.offset_in(k, t);
        let (lambda, omega, _) = interpolation_weights(s, dt);
        apply_scalar(&lambda, &first_local_state(&self.knots[k])) + apply_scalar(&omega, gamma2)
    }

    /// The interpolated state at `t` with the twist's Jacobian with respect to the two knots.
    pub fn twist_jacobian(&self, t: f64) -> Result<TwistJacobian> {
        let k = self.locate(t)?;
        let ls = local_state(&self.knots[k], &self.knots[k + 1]);
        Ok(self.twist_jacobian_in(k, t, &ls))
    }

    /// The interpolated twist and rate at `t` in the interval `k` and the Jacobians of `m twist` with
    /// respect to the variables of the two knots (3 x 18 each), for a fixed 3 x 6 map `m` (a DVL
    /// velocity's dependence on the twist). The same derivative as `m` times
    /// [`KnotView::twist_jacobian_in`], formed in the three rows from the 6 x 6 pieces of the
    /// local state's Jacobians, without the 6 x 36 intermediate.
    pub(crate) fn projected_twist_jacobian_in(
        &self,
        k: usize,
        t: f64,
        ls: &LocalState,
        m: &SMatrix<f64, 3, 6>,
    ) -> (Motion, SMatrix<f64, 3, 18>, SMatrix<f64, 3, 18>) {
        type M36 = SMatrix<f64, 3, 6>;
        let (s, dt) = self.offset_in(k, t);
        let k1 = &self.knots[k];
        let (lambda, omega, _) = interpolation_weights(s, dt);
        let gamma = apply_scalar(&lambda, &first_local_state(k1)) + apply_scalar(&omega, &ls.gamma);
        let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
        let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
        let jr = se3_right_jacobian(&xi);
        let state = motion_from_local_with(&jr, &gamma);
        // m d twist / d gamma = [p0, p1, 0] (the twist does not depend on xi'').
        let p0: M36 = m * d_jr_times(&xi, [&xid])[0];
        let p1: M36 = m * jr;
        // Through Lambda (x) I6 and Omega (x) I6: block j is p0 s[0][j] + p1 s[1][j].
        let through = |s: &Matrix3<f64>, j: usize| -> M36 { p0 * s[(0, j)] + p1 * s[(1, j)] };
        let (a0, a1, a2) = (through(&omega, 0), through(&omega, 1), through(&omega, 2));
        // gamma_2's Jacobians: d/dT_1 = -[I; du; da] J_l^-1 and d/dx_2 block lower triangular
        // (see LocalState::d_pose1 and LocalState::d_knot2).
        let pose = a0 + a1 * ls.du_dxi + a2 * ls.da_dxi;
        let mut j1 = SMatrix::<f64, 3, 18>::zeros();
        j1.fixed_view_mut::<3, 6>(0, 0).copy_from(&-(pose * ls.jli));
        j1.fixed_view_mut::<3, 6>(0, 6)
            .copy_from(&through(&lambda, 1));
        j1.fixed_view_mut::<3, 6>(0, 12)
            .copy_from(&through(&lambda, 2));
        let mut j2 = SMatrix::<f64, 3, 18>::zeros();
        j2.fixed_view_mut::<3, 6>(0, 0).copy_from(&(pose * ls.jri));
        j2.fixed_view_mut::<3, 6>(0, 6)
            .copy_from(&(a1 * ls.jri + a2 * ls.da_dw2));
        j2.fixed_view_mut::<3, 6>(0, 12).copy_from(&(a2 * ls.jri));
        (state, j1, j2)
    }

    /// [`KnotView::twist_jacobian`] at `t` in the interval `k`, given the local state of knot
    /// `k + 1` relative to knot `k` with its Jacobians ([`local_state`]).
    pub(crate) fn twist_jacobian_in(&self, k: usize, t: f64, ls: &LocalState) -> TwistJacobian {
        let (s, dt) = self.offset_in(k, t);
        let k1 = &self.knots[k];
        let (lambda, omega, cond) = interpolation_weights(s, dt);
        let gamma = apply_scalar(&lambda, &first_local_state(k1)) + apply_scalar(&omega, &ls.gamma);
        let state = knot_from_local(&k1.pose, &gamma);

        let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
        let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
        let mut d_local = SMatrix::<f64, 6, 18>::zeros();
        d_local
            .fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&d_jr_times(&xi, [&xid])[0]);
        d_local
            .fixed_view_mut::<6, 6>(0, 6)
            .copy_from(&se3_right_jacobian(&xi));

        // The twist depends on gamma_1 through Lambda (x) I6 and on gamma_2 through
        // Omega (x) I6; fold those into d_local first (6x18 each, from 6x6 blocks).
        let through = |s: &Matrix3<f64>| {
            let mut m = SMatrix::<f64, 6, 18>::zeros();
            for j in 0..3 {
                let block: Matrix6<f64> = (0..3)
                    .map(|i| d_local.fixed_view::<6, 6>(0, 6 * i) * s[(i, j)])
                    .sum();
                m.fixed_view_mut::<6, 6>(0, 6 * j).copy_from(&block);
            }
            m
        };
        let (via_gamma1, via_gamma2) = (through(&lambda), through(&omega));
        let mut jacobian = SMatrix::<f64, 6, 36>::zeros();
        // gamma_1 = [0; w_1; dw_1] does not depend on T_1; gamma_2 does.
        jacobian
            .fixed_view_mut::<6, 18>(0, 0)
            .copy_from(&via_gamma1);
        jacobian
            .fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&(via_gamma2 * ls.d_pose1()));
        jacobian
            .fixed_view_mut::<6, 18>(0, 18)
            .copy_from(&(via_gamma2 * ls.d_knot2()));
        TwistJacobian {
            knot: k,
            state,
            jacobian,
            d_local,
            cond,
        }
    }
}
