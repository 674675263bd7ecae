//! What a calibration's problem says beyond its estimate: the Cramer-Rao bound of the
//! parameters at the truth (for accuracy studies), and the evidence for another jerk density of
//! the motion prior.

use super::cosensor::CoSensor;
use super::joint::covariance::joint_covariance;
use super::joint::problem::JointProblem;
use super::joint::steps::joint_log_evidence;
use super::model::NPARAM;
use super::options::CalibOptions;
use super::outcome::CalibrationOutcome;
use super::samples::{observations, usable};
use super::update::{FreeParams, ParamMat};
use crate::error::{Error, Result};
use crate::trajectory::{Knot, Trajectory};
use crate::types::{CalibrationParams, DvlSample, PoseMeasurement};

/// The Laplace approximation of the log marginal likelihood of the poses and the DVL reports
/// (up to a constant) if the trajectory's jerk density were `qc_factor` times the one `outcome`
/// used, at `outcome`'s calibration and the stated DVL covariances: the trajectory is refitted
/// with the DVL factors for that jerk density, and the evidence combines the cost there with the
/// log-determinants of the joint information and of the prior. Comparing factors tells whether
/// the poses and the DVL together ask for a looser or tighter motion prior than the poses alone
/// chose (docs/accuracy.md, "Real vehicle motion").
pub fn jerk_density_evidence(
    poses: &[PoseMeasurement],
    outcome: &CalibrationOutcome,
    qc_factor: f64,
) -> Result<f64> {
    if !(qc_factor.is_finite() && qc_factor > 0.0) {
        return Err(Error::Input(format!(
            "jerk density factor must be positive, got {qc_factor}"
        )));
    }
    let mut free = [false; NPARAM];
    for (k, f) in free.iter_mut().enumerate() {
        *f = outcome.covariance[(k, k)] > 0.0;
    }
    let traj = &outcome.fitted;
    let jp = JointProblem::new(
        CoSensor::Poses(poses).factors(traj)?,
        traj,
        &outcome.observations,
        &outcome.used,
    )?;
    joint_log_evidence(jp, traj, &outcome.params, &free, qc_factor)
}

/// Cramer-Rao bound of the calibration parameters: the inverse of the calibration block's Schur
/// complement in the Fisher information of the joint problem (GP prior, poses, DVL velocities),
/// evaluated at the true trajectory `truth_knots` (one knot per pose) and the true parameters.
/// The GP hyperparameters are those the estimator would choose from `poses` with `opts.fit`.
pub fn cramer_rao(
    poses: &[PoseMeasurement],
    dvl: &[DvlSample],
    truth_knots: &[Knot],
    truth: &CalibrationParams,
    opts: &CalibOptions,
) -> Result<ParamMat> {
    if truth_knots.len() != poses.len() {
        return Err(Error::Input(format!(
            "{} true states for {} poses",
            truth_knots.len(),
            poses.len()
        )));
    }
    let (obs, _) = observations(dvl, opts);
    let fitted = Trajectory::fit(poses, &opts.fit)?;
    let traj = fitted.with_knots(truth_knots.to_vec(), None);
    let idx = usable(&traj, &obs, truth.time_offset_s, 0.0);
    let jp = JointProblem::new(CoSensor::Poses(poses).factors(&traj)?, &traj, &obs, &idx)?;
    Ok(joint_covariance(&jp, &traj, truth, &FreeParams::ALL.mask())?.0)
}
