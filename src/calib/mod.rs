//! Spatiotemporal DVL-camera calibration: the UIC method.
//!
//! 1. Fit the camera trajectory (GP regression on the poses).
//! 2. Clock offset and scale from speed magnitudes on calm samples ([`offset`]).
//! 3. Rotation, lever arm and scale in closed form with bias elimination ([`mod@closed_form`]).
//! 4. Block-coordinate refinement: calibration update with the trajectory fixed (`refine`),
//!    state update with the calibration fixed (`state`: the trajectory's solver with the DVL
//!    factors added), until nothing changes; a Gauss-Newton step on the joint problem after an
//!    unsettled round speeds up the alternation (`state::joint_step`).
//! 5. Uncertainty from the information matrix of the final problem and a verdict per parameter.
//!
//! [`calibrate`] runs the stages in this order; [`initialise`] is stages 2 and 3 on their own.

pub mod align;
pub mod closed_form;
pub mod model;
pub mod offset;
pub mod prior;
pub(crate) mod refine;
pub mod robust;
pub(crate) mod state;
pub mod whiteness;

/// Covariance or information of the parameters, in [`ParamVec`]'s order.
pub use refine::ParamMat;
/// The estimator's parameter vector: `[dphi; dp; dkappa; ddelta]` (rad about the DVL axes, m,
/// scale, s), the coordinates of [`model::difference`] and of the covariance.
pub use refine::ParamVec;

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::trajectory::solver::measurement_information;
use crate::trajectory::{FitOptions, FitReport, Knot, Trajectory};
use crate::types::CalibrationParams;
use crate::types::{DvlSample, PoseMeasurement};
use closed_form::{ClosedForm, ClosedFormRow, closed_form};
use model::{NPARAM, predict};
use offset::{DvlObs, OffsetMethod, OffsetOptions, OffsetResult, estimate_offset};
use prior::Priors;
use refine::{FreeParams, calibration_update};
use robust::{Loss, RobustSummary};
use state::{
    AssembledJoint, JointProblem, assemble_joint, joint_cost, joint_covariance,
    joint_covariance_of, joint_step, part_linear_estimate, state_update,
};
use whiteness::Whiteness;

/// How the calibration starts.
#[derive(Clone, Debug)]
pub enum Method {
    /// UIC: initialisation from the data alone, then refinement.
    Uic,
    /// Block-coordinate refinement from a user guess.
    Bcd(CalibrationParams),
    /// The user's extrinsics kept fixed; with `estimate_offset` the clock offset (and scale)
    /// is estimated with the extrinsics held, otherwise the guess is only evaluated.
    Fixed {
        /// The user's calibration; its rotation and lever arm are held fixed.
        guess: CalibrationParams,
        /// Whether to estimate the clock offset and velocity scale (`false`: only evaluate the
        /// guess).
        estimate_offset: bool,
    },
}

/// Standard deviations above which a parameter is reported as weakly observable.
#[derive(Clone, Debug)]
pub struct WeakThresholds {
    /// Limit on the rotation standard deviation about each axis, degrees.
    pub rotation_deg: f64,
    /// Limit on the lever-arm standard deviation along each axis, m.
    pub lever_arm_m: f64,
    /// Limit on the clock-offset standard deviation, s.
    pub time_offset_s: f64,
    /// Limit on the velocity-scale standard deviation (dimensionless).
    pub velocity_scale: f64,
}

impl Default for WeakThresholds {
    fn default() -> Self {
        WeakThresholds {
            rotation_deg: 0.5,
            lever_arm_m: 0.01,
            time_offset_s: 0.01,
            velocity_scale: 0.005,
        }
    }
}

/// What a calibration must satisfy to be trusted; a result outside them is
/// [`Status::Failed`].
#[derive(Clone, Debug, PartialEq)]
pub struct SanityLimits {
    /// Largest DVL cost per degree of freedom (1 when the residuals match the stated noise).
    pub max_normalized_cost: f64,
    /// Physical range of the velocity scale: the ratio of the sound speed the DVL assumes to the
    /// water's (0.9..1.1 covers water from 0 to 35 C, fresh to salt).
    pub scale_range: (f64, f64),
    /// Largest share of the DVL reports that may be outliers (down-weighted by the robust loss,
    /// or only found under least squares). Beyond it the disagreement is not a few outliers but
    /// a model that does not fit (a drifting clock, poses of another body, a log of another
    /// recording), and the loss would only hide it.
    pub max_outlier_fraction: f64,
}

impl Default for SanityLimits {
    fn default() -> Self {
        SanityLimits {
            max_normalized_cost: 10.0,
            scale_range: (0.9, 1.1),
            max_outlier_fraction: 0.25,
        }
    }
}

/// The clock offset estimated on the first and on the last third of the recording alone (all
/// other parameters and the trajectory held at the result), to detect a drifting clock.
#[derive(Clone, Debug, PartialEq)]
pub struct DriftCheck {
    /// Offset of the first third, s.
    pub first_third_s: f64,
    /// Offset of the last third, s.
    pub last_third_s: f64,
    /// Standard deviation of their difference, s (each third has a third of the data: the
    /// whole recording's offset std times the square root of six).
    pub difference_std_s: f64,
    /// The drift the two imply, ppm (parts per million of elapsed time).
    pub drift_ppm: f64,
    /// The difference exceeds three standard deviations.
    pub significant: bool,
}

/// Whether a calibration can be trusted.
#[derive(Clone, Debug, PartialEq)]
pub enum Status {
    /// Every sanity check passed.
    Ok,
    /// A check failed: each reason in words, with its likely cause.
    Failed(Vec<String>),
}

impl Status {
    /// Whether the result can be used.
    pub fn is_ok(&self) -> bool {
        matches!(self, Status::Ok)
    }
}

/// Settings of a calibration.
#[derive(Clone, Debug)]
pub struct CalibOptions {
    /// How the calibration starts: UIC, BCD from a guess, or fixed extrinsics.
    pub method: Method,
    /// Per-axis DVL noise (m/s) replacing the reports' own covariance.
    pub dvl_sigma: Option<f64>,
    /// DVL noise used for reports without a covariance.
    pub default_dvl_sigma: f64,
    /// Settings of the clock-offset search; its range also sets the time margin of the DVL
    /// samples kept.
    pub offset: OffsetOptions,
    /// Use the bias-eliminated closed form (the paper's estimator); `false` gives the biased one.
    pub bias_corrected: bool,
    /// Outer block-coordinate iterations.
    pub max_outer_iterations: usize,
    /// Settings of the camera-trajectory fit.
    pub fit: FitOptions,
    /// Standard deviations above which a parameter is reported as weak.
    pub weak: WeakThresholds,
    /// What a result must satisfy to be trusted.
    pub sanity: SanityLimits,
    /// Priors on the calibration (a measured lever arm, a known rotation); none by default.
    pub priors: prior::Priors,
    /// The loss on the DVL and pose residuals ([`robust`]); Cauchy by default.
    pub loss: Loss,
    /// Standard deviation of the broad prior (zero lever arm) applied when `priors` has no
    /// lever-arm prior, metres: it keeps a lever arm the motion does not observe from running
    /// to metres and corrupting the other parameters (1 m by default; `None`: no such prior).
    pub default_lever_arm_sigma_m: Option<f64>,
    /// Inflate the covariance for correlated DVL residuals and for halves of the recording that
    /// disagree (on by default).
    pub honest_covariance: bool,
}

impl Default for CalibOptions {
    fn default() -> Self {
        CalibOptions {
            method: Method::Uic,
            dvl_sigma: None,
            default_dvl_sigma: 0.01,
            offset: OffsetOptions::default(),
            bias_corrected: true,
            max_outer_iterations: 10,
            // The pose-only fit starts the joint refinement, whose state update moves every knot
            // again; a tenth of a standard deviation per knot is close enough to start from.
            fit: FitOptions {
                decrement_per_knot: 0.01,
                ..FitOptions::default()
            },
            weak: WeakThresholds::default(),
            sanity: SanityLimits::default(),
            priors: prior::Priors::default(),
            loss: Loss::default(),
            default_lever_arm_sigma_m: Some(1.0),
            honest_covariance: true,
        }
    }
}

impl CalibOptions {
    /// Checks every setting before anything is computed; the error names the option.
    pub fn validate(&self) -> Result<()> {
        self.offset.validate()?;
        self.priors.validate()?;
        if let Some(s) = self.default_lever_arm_sigma_m
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::option(
                "default_lever_arm_sigma_m",
                "must be a positive number of metres",
            ));
        }
        if let Some(s) = self.dvl_sigma
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::option("--dvl-sigma", "must be positive"));
        }
        if !(self.default_dvl_sigma.is_finite() && self.default_dvl_sigma > 0.0) {
            return Err(Error::option(
                "default_dvl_sigma",
                "must be a positive number of m/s",
            ));
        }
        Ok(())
    }
}

/// What gave a parameter its value.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeterminedBy {
    /// The recording: the parameter was estimated and the data constrain it.
    #[default]
    Data,
    /// Nothing: the parameter was held at the value given (`--method fixed`); it has no
    /// standard deviation.
    Fixed,
    /// A prior rather than the data: the broad default prior that holds an unobserved lever arm,
    /// or a user's prior whose standard deviation the data barely reduced.
    Prior,
}

/// Verdict on one parameter.
#[derive(Clone, Debug)]
pub struct Verdict {
    /// Whether the parameter is well determined (or was held fixed).
    pub ok: bool,
    /// Why the parameter is weak (empty when ok), or how it was held.
    pub reason: String,
    /// Whether the data, a prior, or nothing (held fixed) gave the value.
    pub by: DeterminedBy,
}

/// Verdicts on all parameters.
#[derive(Clone, Debug)]
pub struct Verdicts {
    /// Verdict on the DVL-camera rotation.
    pub rotation: Verdict,
    /// Verdict on the lever arm `p_cam_dvl`.
    pub lever_arm: Verdict,
    /// Verdict on the clock offset `time_offset_s`.
    pub time_offset: Verdict,
    /// Verdict on the DVL velocity scale.
    pub velocity_scale: Verdict,
}

/// Standard deviations of the estimate.
#[derive(Clone, Debug)]
pub struct ParamStd {
    /// About the DVL frame's x, y, z axes (left perturbation of `R_dvl_cam`), degrees.
    pub rotation_deg: Vector3<f64>,
    /// Along the camera frame's x, y, z axes (of the lever arm `p_cam_dvl`), metres.
    pub lever_arm_m: Vector3<f64>,
    /// Standard deviation of the clock offset (`t_cam = t_dvl + time_offset_s`), seconds.
    pub time_offset_s: f64,
    /// Standard deviation of the velocity scale (dimensionless).
    pub velocity_scale: f64,
}

/// The initialisation stage of UIC.
#[derive(Clone, Debug)]
pub struct InitReport {
    /// The clock offset and velocity scale from speed magnitudes.
    pub offset: OffsetResult,
    /// Rotation, lever arm and scale in closed form at that offset.
    pub closed_form: ClosedForm,
    /// Parameters after initialisation (closed form with the searched offset).
    pub params: CalibrationParams,
}

/// One block-coordinate iteration.
#[derive(Clone, Debug)]
pub struct IterationRecord {
    /// The joint cost after the iteration: pose, GP prior and DVL terms, each a sum of squared
    /// residuals weighted by its noise.
    pub cost: f64,
    /// Parameters after the round's calibration update.
    pub params: CalibrationParams,
}

/// Measures of the motion's excitation.
#[derive(Clone, Debug, Default)]
pub struct Excitation {
    /// RMS camera speed and angular speed over the DVL samples used.
    pub rms_speed: f64,
    /// RMS camera angular speed over the DVL samples used, rad/s.
    pub rms_angular_speed: f64,
    /// RMS of `|w x p|` over RMS of `|v|` at the estimated lever arm: how much the lever arm
    /// shows in the DVL velocities.
    pub lever_arm_ratio: f64,
}

/// Counts of the data used.
#[derive(Clone, Debug, Default)]
pub struct Counts {
    /// Camera poses given.
    pub poses: usize,
    /// DVL reports given.
    pub dvl_samples: usize,
    /// DVL reports left out as flagged invalid or with non-finite velocities.
    pub dvl_invalid: usize,
    /// Valid DVL reports the refinement used.
    pub dvl_used: usize,
    /// Valid DVL reports whose covariance could not weigh them (not symmetric positive
    /// definite, or nearly singular), weighted with the default noise instead.
    pub dvl_covariance_replaced: usize,
    /// Valid DVL reports left out because their camera time falls outside the trajectory span
    /// (with a margin for offset changes).
    pub dvl_outside_span: usize,
    /// Valid DVL reports left out because their camera time falls in a gap between poses
    /// (see [`pose_gap_threshold_s`]).
    pub dvl_in_pose_gaps: usize,
    /// Calm (slowly rotating) samples the UIC offset search found; 0 for the other methods.
    pub calm: usize,
    /// Valid DVL reports left out of the initialisation because their velocity jumps away from
    /// their neighbours' (the refinement weighs them by their residuals instead).
    pub dvl_spikes_screened: usize,
    /// DVL reports used whose residual marks them as outliers: down-weighted by the loss.
    pub dvl_downweighted: usize,
    /// Camera poses whose residual against the trajectory marks them as outliers:
    /// down-weighted by the loss.
    pub poses_downweighted: usize,
}

/// What the robust loss did to the DVL reports and to the poses.
#[derive(Clone, Debug, Default)]
pub struct Robustness {
    /// The loss asked for.
    pub loss: Loss,
    /// The DVL factors (residuals in DVL-clock time).
    pub dvl: RobustSummary,
    /// The pose factors (camera-clock time), judged against the pose-only trajectory.
    pub poses: RobustSummary,
    /// Weight of each DVL observation in the result (1 for those not used).
    pub dvl_weights: Vec<f64>,
    /// Weight of each pose in the result.
    pub pose_weights: Vec<f64>,
}

/// Everything a calibration run produced.
#[derive(Clone, Debug)]
pub struct CalibrationOutcome {
    /// The estimated calibration.
    pub params: CalibrationParams,
    /// Covariance of `params` in the estimator's coordinates `[dphi; dp; dkappa; ddelta]` (rad,
    /// m, -, s; see [`model::difference`]); zero for held parameters.
    pub covariance: ParamMat,
    /// Standard deviations from `covariance`.
    pub std: ParamStd,
    /// Verdict on each parameter.
    pub verdicts: Verdicts,
    /// The method of the run.
    pub method: Method,
    /// The UIC initialisation stage (`None` for BCD and fixed extrinsics).
    pub init: Option<InitReport>,
    /// One record per block-coordinate round.
    pub iterations: Vec<IterationRecord>,
    /// Counts of the data used.
    pub counts: Counts,
    /// RMS of DVL residuals per axis, m/s.
    pub residual_rms: Vector3<f64>,
    /// Weighted residual sum over its degrees of freedom: about 1 when the DVL noise is right.
    pub normalized_cost: f64,
    /// Measures of the motion's excitation over the DVL samples used.
    pub excitation: Excitation,
    /// Report of the trajectory fit to the poses (hyperparameters, convergence, residuals).
    pub trajectory: FitReport,
    /// Human-readable warnings of the run (offset-search notes, inflated standard deviations).
    pub warnings: Vec<String>,
    /// Whether the result passed the sanity checks ([`SanityLimits`]).
    pub status: Status,
    /// The clock offset of the first and the last third of the recording compared (when the
    /// offset was estimated and each third has enough samples).
    pub drift: Option<DriftCheck>,
    /// Where the refinement started: the initialisation's parameters, or the user's guess.
    pub start: CalibrationParams,
    /// The final camera trajectory (refitted with the DVL factors).
    pub fitted: Trajectory,
    /// The valid DVL observations (camera epoch, DVL clock) and the indices among them that
    /// the refinement used.
    pub observations: Vec<DvlObs>,
    /// Indices into `observations` of the samples the refinement used.
    pub used: Vec<usize>,
    /// What the robust loss down-weighted.
    pub robust: Robustness,
    /// The autocorrelation of the DVL residuals and the inflation it implied.
    pub whiteness: Whiteness,
    /// The calibration of each half of the recording compared (when each half has enough
    /// samples).
    pub halves: Option<HalvesCheck>,
    /// The priors the estimate used: the user's, and the broad default on the lever arm.
    pub priors: Priors,
    /// Whether the lever arm came from the broad default prior rather than the data.
    pub lever_arm_from_default_prior: bool,
    /// Wall time of each stage of the run, in order (a profile of the run; not part of the
    /// result, and different on every run).
    pub stage_seconds: Vec<(&'static str, f64)>,
}

/// Wall times of the stages of a run.
struct StageClock {
    last: std::time::Instant,
    stages: Vec<(&'static str, f64)>,
}

impl StageClock {
    fn start() -> Self {
        StageClock {
            last: std::time::Instant::now(),
            stages: Vec::new(),
        }
    }

    /// Ends the stage `name` (begun where the previous one ended).
    fn done(&mut self, name: &'static str) {
        let now = std::time::Instant::now();
        self.stages.push((name, (now - self.last).as_secs_f64()));
        self.last = now;
    }
}

impl CalibrationOutcome {
    /// The fraction of the DVL reports given that the result rests on: used, and not
    /// down-weighted as outliers.
    pub fn usable_fraction(&self) -> f64 {
        let c = &self.counts;
        if c.dvl_samples == 0 {
            return 0.0;
        }
        c.dvl_used.saturating_sub(c.dvl_downweighted) as f64 / c.dvl_samples as f64
    }

    /// How much of the recording was usable, in words.
    pub fn usable_words(&self) -> String {
        let c = &self.counts;
        format!(
            "{:.0}% of the DVL reports used: {} of {} ({} invalid, {} outside the camera span, {} \
             in gaps between poses, {} down-weighted as outliers); {} of {} poses down-weighted",
            100.0 * self.usable_fraction(),
            c.dvl_used.saturating_sub(c.dvl_downweighted),
            c.dvl_samples,
            c.dvl_invalid,
            c.dvl_outside_span,
            c.dvl_in_pose_gaps,
            c.dvl_downweighted,
            c.poses_downweighted,
            c.poses
        )
    }
}

/// Each half of the recording calibrated on its own (the trajectory held at the result) and
/// compared: a parameter whose halves disagree by more than three standard deviations has its
/// standard deviation inflated to what the difference implies.
#[derive(Clone, Debug, PartialEq)]
pub struct HalvesCheck {
    /// DVL-clock time where the halves meet, seconds.
    pub split_t: f64,
    /// The first half's calibration.
    pub first: CalibrationParams,
    /// The second half's calibration.
    pub second: CalibrationParams,
    /// Second minus first, in the covariance's coordinates ([`model::difference`]).
    pub difference: [f64; NPARAM],
    /// Standard deviation of that difference (infinite where a half does not determine the
    /// parameter).
    pub difference_std: [f64; NPARAM],
    /// Whether the parameter was compared: both halves determine it to within three times the
    /// standard deviation half the data would give (a calm half does not test the lever arm).
    pub compared: [bool; NPARAM],
    /// The factor each parameter's standard deviation was multiplied by (1: consistent).
    pub inflation: [f64; NPARAM],
}

impl HalvesCheck {
    /// The difference of parameter `k` in its standard deviations.
    pub fn z(&self, k: usize) -> f64 {
        self.difference[k].abs() / self.difference_std[k]
    }
}

/// Whether a reported velocity covariance can weigh its sample: finite, symmetric, positive
/// definite, and not nearly singular (smallest eigenvalue at least 1e-6 of the largest; a nearly
/// singular covariance would claim an almost exact velocity along some direction). Real A50 logs
/// hold covariances with slightly negative eigenvalues.
pub fn usable_covariance(c: &Matrix3<f64>) -> bool {
    if !c.iter().all(|x| x.is_finite()) {
        return false;
    }
    let max = c.amax();
    if max.is_nan() || max <= 0.0 || (c - c.transpose()).amax() > 1e-9 * max {
        return false;
    }
    let ev = c.symmetric_eigenvalues();
    ev.min() > 1e-6 * ev.max()
}

/// DVL observations with their noise, on the camera epoch, and how many reported covariances
/// were replaced by the default noise because they could not weigh their sample.
fn observations(dvl: &[DvlSample], opts: &CalibOptions) -> (Vec<DvlObs>, usize) {
    let mut replaced = 0;
    let obs = dvl
        .iter()
        .filter(|s| s.valid && s.v.iter().all(|x| x.is_finite()))
        .map(|s| {
            let cov = match (opts.dvl_sigma, &s.cov) {
                (Some(sd), _) => Matrix3::identity() * sd * sd,
                (None, Some(c)) if usable_covariance(c) => *c,
                (None, Some(_)) => {
                    replaced += 1;
                    Matrix3::identity() * opts.default_dvl_sigma.powi(2)
                }
                (None, None) => Matrix3::identity() * opts.default_dvl_sigma.powi(2),
            };
            DvlObs {
                t: s.t,
                v: s.v,
                cov,
            }
        })
        .collect();
    (obs, replaced)
}

/// Samples usable at offsets within `margin` of `offset`.
fn usable(traj: &Trajectory, obs: &[DvlObs], offset: f64, margin: f64) -> Vec<usize> {
    let (a, b) = traj.span();
    let gaps = pose_gaps(traj.times());
    (0..obs.len())
        .filter(|&i| obs[i].t + offset - margin >= a && obs[i].t + offset + margin <= b)
        .filter(|&i| !in_gap(&gaps, obs[i].t + offset))
        .collect()
}

/// The shortest interval between consecutive poses that counts as a gap: five median pose
/// intervals, and at least half a second. Inside a gap the trajectory is the motion prior's
/// extrapolation, not a measurement, and a DVL sample there would be compared with a guess.
pub fn pose_gap_threshold_s(times: &[f64]) -> f64 {
    let mut dt: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    dt.sort_by(f64::total_cmp);
    let median = dt.get(dt.len() / 2).copied().unwrap_or(0.0);
    (5.0 * median).max(0.5)
}

/// The gaps between consecutive poses (`times` sorted), as `(start, end)`.
pub fn pose_gaps(times: &[f64]) -> Vec<(f64, f64)> {
    let threshold = pose_gap_threshold_s(times);
    times
        .windows(2)
        .filter(|w| w[1] - w[0] >= threshold)
        .map(|w| (w[0], w[1]))
        .collect()
}

fn in_gap(gaps: &[(f64, f64)], t: f64) -> bool {
    let k = gaps.partition_point(|g| g.1 <= t);
    gaps.get(k).is_some_and(|g| g.0 < t && t < g.1)
}

/// Calibrates the DVL against the camera poses, in the stages of the module documentation: the
/// trajectory fit, [`initialise`] (clock offset and closed form, or the user's guess), the
/// block-coordinate refinement (`refine_jointly`), then the uncertainty, residuals, excitation
/// and verdicts.
pub fn calibrate(
    poses: &[PoseMeasurement],
    dvl: &[DvlSample],
    opts: &CalibOptions,
) -> Result<CalibrationOutcome> {
    opts.validate()?;
    let mut clock = StageClock::start();
    let (obs, replaced) = observations(dvl, opts);
    let mut counts = Counts {
        poses: poses.len(),
        dvl_samples: dvl.len(),
        dvl_invalid: dvl.len() - obs.len(),
        dvl_covariance_replaced: replaced,
        ..Counts::default()
    };
    if obs.len() < 10 {
        return Err(Error::TooFewSamples {
            what: "valid DVL velocity reports".into(),
            found: obs.len(),
            needed: 10,
        });
    }
    // 1. The camera trajectory from the poses alone, bad poses down-weighted.
    let (weighted_poses, traj, pose_robust, pose_weights) = robust_fit(poses, opts)?;
    let poses = &weighted_poses[..];
    clock.done("trajectory fit");
    counts.poses_downweighted = pose_robust.outliers;
    let mut warnings = Vec::new();
    if pose_robust.outliers > 0 {
        warnings.push(format!(
            "{} of {} camera poses lie far from the trajectory the others describe (worst at t = \
             {:.2} s, {:.0} times the stated variance): {} (a misdetected tag or a board \
             seen at a grazing angle?)",
            pose_robust.outliers,
            pose_robust.factors,
            pose_robust.worst.first().map_or(f64::NAN, |o| o.t),
            pose_robust.worst.first().map_or(f64::NAN, |o| o.s),
            downweighted_by(opts.loss)
        ));
    }
    if replaced > 0 {
        warnings.push(format!(
            "{replaced} DVL reports carry a covariance that is not symmetric positive definite \
             (or nearly singular); they are weighted with the default noise of {} m/s instead",
            opts.default_dvl_sigma
        ));
    }
    // 2-3. Where the refinement starts.
    let (start, init, spikes_screened) = initialise(&traj, &obs, opts, &mut warnings)?;
    clock.done("initialisation");
    counts.dvl_spikes_screened = spikes_screened;
    if let Some(i) = &init {
        counts.calm = i.offset.calm.len();
    }
    let mut free = free_parameters(&opts.method);

    // Samples kept for every offset the refinement may reach.
    let margin = opts.offset.window_s.min(0.5);
    let idx = usable(&traj, &obs, start.time_offset_s, margin);
    let gaps = pose_gaps(traj.times());
    counts.dvl_in_pose_gaps = obs
        .iter()
        .filter(|o| in_gap(&gaps, o.t + start.time_offset_s))
        .count();
    counts.dvl_used = idx.len();
    counts.dvl_outside_span = obs.len() - idx.len() - counts.dvl_in_pose_gaps;
    if counts.dvl_in_pose_gaps > 0 {
        let total: f64 = gaps.iter().map(|g| g.1 - g.0).sum();
        warnings.push(format!(
            "{} DVL reports fall in {} gaps between camera poses ({total:.1} s in all, each at \
             least {:.2} s): left out, since the trajectory there is a guess",
            counts.dvl_in_pose_gaps,
            gaps.len(),
            pose_gap_threshold_s(traj.times())
        ));
    }
    if idx.len() < 10 {
        return Err(Error::NoTimeOverlap(format!(
            "only {} DVL samples fall inside the camera time span at offset {:.3} s",
            idx.len(),
            start.time_offset_s
        )));
    }

    // 4. Block-coordinate refinement of the parameters and the trajectory.
    let mut mask = free.mask();
    let priors = effective_priors(opts);
    let mut jp = JointProblem::new(poses, &traj, &obs, &idx)?;
    jp.priors = priors;
    let mut traj = traj;
    // The fit's covariance was for the initialisation; its storage serves the joint problem.
    if let Some(storage) = traj.take_covariance_storage() {
        jp.keep_system(storage);
    }
    // The pose-only trajectory, for the drift check: the refined one has absorbed part of the
    // DVL's misfit under a constant offset. Kept only when the offset is estimated.
    let pose_only = free.time_offset.then(|| traj.clone());
    // A lever arm the motion does not observe is held at its prior: free, it would wander to
    // metres, the trajectory's angular velocity bending to fit the DVL noise through `w x p`,
    // and take the other parameters with it.
    let mut start = start;
    let lever_held = match (opts.priors.lever_arm, priors.lever_arm) {
        // With a closed form its excitation decides (the linearised std cannot see the runaway
        // anyway); without one, the data's own std at the guess.
        (None, Some(l)) if free.lever_arm && init.is_some() => init
            .as_ref()
            .filter(|i| i.closed_form.rotation_snr() < LEVER_HOLD_SNR)
            .map(|_| (f64::INFINITY, l)),
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
    if let Some((worst, l)) = lever_held {
        free.lever_arm = false;
        mask = free.mask();
        start = CalibrationParams::from_r_dvl_cam(
            start.r_dvl_cam(),
            l.lever_arm_cam_m,
            start.velocity_scale,
            start.time_offset_s,
        );
        warnings.push(format!(
            "the motion does not observe the lever arm ({}): it is held at the broad default \
             prior's value, zero, and the other parameters are estimated around it; measure the \
             lever arm and give --lever-arm-prior, or record strong rotations about several axes",
            unobserved_why(worst)
        ));
    }
    let mut refined = refine_jointly(
        &jp,
        traj,
        &obs,
        &idx,
        start,
        free,
        opts.max_outer_iterations,
        LastRound::EndAtUpdate,
    )?;
    if refined.params.velocity_scale < 0.0 && free.rotation {
        refined = mirror_if_better(poses, &jp, refined, &obs, &idx, free, opts, &mut warnings)?;
    }
    clock.done("refinement");
    // 4b. Iteratively reweighted: the DVL factors under the robust loss, refined again from
    // where least squares ended until the weights settle.
    let mut dvl_weights = vec![1.0; obs.len()];
    let mut weighted = obs.clone();
    let mut dvl_robust = RobustSummary::default();
    for pass in 0..=IRLS_PASSES {
        let s = whitened_residuals(&refined.trajectory, &obs, &idx, &refined.params)?;
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
        let mut jw = JointProblem::new(poses, &refined.trajectory, &weighted, &idx)?;
        jw.priors = priors;
        jw.keep_storage(jp.take_storage());
        refined = refine_jointly(
            &jw,
            refined.trajectory,
            &weighted,
            &idx,
            refined.params,
            free,
            opts.max_outer_iterations,
            LastRound::EndAtUpdate,
        )?;
        jp.keep_storage(jw.take_storage());
    }
    clock.done("reweighting");
    counts.dvl_downweighted = dvl_robust.outliers;
    if dvl_robust.outliers > 0 {
        warnings.push(format!(
            "{} of {} DVL reports disagree with the camera's motion beyond what their noise \
             explains (worst at t = {:.2} s, {:.0} times the stated variance): {} (a fish, a \
             lost beam, a bubble?)",
            dvl_robust.outliers,
            dvl_robust.factors,
            dvl_robust.worst.first().map_or(f64::NAN, |o| o.t),
            dvl_robust.worst.first().map_or(f64::NAN, |o| o.s),
            downweighted_by(opts.loss)
        ));
    }
    let (traj, params) = (refined.trajectory, refined.params);

    // 5. Uncertainty, residuals, excitation and the verdicts.
    let normalized_cost = inlier_normalized_cost(&traj, &obs, &idx, &params, &dvl_robust)?;
    let whiteness = residual_whiteness(&traj, &obs, &idx, &params, &dvl_weights)?;
    if opts.honest_covariance && whiteness.correlated {
        // Correlated residuals carry the information of fewer independent ones: the DVL
        // factors' information divided by the integrated autocorrelation time.
        for i in idx.iter().copied() {
            weighted[i].cov *= whiteness.inflation;
        }
        warnings.push(format!(
            "the DVL residuals are correlated in time (integrated autocorrelation time {:.1} \
             samples, {:.2} s; white noise would give 1 +- {:.2}): they carry the information of \
             {:.0} independent reports, not {}, and the standard deviations account for that",
            whiteness.inflation,
            whiteness.inflation * whiteness.sample_interval_s,
            whiteness.tau_noise,
            idx.len() as f64 / whiteness.inflation,
            idx.len()
        ));
    }
    let obs_used = &weighted;
    let mut jp = {
        let mut jw = JointProblem::new(poses, &traj, obs_used, &idx)?;
        jw.priors = priors;
        jw.keep_storage(jp.take_storage());
        jw
    };
    // One assembly of the joint system at the result serves the covariance and both halves.
    let assembled = assemble_joint(&jp, traj.knots(), &params)?;
    clock.done("joint system");
    let halves = if opts.honest_covariance {
        let noise_factor = if normalized_cost > 1.5 {
            normalized_cost
        } else {
            1.0
        };
        halves_estimates(&jp, &assembled, &traj, obs_used, &idx, free, noise_factor)?
    } else {
        None
    };
    clock.done("halves check");
    let mut covariance = uncertainty(
        &jp,
        assembled,
        (&mask, free),
        normalized_cost,
        &mut warnings,
    )?;
    // The drift check compares the thirds of the recording at the model's offset variance: the
    // halves check below would inflate it for the very drift the check is looking for.
    let model_offset_std = covariance[(7, 7)].max(0.0).sqrt();
    let halves = halves.map(|h| compare_halves(h, free, &mut covariance));
    clock.done("covariance");
    if let Some(h) = &halves {
        warnings.extend(halves_notes(h));
    }
    if let Some((_, l)) = lever_held {
        // Held, the lever arm is known as well as its prior says.
        for k in 3..6 {
            covariance[(k, k)] = l.sigma_m * l.sigma_m;
        }
    }
    let std = param_std(&covariance);
    let mut lever_arm_from_default_prior = lever_held.is_some();
    // The parameters a user's prior rather than the data determined.
    let (mut rotation_from_prior, mut lever_arm_from_user_prior) = (false, false);
    if opts.priors.any() || (priors.any() && free.lever_arm && std.lever_arm_m.max() > 0.05) {
        // What the data alone would say, to tell which parameters the priors determined.
        let taken = std::mem::take(&mut jp.priors);
        let (data_only, _) = joint_covariance(&jp, &traj, &params, &mask)?;
        jp.priors = taken;
        if opts.priors.any() {
            warnings.extend(prior_notes(&opts.priors, &data_only, &params));
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
                rotation_from_prior = free.rotation && (d.is_nan() || d > r.sigma_deg.to_radians());
            }
            if let Some(l) = &opts.priors.lever_arm {
                let d = data_worst(3);
                lever_arm_from_user_prior = free.lever_arm && (d.is_nan() || d > l.sigma_m);
            }
        }
        if let (None, Some(l)) = (opts.priors.lever_arm, priors.lever_arm) {
            let data = (3..6)
                .map(|k| data_only[(k, k)].max(0.0).sqrt())
                .fold(0.0, f64::max);
            if data.is_nan() || data >= 0.5 * l.sigma_m {
                lever_arm_from_default_prior = true;
                warnings.push(format!(
                    "the motion did not observe the lever arm (the data alone determine it only \
                     to {:.2} m): it comes from the broad default prior (zero, {:.1} m), which \
                     keeps it from corrupting the other parameters; measure it and give \
                     --lever-arm-prior",
                    data, l.sigma_m
                ));
            }
        }
    }
    let (residual_rms, excitation) = residuals_and_excitation(&traj, &obs, &idx, &params)?;
    let mut verdicts = verdicts(&std, &opts.weak, &excitation, init.as_ref(), &mask);
    if let Some((worst, _)) = lever_held {
        verdicts.lever_arm = Verdict {
            ok: false,
            reason: format!(
                "not observed by the motion ({}): held at the broad default prior's value, zero; \
                 measure the lever arm and give --lever-arm-prior",
                unobserved_why(worst)
            ),
            by: DeterminedBy::Prior,
        };
    } else if lever_arm_from_default_prior {
        verdicts.lever_arm = Verdict {
            ok: false,
            reason: "not observed by the motion: the value is the broad default prior's \
                     (zero); measure the lever arm and give --lever-arm-prior"
                .into(),
            by: DeterminedBy::Prior,
        };
    }
    if rotation_from_prior {
        verdicts.rotation.by = DeterminedBy::Prior;
        push_reason(
            &mut verdicts.rotation,
            "the value comes mainly from --rotation-prior: the data alone determine it less well",
        );
    }
    if lever_arm_from_user_prior {
        verdicts.lever_arm.by = DeterminedBy::Prior;
        push_reason(
            &mut verdicts.lever_arm,
            "the value comes mainly from --lever-arm-prior: the data alone determine it less well",
        );
    }
    if let Some(h) = &halves {
        flag_inconsistent(&mut verdicts, h);
    }
    let mut status = sanity(&params, normalized_cost, init.as_ref(), free, opts);
    let share = dvl_robust.outliers as f64 / dvl_robust.factors.max(1) as f64;
    if share > opts.sanity.max_outlier_fraction {
        let reason = format!(
            "{} of {} DVL reports are outliers to the fit ({:.0} %; at most {:.0} % are \
             credible as outliers): the camera and the DVL disagree throughout, not in a few \
             reports. Likely causes: a drifting clock, camera poses of another body or in the \
             wrong frame, or a DVL log of another recording",
            dvl_robust.outliers,
            dvl_robust.factors,
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
    let drift = match &pose_only {
        // At the stated weights: a drifting clock makes the ends of the recording look like
        // outliers to a constant offset, and down-weighting them would hide the drift.
        Some(t) => drift_check(t, &obs, &idx, &params, model_offset_std)?,
        None => None,
    };
    if let Some(d) = &drift
        && d.significant
    {
        warnings.push(format!(
            "the clock offset drifts: {:.4} s in the first third of the recording and {:.4} s in \
             the last ({:+.1} ms, {:.1} standard deviations), about {:+.0} ppm; the result assumes \
             a constant offset (synchronise the clocks, or calibrate shorter recordings)",
            d.first_third_s,
            d.last_third_s,
            1e3 * (d.last_third_s - d.first_third_s),
            (d.last_third_s - d.first_third_s).abs() / d.difference_std_s,
            d.drift_ppm
        ));
    }
    let trajectory = traj.report().clone();
    clock.done("checks and verdicts");
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
        start,
        fitted: traj,
        observations: obs,
        used: idx,
        robust: Robustness {
            loss: opts.loss,
            dvl: dvl_robust,
            poses: pose_robust,
            dvl_weights,
            pose_weights,
        },
        whiteness,
        halves,
        priors,
        lever_arm_from_default_prior,
        stage_seconds: clock.stages,
    })
}

/// Stages 2 and 3: the parameters the refinement starts from. For UIC the clock offset and
/// scale from speed magnitudes ([`estimate_offset`]), then rotation, lever arm and scale in closed
/// form at that offset ([`closed_form()`]); for BCD and fixed extrinsics the user's guess. The
/// offset search's notes go to `warnings`. Also returns how many velocity spikes were left out
/// of the initialisation.
pub fn initialise(
    traj: &Trajectory,
    obs: &[DvlObs],
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<(CalibrationParams, Option<InitReport>, usize)> {
    // A DVL that measured nothing explains every later failure: say so first.
    let still = obs.iter().filter(|o| o.v.norm() < 1e-4).count();
    if !obs.is_empty() && still == obs.len() {
        return Err(Error::Input(format!(
            "the DVL reports zero velocity in all {} samples used: it measured no motion (out \
             of the water, no bottom lock, or a log of a vehicle at rest); there is nothing to \
             calibrate against",
            obs.len()
        )));
    }
    // Velocities that jump away from their neighbours are left out of the initialisation: the
    // speed search and the closed form are least squares and would follow them.
    let (screened, keep) = screen_spikes(obs, opts);
    let spikes_screened = obs.len() - keep.len();
    let obs = &screened[..];
    let (params, init) = match &opts.method {
        Method::Uic => {
            let mut off = estimate_offset(traj, obs, &opts.offset)?;
            warnings.extend(off.notes.iter().cloned());
            for c in off.calm.iter_mut() {
                *c = keep[*c];
            }
            let idx = usable(traj, obs, off.offset, 0.0);
            let rows = closed_form_rows(traj, obs, &idx, off.offset)?;
            let cf = trimmed_closed_form(&rows, opts.bias_corrected)?;
            let params = CalibrationParams {
                time_offset_s: off.offset,
                ..cf.params
            };
            (
                params,
                Some(InitReport {
                    offset: off,
                    closed_form: cf,
                    params,
                }),
            )
        }
        Method::Bcd(g) => (clock_checked(traj, obs, opts, g, warnings), None),
        Method::Fixed {
            guess,
            estimate_offset: true,
        } => (clock_checked(traj, obs, opts, guess, warnings), None),
        Method::Fixed { guess, .. } => (*guess, None),
    };
    Ok((params, init, spikes_screened))
}

/// Most twist covariances the closed form's rows are given from (see [`closed_form_rows`]).
const CLOSED_FORM_COVARIANCES: usize = 4096;

/// The closed form's rows of the samples `idx` at the clock offset `offset`: each sample's DVL
/// velocity and the camera's twist at its camera time, with a twist covariance.
///
/// The closed form uses the covariances only through their sum (the bias term) and their mean
/// (the angular rate's noise variance), and a covariance costs several times a twist. Up to
/// [`CLOSED_FORM_COVARIANCES`] samples every row gets its own. Beyond that the rows are cut
/// into that many runs of consecutive samples and every row of a run is given the covariance
/// at one member of the run, at a place that moves irregularly from run to run: sums over the
/// rows then estimate the exact ones closely, however the sample times fall between the knots
/// (the covariance changes with that phase, and a regular stride could keep hitting one
/// phase), and the covariance's slow changes along the recording (down-weighted poses, gaps)
/// still show run by run. The cost stops growing with the recording.
fn closed_form_rows(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    offset: f64,
) -> Result<Vec<ClosedFormRow>> {
    let n = idx.len();
    let runs = n.min(CLOSED_FORM_COVARIANCES);
    let covariances: Vec<nalgebra::Matrix6<f64>> = crate::parallel::map_indices(runs, 256, |r| {
        let (a, b) = (r * n / runs, (r + 1) * n / runs);
        // The member at the fractional part of r times the golden ratio of the run (a Weyl
        // sequence: spread evenly and never periodic, so the members fall at every phase).
        let at = ((r as f64 * GOLDEN_RATIO).fract() * (b - a) as f64) as usize;
        let j = a + at.min(b - a - 1);
        let q = traj.query(obs[idx[j]].t + offset)?;
        Ok(q.twist_cov.unwrap_or_else(nalgebra::Matrix6::zeros))
    })
    .into_iter()
    .collect::<Result<_>>()?;
    crate::parallel::map_indices(n, 2048, |j| {
        let i = idx[j];
        // The run holding row j: the last r with r n / runs <= j.
        let r = ((j + 1) * runs).div_ceil(n) - 1;
        Ok(ClosedFormRow {
            v_dvl: obs[i].v,
            twist: traj.twist(obs[i].t + offset)?,
            twist_cov: covariances[r],
        })
    })
    .into_iter()
    .collect()
}

/// `(1 + sqrt 5) / 2`.
const GOLDEN_RATIO: f64 = 1.618_033_988_749_895;

/// The observations without the velocity spikes [`robust::velocity_spikes`] finds (none are
/// removed under the least-squares loss), and the index in `obs` of each kept one.
fn screen_spikes(obs: &[DvlObs], opts: &CalibOptions) -> (Vec<DvlObs>, Vec<usize>) {
    let spikes = if opts.loss == Loss::L2 {
        Vec::new()
    } else {
        let t: Vec<f64> = obs.iter().map(|o| o.t).collect();
        let v: Vec<Vector3<f64>> = obs.iter().map(|o| o.v).collect();
        robust::velocity_spikes(&t, &v, SPIKE_HALF_WINDOW, SPIKE_FACTOR, SPIKE_FLOOR_MPS)
    };
    // Screening more than a tenth would be judging the motion, not spikes.
    if spikes.is_empty() || spikes.len() * 10 > obs.len() {
        return (obs.to_vec(), (0..obs.len()).collect());
    }
    let mut keep = Vec::with_capacity(obs.len() - spikes.len());
    let mut k = 0;
    for i in 0..obs.len() {
        if spikes.get(k) == Some(&i) {
            k += 1;
        } else {
            keep.push(i);
        }
    }
    (keep.iter().map(|&i| obs[i].clone()).collect(), keep)
}

/// Reports on each side of a DVL velocity that the spike screen compares it with.
const SPIKE_HALF_WINDOW: usize = 3;
/// A spike deviates from its neighbours' median by this many times the median deviation...
const SPIKE_FACTOR: f64 = 8.0;
/// ...and by at least this much, m/s.
const SPIKE_FLOOR_MPS: f64 = 0.02;

/// The closed form, solved again without the rows whose residual is more than five robust
/// standard deviations out (bad twists from bad poses, spikes the screen missed) when they are
/// few (at most a fifth).
fn trimmed_closed_form(rows: &[ClosedFormRow], bias_corrected: bool) -> Result<ClosedForm> {
    let cf = closed_form(rows, bias_corrected)?;
    let d: Vec<f64> = rows
        .iter()
        .map(|r| (r.v_dvl - predict(&cf.params, &r.twist)).norm())
        .collect();
    let mut sorted = d.clone();
    sorted.sort_by(f64::total_cmp);
    // The median norm of a 3-D standard normal vector is 1.538.
    let sigma = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0) / 1.538;
    let kept: Vec<ClosedFormRow> = rows
        .iter()
        .zip(&d)
        .filter(|&(_, &x)| x <= 5.0 * sigma)
        .map(|(r, _)| r.clone())
        .collect();
    if kept.len() == rows.len() || kept.len() * 5 < rows.len() * 4 {
        return Ok(cf);
    }
    closed_form(&kept, bias_corrected)
}

/// The guess, with its clock offset replaced by the data's when the two are farther apart than
/// the fine search reaches (a guess without an offset, or clocks that moved): the refinement
/// only moves the offset locally. When the data give no clear offset the guess is kept.
fn clock_checked(
    traj: &Trajectory,
    obs: &[DvlObs],
    opts: &CalibOptions,
    guess: &CalibrationParams,
    warnings: &mut Vec<String>,
) -> CalibrationParams {
    match estimate_offset(traj, obs, &opts.offset) {
        Ok(off) if (off.offset - guess.time_offset_s).abs() > opts.offset.window_s => {
            warnings.push(format!(
                "the guess's clock offset {:.3} s is {:.3} s from the one the speeds give, \
                 {:.3} s: the refinement started from the latter",
                guess.time_offset_s,
                off.offset - guess.time_offset_s,
                off.offset
            ));
            CalibrationParams {
                time_offset_s: off.offset,
                ..*guess
            }
        }
        _ => *guess,
    }
}

/// The parameters a method estimates: all of them, clock offset and scale only (fixed
/// extrinsics with an estimated offset), or none (a fixed guess evaluated).
fn free_parameters(method: &Method) -> FreeParams {
    match method {
        Method::Fixed {
            estimate_offset: true,
            ..
        } => FreeParams {
            rotation: false,
            lever_arm: false,
            scale: true,
            time_offset: true,
        },
        Method::Fixed { .. } => FreeParams {
            rotation: false,
            lever_arm: false,
            scale: false,
            time_offset: false,
        },
        _ => FreeParams::ALL,
    }
}

/// What the refinement ends with.
struct Refined {
    trajectory: Trajectory,
    params: CalibrationParams,
    iterations: Vec<IterationRecord>,
}

/// Stage 4: rounds of a calibration update with the trajectory fixed and a state update with the
/// calibration fixed, until nothing changes (at most `rounds`); a Gauss-Newton step on the joint
/// problem after each unsettled round.
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
        let change = refine::change_in_std(&params, &up.params, &up.hessian, &mask);
        params = up.params;
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
            params = js.params;
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
    poses: &[PoseMeasurement],
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
    let mut fresh = Trajectory::fit(poses, &opts.fit)?;
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
    )?;
    let cost = |r: &Refined| -> Result<f64> {
        Ok(refine::linearize(&r.trajectory, obs, idx, &r.params)?.cost)
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
    state::joint_log_evidence(
        poses,
        &outcome.fitted,
        &outcome.observations,
        &outcome.used,
        &outcome.params,
        &free,
        qc_factor,
    )
}

/// The sanity checks of a result: residuals near the stated DVL noise, a physical velocity
/// scale, and a clock offset inside the offsets searched. Each failure names its likely cause.
fn sanity(
    p: &CalibrationParams,
    normalized_cost: f64,
    init: Option<&InitReport>,
    free: FreeParams,
    opts: &CalibOptions,
) -> Status {
    let lim = &opts.sanity;
    let mut reasons = Vec::new();
    let poor_match = init.is_some_and(|i| i.offset.alignment.is_poor());
    if normalized_cost.is_nan() || normalized_cost > lim.max_normalized_cost {
        reasons.push(format!(
            "the DVL residuals are {normalized_cost:.1} times the stated DVL noise after the \
             refinement (at most {} is credible): the camera and the DVL do not describe the same \
             motion. Likely causes: {}",
            lim.max_normalized_cost,
            if poor_match {
                "a DVL log of another recording, or clocks that do not overlap (the speeds \
                 correlate poorly at every clock offset)"
            } else if !free.rotation {
                fixed_guess_advice(free)
            } else {
                "camera poses in the wrong frame (T_cam_world given for T_world_cam, or poses of \
                 another body), or a DVL covariance far below the real noise (set --dvl-sigma)"
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
                 --offset-range that excludes the right offset)",
                p.time_offset_s
            ));
        }
    }
    if reasons.is_empty() {
        Status::Ok
    } else {
        Status::Failed(reasons)
    }
}

/// What a held guess that does not fit the data most likely means, and what to run instead.
fn fixed_guess_advice(free: FreeParams) -> &'static str {
    if free.time_offset {
        "the given extrinsics most likely do not fit this rig (a rotation or lever arm of another \
         mounting, or in another frame); estimate them with --method uic, or refine them with \
         --method bcd --init"
    } else {
        "the given calibration most likely does not fit this recording (a clock offset of another \
         recording, or extrinsics of another mounting); estimate the clock offset too with \
         --estimate-offset, or everything with --method uic"
    }
}

/// Stage 5: the covariance of the free parameters from the joint problem's information. When
/// the DVL residuals exceed the stated noise by half or more (`normalized_cost`), the covariance
/// is inflated by that factor and a warning says so (with a held guess, that the guess is the
/// likely cause).
fn uncertainty(
    jp: &JointProblem,
    assembled: AssembledJoint,
    (mask, free): (&[bool; NPARAM], FreeParams),
    normalized_cost: f64,
    warnings: &mut Vec<String>,
) -> Result<ParamMat> {
    let (mut covariance, _) = joint_covariance_of(jp, assembled, mask)?;
    if normalized_cost > 1.5 {
        warnings.push(if free.rotation {
            format!(
                "DVL residuals are {:.1} times the stated DVL variance; the standard deviations \
                 are inflated by that factor (set --dvl-sigma to the real noise)",
                normalized_cost
            )
        } else {
            format!(
                "DVL residuals are {:.1} times the stated DVL variance with the extrinsics held \
                 at the given values: {}",
                normalized_cost,
                fixed_guess_advice(free)
            )
        });
        covariance *= normalized_cost;
    }
    Ok(covariance)
}

/// Passes of reweighting after the least-squares refinement (each a full refinement, warm
/// started; they stop early once no weight moves by more than 0.01).
const IRLS_PASSES: usize = 4;

/// Squared whitened DVL residuals `r^T C^-1 r` of the samples `idx` (stated covariances), in
/// the order of `idx`.
fn whitened_residuals(
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

/// The trajectory fitted to the poses with the bad ones down-weighted: a fit, the poses'
/// residuals against it, and refits with the weights of the loss until the outliers found stop
/// changing (at most three fits). Returns the poses as weighted (their covariance divided by
/// the weight), the trajectory, what was done, and the weight of each pose.
fn robust_fit(
    poses: &[PoseMeasurement],
    opts: &CalibOptions,
) -> Result<(Vec<PoseMeasurement>, Trajectory, RobustSummary, Vec<f64>)> {
    let mut traj = Trajectory::fit(poses, &opts.fit)?;
    let mut weighted = poses.to_vec();
    let mut weights = vec![1.0; poses.len()];
    let mut summary = RobustSummary::default();
    if opts.loss == Loss::L2 {
        return Ok((weighted, traj, summary, weights));
    }
    let t: Vec<f64> = poses.iter().map(|p| p.t).collect();
    // The stated noise: the poses' own covariance, or the first fit's estimate of it (later
    // fits see every pose with a covariance and estimate nothing).
    let info = measurement_information(poses, traj.report().pose_sigma)?;
    let refit = FitOptions {
        pose_sigma: Some(traj.report().pose_sigma),
        ..opts.fit.clone()
    };
    for fit in 1..=3 {
        let s: Vec<f64> = poses
            .iter()
            .zip(traj.knots())
            .zip(&info)
            .map(|((m, k), w)| {
                let e = (m.pose.inverse() * k.pose).log();
                (e.transpose() * w * e)[0]
            })
            .collect();
        let (w, sum) = robust::weigh(opts.loss, &s, &t, 6, 1.0);
        let change = w
            .iter()
            .zip(&weights)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        summary = sum;
        if change < 0.01 || fit == 3 {
            break;
        }
        for (k, p) in weighted.iter_mut().enumerate() {
            weights[k] = w[k];
            let cov = info[k].try_inverse().ok_or_else(|| {
                Error::Numerical(format!(
                    "pose {} (t = {}): information not invertible",
                    k + 1,
                    p.t
                ))
            })?;
            p.cov = if w[k] < 1.0 {
                Some(cov / w[k].max(1e-12))
            } else {
                poses[k].cov
            };
        }
        traj = Trajectory::fit(&weighted, &refit)?;
    }
    Ok((weighted, traj, summary, weights))
}

/// What was done with outliers under `loss`, in words.
fn downweighted_by(loss: Loss) -> String {
    match loss {
        Loss::L2 => "kept at full weight (--loss l2): they pull the result".into(),
        l => format!("down-weighted by the {} loss", l.name()),
    }
}

/// The user's priors, with the broad default prior on the lever arm when none is given.
fn effective_priors(opts: &CalibOptions) -> Priors {
    let mut p = opts.priors;
    if p.lever_arm.is_none()
        && let Some(sigma_m) = opts.default_lever_arm_sigma_m
    {
        p.lever_arm = Some(prior::LeverArmPrior {
            lever_arm_cam_m: Vector3::zeros(),
            sigma_m,
        });
    }
    p
}

/// The autocorrelation of the DVL residuals of the samples `idx` that kept at least half their
/// weight, each axis divided by its stated standard deviation.
fn residual_whiteness(
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

/// Why the lever arm was held: the rotation is noise (no std computed), or the data's std.
fn unobserved_why(data_std_m: f64) -> String {
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

/// Fewest samples in each half for the halves check.
const HALF_MIN: usize = 50;
/// Each half's problem spans its samples' knots and this much more on either side, seconds...
const HALF_MARGIN_S: f64 = 5.0;
/// ... and at least this many knots more.
const HALF_MARGIN_KNOTS: usize = 50;

/// The two halves' estimates of the halves check, before the comparison.
struct HalfEstimates {
    split_t: f64,
    first: (CalibrationParams, ParamMat),
    second: (CalibrationParams, ParamMat),
}

/// Each half of the samples `idx` (by DVL time) calibrated on its own, for [`compare_halves`].
///
/// Each half's estimate is the calibration part of one Gauss-Newton step on its joint problem
/// (the half's DVL reports and the poses of its span, with a margin) from the result, and its
/// covariance that problem's marginal one at the result (both from one factorisation; times
/// `noise_factor`, the inflation of the whole's for residuals above the stated noise): a half
/// that does not excite a parameter (a calm first half) gives it a large variance and no false
/// alarm. The halves' normal equations are taken from the whole's, `whole`, assembled at the
/// result ([`part_linear_estimate`]): only the knots near the cut and at the ends of each
/// half's span are assembled again.
fn halves_estimates(
    jp: &JointProblem,
    whole: &AssembledJoint,
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    free: FreeParams,
    noise_factor: f64,
) -> Result<Option<HalfEstimates>> {
    let mask = free.mask();
    if !mask.iter().any(|&m| m) {
        return Ok(None);
    }
    let params = whole.params();
    let mut by_time: Vec<usize> = idx.to_vec();
    by_time.sort_by(|&a, &b| obs[a].t.total_cmp(&obs[b].t));
    let n = by_time.len() / 2;
    if n < HALF_MIN {
        return Ok(None);
    }
    let (first_idx, second_idx) = by_time.split_at(n);
    let times = traj.times();
    let half = |part: &[usize]| -> Result<(CalibrationParams, ParamMat)> {
        // The knots the half's samples fall between, and a margin on either side: further knots
        // carry only poses and the prior, whose pull on the half's parameters has died out.
        let (t0, t1) = part
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
                let t = obs[i].t + params.time_offset_s;
                (a.min(t), b.max(t))
            });
        let lo = times.partition_point(|&t| t < t0 - HALF_MARGIN_S);
        let hi = times.partition_point(|&t| t <= t1 + HALF_MARGIN_S);
        let lo = lo.saturating_sub(HALF_MARGIN_KNOTS);
        let hi = (hi + HALF_MARGIN_KNOTS).min(times.len());
        let jh = jp.part(part, lo..hi);
        let knots = &traj.knots()[lo..hi];
        let (p, cov) = part_linear_estimate(jp, whole, &jh, knots, lo..hi, &mask)?;
        Ok((p, cov * noise_factor))
    };
    let first = half(first_idx)?;
    let second = half(second_idx)?;
    Ok(Some(HalfEstimates {
        split_t: 0.5 * (obs[first_idx[n - 1]].t + obs[second_idx[0]].t),
        first,
        second,
    }))
}

/// Compares the halves' estimates; where they differ by more than three standard deviations
/// the rows and columns of `covariance` are scaled so that the difference is one (the variance
/// the difference itself estimates).
fn compare_halves(h: HalfEstimates, free: FreeParams, covariance: &mut ParamMat) -> HalvesCheck {
    let mask = free.mask();
    let ((first, c1), (second, c2)) = (h.first, h.second);
    let d = model::difference(&second, &first);
    let mut difference = [0.0; NPARAM];
    let mut difference_std = [f64::INFINITY; NPARAM];
    let mut inflation = [1.0; NPARAM];
    let mut compared = [false; NPARAM];
    for k in 0..NPARAM {
        difference[k] = d[k];
        let var = c1[(k, k)] + c2[(k, k)];
        if !(mask[k] && var.is_finite() && var > 0.0) {
            continue;
        }
        difference_std[k] = var.sqrt();
        // A half that determines a parameter far worse than half the data should (a calm half
        // and the lever arm) is no test of it: its estimate is as weak as its linearised
        // variance is unreliable.
        let even = 2.0 * covariance[(k, k)].max(0.0);
        compared[k] =
            c1[(k, k)] <= HALF_VARIANCE_LIMIT * even && c2[(k, k)] <= HALF_VARIANCE_LIMIT * even;
        let z = d[k].abs() / difference_std[k];
        if compared[k] && z > 3.0 {
            inflation[k] = z;
        }
    }
    for k in 0..NPARAM {
        for j in 0..NPARAM {
            covariance[(k, j)] *= inflation[k] * inflation[j];
        }
    }
    HalvesCheck {
        split_t: h.split_t,
        first,
        second,
        difference,
        difference_std,
        compared,
        inflation,
    }
}

/// A half whose variance of a parameter exceeds this many times what half the data would give
/// on average (twice the whole's) does not take part in the comparison of that parameter.
const HALF_VARIANCE_LIMIT: f64 = 9.0;

/// Names of the parameters in the covariance's order, with the factor to their display unit
/// and the unit (empty for the scale).
pub const PARAM_NAMES: [(&str, f64, &str); NPARAM] = [
    ("rotation about x", 57.295_779_513_082_32, "deg"),
    ("rotation about y", 57.295_779_513_082_32, "deg"),
    ("rotation about z", 57.295_779_513_082_32, "deg"),
    ("lever arm x", 1e3, "mm"),
    ("lever arm y", 1e3, "mm"),
    ("lever arm z", 1e3, "mm"),
    ("velocity scale", 1.0, ""),
    ("clock offset", 1e3, "ms"),
];

/// A warning per parameter whose halves disagree.
fn halves_notes(h: &HalvesCheck) -> Vec<String> {
    (0..NPARAM)
        .filter(|&k| h.inflation[k] > 1.0)
        .map(|k| {
            let (name, f, unit) = PARAM_NAMES[k];
            format!(
                "the two halves of the recording disagree on the {name}: {:+.4} {unit} apart, \
                 {:.1} standard deviations; its standard deviation is inflated {:.1} times to \
                 cover the difference (correlated DVL errors, motion the model does not capture, \
                 or a calibration that changed during the recording)",
                h.difference[k] * f,
                h.z(k),
                h.inflation[k]
            )
        })
        .collect()
}

/// Appends `reason` to a verdict's reason.
fn push_reason(v: &mut Verdict, reason: &str) {
    v.reason = if v.reason.is_empty() {
        reason.to_owned()
    } else {
        format!("{}; {reason}", v.reason)
    };
}

/// Verdicts of the parameters whose halves disagree, turned weak with the reason.
fn flag_inconsistent(v: &mut Verdicts, h: &HalvesCheck) {
    let groups: [(&mut Verdict, std::ops::Range<usize>, &str); 4] = [
        (&mut v.rotation, 0..3, "rotation"),
        (&mut v.lever_arm, 3..6, "lever arm"),
        (&mut v.velocity_scale, 6..7, "velocity scale"),
        (&mut v.time_offset, 7..8, "clock offset"),
    ];
    for (verdict, range, what) in groups {
        let worst = range.clone().map(|k| h.z(k)).fold(0.0, f64::max);
        if range.clone().any(|k| h.inflation[k] > 1.0) {
            verdict.ok = false;
            let reason = format!(
                "the {what} of the two halves of the recording differ by {worst:.1} standard \
                 deviations (the standard deviation was inflated to cover it)"
            );
            verdict.reason = if verdict.reason.is_empty() {
                reason
            } else {
                format!("{}; {reason}", verdict.reason)
            };
        }
    }
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
fn residuals_and_excitation(
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

fn param_std(c: &ParamMat) -> ParamStd {
    let s = |k: usize| c[(k, k)].max(0.0).sqrt();
    ParamStd {
        rotation_deg: Vector3::new(s(0), s(1), s(2)).map(f64::to_degrees),
        lever_arm_m: Vector3::new(s(3), s(4), s(5)),
        velocity_scale: s(6),
        time_offset_s: s(7),
    }
}

fn verdicts(
    std: &ParamStd,
    th: &WeakThresholds,
    ex: &Excitation,
    init: Option<&InitReport>,
    free: &[bool; NPARAM],
) -> Verdicts {
    let judge = |free: bool, worst: f64, limit: f64, what: &str, unit: &str, why: &str| {
        if !free {
            Verdict {
                ok: true,
                reason: "held fixed at the value given with --init".into(),
                by: DeterminedBy::Fixed,
            }
        } else if worst.is_finite() && worst <= limit {
            Verdict {
                ok: true,
                reason: String::new(),
                by: DeterminedBy::Data,
            }
        } else {
            Verdict {
                ok: false,
                reason: format!(
                    "{what} standard deviation {worst:.3e} {unit} exceeds {limit} {unit}: {why}"
                ),
                by: DeterminedBy::Data,
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
        &lever_why,
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
            "the camera moved along too few directions",
        ),
        lever_arm: lever,
        time_offset: judge(
            free[7],
            std.time_offset_s,
            th.time_offset_s,
            "clock offset",
            "s",
            offset_why,
        ),
        velocity_scale: judge(
            free[6],
            std.velocity_scale,
            th.velocity_scale,
            "velocity scale",
            "",
            "the camera moved too little",
        ),
    }
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
    let jp = JointProblem::new(poses, &traj, &obs, &idx)?;
    Ok(joint_covariance(&jp, &traj, truth, &FreeParams::ALL.mask())?.0)
}

#[cfg(test)]
mod prior_note_tests {
    use super::*;
    use crate::calib::prior::LeverArmPrior;
    use crate::calib::refine::ParamMat;
    use crate::lie::Se3;

    /// A lever arm estimated at 0.1 m on x with the data alone knowing it to `sd` m, and a prior
    /// at 0 with `sp` m: the notes of `prior_notes`.
    fn notes(sd: f64, sp: f64, estimate_x: f64) -> Vec<String> {
        let priors = Priors {
            lever_arm: Some(LeverArmPrior {
                lever_arm_cam_m: Vector3::zeros(),
                sigma_m: sp,
            }),
            rotation: None,
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
mod closed_form_rows_tests {
    use super::*;
    use crate::sim::{MotionKind, SimConfig, simulate};
    use nalgebra::{Matrix6, Vector6};

    /// 30 min of the lively motion, DVL at 8 Hz (14400 reports, three times
    /// [`CLOSED_FORM_COVARIANCES`]), its fitted trajectory, the observations and the usable ones.
    fn data() -> (Trajectory, Vec<DvlObs>, Vec<usize>, f64) {
        let cfg = SimConfig {
            duration_s: 1800.0,
            seed: 11,
            dvl_rate_hz: 8.0,
            motion: MotionKind::Sinusoid,
            ..SimConfig::default()
        };
        let sim = simulate(&cfg).expect("simulation");
        let traj = Trajectory::fit(&sim.poses, &FitOptions::default()).expect("fit");
        let (obs, _) = observations(&sim.dvl, &CalibOptions::default());
        let offset = sim.truth.time_offset_s;
        let idx = usable(&traj, &obs, offset, 0.0);
        (traj, obs, idx, offset)
    }

    fn bias(covs: impl Iterator<Item = Matrix6<f64>>) -> Matrix6<f64> {
        let s = Matrix6::from_diagonal(&Vector6::new(1.0, 1.0, 1.0, -1.0, -1.0, -1.0));
        covs.map(|c| s * c * s).sum()
    }

    #[test]
    fn rows_carry_exact_twists_and_covariances_that_sum_to_the_exact_bias() {
        let (traj, obs, idx, offset) = data();
        assert!(idx.len() > 3 * CLOSED_FORM_COVARIANCES, "{}", idx.len());
        let exact: Vec<_> = idx
            .iter()
            .map(|&i| traj.query(obs[i].t + offset).expect("query"))
            .collect();
        // Up to the limit every row has its own covariance, to the last bit.
        let few = &idx[..3000];
        let rows = closed_form_rows(&traj, &obs, few, offset).expect("rows");
        for (r, q) in rows.iter().zip(&exact) {
            assert_eq!(r.twist, q.twist);
            assert_eq!(Some(r.twist_cov), q.twist_cov);
        }
        // Beyond it the twists are still every row's own, and the bias term (the sum of the
        // covariances) is within a percent of the exact one (0.04 % here).
        let rows = closed_form_rows(&traj, &obs, &idx, offset).expect("rows");
        assert!(rows.iter().zip(&exact).all(|(r, q)| r.twist == q.twist));
        let shared = rows
            .iter()
            .zip(&exact)
            .filter(|(r, q)| Some(r.twist_cov) != q.twist_cov)
            .count();
        assert!(shared > idx.len() / 2, "{shared} rows share a covariance");
        let b_rows = bias(rows.iter().map(|r| r.twist_cov));
        let b_exact = bias(exact.iter().map(|q| q.twist_cov.expect("covariance")));
        let rel = (b_rows - b_exact).norm() / b_exact.norm();
        assert!(rel < 0.01, "bias term off by {rel}");
        // Every fourth report (8 Hz against knots at 10 Hz) falls at one phase between the
        // knots: a regular stride of 4 misses by 9 to 28 % here.
        for phase in 0..4 {
            let strided = bias(
                exact
                    .iter()
                    .skip(phase)
                    .step_by(4)
                    .map(|q| q.twist_cov.expect("covariance")),
            ) * 4.0;
            let off = (strided - b_exact).norm() / b_exact.norm();
            assert!(off > 5.0 * rel, "phase {phase}: {off} against {rel}");
        }
        // The angular rate's noise variance, the mean of the angular diagonal.
        let w = |c: &Matrix6<f64>| (c[(3, 3)] + c[(4, 4)] + c[(5, 5)]) / 3.0;
        let m_rows: f64 = rows.iter().map(|r| w(&r.twist_cov)).sum::<f64>();
        let m_exact: f64 = exact
            .iter()
            .map(|q| w(&q.twist_cov.expect("cov")))
            .sum::<f64>();
        assert!(
            ((m_rows - m_exact) / m_exact).abs() < 0.01,
            "{m_rows} vs {m_exact}"
        );
    }
}
