//! Steps on the joint problem: the state update (the trajectory refitted with the DVL factors,
//! the calibration fixed), a Gauss-Newton step on trajectory and calibration together, the
//! joint cost, and the evidence for a motion prior's jerk density.

use super::covariance::{joint_system, reduced};
use super::factors::DvlFactors;
use super::problem::JointProblem;
use crate::calib::model::NPARAM;
use crate::error::Result;
use crate::trajectory::Trajectory;
use crate::trajectory::blocktri::V18;
use crate::trajectory::solver::{GaussNewtonOptions, STEP_DECREMENT, gauss_newton, step};
use crate::types::CalibrationParams;

/// State update: the trajectory refitted with the DVL factors at fixed calibration `p`.
/// Returns the new trajectory (without posterior covariance: the refinement only interpolates
/// it, and the calibration's covariance comes from [`joint_covariance`]) and the total cost.
pub fn state_update(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    max_iterations: usize,
) -> Result<(Trajectory, f64)> {
    let problem = DvlFactors::new(jp, p)?;
    let opts = GaussNewtonOptions {
        max_iterations,
        stop_decrement: STEP_DECREMENT,
        factor: false,
        storage: jp.take_system(),
    };
    let solved = gauss_newton(&problem, traj.knots().to_vec(), opts)?;
    if let Some(s) = solved.spare {
        jp.keep_system(s);
    }
    let prior_cost = if jp.priors.any() {
        jp.priors.terms(p).cost
    } else {
        0.0
    };
    Ok((
        traj.with_knots(solved.knots, None),
        solved.cost + prior_cost,
    ))
}

/// The joint cost at the trajectory `traj` and the calibration `p`: pose, GP prior, DVL and
/// calibration prior terms (what [`state_update`] returns for its own result).
pub fn joint_cost(jp: &JointProblem, traj: &Trajectory, p: &CalibrationParams) -> Result<f64> {
    let prior_cost = if jp.priors.any() {
        jp.priors.terms(p).cost
    } else {
        0.0
    };
    Ok(DvlFactors::new(jp, p)?.cost(traj.knots()) + prior_cost)
}

/// Outcome of a joint step.
pub struct JointStep {
    pub trajectory: Trajectory,
    pub params: CalibrationParams,
}

/// One Gauss-Newton step on the joint problem (trajectory and free calibration parameters
/// together, the calibration eliminated by its Schur complement), with step halving. `None`
/// when no step along the Gauss-Newton direction lowers the joint cost.
///
/// Block-coordinate descent converges linearly when the trajectory and the calibration (above
/// all the clock offset) are coupled; a joint step moves both towards their common fixed
/// point at once.
pub fn joint_step(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    free: &[bool; NPARAM],
) -> Result<Option<JointStep>> {
    let js = joint_system(jp, traj, p, free)?;
    // Calibration step from the Schur complement, then the trajectory's step for it:
    // `H_xx dx = g_x - H_x theta dtheta`.
    let (schur, b) = reduced(&js, free);
    let Some(dtheta) = schur.cholesky().map(|c| c.solve(&b)) else {
        jp.keep_joint(js);
        return Ok(None);
    };
    let u = js.factor.solve();
    let correction = js
        .factor
        .solve_many(&js.cross.iter().map(|c| c * dtheta).collect::<Vec<V18>>());
    let start_cost = js.cost;
    jp.keep_joint(js);
    let dx: Vec<V18> = u.iter().zip(&correction).map(|(u, c)| u - c).collect();
    let mut scale = 1.0;
    for _ in 0..8 {
        let params = p.updated(&(dtheta * scale));
        // A step that moves a sample outside the trajectory is too long.
        if let Ok(f) = DvlFactors::new(jp, &params) {
            let knots = step(traj.knots(), &dx, scale);
            let mut cost = f.cost(&knots);
            if jp.priors.any() {
                cost += jp.priors.terms(&params).cost;
            }
            if cost.is_finite() && cost <= start_cost {
                return Ok(Some(JointStep {
                    trajectory: traj.with_knots(knots, None),
                    params,
                }));
            }
        }
        scale *= 0.5;
    }
    Ok(None)
}

/// Laplace approximation of the log marginal likelihood of the co-sensor's measurements and the
/// DVL reports of `jp` (up to a constant that does not depend on `qc_factor`) when the jerk
/// density is `qc_factor` times the trajectory's: the trajectory is refitted with the DVL
/// factors at the calibration `p`, and `-1/2 [cost + log det H + (N - 1) * 18 log qc_factor]`
/// is evaluated there (`H` the joint information of trajectory and free parameters, `N` the
/// knots; the `Q_k` of the prior scale with `Qc`, and `log det (Q(dt) (x) Qc)` has `3 log` of each of Qc's six values).
pub fn joint_log_evidence(
    jp: JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    free: &[bool; NPARAM],
    qc_factor: f64,
) -> Result<f64> {
    let jp = jp.with_qc_factor(qc_factor);
    let (fitted, _) = state_update(&jp, traj, p, 20)?;
    let js = joint_system(&jp, &fitted, p, free)?;
    let (schur, _) = reduced(&js, free);
    let log_det_theta = schur.cholesky().map_or(f64::INFINITY, |c| {
        2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>()
    });
    let n = fitted.knots().len() as f64;
    Ok(-0.5 * (js.cost + js.factor.log_det() + log_det_theta + (n - 1.0) * 18.0 * qc_factor.ln()))
}
