//! Spatiotemporal DVL-camera calibration: the UIC method, in stages.
//!
//! 1. The co-sensor's trajectory: GP regression on its measurements (camera poses), outlying
//!    ones down-weighted ([`cosensor`]).
//! 2. Clock offset and scale from speed magnitudes ([`offset`], after the global alignment of
//!    [`align`]).
//! 3. Rotation, lever arm and scale in closed form with bias elimination ([`mod@closed_form`]);
//!    2 and 3 are [`initialise`] ([`init`]).
//! 4. Block-coordinate refinement ([`refinement`]): calibration update with the trajectory fixed
//!    ([`update`]), state update with the calibration fixed (the trajectory's solver with the
//!    DVL factors added, [`joint`]), until nothing changes, sped up by joint Gauss-Newton steps;
//!    then the DVL reports reweighted by the robust loss ([`robust`]).
//! 5. What the result is worth ([`diagnostics`]): the covariance from the joint problem's
//!    information, inflated for correlated residuals ([`whiteness`]) and for halves of the
//!    recording that disagree ([`halves`]); what the priors ([`prior`]) determined; a verdict per
//!    parameter, the sanity checks and the clock's drift ([`outcome`] holds what a run gives).
//!
//! A DVL clock that stepped is calibrated segment by segment, the extrinsics shared
//! ([`segments`]); one that drifts, with its drift estimated ([`clock_drift`]).
//!
//! [`calibrate`] runs the stages in this order, with the settings of [`options`] (whose messages
//! name the settings as [`setting`] words them) on the samples of [`samples`].

pub mod advice;
pub mod align;
pub mod analysis;
pub mod clock_drift;
pub mod closed_form;
pub(crate) mod correlate;
pub mod cosensor;
pub mod diagnostics;
pub mod fusion;
pub mod given;
pub mod halves;
pub mod imu;
pub mod init;
pub(crate) mod joint;
pub mod model;
pub mod motion_prior;
pub mod noise;
pub mod offset;
pub mod options;
pub mod outcome;
pub mod prior;
pub mod refinement;
pub mod robust;
pub mod samples;
pub mod segments;
pub mod setting;
pub mod spacing;
pub(crate) mod update;
pub mod whiteness;

/// Covariance or information of the parameters, in [`ParamVec`]'s order.
pub use update::ParamMat;
/// The estimator's parameter vector: `[dphi; dp; dkappa; ddelta]` (rad about the DVL axes, m,
/// scale, s), the coordinates of [`model::difference`] and of the covariance.
pub use update::ParamVec;

pub use analysis::{cramer_rao, jerk_density_evidence};
pub use cosensor::CoSensor;
pub use init::initialise;
pub use model::PARAM_NAMES;
pub use options::{CalibOptions, Method, SanityLimits, WARM_WINDOW_S, WeakThresholds};
pub use outcome::{
    CalibrationOutcome, ClockDrift, Counts, DeterminedBy, DriftCheck, Excitation, HalvesCheck,
    InitReport, IterationRecord, ParamStd, Robustness, Status, Verdict, Verdicts, WarmStartUse,
    WeakCause,
};
pub use samples::{pose_gap_threshold_s, pose_gaps, usable_covariance};
pub use setting::{Setting, SettingNames};

use crate::error::Result;
use crate::types::{DvlSample, PoseMeasurement};
use joint::covariance::assemble_joint;
use joint::drift::{DriftAt, drift_solution};
use joint::problem::JointProblem;
use outcome::StageClock;

/// Calibrates the DVL against camera poses: [`calibrate_against`] with the poses as the
/// co-sensor.
pub fn calibrate(
    poses: &[PoseMeasurement],
    dvl: &[DvlSample],
    opts: &CalibOptions,
) -> Result<CalibrationOutcome> {
    calibrate_against(CoSensor::Poses(poses), dvl, opts)
}

/// Calibrates the DVL against the co-sensor's measurements, in the stages of the module
/// documentation; with [`CalibOptions::clock_drift`], the drift too ([`clock_drift`]).
pub fn calibrate_against(
    cosensor: CoSensor,
    dvl: &[DvlSample],
    opts: &CalibOptions,
) -> Result<CalibrationOutcome> {
    if opts.clock_drift {
        clock_drift::calibrate_with_drift(dvl, |d, at| calibrate_stages(cosensor, d, opts, at))
    } else {
        calibrate_stages(cosensor, dvl, opts, None)
    }
}

/// The stages of the module documentation, the DVL times mapped by the drift `drift_at`
/// beforehand (whose correction the run then finds). Each stage's warnings are written as its
/// checks are made, in this order.
fn calibrate_stages(
    cosensor: CoSensor,
    dvl: &[DvlSample],
    opts: &CalibOptions,
    drift_at: Option<DriftAt>,
) -> Result<CalibrationOutcome> {
    opts.validate()?;
    let mut clock = StageClock::start();
    let mut warnings = Vec::new();
    // The values the user gave (a guess, held extrinsics, priors), checked for their units.
    given::check_given(opts, &mut warnings)?;
    // The valid DVL reports (at least ten) with their noise.
    let observed = samples::observe(dvl, opts)?;
    // 1. The co-sensor's trajectory, outlying measurements down-weighted.
    let (traj, fit) = cosensor.fit(opts, &mut warnings)?;
    warnings.extend(observed.warning(opts));
    clock.done("trajectory fit");
    let obs = observed.obs;
    let mut counts = Counts {
        poses: cosensor.len(),
        dvl_samples: dvl.len(),
        dvl_invalid: dvl.len() - obs.len(),
        dvl_covariance_replaced: observed.replaced,
        poses_downweighted: fit.robust.outliers,
        ..Counts::default()
    };

    // 2-3. Where the refinement starts: the data alone (UIC), or the user's guess.
    let (start, init, spikes_screened) = initialise(&traj, &obs, opts, &mut warnings)?;
    clock.done("initialisation");
    counts.dvl_spikes_screened = spikes_screened;
    counts.calm = init.as_ref().map_or(0, |i| i.offset.calm.len());
    // The samples the refinement may use at every offset it reaches.
    let idx = samples::usable_samples(
        &traj,
        &obs,
        start.time_offset_s,
        opts,
        &mut counts,
        &mut warnings,
    )?;

    // 4. The refinement by least squares (a lever arm the motion cannot see held at its
    //    prior), then with the DVL reports reweighted by the robust loss.
    let mut pass = refinement::run(
        &fit,
        traj,
        &obs,
        &idx,
        start,
        init.as_ref(),
        opts,
        &mut clock,
        &mut warnings,
    )?;
    // Each sensor's noise as the joint estimate shows it (variance components); far from the
    // stated noise, the groups are reweighed and the refinement runs again from where it ended.
    let mut fit = fit;
    let mut noise = noise_components(&fit, &pass, &idx, (1.0, 1.0), 0)?;
    clock.done("noise");
    let mut obs_scaled = None;
    // With the extrinsics held, a misfit is the given values' error, not the sensors' noise:
    // the components are reported but not applied (the contradiction check names the cause).
    // So is a misfit the robust loss finds in a large share of the reports (a DVL that does not
    // describe the camera's motion): rescaled, it would hide among them.
    let first_robust = &pass.reweighted.robust;
    let outlier_share = first_robust.outliers as f64 / first_robust.factors.max(1) as f64;
    let trusted = pass.setup.free.rotation && outlier_share <= opts.sanity.max_outlier_fraction;
    let engaged = if trusted { noise.far() } else { (false, false) };
    if engaged.0 || engaged.1 {
        let first_start = pass.setup.start;
        let (mut dvl_applied, mut cos_applied) = (1.0, 1.0);
        for round in 1..=noise::ROUNDS {
            if engaged.0 {
                dvl_applied *= noise.dvl.scale;
            }
            if engaged.1 {
                cos_applied *= noise.cosensor.scale;
            }
            fit.variance_scale = cos_applied;
            let scaled = noise::scaled(&obs, dvl_applied);
            let refined = pass.reweighted.refined;
            let again = refinement::run(
                &fit,
                refined.trajectory,
                &scaled,
                &idx,
                refined.params,
                init.as_ref(),
                opts,
                &mut clock,
                &mut Vec::new(),
            )?;
            pass = again.continuing(first_start, pass.setup.pose_only);
            noise = noise_components(&fit, &pass, &idx, (dvl_applied, cos_applied), round)?;
            obs_scaled = Some(scaled);
            if noise.settled(engaged) {
                break;
            }
        }
        warnings.extend(noise.warnings());
    }
    let obs = obs_scaled.unwrap_or(obs);
    // The motion prior's density along the recording, when the fit chose it (for the same
    // reasons as above, not to absorb a misfit of held extrinsics).
    let traj_report = pass.reweighted.refined.trajectory.report();
    let motion_prior = if opts.varying_motion_prior && trusted && traj_report.qc_estimated {
        let mut rerun = |traj, params| {
            let (init, mut quiet) = (init.as_ref(), Vec::new());
            refinement::run(
                &fit, traj, &obs, &idx, params, init, opts, &mut clock, &mut quiet,
            )
        };
        let (kept, check) = motion_prior::choose(&fit, pass, &idx, &mut rerun)?;
        pass = kept;
        clock.done("motion prior");
        Some(check)
    } else {
        None
    };
    // DVL residuals correlated in time: refined again with the reports weighed by the
    // information they carry (for the same reasons as above, only where the misfit is noise).
    let correlation = if trusted && opts.honest_covariance {
        let (again, measured) = refinement::refine_for_correlation(
            &fit,
            pass,
            &obs,
            &idx,
            init.as_ref(),
            opts,
            &mut clock,
        )?;
        pass = again;
        Some(measured)
    } else {
        None
    };
    let refinement::Pass {
        setup:
            refinement::Setup {
                free,
                start,
                lever_held,
                lever_axes,
                pose_only,
                priors,
            },
        reweighted,
        storage,
    } = pass;
    counts.dvl_downweighted = reweighted.robust.outliers;
    let refinement::Reweighted {
        refined,
        weights: dvl_weights,
        mut weighted,
        robust: dvl_robust,
    } = reweighted;
    let (traj, params) = (refined.trajectory, refined.params);

    // 5. What the result is worth: the residuals against the stated noise, ...
    let (normalized_cost, whiteness) = diagnostics::noise(
        &traj,
        &obs,
        &idx,
        &params,
        &dvl_robust,
        &dvl_weights,
        &mut weighted,
        correlation,
        opts,
        &mut warnings,
    )?;
    let cosensor = fit.factors(&traj)?;
    // ... the joint system at the result, which serves the covariance and both halves, ...
    let mut jp = JointProblem::new(cosensor, &traj, &weighted, &idx)?;
    jp.priors = priors;
    jp.keep_storage(storage);
    let assembled = assemble_joint(&jp, traj.knots(), &params)?;
    // ... the drift's correction and its covariance, when it is estimated, ...
    let drift_solution = match drift_at {
        Some(at) => Some(drift_solution(
            &jp,
            &assembled,
            traj.knots(),
            &free.mask(),
            at,
        )?),
        None => None,
    };
    clock.done("joint system");
    let halves = halves::estimate(
        &jp,
        &assembled,
        &traj,
        &weighted,
        &idx,
        free,
        normalized_cost,
        opts,
    )?;
    clock.done("halves check");
    // ... the covariance (the drift check compares the thirds of the recording at the model's
    // offset variance: the halves would inflate it for the very drift it looks for), ...
    let added = drift_solution.as_ref().map(|s| s.added_covariance());
    let mut covariance = diagnostics::uncertainty(
        &jp,
        assembled,
        free,
        normalized_cost,
        opts,
        added,
        &mut warnings,
    )?;
    let clock_drift = drift_at
        .zip(drift_solution)
        .map(|(at, s)| clock_drift::estimate(at, &s, diagnostics::cost_inflation(normalized_cost)));
    let model_offset_std = covariance[(7, 7)].max(0.0).sqrt();
    let halves = halves.map(|h| halves::compare_halves(h, free, &mut covariance));
    clock.done("covariance");
    if let Some(h) = &halves {
        warnings.extend(halves::halves_notes(h));
    }
    if let Some((_, l)) = lever_held {
        // Held, the lever arm is known as well as its prior says.
        for k in 3..6 {
            covariance[(k, k)] = l.sigma_m * l.sigma_m;
        }
    }
    if let Some(a) = &lever_axes {
        // Along its held directions too, as the broad prior says (the tight hold is no
        // knowledge).
        let mut block = covariance.fixed_view_mut::<3, 3>(3, 3);
        block += a.projector() * (a.prior.sigma_m * a.prior.sigma_m);
    }
    let std = diagnostics::param_std(&covariance);
    // ... what the priors rather than the data determined, ...
    let roles = diagnostics::prior_roles(
        &mut jp,
        &traj,
        &params,
        free,
        &std,
        &priors,
        lever_held.is_some(),
        opts,
        &mut warnings,
    )?;
    // ... the motion's excitation and a verdict per parameter, ...
    let (residual_rms, excitation) =
        diagnostics::residuals_and_excitation(&traj, &obs, &idx, &params)?;
    let mut verdicts = diagnostics::judge(
        &std,
        &excitation,
        init.as_ref(),
        free,
        lever_held,
        lever_axes.as_ref(),
        roles,
        opts,
    );
    if let Some(h) = &halves {
        halves::flag_inconsistent(&mut verdicts, h);
    }
    // ... the held extrinsics against the data, the sanity checks, and the clock's drift.
    let contradicted = match opts.method {
        Method::Fixed { .. } => given::contradicted(&traj, &weighted, &idx, &params, free)?,
        _ => Vec::new(),
    };
    let status = diagnostics::status(
        &params,
        normalized_cost,
        noise.dvl.applied,
        init.as_ref(),
        free,
        &dvl_robust,
        &contradicted,
        opts,
    )
    // Poses too sparse for the motion fail the result by themselves: the trajectory's rates and
    // velocities are wrong, and the std with them (on the blurred sample recording, the clock
    // offset 3.3 std off with every check passed otherwise).
    .failed_first_by(fit.sparse.as_ref().map(spacing::SparsePoses::reason));
    let drift = diagnostics::drift(
        free.time_offset.then_some(&pose_only),
        &obs,
        &idx,
        &params,
        model_offset_std,
        opts,
        &mut warnings,
    )?;
    let trajectory = traj.report().clone();
    clock.done("checks and verdicts");
    // The problems borrow the observations that the outcome keeps.
    drop(jp);
    Ok(CalibrationOutcome {
        params,
        covariance,
        std,
        verdicts,
        method: opts.method.clone(),
        init,
        iterations: refined.iterations,
        counts,
        residual_rms,
        normalized_cost,
        excitation,
        trajectory,
        warnings,
        status,
        drift,
        clock_drift,
        start,
        fitted: traj,
        observations: obs,
        used: idx,
        robust: Robustness {
            loss: opts.loss,
            dvl: dvl_robust,
            poses: fit.robust,
            dvl_weights,
            pose_weights: fit.weights,
        },
        whiteness,
        halves,
        priors,
        lever_arm_from_default_prior: roles.lever_arm_from_default_prior,
        contradicted,
        noise,
        motion_prior,
        stage_seconds: clock.stages,
    })
}

/// The variance components at the end of a refinement `pass` (see [`noise`]), the co-sensor's
/// and the DVL's variances already multiplied by `applied`.
fn noise_components(
    fit: &cosensor::CoSensorFit,
    pass: &refinement::Pass,
    idx: &[usize],
    applied: (f64, f64),
    rounds: usize,
) -> Result<noise::NoiseCheck> {
    let r = &pass.reweighted.refined;
    let jp = pass.joint_problem(fit, &r.trajectory, idx)?;
    let free = pass.setup.free.mask().iter().filter(|&&f| f).count();
    noise::components(&jp, &r.trajectory, &r.params, free, applied, rounds)
}
