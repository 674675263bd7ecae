//! Stage 4: the refinement. Rounds of a calibration update with the trajectory fixed and a state
//! update with the calibration fixed (block-coordinate descent), sped up by joint Gauss-Newton
//! steps ([`refine_jointly`]); a lever arm the motion does not observe held at its prior first;
//! a negative scale checked against its mirrored solution; then the DVL reports reweighted by the
//! robust loss and the refinement repeated until the weights settle ([`reweigh`]).

use nalgebra::{Matrix3, Vector3};

use super::cosensor::CoSensorFit;
use super::joint::covariance::joint_covariance;
use super::joint::problem::{JointProblem, JointStorage};
use super::joint::steps::{joint_cost, joint_step, state_update};
use super::model::{DvlObs, predict};
use super::noise;
use super::options::CalibOptions;
use super::outcome::{InitReport, IterationRecord, StageClock};
use super::prior::{HeldLeverAxes, LeverArmPrior, Priors};
use super::robust::{self, Loss, RobustSummary};
use super::setting::Setting;
use super::update::{self, FreeParams, calibration_update};
use super::whiteness::{self, Whiteness};
use crate::error::Result;
use crate::trajectory::Trajectory;
use crate::types::CalibrationParams;

/// What a refinement settled before its rounds, which the later stages use.
pub(crate) struct Setup {
    /// The parameters estimated (the lever arm is not when it is held).
    pub free: FreeParams,
    /// The calibration the rounds started from (the lever arm at its prior when held).
    pub start: CalibrationParams,
    /// The lever arm held at the broad default prior: the data's standard deviation of it
    /// (infinite when the rotation is noise) and the prior.
    pub lever_held: Option<(f64, LeverArmPrior)>,
    /// Directions of the lever arm held at the broad default prior, the others estimated (the
    /// motion turned about too few axes).
    pub lever_axes: Option<PartialLeverHold>,
    /// The trajectory fitted to the co-sensor alone, for the noise and drift checks: the
    /// refined one has absorbed part of the DVL's misfit.
    pub pose_only: Trajectory,
    /// The priors of the problem: the user's, and the broad default on the lever arm.
    pub priors: Priors,
}

/// What the least-squares refinement gives the later stages.
pub(crate) struct Refinement<'a> {
    /// The joint problem of the DVL samples used (its storage serves every later system).
    pub jp: JointProblem<'a>,
    /// The trajectory, calibration and rounds it ended with.
    pub refined: Refined,
    /// What it settled before its rounds.
    pub setup: Setup,
}

/// The least-squares refinement from `start`, with the trajectory `traj` fitted to the
/// co-sensor `cos`, of the samples `idx` of `obs`. A lever arm the motion does not observe is
/// held at the broad default prior (with a warning): free, it would wander to metres, the
/// trajectory's angular velocity bending to fit the DVL noise through `w x p`, and take the
/// other parameters with it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine<'a>(
    cos: &CoSensorFit,
    mut traj: Trajectory,
    obs: &'a [DvlObs],
    idx: &'a [usize],
    start: CalibrationParams,
    init: Option<&InitReport>,
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<Refinement<'a>> {
    let mut free = opts.method.free_parameters();
    let mask = free.mask();
    let priors = opts.effective_priors();
    let mut jp = JointProblem::new(cos.factors(&traj)?, &traj, obs, idx)?;
    jp.priors = priors;
    // The fit's covariance was for the initialisation; its storage serves the joint problem.
    if let Some(storage) = traj.take_covariance_storage() {
        jp.keep_system(storage);
    }
    let pose_only = traj.clone();
    let mut start = start;
    // With a closed form, the excitation of its rotation rates decides which directions of the
    // lever arm the motion observes (the linearised std cannot see the runaway anyway); without
    // one, the data's own std at the guess decide for the whole lever arm.
    let unobserved = match (opts.priors.lever_arm, priors.lever_arm, init) {
        (None, Some(_), Some(i)) if free.lever_arm => {
            i.closed_form.unobserved_lever_directions(LEVER_HOLD_SNR)
        }
        _ => Vec::new(),
    };
    let lever_held = match (opts.priors.lever_arm, priors.lever_arm) {
        (None, Some(l)) if free.lever_arm && init.is_some() => {
            (unobserved.len() == 3).then_some((f64::INFINITY, l))
        }
        (None, Some(l)) if free.lever_arm => {
            let taken = std::mem::take(&mut jp.priors);
            let (data_only, _) = joint_covariance(&jp, &traj, &start, &mask)?;
            jp.priors = taken;
            let worst = (3..6)
                .map(|k| data_only[(k, k)].max(0.0).sqrt())
                .fold(0.0, f64::max);
            (worst.is_nan() || worst > LEVER_HOLD_FRACTION * l.sigma_m).then_some((worst, l))
        }
        _ => None,
    };
    let mut priors = priors;
    let lever_axes = match priors.lever_arm {
        Some(l) if lever_held.is_none() && !unobserved.is_empty() => {
            let held = PartialLeverHold {
                directions: unobserved,
                prior: l,
            };
            let projector = held.projector();
            priors.held_lever_axes = Some(HeldLeverAxes {
                projector,
                lever_arm_cam_m: l.lever_arm_cam_m,
                sigma_m: l.sigma_m * HELD_AXIS_SIGMA_FRACTION,
            });
            jp.priors = priors;
            let p = start.lever_arm_cam_m();
            start = CalibrationParams::from_r_dvl_cam(
                start.r_dvl_cam(),
                p - projector * (p - l.lever_arm_cam_m),
                start.velocity_scale,
                start.time_offset_s,
            );
            warnings.push(format!(
                "the motion turned about too few axes to observe the lever arm along {}: that \
                 component is held at the broad default prior's value, zero, and the others are \
                 estimated; measure it and give {}, or rotate about another axis too",
                held.words(),
                opts.name(Setting::LeverArmPrior)
            ));
            Some(held)
        }
        _ => None,
    };
    if let Some((worst, l)) = lever_held {
        free.lever_arm = false;
        start = CalibrationParams::from_r_dvl_cam(
            start.r_dvl_cam(),
            l.lever_arm_cam_m,
            start.velocity_scale,
            start.time_offset_s,
        );
        warnings.push(format!(
            "the motion does not observe the lever arm ({}): it is held at the broad default \
             prior's value, zero, and the other parameters are estimated around it; measure the \
             lever arm and give {}, or record strong rotations about several axes",
            unobserved_why(worst),
            opts.name(Setting::LeverArmPrior)
        ));
    }
    let mut refined = refine_jointly(
        &jp,
        traj,
        obs,
        idx,
        start,
        free,
        opts.max_outer_iterations,
        LastRound::EndAtUpdate,
        opts.offset.range,
    )?;
    if refined.params.velocity_scale < 0.0 && free.rotation {
        refined = mirror_if_better(cos, &jp, refined, obs, idx, free, opts, warnings)?;
    }
    Ok(Refinement {
        jp,
        refined,
        setup: Setup {
            free,
            start,
            lever_held,
            lever_axes,
            pose_only,
            priors,
        },
    })
}

/// The least-squares result reweighted by the robust loss.
pub(crate) struct Reweighted {
    /// The trajectory, calibration and rounds of the last refinement.
    pub refined: Refined,
    /// The weight of each DVL observation (1 for those not used).
    pub weights: Vec<f64>,
    /// The observations with each used one's covariance divided by its weight.
    pub weighted: Vec<DvlObs>,
    /// What the loss found.
    pub robust: RobustSummary,
}

/// Iteratively reweighted: the DVL factors under the robust loss, refined again from where
/// least squares ended until the weights settle (at most [`IRLS_PASSES`] refinements), each
/// on the storage of `jp`, the least-squares problem. A warning names the outliers.
#[allow(clippy::too_many_arguments)]
pub(crate) fn reweigh(
    cos: &CoSensorFit,
    jp: &JointProblem,
    mut refined: Refined,
    free: FreeParams,
    obs: &[DvlObs],
    idx: &[usize],
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<Reweighted> {
    let mut dvl_weights = vec![1.0; obs.len()];
    let mut weighted = obs.to_vec();
    let mut dvl_robust = RobustSummary::default();
    for pass in 0..=IRLS_PASSES {
        let s = whitened_residuals(&refined.trajectory, obs, idx, &refined.params)?;
        let t: Vec<f64> = idx.iter().map(|&i| obs[i].t).collect();
        let (w, mut summary) = robust::weigh(opts.loss, &s, &t, 3, 1.0);
        for o in summary.worst.iter_mut() {
            o.index = idx[o.index];
        }
        let change = idx
            .iter()
            .zip(&w)
            .map(|(&i, &wi)| (dvl_weights[i] - wi).abs())
            .fold(0.0, f64::max);
        for (&i, &wi) in idx.iter().zip(&w) {
            dvl_weights[i] = wi;
            weighted[i].cov = obs[i].cov / wi.max(1e-12);
        }
        dvl_robust = summary;
        if change < 0.01 || pass == IRLS_PASSES {
            break;
        }
        let mut jw = JointProblem::new(
            cos.factors(&refined.trajectory)?,
            &refined.trajectory,
            &weighted,
            idx,
        )?;
        jw.priors = jp.priors;
        jw.keep_storage(jp.take_storage());
        refined = refine_jointly(
            &jw,
            refined.trajectory,
            &weighted,
            idx,
            refined.params,
            free,
            opts.max_outer_iterations,
            LastRound::EndAtUpdate,
            opts.offset.range,
        )?;
        jp.keep_storage(jw.take_storage());
    }
    if dvl_robust.outliers > 0 {
        warnings.push(format!(
            "{} of {} DVL reports disagree with the camera's motion beyond what their noise \
             explains (worst at t = {:.2} s, {:.0} times the stated variance): {} (a fish, a \
             lost beam, a bubble?)",
            dvl_robust.outliers,
            dvl_robust.factors,
            dvl_robust.worst.first().map_or(f64::NAN, |o| o.t),
            dvl_robust.worst.first().map_or(f64::NAN, |o| o.s),
            opts.outliers_handled()
        ));
    }
    Ok(Reweighted {
        refined,
        weights: dvl_weights,
        weighted,
        robust: dvl_robust,
    })
}

/// A whole refinement: least squares, then reweighted, with the storage its systems used.
pub(crate) struct Pass {
    /// What the refinement settled before its rounds.
    pub setup: Setup,
    /// The result.
    pub reweighted: Reweighted,
    /// The storage of the joint systems, for the next problem of the same knots.
    pub storage: JointStorage,
}

impl Pass {
    /// The joint problem at the trajectory `traj` (this pass's or another's), with this pass's
    /// weighted DVL reports `idx` and priors.
    pub(crate) fn joint_problem<'a>(
        &'a self,
        fit: &CoSensorFit,
        traj: &Trajectory,
        idx: &'a [usize],
    ) -> Result<JointProblem<'a>> {
        let mut jp = JointProblem::new(fit.factors(traj)?, traj, &self.reweighted.weighted, idx)?;
        jp.priors = self.setup.priors;
        Ok(jp)
    }

    /// This pass, run again from where an earlier one ended, carrying the run's start and its
    /// co-sensor-only trajectory (which the later checks read) instead of its own.
    pub(crate) fn continuing(mut self, start: CalibrationParams, pose_only: Trajectory) -> Pass {
        self.setup.start = start;
        self.setup.pose_only = pose_only;
        self
    }
}

/// [`refine`] then [`reweigh`], the clock marking each.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run(
    cos: &CoSensorFit,
    traj: Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    start: CalibrationParams,
    init: Option<&InitReport>,
    opts: &CalibOptions,
    clock: &mut StageClock,
    warnings: &mut Vec<String>,
) -> Result<Pass> {
    let Refinement { jp, refined, setup } =
        refine(cos, traj, obs, idx, start, init, opts, warnings)?;
    clock.done("refinement");
    let reweighted = reweigh(cos, &jp, refined, setup.free, obs, idx, opts, warnings)?;
    clock.done("reweighting");
    Ok(Pass {
        setup,
        reweighted,
        storage: jp.take_storage(),
    })
}

/// The DVL residuals' whiteness measured after the refinement, and whether the refinement was
/// run again with the reports weighed by it ([`refine_for_correlation`]).
#[derive(Clone, Debug)]
pub(crate) struct Correlation {
    pub whiteness: Whiteness,
    /// The reports' covariances were multiplied by the autocorrelation time for the estimate
    /// (so the covariance formed from them needs no further division).
    pub reweighed: bool,
}

/// DVL residuals correlated in time carry the information of fewer independent reports than
/// they number ([`super::whiteness`]). Weighed as independent, they also pull the trajectory
/// with that excess weight: its rates, through which the lever arm is seen, follow the DVL's
/// slowly wandering errors instead of the poses (on a motion-captured trolley track with noise
/// correlated over 1 s, a lever-arm error twice the spline estimator's along the yaw axis).
///
/// When the residuals at `pass` are correlated, the refinement runs again from where `pass`
/// ended with each report's information divided by the integrated autocorrelation time. The
/// robust weights `pass` found are kept, and the rerun is least squares: judged against the
/// divided noise, outliers would pass for inliers. Returns the pass and the whiteness measured
/// at `pass` ([`Correlation`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine_for_correlation(
    cos: &CoSensorFit,
    pass: Pass,
    obs: &[DvlObs],
    idx: &[usize],
    init: Option<&InitReport>,
    opts: &CalibOptions,
    clock: &mut StageClock,
) -> Result<(Pass, Correlation)> {
    let r = &pass.reweighted;
    let w = residual_whiteness(
        &r.refined.trajectory,
        obs,
        idx,
        &r.refined.params,
        &r.weights,
    )?;
    if !w.correlated {
        let white = Correlation {
            whiteness: w,
            reweighed: false,
        };
        return Ok((pass, white));
    }
    let scaled = noise::scaled(&r.weighted, w.inflation);
    let Pass {
        setup, reweighted, ..
    } = pass;
    let least_squares = CalibOptions {
        loss: Loss::L2,
        ..opts.clone()
    };
    let mut again = run(
        cos,
        reweighted.refined.trajectory,
        &scaled,
        idx,
        reweighted.refined.params,
        init,
        &least_squares,
        clock,
        &mut Vec::new(),
    )?;
    again.setup.start = setup.start;
    again.setup.pose_only = setup.pose_only;
    // Least squares left every weight at one: the observations weighed are `scaled`.
    again.reweighted.weights = reweighted.weights;
    again.reweighted.robust = reweighted.robust;
    let found = Correlation {
        whiteness: w,
        reweighed: true,
    };
    Ok((again, found))
}

/// The autocorrelation of the DVL residuals of the samples `idx` that kept at least half their
/// weight, each axis divided by its stated standard deviation.
pub(crate) fn residual_whiteness(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
    weights: &[f64],
) -> Result<Whiteness> {
    let mut kept: Vec<usize> = idx.iter().copied().filter(|&i| weights[i] >= 0.5).collect();
    kept.sort_by(|&a, &b| obs[a].t.total_cmp(&obs[b].t));
    let r: Vec<Vector3<f64>> = crate::parallel::map_indices(kept.len(), 2048, |j| {
        let o = &obs[kept[j]];
        let twist = traj.twist(o.t + params.time_offset_s)?;
        let r = o.v - predict(params, &twist);
        Ok(Vector3::new(
            r.x / o.cov[(0, 0)].max(1e-300).sqrt(),
            r.y / o.cov[(1, 1)].max(1e-300).sqrt(),
            r.z / o.cov[(2, 2)].max(1e-300).sqrt(),
        ))
    })
    .into_iter()
    .collect::<Result<_>>()?;
    let t: Vec<f64> = kept.iter().map(|&i| obs[i].t).collect();
    Ok(whiteness::whiteness(&t, &r))
}

/// The offset of `p` kept inside `range`, when given.
fn within(mut p: CalibrationParams, range: Option<(f64, f64)>) -> CalibrationParams {
    if let Some((lo, hi)) = range {
        p.time_offset_s = p.time_offset_s.clamp(lo, hi);
    }
    p
}

/// Passes of reweighting after the least-squares refinement (each a full refinement, warm
/// started; they stop early once no weight moves by more than 0.01).
const IRLS_PASSES: usize = 4;

/// Squared whitened DVL residuals `r^T C^-1 r` of the samples `idx` (stated covariances), in
/// the order of `idx`.
pub(crate) fn whitened_residuals(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
) -> Result<Vec<f64>> {
    crate::parallel::map_indices(idx.len(), 2048, |j| {
        let o = &obs[idx[j]];
        let twist = traj.twist(o.t + params.time_offset_s)?;
        let r = o.v - predict(params, &twist);
        let w = o.information()?;
        Ok((r.transpose() * w * r)[0])
    })
    .into_iter()
    .collect()
}

/// Why the lever arm was held: the rotation is noise (no std computed), or the data's std.
pub(crate) fn unobserved_why(data_std_m: f64) -> String {
    if data_std_m.is_finite() {
        format!("the data alone determine it only to {data_std_m:.2} m")
    } else {
        "the camera's rotation rate is mostly noise".into()
    }
}

/// A lever arm whose data-only standard deviation exceeds this fraction of the default prior's
/// is held at the prior's value.
const LEVER_HOLD_FRACTION: f64 = 0.25;

/// ... and so is one whose least excited rotation axis's mean squared rate is below this many
/// times the angular velocity's noise variance.
const LEVER_HOLD_SNR: f64 = 4.0;

/// The held directions' standard deviation as a fraction of the broad prior's: tight enough
/// to hold them (a micrometre for the 1 m default), loose enough for the normal equations.
const HELD_AXIS_SIGMA_FRACTION: f64 = 1e-6;

/// Lever-arm directions held at the broad default prior while the others are estimated.
#[derive(Clone, Debug)]
pub(crate) struct PartialLeverHold {
    /// The held directions, unit vectors in the camera frame.
    pub directions: Vec<Vector3<f64>>,
    /// The broad default prior they are held at.
    pub prior: LeverArmPrior,
}

impl PartialLeverHold {
    /// The projector onto the held directions.
    pub fn projector(&self) -> Matrix3<f64> {
        self.directions.iter().map(|u| u * u.transpose()).sum()
    }

    /// The held directions in words, as the warnings and verdicts say them.
    pub fn words(&self) -> String {
        let v: Vec<String> = self.directions.iter().map(axis_words).collect();
        v.join(" and ")
    }
}

/// A direction of the camera frame in words: its nearest axis when within 10 degrees
/// (`the camera's z axis`), else its components.
pub(crate) fn axis_words(u: &Vector3<f64>) -> String {
    let k = u.iamax();
    if u[k].abs() > 10f64.to_radians().cos() {
        format!("the camera's {} axis", ["x", "y", "z"][k])
    } else {
        format!("the camera direction ({:.2}, {:.2}, {:.2})", u.x, u.y, u.z)
    }
}

/// What the refinement ends with.
pub(crate) struct Refined {
    pub trajectory: Trajectory,
    pub params: CalibrationParams,
    pub iterations: Vec<IterationRecord>,
}

/// Stage 4: rounds of a calibration update with the trajectory fixed and a state update with the
/// calibration fixed, until nothing changes (at most `rounds`); a Gauss-Newton step on the joint
/// problem after each unsettled round. The clock offset is kept inside `range` (when given)
/// after every step.
#[allow(clippy::too_many_arguments)]
fn refine_jointly(
    jp: &JointProblem,
    mut traj: Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    start: CalibrationParams,
    free: FreeParams,
    rounds: usize,
    last: LastRound,
    range: Option<(f64, f64)>,
) -> Result<Refined> {
    let mask = free.mask();
    let mut params = start;
    let mut iterations = Vec::new();
    let mut last_cost = f64::INFINITY;
    let mut after_joint_step = false;
    let rounds = rounds.max(1);
    for round in 1..=rounds {
        // Calibration update with the trajectory fixed, then state update with it fixed.
        let up = calibration_update(&traj, obs, idx, &params, free, &jp.priors, 50)?;
        let updated = within(up.params, range);
        let change = update::change_in_std(&params, &updated, &up.hessian, &mask);
        params = updated;
        // Right after a joint step, a calibration update that moves no parameter by a
        // twentieth of its standard deviation confirms the fixed point the step reached: the
        // state update that would follow moves the trajectory by as little, and the rounds
        // would stop after it. The trajectory is then the joint step's.
        if last == LastRound::EndAtUpdate
            && after_joint_step
            && change < 0.05
            && params.velocity_scale > 0.0
        {
            let cost = joint_cost(jp, &traj, &params)?;
            iterations.push(IterationRecord { cost, params });
            break;
        }
        // Warm-started from the previous state, one Gauss-Newton step per round: the rounds
        // themselves iterate it.
        let (refit, cost) = state_update(jp, &traj, &params, 1)?;
        traj = refit;
        iterations.push(IterationRecord { cost, params });
        let rel = (last_cost - cost).abs() / cost.max(1e-300);
        last_cost = cost;
        // Settled: no parameter moved by more than a twentieth of its standard deviation, or
        // the joint cost changed by less than a part in 1e7.
        if iterations.len() >= 2 && (change < 0.05 || rel < 1e-7) {
            break;
        }
        // The alternation converges linearly (each round removes about half of the remaining
        // error when the clock offset and the trajectory are coupled). A Gauss-Newton step on
        // the joint problem takes both close to the fixed point the rounds are heading for; the
        // next round then starts there and confirms it.
        after_joint_step = false;
        if round < rounds
            && let Some(js) = joint_step(jp, &traj, &params, &mask)?
        {
            traj = js.trajectory;
            params = within(js.params, range);
            after_joint_step = true;
        }
    }
    Ok(Refined {
        trajectory: traj,
        params,
        iterations,
    })
}

/// How the refinement's last round ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LastRound {
    /// With the calibration update when it confirms a joint step (see [`refine_jointly`]).
    EndAtUpdate,
    /// Always with a state update: the trajectory refitted to the final calibration. The
    /// mirror check compares the DVL costs of two refinements on their refitted trajectories.
    Refit,
}

/// A negative scale is the rotation 180 deg off in disguise: when the motion stays near a plane,
/// `kappa R u` and `(-kappa) (R F) u` agree for every `u` in it, where `F` rotates half a turn
/// about the plane's normal `n` (`F = 2 n n^T - I`). The mirrored solution is refined from a
/// fresh trajectory and kept when its DVL cost is lower.
#[allow(clippy::too_many_arguments)]
fn mirror_if_better(
    cos: &CoSensorFit,
    jp: &JointProblem,
    refined: Refined,
    obs: &[DvlObs],
    idx: &[usize],
    free: FreeParams,
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<Refined> {
    let p = refined.params;
    let mut m = Matrix3::zeros();
    for &i in idx {
        let twist = refined.trajectory.twist(obs[i].t + p.time_offset_s)?;
        let v = twist.fixed_rows::<3>(0).into_owned();
        let w = twist.fixed_rows::<3>(3).into_owned();
        let u = v + w.cross(&p.lever_arm_cam_m());
        m += u * u.transpose();
    }
    let eig = m.symmetric_eigen();
    let k = eig.eigenvalues.imin();
    let n = eig.eigenvectors.column(k).into_owned();
    let flip = n * n.transpose() * 2.0 - Matrix3::identity();
    let mirrored = CalibrationParams::from_r_dvl_cam(
        p.r_dvl_cam() * flip,
        p.lever_arm_cam_m(),
        -p.velocity_scale,
        p.time_offset_s,
    );
    let mut fresh = cos.fit_afresh(&opts.fit)?;
    if let Some(storage) = fresh.take_covariance_storage() {
        jp.keep_system(storage);
    }
    let other = refine_jointly(
        jp,
        fresh,
        obs,
        idx,
        mirrored,
        free,
        opts.max_outer_iterations,
        LastRound::Refit,
        opts.offset.range,
    )?;
    let cost = |r: &Refined| -> Result<f64> {
        Ok(update::linearize(&r.trajectory, obs, idx, &r.params)?.cost)
    };
    let (c0, c1) = (cost(&refined)?, cost(&other)?);
    if other.params.velocity_scale > 0.0 && c1 <= c0 {
        warnings.push(format!(
            "the refinement first reached a negative velocity scale ({:.4}): the rotation half a \
             turn off; the mirrored solution (scale {:.4}) fits the DVL better and is the result",
            p.velocity_scale, other.params.velocity_scale
        ));
        Ok(other)
    } else {
        Ok(refined)
    }
}
