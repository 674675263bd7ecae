//! What a calibration run produced: the estimate with its covariance and standard deviations,
//! a verdict per parameter, the counts of the data used, what the robust loss did, the checks
//! of the recording's parts, and whether the result can be trusted.

use std::ops::Range;

use nalgebra::Vector3;

use super::closed_form::{ClosedForm, RotationSearch};
use super::given::Contradiction;
use super::model::{DvlObs, NPARAM};
use super::noise::NoiseCheck;
use super::offset::OffsetResult;
use super::options::Method;
use super::prior::Priors;
use super::robust::{Loss, RobustSummary};
use super::update::ParamMat;
use super::whiteness::Whiteness;
use crate::trajectory::{FitReport, Trajectory};
use crate::types::CalibrationParams;

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

    /// A failure with `cause` (the cause the other reasons only show symptoms of) as its first
    /// reason, also when nothing else failed: the cause alone makes the result untrustworthy.
    pub fn failed_first_by(self, cause: Option<String>) -> Status {
        match (self, cause) {
            (Status::Failed(r), Some(c)) => Status::Failed(std::iter::once(c).chain(r).collect()),
            (Status::Ok, Some(c)) => Status::Failed(vec![c]),
            (s, None) => s,
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

/// The DVL clock's drift, estimated with the calibration: `t_cam = t_dvl + time_offset_s +
/// 1e-6 ppm (t_dvl - reference_t_s)`, the offset being the one at the reference.
#[derive(Clone, Debug, PartialEq)]
pub struct ClockDrift {
    /// The drift, ppm (parts per million of DVL-clock time).
    pub ppm: f64,
    /// Its standard deviation, ppm (inflated as the other parameters' are for residuals beyond
    /// the stated noise).
    pub std_ppm: f64,
    /// The reference DVL time, s (relative to the run's epoch): the middle of the valid reports.
    pub reference_t_s: f64,
    /// The last Gauss-Newton correction of the drift, ppm (the estimate has settled when it is
    /// a small part of the standard deviation).
    pub last_step_ppm: f64,
    /// Calibrations run, each at the drift the one before it found.
    pub rounds: usize,
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

/// Why the data left a parameter weak, as a value (the words are in [`Verdict::reason`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeakCause {
    /// The camera's angular velocity is mostly noise (its least excited axis): the lever arm
    /// was held at the broad default prior.
    RotationRateNoise,
    /// The camera rotated too little for the data to determine the parameter (the lever arm,
    /// also when held at the default prior for the data's large standard deviation).
    LittleRotation,
    /// The camera moved along too few directions (the rotation).
    FewDirections,
    /// The speed changed too little (the clock offset).
    LittleSpeedChange,
    /// The camera moved too little (the velocity scale).
    LittleMotion,
    /// The value comes mainly from the user's prior.
    UserPrior,
    /// The rig rotated about at most one axis (the IMU's rotation; the lever arm along that
    /// axis).
    FewRotationAxes,
    /// The rotation rate varied too little (the IMU's clock offset).
    SteadyRotationRate,
    /// The motion repeats, so other clock offsets align the gyro's rates with the camera's
    /// about as well (the IMU's clock offset).
    RepeatingMotion,
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
    /// What in the recording left it weak (`None` when ok or held fixed).
    pub cause: Option<WeakCause>,
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
    /// (see [`super::pose_gap_threshold_s`]).
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
    /// m, -, s; see [`super::model::difference`]); zero for held parameters.
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
    /// Whether the result passed the sanity checks ([`super::SanityLimits`]).
    pub status: Status,
    /// The clock offset of the first and the last third of the recording compared (when the
    /// offset was estimated and each third has enough samples).
    pub drift: Option<DriftCheck>,
    /// The clock drift, when it was estimated ([`super::CalibOptions::clock_drift`]).
    pub clock_drift: Option<ClockDrift>,
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
    /// The held parameters the data contradict (fixed extrinsics only), most explaining first.
    pub contradicted: Vec<Contradiction>,
    /// The DVL's noise as the recording shows it, against the stated noise; when applied, the
    /// reports (and `observations`) carry the stated covariances scaled by it.
    pub noise: NoiseCheck,
    /// The motion prior's jerk density along the recording ([`super::motion_prior`]); `None`
    /// when it was not chosen (a density given, the extrinsics held, or the option off).
    pub motion_prior: Option<MotionPriorCheck>,
    /// Wall time of each stage of the run, in order (a profile of the run; not part of the
    /// result, and different on every run).
    pub stage_seconds: Vec<(&'static str, f64)>,
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

/// Wall times of the stages of a run.
pub(crate) struct StageClock {
    last: std::time::Instant,
    pub(crate) stages: Vec<(&'static str, f64)>,
}

impl StageClock {
    pub(crate) fn start() -> Self {
        StageClock {
            last: std::time::Instant::now(),
            stages: Vec::new(),
        }
    }

    /// Ends the stage `name` (begun where the previous one ended).
    pub(crate) fn done(&mut self, name: &'static str) {
        let now = std::time::Instant::now();
        self.stages.push((name, (now - self.last).as_secs_f64()));
        self.last = now;
    }
}

/// The initialisation stage of UIC.
#[derive(Clone, Debug)]
pub struct InitReport {
    /// The clock offset and velocity scale from speed magnitudes.
    pub offset: OffsetResult,
    /// Rotation, lever arm and scale in closed form at that offset.
    pub closed_form: ClosedForm,
    /// The minimum of the DVL residuals over rotations, when it lies far from the closed form's
    /// rotation and the refinement started from it instead.
    pub rotation_search: Option<RotationSearch>,
    /// Parameters after initialisation (closed form with the searched offset, or the warm
    /// start's at that offset).
    pub params: CalibrationParams,
    /// How [`CalibOptions::warm_start`](super::options::CalibOptions::warm_start) was used.
    pub warm: WarmStartUse,
}

/// What became of a warm start ([`CalibOptions::warm_start`](super::options::CalibOptions)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WarmStartUse {
    /// None was given.
    #[default]
    None,
    /// The offset was searched near it and the refinement started from it.
    Started,
    /// The offset was searched near it, but it fitted the velocities clearly worse than the
    /// closed form, which started the refinement.
    OffsetOnly,
    /// The offset search near it ended on its window's edge: the whole search was run, and the
    /// better-fitting of the two starts the refinement.
    SearchedAgain,
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
    /// Second minus first, in the covariance's coordinates ([`super::model::difference`]).
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

/// One stretch of the recording with its own density factors.
#[derive(Clone, Debug, PartialEq)]
pub struct Stretch {
    /// First and last knot times of the stretch, seconds.
    pub span_s: (f64, f64),
    /// Its intervals between knots.
    pub intervals: Range<usize>,
    /// The factors on the jerk density, translational and rotational (1 where the density
    /// stayed constant).
    pub factor: [f64; 2],
    /// Standard deviations of their logarithms (penalised estimate).
    pub std_ln: [f64; 2],
    /// The stretch's redundancy per part, `m - t` (see the module documentation).
    pub redundancy: [f64; 2],
}

/// What the choice of the motion prior's density found.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionPriorCheck {
    /// The stretches with their factors (those estimated, whether kept or not).
    pub stretches: Vec<Stretch>,
    /// Whether the varying density was kept (`false`: the constant one, and its result).
    pub applied: bool,
    /// Refinements run under new densities.
    pub rounds: usize,
    /// Laplace log evidence of poses and DVL, varying density less constant.
    pub evidence_gain: f64,
    /// Effective number of the factors' parameters (the penalised fit's degrees of freedom).
    pub effective_parameters: f64,
}

impl MotionPriorCheck {
    /// The smallest and largest factor applied, translational and rotational (1 when none).
    pub fn factor_range(&self) -> [(f64, f64); 2] {
        let mut out = [(1.0, 1.0); 2];
        if !self.applied {
            return out;
        }
        for (part, range) in out.iter_mut().enumerate() {
            *range = self
                .stretches
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(lo, hi), s| {
                    (lo.min(s.factor[part]), hi.max(s.factor[part]))
                });
        }
        out
    }

    /// [`MotionPriorCheck::factor_range`] as `[v_min, v_max, w_min, w_max]`.
    pub fn factor_range_flat(&self) -> Vec<f64> {
        let [t, r] = self.factor_range();
        vec![t.0, t.1, r.0, r.1]
    }
}
