//! Stage 5: what the result is worth. The residuals against the stated noise and their
//! whiteness ([`noise`]), the covariance ([`uncertainty`]), what the priors rather than the data
//! determined ([`prior_roles`]), the motion's excitation, a verdict per parameter ([`judge`]),
//! the sanity checks ([`status`]) and the clock's drift ([`drift`]). Each check's warning is
//! written where the check is made. The IMU's verdicts ([`imu_verdicts`]) are made by the same
//! rule and words as the DVL's ([`verdict_by_std`]), from the motion its trajectory saw.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use super::given::Contradiction;
use super::imu::ImuEstimate;
use super::joint::covariance::{AssembledJoint, joint_covariance, joint_covariance_of};
use super::joint::problem::JointProblem;
use super::model::{DvlObs, NPARAM, predict};
use super::offset::OffsetMethod;
use super::options::{CalibOptions, WeakThresholds};
use super::outcome::{
    DeterminedBy, DriftCheck, Excitation, InitReport, ParamStd, Status, Verdict, Verdicts,
    WeakCause,
};
use super::prior::{LeverArmPrior, Priors};
use super::refinement::{
    Correlation, PartialLeverHold, residual_whiteness, unobserved_why, whitened_residuals,
};
use super::robust::RobustSummary;
use super::setting::Setting;
use super::update::{FreeParams, ParamMat, calibration_update};
use super::whiteness::Whiteness;
use crate::error::Result;
use crate::trajectory::Trajectory;
use crate::types::CalibrationParams;

/// The DVL cost per degree of freedom over the inliers (at the stated noise `obs`), and the
/// residuals' whiteness (`measured` when the refinement measured it already at `params`:
/// [`super::refinement::refine_for_correlation`]). When the residuals are correlated in time (and
/// `opts` asks for honest standard deviations), the information of each used observation in
/// `weighted` is divided by the integrated autocorrelation time, with a warning, unless the
/// refinement already weighed them so.
#[allow(clippy::too_many_arguments)]
pub(crate) fn noise(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
    robust: &RobustSummary,
    weights: &[f64],
    weighted: &mut [DvlObs],
    measured: Option<Correlation>,
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<(f64, Whiteness)> {
    let normalized_cost = inlier_normalized_cost(traj, obs, idx, params, robust)?;
    let (whiteness, reweighed) = match measured {
        Some(c) => (c.whiteness, c.reweighed),
        None => (residual_whiteness(traj, obs, idx, params, weights)?, false),
    };
    if opts.honest_covariance && whiteness.correlated {
        // Correlated residuals carry the information of fewer independent ones: the DVL
        // factors' information divided by the integrated autocorrelation time.
        if !reweighed {
            for i in idx.iter().copied() {
                weighted[i].cov *= whiteness.inflation;
            }
        }
        warnings.push(format!(
            "the DVL residuals are correlated in time (integrated autocorrelation time {:.1} \
             samples, {:.2} s; white noise would give 1 +- {:.2}): they carry the information of \
             {:.0} independent reports, not {}, and {} account for that",
            whiteness.inflation,
            whiteness.inflation * whiteness.sample_interval_s,
            whiteness.tau_noise,
            idx.len() as f64 / whiteness.inflation,
            idx.len(),
            if reweighed {
                "the estimate (refined again with them weighted so) and its standard deviations"
            } else {
                "the standard deviations"
            }
        ));
    }
    Ok((normalized_cost, whiteness))
}

/// Which parameters a prior rather than the data determined.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PriorRoles {
    /// The rotation comes mainly from the user's rotation prior.
    pub rotation_from_user_prior: bool,
    /// The lever arm comes mainly from the user's lever-arm prior.
    pub lever_arm_from_user_prior: bool,
    /// The lever arm comes from the broad default prior (held at it, or not observed).
    pub lever_arm_from_default_prior: bool,
}

/// What the data alone would say, to tell which parameters the priors determined, with the
/// notes on the user's priors (and on a lever arm left to the default prior) as warnings.
/// `lever_held`: the lever arm was held at the default prior before the refinement.
#[allow(clippy::too_many_arguments)]
pub(crate) fn prior_roles(
    jp: &mut JointProblem,
    traj: &Trajectory,
    params: &CalibrationParams,
    free: FreeParams,
    std: &ParamStd,
    priors: &Priors,
    lever_held: bool,
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<PriorRoles> {
    let mut roles = PriorRoles {
        lever_arm_from_default_prior: lever_held,
        ..PriorRoles::default()
    };
    if !(opts.priors.any() || (priors.any() && free.lever_arm && std.lever_arm_m.max() > 0.05)) {
        return Ok(roles);
    }
    let taken = std::mem::take(&mut jp.priors);
    let (data_only, _) = joint_covariance(jp, traj, params, &free.mask())?;
    jp.priors = taken;
    if opts.priors.any() {
        warnings.extend(prior_notes(&opts.priors, &data_only, params));
        let data_worst = |first: usize| {
            (first..first + 3)
                .map(|k| data_only[(k, k)].max(0.0).sqrt())
                .fold(0.0, f64::max)
        };
        // The prior determined a parameter when the data alone know it less well than the
        // prior does (the posterior standard deviation is then above 0.7 times the prior's):
        // the same test as the notes of prior_notes.
        if let Some(r) = &opts.priors.rotation {
            let d = data_worst(0);
            roles.rotation_from_user_prior =
                free.rotation && (d.is_nan() || d > r.sigma_deg.to_radians());
        }
        if let Some(l) = &opts.priors.lever_arm {
            let d = data_worst(3);
            roles.lever_arm_from_user_prior = free.lever_arm && (d.is_nan() || d > l.sigma_m);
        }
    }
    if let (None, Some(l), None) = (
        opts.priors.lever_arm,
        priors.lever_arm,
        priors.held_lever_axes,
    ) {
        let data = (3..6)
            .map(|k| data_only[(k, k)].max(0.0).sqrt())
            .fold(0.0, f64::max);
        if data.is_nan() || data >= 0.5 * l.sigma_m {
            roles.lever_arm_from_default_prior = true;
            warnings.push(format!(
                "the motion did not observe the lever arm (the data alone determine it only \
                 to {:.2} m): it comes from the broad default prior (zero, {:.1} m), which \
                 keeps it from corrupting the other parameters; measure it and give {}",
                data,
                l.sigma_m,
                opts.name(Setting::LeverArmPrior)
            ));
        }
    }
    Ok(roles)
}

/// A verdict per parameter: its standard deviation against the thresholds of `opts`, then what
/// held or determined it (`lever_held`: held at the default prior, with the data's standard
/// deviation of it; `roles`: what the priors determined).
#[allow(clippy::too_many_arguments)]
pub(crate) fn judge(
    std: &ParamStd,
    excitation: &Excitation,
    init: Option<&InitReport>,
    free: FreeParams,
    lever_held: Option<(f64, LeverArmPrior)>,
    lever_axes: Option<&PartialLeverHold>,
    roles: PriorRoles,
    opts: &CalibOptions,
) -> Verdicts {
    let mut verdicts = verdicts(std, opts, excitation, init, &free.mask());
    let lever_prior = opts.name(Setting::LeverArmPrior);
    if let Some(a) = lever_axes {
        verdicts.lever_arm = Verdict {
            ok: false,
            reason: format!(
                "the motion turned about too few axes to observe the lever arm along {}: that \
                 component is held at the broad default prior's value, zero (its std is the \
                 prior's), the others are measured; measure it and give {lever_prior}, or rotate \
                 about another axis too",
                a.words()
            ),
            by: DeterminedBy::Data,
            cause: Some(WeakCause::FewRotationAxes),
        };
    } else if let Some((worst, _)) = lever_held {
        verdicts.lever_arm = Verdict {
            ok: false,
            reason: format!(
                "not observed by the motion ({}): held at the broad default prior's value, zero; \
                 measure the lever arm and give {lever_prior}",
                unobserved_why(worst)
            ),
            by: DeterminedBy::Prior,
            cause: Some(if worst.is_finite() {
                WeakCause::LittleRotation
            } else {
                WeakCause::RotationRateNoise
            }),
        };
    } else if roles.lever_arm_from_default_prior {
        verdicts.lever_arm = Verdict {
            ok: false,
            reason: format!(
                "not observed by the motion: the value is the broad default prior's (zero); \
                 measure the lever arm and give {lever_prior}"
            ),
            by: DeterminedBy::Prior,
            cause: Some(WeakCause::LittleRotation),
        };
    }
    if roles.rotation_from_user_prior {
        verdicts.rotation.by = DeterminedBy::Prior;
        verdicts.rotation.cause = Some(WeakCause::UserPrior);
        push_reason(
            &mut verdicts.rotation,
            &format!(
                "the value comes mainly from {}: the data alone determine it less well",
                opts.name(Setting::RotationPrior)
            ),
        );
    }
    if roles.lever_arm_from_user_prior {
        verdicts.lever_arm.by = DeterminedBy::Prior;
        verdicts.lever_arm.cause = Some(WeakCause::UserPrior);
        push_reason(
            &mut verdicts.lever_arm,
            &format!(
                "the value comes mainly from {lever_prior}: the data alone determine it less well"
            ),
        );
    }
    verdicts
}

/// Whether the result can be trusted: no held parameter the data contradict, the sanity checks
/// of [`sanity`], and a share of outliers among the DVL reports that a few bad reports can
/// explain.
#[allow(clippy::too_many_arguments)]
pub(crate) fn status(
    p: &CalibrationParams,
    normalized_cost: f64,
    dvl_noise_applied: f64,
    init: Option<&InitReport>,
    free: FreeParams,
    robust: &RobustSummary,
    contradicted: &[Contradiction],
    opts: &CalibOptions,
) -> Status {
    let mut status = sanity(p, normalized_cost, dvl_noise_applied, init, free, opts);
    if !contradicted.is_empty() {
        // The parameter the data contradict is the cause the other reasons only guess at.
        let mut reasons: Vec<String> = contradicted.iter().map(Contradiction::reason).collect();
        if let Status::Failed(r) = status {
            reasons.extend(r);
        }
        status = Status::Failed(reasons);
    }
    let share = robust.outliers as f64 / robust.factors.max(1) as f64;
    if share > opts.sanity.max_outlier_fraction {
        let reason = format!(
            "{} of {} DVL reports are outliers to the fit ({:.0} %; at most {:.0} % are \
             credible as outliers): the camera and the DVL disagree throughout, not in a few \
             reports. Likely causes: a drifting clock, camera poses of another body or in the \
             wrong frame, or a DVL log of another recording",
            robust.outliers,
            robust.factors,
            100.0 * share,
            100.0 * opts.sanity.max_outlier_fraction
        );
        status = match status {
            Status::Ok => Status::Failed(vec![reason]),
            Status::Failed(mut r) => {
                r.push(reason);
                Status::Failed(r)
            }
        };
    }
    status
}

/// The drift check at the stated weights, against the trajectory fitted to the co-sensor alone
/// (`None`: the offset was not estimated): a drifting clock makes the ends of the recording
/// look like outliers to a constant offset, and down-weighting them would hide the drift. A
/// significant drift is a warning.
pub(crate) fn drift(
    pose_only: Option<&Trajectory>,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
    offset_std: f64,
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<Option<DriftCheck>> {
    let drift = match pose_only {
        Some(t) => drift_check(t, obs, idx, params, offset_std)?,
        None => None,
    };
    if let Some(d) = &drift
        && d.significant
    {
        // With the drift estimated, the DVL times were mapped by it: what is left is a drift
        // that is not constant.
        let assumed = if opts.clock_drift {
            " beyond the drift estimated; the result assumes a constant drift (a clock that \
             steps or wanders: synchronise the clocks, or calibrate shorter recordings)"
                .to_owned()
        } else {
            format!(
                "; the result assumes a constant offset (estimate the drift with {}, synchronise \
                 the clocks, or calibrate shorter recordings)",
                opts.name(Setting::ClockDrift)
            )
        };
        warnings.push(format!(
            "the clock offset drifts: {:.4} s in the first third of the recording and {:.4} s in \
             the last ({:+.1} ms, {:.1} standard deviations), about {:+.0} ppm{assumed}",
            d.first_third_s,
            d.last_third_s,
            1e3 * (d.last_third_s - d.first_third_s),
            (d.last_third_s - d.first_third_s).abs() / d.difference_std_s,
            d.drift_ppm
        ));
    }
    Ok(drift)
}

use super::noise::COST_INFLATION_FROM;

/// The factor [`uncertainty`] inflates the covariance by at a normalized cost.
pub(crate) fn cost_inflation(normalized_cost: f64) -> f64 {
    if normalized_cost > COST_INFLATION_FROM {
        normalized_cost
    } else {
        1.0
    }
}

/// Stage 5: the covariance of the free parameters from the joint problem's information (with
/// `added`, what marginalising a further parameter adds). When the DVL residuals exceed the
/// stated noise by half or more (`normalized_cost`), the covariance is inflated by that factor
/// and a warning says so (with a held guess, that the guess is the likely cause).
pub(crate) fn uncertainty(
    jp: &JointProblem,
    assembled: AssembledJoint,
    free: FreeParams,
    normalized_cost: f64,
    opts: &CalibOptions,
    added: Option<ParamMat>,
    warnings: &mut Vec<String>,
) -> Result<ParamMat> {
    let (mut covariance, _) = joint_covariance_of(jp, assembled, &free.mask())?;
    if let Some(a) = added {
        covariance += a;
    }
    if normalized_cost > COST_INFLATION_FROM {
        warnings.push(if free.rotation {
            format!(
                "DVL residuals are {:.1} times the stated DVL variance; the standard deviations \
                 are inflated by that factor (set {} to the real noise)",
                normalized_cost,
                opts.name(Setting::DvlSigma)
            )
        } else {
            format!(
                "DVL residuals are {:.1} times the stated DVL variance with the extrinsics held \
                 at the given values: {}",
                normalized_cost,
                fixed_guess_advice(free, opts)
            )
        });
        covariance *= normalized_cost;
    }
    Ok(covariance)
}

/// The sanity checks of a result: residuals near the stated DVL noise, a physical velocity
/// scale, and a clock offset inside the offsets searched. Each failure names its likely cause.
fn sanity(
    p: &CalibrationParams,
    normalized_cost: f64,
    dvl_noise_applied: f64,
    init: Option<&InitReport>,
    free: FreeParams,
    opts: &CalibOptions,
) -> Status {
    let lim = &opts.sanity;
    let mut reasons = Vec::new();
    let poor_match = init.is_some_and(|i| i.offset.alignment.is_poor());
    // The cost against the noise the reports state, before any variance component was applied.
    let stated_cost = normalized_cost * dvl_noise_applied;
    if normalized_cost.is_nan()
        || normalized_cost > lim.max_normalized_cost
        || stated_cost > lim.max_noise_ratio * lim.max_noise_ratio
    {
        reasons.push(format!(
            "the DVL residuals are {stated_cost:.1} times the stated DVL noise (variance) after \
             the refinement (at most {} is credible{}): the camera and the DVL do not describe \
             the same motion. Likely causes: {}",
            if dvl_noise_applied == 1.0 {
                lim.max_normalized_cost
            } else {
                lim.max_noise_ratio * lim.max_noise_ratio
            },
            if dvl_noise_applied == 1.0 {
                ""
            } else {
                ", the DVL's noise misstated by a factor of 20 at most"
            },
            if poor_match {
                "a DVL log of another recording, or clocks that do not overlap (the speeds \
                 correlate poorly at every clock offset)"
                    .to_owned()
            } else if !free.rotation {
                fixed_guess_advice(free, opts)
            } else {
                format!(
                    "camera poses in the wrong frame (T_cam_world given for T_world_cam, or poses \
                     of another body), or a DVL covariance far below the real noise (set {})",
                    opts.name(Setting::DvlSigma)
                )
            }
        ));
    }
    let (lo, hi) = lim.scale_range;
    if free.scale && !(p.velocity_scale >= lo && p.velocity_scale <= hi) {
        reasons.push(if p.velocity_scale < 0.0 {
            format!(
                "the velocity scale is negative ({:.4}): the rotation came out half a turn off and \
                 the mirrored solution does not fit; the motion did not excite the rotation",
                p.velocity_scale
            )
        } else {
            format!(
                "the velocity scale {:.4} is outside the physical range [{lo}, {hi}] (the ratio of \
                 sound speeds): camera poses in other units than metres (a board or baseline size \
                 in mm?), or a DVL log of another recording",
                p.velocity_scale
            )
        });
    }
    if free.time_offset
        && let Some(i) = init
    {
        let (a, b) = i.offset.searched;
        let edge = 0.01 * (b - a);
        if !(p.time_offset_s > a + edge && p.time_offset_s < b - edge) {
            reasons.push(format!(
                "the clock offset {:.4} s ended at the edge of the offsets searched [{a:.4}, \
                 {b:.4}] s: the clocks could not be aligned (logs that overlap little, or an \
                 {} that excludes the right offset)",
                p.time_offset_s,
                opts.name(Setting::OffsetRange)
            ));
        }
    }
    // A run from a guess has no search to compare with; its offset still may not rest on a
    // bound of the range given.
    if free.time_offset
        && init.is_none()
        && let Some((a, b)) = opts.offset.range
        && (p.time_offset_s <= a || p.time_offset_s >= b)
    {
        reasons.push(format!(
            "the clock offset {:.4} s ended on a bound of {} [{a:.4}, {b:.4}] s: the data ask \
             for an offset outside it (a range that excludes the right offset?)",
            p.time_offset_s,
            opts.name(Setting::OffsetRange)
        ));
    }
    if reasons.is_empty() {
        Status::Ok
    } else {
        Status::Failed(reasons)
    }
}

/// What a held guess that does not fit the data most likely means, and what to run instead.
fn fixed_guess_advice(free: FreeParams, opts: &CalibOptions) -> String {
    if free.time_offset {
        format!(
            "the given extrinsics most likely do not fit this rig (a rotation or lever arm of \
             another mounting, or in another frame); estimate them with {}, or refine them with \
             {}",
            opts.name(Setting::Uic),
            opts.name(Setting::RefineGuess)
        )
    } else {
        format!(
            "the given calibration most likely does not fit this recording (a clock offset of \
             another recording, or extrinsics of another mounting); estimate the clock offset too \
             with {}, or everything with {}",
            opts.name(Setting::EstimateOffset),
            opts.name(Setting::Uic)
        )
    }
}

/// The verdicts by the standard deviations alone (what held or determined a parameter is
/// [`judge`]'s); the DVL's std from the three sensors together are judged by it too.
pub(crate) fn verdicts(
    std: &ParamStd,
    opts: &CalibOptions,
    ex: &Excitation,
    init: Option<&InitReport>,
    free: &[bool; NPARAM],
) -> Verdicts {
    let th = &opts.weak;
    let judge = |free: bool,
                 worst: f64,
                 limit: f64,
                 what: &str,
                 unit: &str,
                 (why, cause): (&str, WeakCause)| {
        if free {
            verdict_by_std(worst, limit, what, unit, why, cause)
        } else {
            Verdict {
                ok: true,
                reason: format!(
                    "held fixed at the value given with {}",
                    opts.name(Setting::Guess)
                ),
                by: DeterminedBy::Fixed,
                cause: None,
            }
        }
    };
    let lever_why = format!(
        "the camera rotated too little (RMS {:.3} rad/s, lever-arm velocity {:.1}% of the speed); \
         record strong rotations about several axes",
        ex.rms_angular_speed,
        100.0 * ex.lever_arm_ratio
    );
    let mut lever = judge(
        free[3],
        std.lever_arm_m.max(),
        th.lever_arm_m,
        "lever arm",
        "m",
        (&lever_why, WeakCause::LittleRotation),
    );
    if let Some(i) = init
        && !i.closed_form.lever_arm_solved
        && lever.ok
        && free[3]
    {
        lever = Verdict {
            ok: false,
            reason: "angular velocity too small to solve the lever arm in closed form".into(),
            by: DeterminedBy::Data,
            cause: Some(WeakCause::LittleRotation),
        };
    }
    let offset_why = match init.map(|i| i.offset.method) {
        Some(OffsetMethod::SpeedCorrelation) => {
            "no calm segment and little change of speed; start the recording with a calm stretch \
             of varying speed"
        }
        _ => "the speed changed too little; vary the speed during the recording",
    };
    Verdicts {
        rotation: judge(
            free[0],
            std.rotation_deg.max(),
            th.rotation_deg,
            "rotation",
            "deg",
            (
                "the camera moved along too few directions",
                WeakCause::FewDirections,
            ),
        ),
        lever_arm: lever,
        time_offset: judge(
            free[7],
            std.time_offset_s,
            th.time_offset_s,
            "clock offset",
            "s",
            (offset_why, WeakCause::LittleSpeedChange),
        ),
        velocity_scale: judge(
            free[6],
            std.velocity_scale,
            th.velocity_scale,
            "velocity scale",
            "",
            ("the camera moved too little", WeakCause::LittleMotion),
        ),
    }
}

/// The verdict on a parameter the data determined, by its worst standard deviation `worst`
/// against `limit`: well determined, or weak with the reason `{what} standard deviation ...
/// exceeds ...: {why}` and the `cause` that names what the motion lacked. The DVL's verdicts and
/// the IMU's ([`imu_verdicts`]) are made by it.
pub(crate) fn verdict_by_std(
    worst: f64,
    limit: f64,
    what: &str,
    unit: &str,
    why: &str,
    cause: WeakCause,
) -> Verdict {
    if worst.is_finite() && worst <= limit {
        Verdict {
            ok: true,
            reason: String::new(),
            by: DeterminedBy::Data,
            cause: None,
        }
    } else {
        Verdict {
            ok: false,
            reason: format!(
                "{what} standard deviation {worst:.3e} {unit} exceeds {limit} {unit}: {why}"
            ),
            by: DeterminedBy::Data,
            cause: Some(cause),
        }
    }
}

/// The motion the camera-IMU calibration saw: the rig's rotation over the recording, from the
/// knots of the trajectory it was estimated with, each weighted by the time it stands for.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuMotion {
    /// RMS rotation rate about the motion's principal axes, largest first, rad/s: the rotation
    /// observes `R_cam_imu` about as many axes as these are well above zero.
    pub principal_rates: [f64; 3],
    /// RMS rotation rate about each IMU axis, rad/s.
    pub axis_rates: Vector3<f64>,
    /// RMS rotation rate, rad/s.
    pub rms_rate: f64,
    /// RMS angular acceleration, rad/s^2.
    pub rms_angular_accel: f64,
    /// RMS deviation of the rotation rate from its mean over the recording, rad/s.
    pub rate_variation: f64,
}

/// The verdicts on the IMU's rotation, lever arm and clock offset, with the motion they were
/// made from.
#[derive(Clone, Debug)]
pub struct ImuVerdicts {
    /// On `R_cam_imu`.
    pub rotation: Verdict,
    /// On the lever arm `p_cam_imu`.
    pub lever_arm: Verdict,
    /// On the IMU's clock offset.
    pub time_offset: Verdict,
    /// What the motion gave.
    pub motion: ImuMotion,
}

/// The rig's rotation over the knots of `est`.
pub fn imu_motion(est: &ImuEstimate) -> ImuMotion {
    let t = &est.times;
    let n = t.len().min(est.knots.len());
    let weight = |i: usize| {
        let a = if i > 0 { t[i - 1] } else { t[i] };
        let b = if i + 1 < n { t[i + 1] } else { t[i] };
        0.5 * (b - a)
    };
    let r_imu_cam = est.state.t_cam_imu.rot.transpose();
    let (mut total, mut mean, mut second, mut accel) =
        (0.0, Vector3::zeros(), Matrix3::zeros(), 0.0);
    for (i, k) in est.knots.iter().enumerate().take(n) {
        let w = weight(i);
        let rate = k.twist.fixed_rows::<3>(3).into_owned();
        let alpha = k.rate.fixed_rows::<3>(3).into_owned();
        total += w;
        mean += w * rate;
        second += w * rate * rate.transpose();
        accel += w * alpha.norm_squared();
    }
    let total = if total > 0.0 { total } else { f64::NAN };
    let (mean, second) = (mean / total, second / total);
    let mut principal: Vec<f64> = SymmetricEigen::new(second)
        .eigenvalues
        .iter()
        .map(|e| e.max(0.0).sqrt())
        .collect();
    principal.sort_by(|a, b| b.total_cmp(a));
    let in_imu = r_imu_cam * second * r_imu_cam.transpose();
    ImuMotion {
        principal_rates: [principal[0], principal[1], principal[2]],
        axis_rates: in_imu.diagonal().map(|v| v.max(0.0).sqrt()),
        rms_rate: second.trace().max(0.0).sqrt(),
        rms_angular_accel: (accel / total).sqrt(),
        rate_variation: (second.trace() - mean.norm_squared()).max(0.0).sqrt(),
    }
}

/// The IMU's verdicts by the thresholds `weak` (the DVL's: the worst axis's rotation and
/// lever-arm standard deviation, and the offset's), each weak one with the motion it lacked: for
/// the rotation, rotation about more than one axis; for the lever arm, rotation rate and
/// angular acceleration; for the clock offset, a rotation rate that varies.
pub fn imu_verdicts(est: &ImuEstimate, weak: &WeakThresholds) -> ImuVerdicts {
    let m = imu_motion(est);
    let (s_rot, s_lever, s_off) = est.std();
    let [a, b, c] = m.principal_rates;
    let mut v = ImuVerdicts {
        rotation: verdict_by_std(
            s_rot.max().to_degrees(),
            weak.rotation_deg,
            "IMU rotation",
            "deg",
            &format!(
                "the rig rotated about at most one axis (RMS rate about the motion's principal \
                 axes {a:.3}, {b:.3} and {c:.3} rad/s); rotate about several axes while the \
                 board stays in view"
            ),
            WeakCause::FewRotationAxes,
        ),
        lever_arm: verdict_by_std(
            s_lever.max(),
            weak.lever_arm_m,
            "IMU lever arm",
            "m",
            &format!(
                "the rig rotated too little (RMS rate {:.3} rad/s, RMS angular acceleration \
                 {:.3} rad/s^2); rotate briskly about several axes, speeding the rotation up and \
                 slowing it down",
                m.rms_rate, m.rms_angular_accel
            ),
            WeakCause::LittleRotation,
        ),
        time_offset: verdict_by_std(
            s_off,
            weak.time_offset_s,
            "IMU clock offset",
            "s",
            &format!(
                "the rotation rate varied too little (by {:.3} rad/s RMS about its mean, RMS \
                 angular acceleration {:.3} rad/s^2); turn, stop and turn back during the \
                 recording",
                m.rate_variation, m.rms_angular_accel
            ),
            WeakCause::SteadyRotationRate,
        ),
        motion: m,
    };
    if !est.offset_alternatives_s.is_empty() {
        let others: Vec<String> = est
            .offset_alternatives_s
            .iter()
            .map(|o| format!("{o:.2} s"))
            .collect();
        v.time_offset = Verdict {
            ok: false,
            reason: format!(
                "IMU clock offset ambiguous: the motion repeats, and offsets of {} align the \
                 gyro's rates with the camera's about as well as the {:.4} s kept (the one at \
                 which the two recordings overlap most); its standard deviation holds only \
                 near it. Vary the motion (turn, stop, turn back at irregular times), or share \
                 one clock between the IMU and the camera",
                others.join(", "),
                est.state.time_offset_s
            ),
            by: DeterminedBy::Data,
            cause: Some(WeakCause::RepeatingMotion),
        };
    }
    v
}

/// The DVL cost per degree of freedom under the stated noise, over the samples that are not
/// outliers: about 1 when the noise is right, whatever the outliers.
fn inlier_normalized_cost(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
    robust: &RobustSummary,
) -> Result<f64> {
    let s = whitened_residuals(traj, obs, idx, params)?;
    let limit = robust.threshold * robust.noise_scale;
    let (sum, n) = s
        .iter()
        .filter(|&&x| robust.applied.is_none() || x <= limit)
        .fold((0.0, 0usize), |(a, n), &x| (a + x, n + 1));
    let dof = (3 * n).saturating_sub(NPARAM).max(1) as f64;
    Ok(sum / dof)
}

/// The clock offset of the first and the last third of the samples `idx` (by DVL time), each
/// estimated with every other parameter held at the result, against `traj` (the pose-only fit). `None` when a
/// third has too few samples.
fn drift_check(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
    offset_std: f64,
) -> Result<Option<DriftCheck>> {
    let mut by_time: Vec<usize> = idx.to_vec();
    by_time.sort_by(|&a, &b| obs[a].t.total_cmp(&obs[b].t));
    let n = by_time.len() / 3;
    if n < 30 || !(offset_std.is_finite() && offset_std > 0.0) {
        return Ok(None);
    }
    let only_offset = FreeParams {
        rotation: false,
        lever_arm: false,
        scale: false,
        time_offset: true,
    };
    let third = |part: &[usize]| -> Result<(f64, f64)> {
        let up = calibration_update(traj, obs, part, params, only_offset, &Priors::default(), 20)?;
        let mid = 0.5 * (obs[part[0]].t + obs[part[part.len() - 1]].t);
        Ok((up.params.time_offset_s, mid))
    };
    let (o1, t1) = third(&by_time[..n])?;
    let (o3, t3) = third(&by_time[by_time.len() - n..])?;
    let difference_std_s = offset_std * 6f64.sqrt();
    Ok(Some(DriftCheck {
        first_third_s: o1,
        last_third_s: o3,
        difference_std_s,
        drift_ppm: 1e6 * (o3 - o1) / (t3 - t1).max(1e-9),
        significant: (o3 - o1).abs() > 3.0 * difference_std_s,
    }))
}

/// Appends `reason` to a verdict's reason.
fn push_reason(v: &mut Verdict, reason: &str) {
    v.reason = if v.reason.is_empty() {
        reason.to_owned()
    } else {
        format!("{}; {reason}", v.reason)
    };
}

/// For each prior, whether it or the data determined its parameter: the prior did when its
/// variance is below the data's alone on some axis.
///
/// A prior that disagrees with the data is named too: for a linear Gaussian problem the
/// estimate is the data's own estimate pulled toward the prior, `estimate - prior = (data -
/// prior) s_p^2 / (s_d^2 + s_p^2)` on each axis, so the data's estimate lies at `prior +
/// (estimate - prior) (s_d^2 + s_p^2) / s_p^2`, and its distance from the prior in units of
/// `sqrt(s_d^2 + s_p^2)` is the disagreement.
fn prior_notes(priors: &Priors, data_only: &ParamMat, params: &CalibrationParams) -> Vec<String> {
    let worst = |first: usize| {
        (first..first + 3)
            .map(|k| data_only[(k, k)].max(0.0).sqrt())
            .fold(0.0, f64::max)
    };
    let residual = priors.terms(params);
    let disagreement = |first: usize, sigma: f64| {
        (first..first + 3)
            .map(|k| {
                let sd2 = data_only[(k, k)].max(0.0);
                let sp2 = sigma * sigma;
                // The gradient is r / sigma^2, so r = gradient * sigma^2.
                let r = residual.gradient[k] * sp2;
                r.abs() * (sd2 + sp2).sqrt() / sp2
            })
            .fold(0.0, f64::max)
    };
    let mut notes = Vec::new();
    let conflict = |what: &str, z: f64| {
        if z > 3.0 {
            Some(format!(
                "the {what} prior and the data disagree by {z:.1} standard deviations: check the \
                 measured value and its frame (the lever arm is the DVL origin in the camera \
                 frame; the rotation is R_cam_dvl)"
            ))
        } else {
            None
        }
    };
    let mut conflicts = Vec::new();
    if let Some(l) = &priors.lever_arm {
        conflicts.extend(conflict("lever-arm", disagreement(3, l.sigma_m)));
    }
    if let Some(r) = &priors.rotation {
        conflicts.extend(conflict(
            "rotation",
            disagreement(0, r.sigma_deg.to_radians()),
        ));
    }
    if let Some(l) = &priors.lever_arm {
        let data = worst(3);
        notes.push(if data > l.sigma_m {
            format!(
                "the lever arm comes mainly from its prior ({:.1} mm per axis): the data alone \
                 determine it only to {:.1} mm on its weakest axis",
                1e3 * l.sigma_m,
                1e3 * data
            )
        } else {
            format!(
                "the lever arm comes mainly from the data ({:.1} mm on its weakest axis alone; \
                 prior {:.1} mm)",
                1e3 * data,
                1e3 * l.sigma_m
            )
        });
    }
    if let Some(r) = &priors.rotation {
        let data = worst(0).to_degrees();
        notes.push(if data > r.sigma_deg {
            format!(
                "the rotation comes mainly from its prior ({:.2} deg): the data alone determine \
                 it only to {data:.2} deg about its weakest axis",
                r.sigma_deg
            )
        } else {
            format!(
                "the rotation comes mainly from the data ({data:.3} deg about its weakest axis \
                 alone; prior {:.2} deg)",
                r.sigma_deg
            )
        });
    }
    notes.extend(conflicts);
    notes
}

/// The RMS DVL residual per axis and the motion's excitation over the samples used. Sums are
/// formed per piece of samples and then over the pieces in order (thread-count independent).
pub(crate) fn residuals_and_excitation(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
) -> Result<(Vector3<f64>, Excitation)> {
    let pieces = crate::parallel::map_pieces(idx.len(), 2048, |r| {
        let mut sq = Vector3::zeros();
        let (mut sv, mut sw, mut sl) = (0.0, 0.0, 0.0);
        for &i in &idx[r] {
            let twist = traj.twist(obs[i].t + params.time_offset_s)?;
            let r = obs[i].v - predict(params, &twist);
            sq += r.component_mul(&r);
            let v = twist.fixed_rows::<3>(0).into_owned();
            let w = twist.fixed_rows::<3>(3).into_owned();
            sv += v.norm_squared();
            sw += w.norm_squared();
            sl += w.cross(&params.lever_arm_cam_m()).norm_squared();
        }
        Ok((sq, sv, sw, sl))
    });
    let mut sq = Vector3::zeros();
    let (mut sv, mut sw, mut sl) = (0.0, 0.0, 0.0);
    for piece in pieces {
        let (q, v, w, l): (Vector3<f64>, f64, f64, f64) = piece?;
        sq += q;
        sv += v;
        sw += w;
        sl += l;
    }
    let n = idx.len() as f64;
    let excitation = Excitation {
        rms_speed: (sv / n).sqrt(),
        rms_angular_speed: (sw / n).sqrt(),
        lever_arm_ratio: (sl / sv.max(1e-300)).sqrt(),
    };
    Ok(((sq / n).map(f64::sqrt), excitation))
}

pub(crate) fn param_std(c: &ParamMat) -> ParamStd {
    let s = |k: usize| c[(k, k)].max(0.0).sqrt();
    ParamStd {
        rotation_deg: Vector3::new(s(0), s(1), s(2)).map(f64::to_degrees),
        lever_arm_m: Vector3::new(s(3), s(4), s(5)),
        velocity_scale: s(6),
        time_offset_s: s(7),
    }
}

#[cfg(test)]
mod prior_note_tests {
    use super::*;
    use crate::lie::Se3;
    use nalgebra::Matrix3;

    /// A lever arm estimated at 0.1 m on x with the data alone knowing it to `sd` m, and a prior
    /// at 0 with `sp` m: the notes of `prior_notes`.
    fn notes(sd: f64, sp: f64, estimate_x: f64) -> Vec<String> {
        let priors = Priors {
            lever_arm: Some(LeverArmPrior {
                lever_arm_cam_m: Vector3::zeros(),
                sigma_m: sp,
            }),
            ..Priors::default()
        };
        let mut data_only = ParamMat::identity() * 1e-6;
        for k in 3..6 {
            data_only[(k, k)] = sd * sd;
        }
        let params = CalibrationParams {
            t_cam_dvl: Se3::new(Matrix3::identity(), Vector3::new(estimate_x, 0.0, 0.0)),
            time_offset_s: 0.0,
            velocity_scale: 1.0,
        };
        prior_notes(&priors, &data_only, &params)
    }

    #[test]
    fn a_broad_prior_the_data_overrule_is_no_conflict() {
        // The data alone say 0.1 m to 1 mm; a 0.5 m prior at 0 is 0.2 of its sigma away.
        let n = notes(1e-3, 0.5, 0.1);
        assert!(!n.iter().any(|m| m.contains("disagree")), "{n:?}");
    }

    #[test]
    fn a_tight_prior_far_from_the_data_is_named_with_its_distance() {
        // sd = sp = 1 mm: the estimate sits half way, so the data said 0.1 m when the estimate
        // is 0.05 m: 0.1 / sqrt(2) mm = 70.7 standard deviations.
        let n = notes(1e-3, 1e-3, 0.05);
        assert!(
            n.iter()
                .any(|m| m.contains("disagree by 70.7 standard deviations")),
            "{n:?}"
        );
        // The same data and a prior ten times broader: the estimate moves to 0.1 * 100/101 and
        // the data's 0.1 m is 0.1 / sqrt(1.01e-4) = 9.95 standard deviations from the prior
        // (printed with one decimal).
        let n = notes(1e-3, 1e-2, 0.1 * 100.0 / 101.0);
        assert!(n.iter().any(|m| m.contains("disagree by 10.0")), "{n:?}");
    }
}

#[cfg(test)]
mod imu_verdict_tests {
    use super::*;
    use crate::calib::imu::{BiasNodes, ImuState};
    use crate::lie::Se3;
    use crate::trajectory::Knot;
    use crate::types::imu::ImuBias;
    use nalgebra::{DMatrix, Vector6};

    /// An estimate over 10 s of knots 0.1 s apart whose angular velocity is `w(t)` (camera
    /// frame), with the IMU turned 90 degrees about the camera's z, and `std` as every
    /// calibration parameter's standard deviation (rotation in rad).
    fn estimate(w: impl Fn(f64) -> Vector3<f64>, std: f64) -> ImuEstimate {
        let times: Vec<f64> = (0..=100).map(|i| 0.1 * i as f64).collect();
        let knots = times
            .iter()
            .map(|&t| {
                let (a, b) = (w(t), (w(t + 1e-4) - w(t - 1e-4)) / 2e-4);
                Knot {
                    pose: Se3::identity(),
                    twist: Vector6::new(0.0, 0.0, 0.0, a.x, a.y, a.z),
                    rate: Vector6::new(0.0, 0.0, 0.0, b.x, b.y, b.z),
                }
            })
            .collect();
        let r = crate::lie::so3::exp(&Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2));
        let state = ImuState {
            t_cam_imu: Se3::new(r, Vector3::zeros()),
            time_offset_s: 0.0,
            gravity_rotation: Matrix3::identity(),
            gravity_magnitude: 9.81,
            bias: BiasNodes::spanning(0.0, 10.0, 10.0, ImuBias::default()),
            dvl: None,
        };
        let n = state.dim();
        ImuEstimate {
            state,
            covariance: DMatrix::identity(n, n) * std * std,
            iterations: 1,
            converged: true,
            bins_used: 1,
            bins_total: 1,
            times,
            knots,
            cost: 0.0,
            noise_factor: (1.0, 1.0),
            dvl_noise_factor: 1.0,
            offset_alternatives_s: Vec::new(),
            prior_shift: None,
        }
    }

    /// The std are the data's and the motion prior's together: taking the prior's shift out
    /// leaves the data's, and the shift over it says which of the two leads.
    #[test]
    fn the_data_std_leave_the_motion_priors_share_out() {
        let mut est = estimate(|_| Vector3::new(0.5, 0.0, 0.0), 0.01);
        est.prior_shift = Some(crate::calib::imu::PriorShift {
            rotation: Vector3::zeros(),
            lever_arm: Vector3::new(-0.006, 0.0, 0.0),
            time_offset_s: 0.008,
        });
        let (r, l, o) = est.data_std();
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(close(r.x, 0.01) && close(l.x, 0.008) && close(l.y, 0.01) && close(o, 0.006));
        let over = est.prior_shift.expect("shift").over_data_std(&est);
        assert!(close(over[3], 0.75) && close(over[6], 4.0 / 3.0) && over[0] == 0.0);
        // The total std are untouched.
        assert!(close(est.std().1.x, 0.01));
    }

    #[test]
    fn rotation_about_one_axis_is_the_named_cause_of_a_weak_imu_rotation() {
        // A steady 0.5 rad/s about the camera's x axis: one principal axis, no variation.
        let est = estimate(|_| Vector3::new(0.5, 0.0, 0.0), 1.0);
        let v = imu_verdicts(&est, &WeakThresholds::default());
        let m = &v.motion;
        assert!((m.principal_rates[0] - 0.5).abs() < 1e-12, "{m:?}");
        assert!(m.principal_rates[1] < 1e-12 && m.principal_rates[2] < 1e-12);
        // The camera's x axis is the IMU's -y axis.
        assert!(
            (m.axis_rates - Vector3::new(0.0, 0.5, 0.0)).norm() < 1e-12,
            "{m:?}"
        );
        assert!(
            m.rms_angular_accel < 1e-9 && m.rate_variation < 1e-9,
            "{m:?}"
        );
        for (verdict, cause, words) in [
            (
                &v.rotation,
                WeakCause::FewRotationAxes,
                "about at most one axis",
            ),
            (
                &v.lever_arm,
                WeakCause::LittleRotation,
                "rotated too little",
            ),
            (
                &v.time_offset,
                WeakCause::SteadyRotationRate,
                "varied too little",
            ),
        ] {
            assert!(!verdict.ok);
            assert_eq!(verdict.cause, Some(cause));
            assert_eq!(verdict.by, DeterminedBy::Data);
            assert!(verdict.reason.contains(words), "{}", verdict.reason);
            assert!(verdict.reason.contains("exceeds"), "{}", verdict.reason);
        }
        assert!(
            v.rotation
                .reason
                .starts_with("IMU rotation standard deviation")
        );
    }

    #[test]
    fn small_std_are_well_determined_with_no_reason() {
        let est = estimate(
            |t| Vector3::new(t.sin(), (2.0 * t).cos(), 0.3 * (3.0 * t).sin()),
            1e-5,
        );
        let v = imu_verdicts(&est, &WeakThresholds::default());
        for verdict in [&v.rotation, &v.lever_arm, &v.time_offset] {
            assert!(verdict.ok && verdict.reason.is_empty() && verdict.cause.is_none());
        }
        assert!(v.motion.principal_rates[2] > 0.05, "{:?}", v.motion);
        assert!(v.motion.rms_angular_accel > 0.5, "{:?}", v.motion);
    }
}
