//! The joint problem over trajectory and calibration: state update (trajectory refitted with the
//! DVL velocities as factors, calibration fixed) and the marginal covariance of the calibration.
//!
//! A DVL sample at camera time `t_i + delta` lies between two knots; its predicted velocity
//! depends on both through the GP interpolation, so its factor adds to the two diagonal blocks
//! and the off-diagonal block between them: the normal equations stay block tridiagonal.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector6};

use super::model::{NPARAM, Params, d_predict_d_params, d_predict_d_twist, predict};
use super::offset::DvlObs;
use super::refine::{ParamMat, pin_fixed};
use crate::error::{Error, Result};
use crate::trajectory::blocktri::{BlockTridiagonal, V18};
use crate::trajectory::fit::{NormalEquations, Problem, gauss_newton, measurement_information};
use crate::trajectory::lie::Se3;
use crate::trajectory::{Knot, KnotView, Trajectory};
use crate::types::PoseMeasurement;

/// What the joint problem needs besides the knot states, set up once per calibration: the pose
/// terms (with the weights and Qc of the trajectory's fit) and the DVL terms.
pub struct JointProblem<'a> {
    pub obs: &'a [DvlObs],
    /// DVL samples used.
    pub idx: &'a [usize],
    /// DVL information matrices, one per observation.
    pub dvl_info: Vec<Matrix3<f64>>,
    times: Vec<f64>,
    meas: Vec<Se3>,
    pose_info: Vec<Matrix6<f64>>,
    qc_inv: Vector6<f64>,
}

impl<'a> JointProblem<'a> {
    /// The joint problem of `traj` (fitted to `poses`) and the DVL samples `idx` of `obs`.
    pub fn new(
        poses: &[PoseMeasurement],
        traj: &Trajectory,
        obs: &'a [DvlObs],
        idx: &'a [usize],
    ) -> Result<Self> {
        let dvl_info = obs
            .iter()
            .map(|o| {
                o.cov.try_inverse().ok_or_else(|| {
                    Error::Input(format!("DVL sample at t = {}: singular covariance", o.t))
                })
            })
            .collect::<Result<_>>()?;
        Ok(JointProblem {
            obs,
            idx,
            dvl_info,
            times: traj.times().to_vec(),
            meas: poses.iter().map(|m| m.pose).collect(),
            pose_info: measurement_information(poses, traj.report().pose_sigma)?,
            qc_inv: traj.qc().map(|q| 1.0 / q),
        })
    }

    /// The pose and GP-prior terms (the trajectory fit's own problem).
    fn pose_problem(&self) -> Problem<'_> {
        Problem {
            times: &self.times,
            meas: &self.meas,
            info: &self.pose_info,
            qc_inv: self.qc_inv,
        }
    }

    fn view<'k>(&'k self, knots: &'k [Knot]) -> KnotView<'k> {
        KnotView {
            times: &self.times,
            knots,
        }
    }
}

/// Contributions of the DVL factors at fixed calibration.
struct DvlTerms {
    cost: f64,
    /// `H_x theta` per knot (18 x 8).
    cross: Vec<SMatrix<f64, 18, NPARAM>>,
    theta: ParamMat,
}

/// Adds the DVL factors, linearised at the knots `view`, to `sys`.
fn add_dvl_factors(
    jp: &JointProblem,
    view: KnotView,
    p: &Params,
    sys: &mut BlockTridiagonal,
    with_params: bool,
) -> Result<DvlTerms> {
    let n = view.knots.len();
    let mut cross = if with_params {
        vec![SMatrix::<f64, 18, NPARAM>::zeros(); n]
    } else {
        Vec::new()
    };
    let mut theta = ParamMat::zeros();
    let mut cost = 0.0;
    let dh = d_predict_d_twist(p);
    for &i in jp.idx {
        let o = &jp.obs[i];
        let w = &jp.dvl_info[i];
        let tj = view.twist_jacobian(o.t + p.time_offset)?;
        let r = o.v - predict(p, &tj.state.twist);
        let jx = dh * tj.jacobian;
        let j1: SMatrix<f64, 3, 18> = jx.fixed_view::<3, 18>(0, 0).into_owned();
        let j2: SMatrix<f64, 3, 18> = jx.fixed_view::<3, 18>(0, 18).into_owned();
        let (wj1, wj2) = (w * j1, w * j2);
        let k = tj.knot;
        sys.diag[k] += j1.transpose() * wj1;
        sys.diag[k + 1] += j2.transpose() * wj2;
        sys.upper[k] += j1.transpose() * wj2;
        sys.rhs[k] += wj1.transpose() * r;
        sys.rhs[k + 1] += wj2.transpose() * r;
        cost += (r.transpose() * w * r)[0];
        if with_params {
            let jt = d_predict_d_params(p, &tj.state.twist, &tj.state.rate);
            let wjt = w * jt;
            cross[k] += j1.transpose() * wjt;
            cross[k + 1] += j2.transpose() * wjt;
            theta += jt.transpose() * wjt;
        }
    }
    Ok(DvlTerms { cost, cross, theta })
}

/// The trajectory cost with the DVL factors at a fixed calibration.
struct WithDvl<'a> {
    jp: &'a JointProblem<'a>,
    params: &'a Params,
}

impl NormalEquations for WithDvl<'_> {
    fn normal_equations(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> Result<f64> {
        let cost = self.jp.pose_problem().assemble_into(knots, sys);
        Ok(cost + add_dvl_factors(self.jp, self.jp.view(knots), self.params, sys, false)?.cost)
    }
}

/// State update: the trajectory refitted with the DVL factors at fixed calibration `p`.
/// Returns the new trajectory (without posterior covariance: the refinement only interpolates
/// it, and the calibration's covariance comes from [`joint_covariance`]) and the total cost.
pub fn state_update(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &Params,
    max_iterations: usize,
) -> Result<(Trajectory, f64)> {
    let problem = WithDvl { jp, params: p };
    let solved = gauss_newton(&problem, traj.knots().to_vec(), max_iterations)?;
    Ok((traj.with_knots(solved.knots, None), solved.cost))
}

/// Marginal covariance of the calibration parameters in the joint problem (trajectory and
/// calibration), at the current estimate: the inverse of the Schur complement
/// `H_tt - H_tx H_xx^-1 H_xt`. Also returns the total cost.
pub fn joint_covariance(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &Params,
    free: &[bool; NPARAM],
) -> Result<(ParamMat, f64)> {
    let (mut sys, pose_cost) = jp.pose_problem().assemble(traj.knots());
    let terms = add_dvl_factors(jp, traj.view(), p, &mut sys, true)?;
    let factor = sys.factor()?;
    let mut schur = terms.theta;
    for c in 0..NPARAM {
        if !free[c] {
            continue;
        }
        let rhs: Vec<V18> = terms
            .cross
            .iter()
            .map(|m| m.column(c).into_owned())
            .collect();
        let y = factor.solve_rhs(&rhs);
        for r in 0..NPARAM {
            let dot: f64 = terms
                .cross
                .iter()
                .zip(&y)
                .map(|(m, yk)| m.column(r).dot(yk))
                .sum();
            schur[(r, c)] -= dot;
        }
    }
    pin_fixed(&mut schur, free);
    let schur = (schur + schur.transpose()) * 0.5;
    let mut cov = schur
        .try_inverse()
        .unwrap_or_else(|| ParamMat::from_diagonal_element(f64::INFINITY));
    for k in 0..NPARAM {
        if !free[k] {
            cov[(k, k)] = 0.0;
        }
    }
    Ok((cov, pose_cost + terms.cost))
}
