//! The calibration result file (YAML).
//!
//! Keys, in order: `status` (`ok` or `failed`) and `failure` (the reasons, when failed), then
//! `T_cam_dvl` (4x4, rows), `T_dvl_cam` (its inverse),
//! `quaternion_cam_dvl_xyzw`, `lever_arm_cam_m` (the translation of `T_cam_dvl`),
//! `time_offset_s` (`t_cam = t_dvl + time_offset_s`), `velocity_scale`, with `--clock-drift`
//! `clock_drift_ppm` and `clock_reference_t_dvl_s` (`t_cam = t_dvl + time_offset_s + 1e-6
//! clock_drift_ppm (t_dvl - clock_reference_t_dvl_s)`), with an IMU calibrated `T_cam_imu`,
//! `imu_time_offset_s` (`t_cam = t_imu + imu_time_offset_s`), `imu_gravity_world_mps2` and
//! `imu_bias_start` (the IMU's std and verdicts under `imu` in `std` and `observability`),
//! then the optional `std`,
//! `observability`, `info` and `provenance` sections.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Matrix3, Matrix4, Vector3};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::provenance::Provenance;
use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::types::CalibrationParams;

/// Tolerance of the rigidity and consistency checks of [`CalibrationFile::to_params`].
pub const RIGID_TOL: f64 = 1e-6;

/// Standard deviations of the estimated quantities. A quantity held fixed has none: its entry
/// is `null` (files of earlier versions wrote 0 for it; they read as they are).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationStd {
    /// Rotation, degrees, about the DVL frame's x, y, z axes (a left perturbation of
    /// `R_dvl_cam`, the estimator's coordinates); `None` when held fixed.
    #[serde(default)]
    pub rotation_deg: Option<[f64; 3]>,
    /// Lever arm, metres, camera frame; `None` when held fixed.
    #[serde(default)]
    pub lever_arm_m: Option<[f64; 3]>,
    /// Standard deviation of the clock offset `time_offset_s`, s; `None` when held fixed.
    #[serde(default)]
    pub time_offset_s: Option<f64>,
    /// Standard deviation of the DVL velocity scale factor (dimensionless); `None` when held
    /// fixed.
    #[serde(default)]
    pub velocity_scale: Option<f64>,
    /// Standard deviation of `clock_drift_ppm`, ppm, when the drift was estimated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock_drift_ppm: Option<f64>,
    /// The IMU's, when one was calibrated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu: Option<ImuStd>,
}

/// Standard deviations of the IMU's calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuStd {
    /// Rotation of `T_cam_imu`, degrees, about the IMU frame's x, y, z axes (a right
    /// perturbation of `R_cam_imu`).
    pub rotation_deg: [f64; 3],
    /// Lever arm `p_cam_imu`, metres, camera frame.
    pub lever_arm_m: [f64; 3],
    /// `imu_time_offset_s`, s.
    pub time_offset_s: f64,
}

/// What determined each of the IMU's quantities, and how well.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuObservability {
    /// The rotation of `T_cam_imu`.
    pub rotation: Observability,
    /// Its translation.
    pub lever_arm: Observability,
    /// `imu_time_offset_s`.
    pub time_offset: Observability,
}

/// The IMU's biases at the start of the recording.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuBiasFile {
    /// Gyro bias, rad/s, IMU frame.
    pub gyro_radps: [f64; 3],
    /// Accelerometer bias, m/s^2, IMU frame.
    pub accel_mps2: [f64; 3],
}

/// What determined a quantity, and how well.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Observability {
    /// Estimated from the data, with a standard deviation within its limit. (Files of earlier
    /// versions also wrote `ok` for quantities held fixed.)
    Ok,
    /// Estimated, with a standard deviation above its limit: the data constrained it poorly.
    Weak,
    /// Not estimated: held at the value given (`--method fixed --init`); it has no standard
    /// deviation.
    Fixed,
    /// Determined by a prior rather than the data: the broad default prior on an unobserved
    /// lever arm, or a `--lever-arm-prior` / `--rotation-prior` the data barely sharpened. Its
    /// standard deviation is about the prior's.
    Prior,
}

impl Observability {
    /// The state in words, as the summary and `compare-calib` print it.
    pub fn words(self) -> &'static str {
        match self {
            Observability::Ok => "ok",
            Observability::Weak => "WEAK",
            Observability::Fixed => "fixed (from --init)",
            Observability::Prior => "from prior",
        }
    }
}

/// Observability of each estimated quantity.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObservabilityFlags {
    /// Observability of the rotation of `T_cam_dvl`.
    pub rotation: Observability,
    /// Observability of the lever arm (translation of `T_cam_dvl`).
    pub lever_arm: Observability,
    /// Observability of the clock offset `time_offset_s`.
    pub time_offset: Observability,
    /// Observability of the DVL velocity scale factor.
    pub velocity_scale: Observability,
    /// The IMU's, when one was calibrated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu: Option<ImuObservability>,
}

/// Free-form information about how the result was obtained.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CalibrationInfo {
    /// Name of the estimation method.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<String>,
    /// Iterations of the solver.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<u64>,
    /// Things the user should look at.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Other remarks.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// The run's figures (data counts, residual RMS, ...), written as keys of `info`.
    #[serde(flatten, skip_serializing_if = "RunFigures::is_empty")]
    pub figures: RunFigures,
}

/// One of the worst residuals of a run ([`RunFigures::dvl_worst_residuals`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorstResidual {
    /// Time of the report or pose, s, from the run's epoch (its own clock).
    pub t_s: f64,
    /// Squared whitened residual over the noise scale (dimensionless).
    pub variances_out: f64,
    /// The robust loss's weight, 0..1.
    pub weight: f64,
}

/// One clock segment of a DVL log whose clock stepped ([`RunFigures::clock_segments`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClockSegmentFigure {
    /// The first and last line (bag: message number) of its reports in the log.
    pub lines: [usize; 2],
    /// Its reports.
    pub samples: usize,
    /// Its span on its own clock, s.
    pub duration_s: f64,
    /// Its clock offset (`t_cam = t_dvl + time_offset_s` for its reports), when it was used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_offset_s: Option<f64>,
    /// That offset's standard deviation, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_offset_std_s: Option<f64>,
    /// Why it was left out, when it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub left_out: Option<String>,
    /// When the camera clock stepped: the first and last line of the segment's poses in the
    /// pose file (its offset is then on that segment's own camera clock).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_lines: Option<[usize; 2]>,
}

/// Declares [`RunFigures`]: one optional field per key of `info`, named as the key.
macro_rules! run_figures {
    ($( $(#[$doc:meta])* $key:ident: $ty:ty, )*) => {
        /// The figures of a calibration run that the result file records as keys of `info`
        /// (`docs/formats.md` lists them with their units). The pipeline fills them; a key whose
        /// field is `None` is left out. They are written in the alphabetical order of their keys,
        /// numbers in the shortest form that reads back (`.nan` where a figure is not a number).
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct RunFigures {
            $( $(#[$doc])* pub $key: Option<$ty>, )*
            /// Keys of `info` in a file read that are none of the above, or whose value is not
            /// of the type above (files of other versions), kept as they were read.
            pub other: BTreeMap<String, serde_yaml::Value>,
        }

        impl RunFigures {
            /// Every key the figures have, in the order of the fields.
            pub const KEYS: &'static [&'static str] = &[$(stringify!($key)),*];

            /// Whether no figure is given.
            pub fn is_empty(&self) -> bool {
                $( self.$key.is_none() && )* self.other.is_empty()
            }

            /// The figures as the keys and values of `info`.
            fn to_map(
                &self,
            ) -> std::result::Result<BTreeMap<String, serde_yaml::Value>, serde_yaml::Error> {
                let mut map = self.other.clone();
                $(
                    if let Some(v) = &self.$key {
                        map.insert(stringify!($key).to_owned(), serde_yaml::to_value(v)?);
                    }
                )*
                Ok(map)
            }

            /// The figures of the keys of `info` read from a file.
            fn from_map(mut map: BTreeMap<String, serde_yaml::Value>) -> RunFigures {
                RunFigures {
                    $( $key: take(&mut map, stringify!($key)), )*
                    other: map,
                }
            }
        }
    };
}

/// The value of `key`, removed from `map`, when it has the type asked for.
fn take<T: DeserializeOwned>(
    map: &mut BTreeMap<String, serde_yaml::Value>,
    key: &str,
) -> Option<T> {
    let value = serde_yaml::from_value(map.get(key)?.clone()).ok()?;
    map.remove(key);
    Some(value)
}

run_figures! {
    /// The IMU's sample file, when an IMU was calibrated.
    imu_file: String,
    /// IMU samples read.
    imu_samples: usize,
    /// Bins of IMU samples inside the camera's span, used.
    imu_bins_used: usize,
    /// Bins in all.
    imu_bins: usize,
    /// The factor the stated gyro noise density was multiplied by (at least 1).
    imu_noise_factor_gyro: f64,
    /// The factor the stated accelerometer noise density was multiplied by (at least 1).
    imu_noise_factor_accel: f64,
    /// Gauss-Newton iterations of the IMU's last solution.
    imu_iterations: usize,
    /// How far the IMU's rotation moves (deg, per axis) under a motion prior ten times
    /// looser: the prior's share of its std.
    imu_prior_shift_rotation_deg: [f64; 3],
    /// The same for the IMU's lever arm (m, per axis).
    imu_prior_shift_lever_arm_m: [f64; 3],
    /// The same for the IMU's clock offset (s).
    imu_prior_shift_time_offset_s: f64,
    /// DVL + IMU: how far the DVL's parameters move under a motion prior ten times looser,
    /// per parameter (the prior's share of their std).
    dvl_prior_shift_per_parameter: Vec<f64>,
    /// How the camchain was obtained, when the cameras were calibrated from the same images.
    camchain_source: String,
    /// Camera poses given.
    poses: usize,
    /// Camera poses dropped as held (repeats of the pose before them while the rig moved).
    poses_held_dropped: usize,
    /// Where the poses' covariances came from.
    pose_covariances: String,
    /// The board's printed size over the size its file states, as the stereo pair measured it.
    board_scale: f64,
    /// Its standard deviation.
    board_scale_std: f64,
    /// Whether the poses were solved with the board at the measured size.
    board_scale_applied: bool,
    /// Per camera, its focal length as the recording measures it over the camchain's (null
    /// when too few frames measured it).
    focal_length_scale: Vec<Option<f64>>,
    /// Their standard deviations.
    focal_length_scale_std: Vec<Option<f64>>,
    /// The DVL log read.
    dvl_log: String,
    /// The A50 time stamp used.
    dvl_time_source: String,
    /// Velocity reports in the log.
    dvl_velocity_reports: usize,
    /// Reports the A50 marked invalid.
    dvl_invalid: usize,
    /// Repeated reports.
    dvl_duplicates: usize,
    /// Malformed lines skipped.
    dvl_rejected_lines: usize,
    /// Reports given to the calibration.
    dvl_samples: usize,
    /// Reports the refinement used.
    dvl_used: usize,
    /// Reports whose covariance was replaced by the default noise.
    dvl_covariance_replaced: usize,
    /// Reports outside the camera trajectory's time span.
    dvl_outside_camera_span: usize,
    /// Reports falling in gaps between poses.
    dvl_in_pose_gaps: usize,
    /// The sound speed the DVL assumes, m/s.
    dvl_sound_speed_mps: f64,
    /// The water's sound speed, m/s.
    water_sound_speed_mps: f64,
    /// RMS of the DVL residuals per axis, m/s, DVL frame.
    dvl_residual_rms_mps: [f64; 3],
    /// Weighted squared residuals per degree of freedom.
    dvl_normalized_cost: f64,
    /// The DVL's variance as the joint estimate shows it over the variance its reports state
    /// (its variance component: 1 when stated right).
    dvl_variance_component: f64,
    /// Its standard deviation.
    dvl_variance_component_std: f64,
    /// The factor the DVL's stated variances were multiplied by before the final refinement.
    dvl_variance_applied: f64,
    /// The camera poses' variance as the joint estimate shows it over the variance stated.
    pose_variance_component: f64,
    /// Its standard deviation.
    pose_variance_component_std: f64,
    /// The factor the poses' stated variances were multiplied by before the final refinement.
    pose_variance_applied: f64,
    /// How many times the refinement ran again with the noise rescaled.
    noise_rounds: usize,
    /// The joint cost after each round.
    cost_per_iteration: Vec<f64>,
    /// RMS angular speed of the camera over the reports used, rad/s.
    rms_angular_speed_radps: f64,
    /// RMS speed of the camera over the reports used, m/s.
    rms_speed_mps: f64,
    /// RMS lever-arm velocity over RMS speed.
    lever_arm_velocity_ratio: f64,
    /// The trajectory prior's jerk power spectral density, translation then rotation.
    trajectory_qc: Vec<f64>,
    /// Whether the jerk density varies along the recording (chosen by the evidence).
    jerk_density_varying: bool,
    /// The smallest and largest factor on the jerk density over the stretches, translation then
    /// rotation (1 where it did not vary).
    jerk_density_factor_range: Vec<f64>,
    /// How the initial clock offset was found.
    clock_offset_init: String,
    /// The offset at which the speed series correlate best, s.
    clock_alignment_lag_s: f64,
    /// Their correlation there.
    clock_alignment_correlation: f64,
    /// The best other peak of the correlation, s.
    clock_alignment_second_lag_s: f64,
    /// Its correlation.
    clock_alignment_second_correlation: f64,
    /// Whether the two peaks are too close to tell apart.
    clock_alignment_ambiguous: bool,
    /// Slowly rotating reports the offset search used.
    calm_samples: usize,
    /// The robust loss.
    loss: String,
    /// Reports left out of the initialisation as velocity spikes.
    dvl_spikes_screened_from_init: usize,
    /// Reports the loss down-weighted as outliers.
    dvl_downweighted: usize,
    /// Poses the loss down-weighted as outliers.
    poses_downweighted: usize,
    /// The worst DVL reports.
    dvl_worst_residuals: Vec<WorstResidual>,
    /// The DVL clock's segments when it stepped or restarted (one clock offset each).
    clock_segments: Vec<ClockSegmentFigure>,
    /// The worst poses.
    poses_worst_residuals: Vec<WorstResidual>,
    /// The DVL noise the residuals show, over the stated variance.
    dvl_noise_over_stated_variance: f64,
    /// Integrated autocorrelation time of the DVL residuals per axis, samples.
    dvl_residual_autocorrelation_time_samples: Vec<f64>,
    /// Whether that time is beyond what white noise gives.
    dvl_residuals_correlated: bool,
    /// The factor the DVL information was divided by for it.
    dvl_information_divided_by: f64,
    /// Where the recording was split for the halves check, s, DVL clock.
    halves_split_dvl_time_s: f64,
    /// The halves' difference over its standard deviation, per parameter (NaN where not
    /// compared).
    halves_difference_in_std: Vec<f64>,
    /// The factor each standard deviation was inflated by for the halves' difference.
    halves_std_inflation: Vec<f64>,
    /// Whether the lever arm is the broad default prior's.
    lever_arm_from_default_prior: bool,
    /// The share of the DVL reports the result rests on.
    usable_fraction: f64,
    /// The clock offset of the recording's first third alone, s.
    clock_offset_first_third_s: f64,
    /// The same of the last third, s.
    clock_offset_last_third_s: f64,
    /// Their difference over the time between the thirds' middles, ppm.
    clock_drift_apparent_ppm: f64,
}

impl Serialize for RunFigures {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        self.to_map()
            .map_err(serde::ser::Error::custom)?
            .serialize(s)
    }
}

impl<'de> Deserialize<'de> for RunFigures {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        BTreeMap::<String, serde_yaml::Value>::deserialize(d).map(RunFigures::from_map)
    }
}

/// Whether a result can be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ResultStatus {
    /// Every sanity check passed.
    Ok,
    /// A sanity check failed; the file's `failure` says why. Do not mount a DVL with it.
    Failed,
}

/// The calibration result file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// `ok` or `failed` (absent from hand-written files and those of older versions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub status: Option<ResultStatus>,
    /// Why the calibration failed, one reason an entry (empty unless `status` is `failed`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failure: Vec<String>,
    /// `T_cam_dvl`: maps DVL-frame points into the camera frame; rows of the 4x4 matrix.
    #[serde(rename = "T_cam_dvl")]
    pub t_cam_dvl: [[f64; 4]; 4],
    /// `T_dvl_cam`, the inverse of `T_cam_dvl`.
    #[serde(rename = "T_dvl_cam")]
    pub t_dvl_cam: [[f64; 4]; 4],
    /// Rotation of `T_cam_dvl` as a unit quaternion `[x, y, z, w]`.
    pub quaternion_cam_dvl_xyzw: [f64; 4],
    /// The DVL origin in camera coordinates (translation of `T_cam_dvl`), metres.
    pub lever_arm_cam_m: [f64; 3],
    /// `t_cam = t_dvl + time_offset_s`.
    pub time_offset_s: f64,
    /// DVL velocity scale factor.
    pub velocity_scale: f64,
    /// The DVL clock's drift, ppm, when it was estimated: `t_cam = t_dvl + time_offset_s +
    /// 1e-6 clock_drift_ppm (t_dvl - clock_reference_t_dvl_s)`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock_drift_ppm: Option<f64>,
    /// The drift's reference time on the DVL clock, s (the log's own time base, e.g. Unix
    /// seconds): `time_offset_s` is the offset there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock_reference_t_dvl_s: Option<f64>,
    /// `T_cam_imu`, when an IMU was calibrated: maps IMU-frame points into the camera frame;
    /// rows of the 4x4 matrix.
    #[serde(rename = "T_cam_imu", default, skip_serializing_if = "Option::is_none")]
    pub t_cam_imu: Option<[[f64; 4]; 4]>,
    /// `t_cam = t_imu + imu_time_offset_s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_time_offset_s: Option<f64>,
    /// Gravity in the world (board) frame as the IMU measured it, m/s^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_gravity_world_mps2: Option<[f64; 3]>,
    /// The IMU's biases at the start of the recording.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_bias_start: Option<ImuBiasFile>,
    /// Standard deviations of the estimated quantities (optional `std` section).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std: Option<CalibrationStd>,
    /// Whether the data constrained each quantity well (optional `observability` section).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observability: Option<ObservabilityFlags>,
    /// How the result was obtained (optional `info` section).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub info: Option<CalibrationInfo>,
    /// Version, command line, time and input digests of the run (optional `provenance`
    /// section).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<Provenance>,
}

/// The rows of a 4x4 matrix, as the result file lists them.
pub fn rows(m: &Matrix4<f64>) -> [[f64; 4]; 4] {
    let mut r = [[0.0; 4]; 4];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = m[(i, j)];
        }
    }
    r
}

fn matrix(r: &[[f64; 4]; 4]) -> Matrix4<f64> {
    Matrix4::from_fn(|i, j| r[i][j])
}

fn max_abs(m: impl IntoIterator<Item = f64>) -> f64 {
    m.into_iter().fold(0.0, |a, x| a.max(x.abs()))
}

/// Checks that `m` is a rigid transform: finite, orthonormal rotation block with determinant
/// +1, last row `0 0 0 1`.
fn check_rigid(name: &str, m: &Matrix4<f64>) -> Result<Se3> {
    if m.iter().any(|x| !x.is_finite()) {
        return Err(Error::Input(format!("{name} has a non-finite entry")));
    }
    let last = max_abs([m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)] - 1.0]);
    if last > RIGID_TOL {
        return Err(Error::Input(format!(
            "{name} is not a rigid transform: its last row is not 0 0 0 1"
        )));
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let ortho = max_abs((r.transpose() * r - Matrix3::identity()).iter().copied());
    if ortho > RIGID_TOL {
        return Err(Error::Input(format!(
            "{name} is not a rigid transform: its rotation block is not orthonormal \
             (max |R^T R - I| = {ortho:.3e} > {RIGID_TOL:e})"
        )));
    }
    if r.determinant() < 0.0 {
        return Err(Error::Input(format!(
            "{name} is not a rigid transform: its rotation block is a reflection (det < 0)"
        )));
    }
    Ok(Se3::new(r, m.fixed_view::<3, 1>(0, 3).into_owned()))
}

impl CalibrationFile {
    /// The file contents for `p`, without the optional sections.
    pub fn from_params(p: &CalibrationParams) -> CalibrationFile {
        let t = &p.t_cam_dvl;
        CalibrationFile {
            status: None,
            failure: Vec::new(),
            t_cam_dvl: rows(&t.to_matrix()),
            t_dvl_cam: rows(&t.inverse().to_matrix()),
            quaternion_cam_dvl_xyzw: t.quaternion_xyzw(),
            lever_arm_cam_m: [t.trans.x, t.trans.y, t.trans.z],
            time_offset_s: p.time_offset_s,
            velocity_scale: p.velocity_scale,
            clock_drift_ppm: None,
            clock_reference_t_dvl_s: None,
            t_cam_imu: None,
            imu_time_offset_s: None,
            imu_gravity_world_mps2: None,
            imu_bias_start: None,
            std: None,
            observability: None,
            info: None,
            provenance: None,
        }
    }

    /// The calibration parameters, after checking that `T_cam_dvl` is a rigid transform
    /// (orthonormal rotation to [`RIGID_TOL`], last row `0 0 0 1`) consistent with `T_dvl_cam`,
    /// the quaternion and the lever arm, and that the time offset and a positive velocity scale
    /// are finite.
    pub fn to_params(&self) -> Result<CalibrationParams> {
        let t = check_rigid("T_cam_dvl", &matrix(&self.t_cam_dvl))?;
        let t_inv = check_rigid("T_dvl_cam", &matrix(&self.t_dvl_cam))?;
        let scale = 1.0 + t.trans.norm();
        let prod = (t_inv * t).to_matrix() - Matrix4::identity();
        if max_abs(prod.iter().copied()) > RIGID_TOL * scale {
            return Err(Error::Input(
                "T_dvl_cam is not the inverse of T_cam_dvl".to_string(),
            ));
        }
        let q = self.quaternion_cam_dvl_xyzw;
        let qn = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !qn.is_finite() || (qn - 1.0).abs() > RIGID_TOL {
            return Err(Error::Input(format!(
                "quaternion_cam_dvl_xyzw is not a unit quaternion (norm {qn})"
            )));
        }
        let rq = Se3::from_quaternion_xyzw(&q, Vector3::zeros()).rot;
        if max_abs((rq - t.rot).iter().copied()) > RIGID_TOL {
            return Err(Error::Input(
                "quaternion_cam_dvl_xyzw does not match the rotation of T_cam_dvl".to_string(),
            ));
        }
        let arm = Vector3::from(self.lever_arm_cam_m);
        if !arm.iter().all(|x| x.is_finite())
            || max_abs((arm - t.trans).iter().copied()) > RIGID_TOL * scale
        {
            return Err(Error::Input(
                "lever_arm_cam_m does not match the translation of T_cam_dvl".to_string(),
            ));
        }
        if !self.time_offset_s.is_finite() {
            return Err(Error::Input("time_offset_s is not finite".to_string()));
        }
        if !(self.velocity_scale.is_finite() && self.velocity_scale > 0.0) {
            return Err(Error::Input(format!(
                "velocity_scale {} is not a positive number",
                self.velocity_scale
            )));
        }
        Ok(CalibrationParams {
            t_cam_dvl: t.renormalized(),
            time_offset_s: self.time_offset_s,
            velocity_scale: self.velocity_scale,
        })
    }
}

const HEADER: &str = "\
# dvlcal calibration result.
# T_cam_dvl maps DVL-frame points into the camera frame: p_cam = R_cam_dvl p_dvl + lever_arm_cam_m,
# so lever_arm_cam_m is the DVL origin in camera coordinates. Matrices are listed by rows.
# Clocks: t_cam = t_dvl + time_offset_s. Velocities: v_dvl = velocity_scale * R_dvl_cam * v_cam(DVL origin).
";

/// A YAML flow sequence of numbers (shortest digits that read back exactly).
fn flow(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

/// The file contents: a comment header, the main keys (matrices one row per line), then the
/// optional sections.
fn to_yaml(path: &Path, c: &CalibrationFile) -> Result<String> {
    let mut s = String::from(HEADER);
    if let Some(st) = c.status {
        let _ = writeln!(
            s,
            "status: {}",
            match st {
                ResultStatus::Ok => "ok",
                ResultStatus::Failed => "failed",
            }
        );
    }
    if !c.failure.is_empty() {
        #[derive(Serialize)]
        struct Failure<'a> {
            failure: &'a [String],
        }
        let text = serde_yaml::to_string(&Failure {
            failure: &c.failure,
        })
        .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
        s.push_str(&text);
    }
    for (key, m) in [("T_cam_dvl", &c.t_cam_dvl), ("T_dvl_cam", &c.t_dvl_cam)] {
        let _ = writeln!(s, "{key}:");
        for row in m {
            let _ = writeln!(s, "  - {}", flow(row));
        }
    }
    let _ = writeln!(
        s,
        "quaternion_cam_dvl_xyzw: {}",
        flow(&c.quaternion_cam_dvl_xyzw)
    );
    let _ = writeln!(s, "lever_arm_cam_m: {}", flow(&c.lever_arm_cam_m));
    let _ = writeln!(s, "time_offset_s: {:?}", c.time_offset_s);
    let _ = writeln!(s, "velocity_scale: {:?}", c.velocity_scale);
    if let Some(d) = c.clock_drift_ppm {
        let _ = writeln!(s, "clock_drift_ppm: {d:?}");
    }
    if let Some(t) = c.clock_reference_t_dvl_s {
        let _ = writeln!(s, "clock_reference_t_dvl_s: {t:?}");
    }
    if let Some(m) = &c.t_cam_imu {
        let _ = writeln!(s, "T_cam_imu:");
        for row in m {
            let _ = writeln!(s, "  - {}", flow(row));
        }
    }
    if let Some(t) = c.imu_time_offset_s {
        let _ = writeln!(s, "imu_time_offset_s: {t:?}");
    }
    if let Some(g) = &c.imu_gravity_world_mps2 {
        let _ = writeln!(s, "imu_gravity_world_mps2: {}", flow(g));
    }
    if let Some(b) = &c.imu_bias_start {
        let _ = writeln!(s, "imu_bias_start:");
        let _ = writeln!(s, "  gyro_radps: {}", flow(&b.gyro_radps));
        let _ = writeln!(s, "  accel_mps2: {}", flow(&b.accel_mps2));
    }

    #[derive(Serialize)]
    struct Optional<'a> {
        #[serde(skip_serializing_if = "Option::is_none")]
        std: &'a Option<CalibrationStd>,
        #[serde(skip_serializing_if = "Option::is_none")]
        observability: &'a Option<ObservabilityFlags>,
        #[serde(skip_serializing_if = "Option::is_none")]
        info: &'a Option<CalibrationInfo>,
        #[serde(skip_serializing_if = "Option::is_none")]
        provenance: &'a Option<Provenance>,
    }
    if c.std.is_some() || c.observability.is_some() || c.info.is_some() || c.provenance.is_some() {
        let tail = serde_yaml::to_string(&Optional {
            std: &c.std,
            observability: &c.observability,
            info: &c.info,
            provenance: &c.provenance,
        })
        .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
        s.push_str(&tail);
    }
    Ok(s)
}

/// Writes the calibration file with a comment header explaining the conventions, atomically.
/// Non-finite numbers in the main keys are refused.
pub fn write_calib_yaml(path: &Path, c: &CalibrationFile) -> Result<()> {
    let scalars = [c.time_offset_s, c.velocity_scale];
    let mut main = c
        .t_cam_dvl
        .iter()
        .chain(c.t_dvl_cam.iter())
        .flatten()
        .chain(c.quaternion_cam_dvl_xyzw.iter())
        .chain(c.lever_arm_cam_m.iter())
        .chain(scalars.iter());
    if main.any(|x| !x.is_finite()) {
        return Err(super::non_finite(path, "a calibration value".to_string()));
    }
    let mut imu = c
        .t_cam_imu
        .iter()
        .flatten()
        .flatten()
        .chain(c.imu_time_offset_s.iter());
    if imu.any(|x| !x.is_finite()) {
        return Err(super::non_finite(
            path,
            "an IMU calibration value".to_string(),
        ));
    }
    let text = to_yaml(path, c)?;
    super::write_atomic(path, text.as_bytes())
}

/// Reads a calibration file and checks it with [`CalibrationFile::to_params`]. Errors name the
/// file, and the line where the YAML parser reports one.
pub fn read_calib_yaml(path: &Path) -> Result<CalibrationFile> {
    let text = crate::files::read_text(path)?;
    parse_calib_yaml(&text, path)
}

/// Whether the text of a result file holds the IMU's keys and none of the DVL's (a camera +
/// IMU result, [`super::imu_result`]), from its top-level keys.
pub fn is_imu_only_text(text: &str) -> bool {
    let top = |k: &str| text.lines().any(|l| l.starts_with(k));
    top("T_cam_imu:") && !top("T_cam_dvl:")
}

/// Parses the text of a calibration file as [`read_calib_yaml`] does; `path` names the file in
/// messages.
pub fn parse_calib_yaml(text: &str, path: &Path) -> Result<CalibrationFile> {
    if is_imu_only_text(text) {
        return Err(Error::Input(format!(
            "{}: a camera + IMU result (T_cam_imu, no T_cam_dvl): it holds no DVL calibration, \
             which is what is read here",
            path.display()
        )));
    }
    if text.lines().any(|l| l.starts_with("T_imu_dvl:")) {
        return Err(Error::Input(format!(
            "{}: a DVL + IMU result (T_imu_dvl, no camera): it holds the DVL relative to the \
             IMU, not to a camera, which is what is read here",
            path.display()
        )));
    }
    let c: CalibrationFile = serde_yaml::from_str(text).map_err(|e| match e.location() {
        Some(loc) => Error::parse(path, loc.line(), format!("column {}: {e}", loc.column())),
        None => Error::Input(format!("{}: {e}", path.display())),
    })?;
    c.to_params()
        .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
    Ok(c)
}

/// The forms a guess of the extrinsics may take (`--init`, `--guess`): one rotation (a
/// `T_cam_dvl` matrix, a quaternion, or roll-pitch-yaw), a lever arm unless `T_cam_dvl` carries
/// it, and optionally the clock offset and the scale.
#[derive(Deserialize)]
struct GuessFile {
    #[serde(rename = "T_cam_dvl")]
    t_cam_dvl: Option<[[f64; 4]; 4]>,
    quaternion_cam_dvl_xyzw: Option<[f64; 4]>,
    rpy_cam_dvl_deg: Option<[f64; 3]>,
    lever_arm_cam_m: Option<[f64; 3]>,
    time_offset_s: Option<f64>,
    velocity_scale: Option<f64>,
    status: Option<ResultStatus>,
}

/// `R = Rz(yaw) Ry(pitch) Rx(roll)` from `[roll, pitch, yaw]` in degrees (the ROS convention:
/// rotations about the fixed x, y and z axes, in that order).
pub fn rotation_from_rpy_deg(rpy: &[f64; 3]) -> Matrix3<f64> {
    let [r, p, y] = rpy.map(f64::to_radians);
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, r.cos(), -r.sin(), 0.0, r.sin(), r.cos());
    let ry = Matrix3::new(p.cos(), 0.0, p.sin(), 0.0, 1.0, 0.0, -p.sin(), 0.0, p.cos());
    let rz = Matrix3::new(y.cos(), -y.sin(), 0.0, y.sin(), y.cos(), 0.0, 0.0, 0.0, 1.0);
    rz * ry * rx
}

/// Reads a guess of the calibration: a whole result file, or a minimal YAML with `T_cam_dvl`
/// alone, or `quaternion_cam_dvl_xyzw` and `lever_arm_cam_m`, or `rpy_cam_dvl_deg` (roll, pitch,
/// yaw of `R_cam_dvl`, degrees, `Rz(yaw) Ry(pitch) Rx(roll)`) and `lever_arm_cam_m`. A missing
/// `time_offset_s` is 0 and a missing `velocity_scale` is 1. When several forms of the rotation
/// or lever arm are given they must agree. A result file with `status: failed` is refused.
pub fn read_calibration_guess(path: &Path) -> Result<CalibrationParams> {
    let text = crate::files::read_text(path)?;
    parse_calibration_guess(&text, path)
}

/// Parses the text of a calibration guess as [`read_calibration_guess`] does; `path` names the
/// file in messages.
pub fn parse_calibration_guess(text: &str, path: &Path) -> Result<CalibrationParams> {
    let g: GuessFile = serde_yaml::from_str(text).map_err(|e| match e.location() {
        Some(loc) => Error::parse(path, loc.line(), format!("column {}: {e}", loc.column())),
        None => Error::Input(format!("{}: {e}", path.display())),
    })?;
    let bad = |msg: String| Error::Input(format!("{}: {msg}", path.display()));
    if g.status == Some(ResultStatus::Failed) {
        return Err(bad(
            "is a failed calibration (status: failed): it cannot serve as a guess".into(),
        ));
    }
    let from_t = match &g.t_cam_dvl {
        Some(m) => Some(check_rigid("T_cam_dvl", &matrix(m)).map_err(|e| bad(e.to_string()))?),
        None => None,
    };
    let from_q = match g.quaternion_cam_dvl_xyzw {
        Some(q) => {
            let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
            if !(n.is_finite() && n > 0.5 && n < 1.5) {
                return Err(bad(format!(
                    "quaternion_cam_dvl_xyzw has norm {n}: not a rotation"
                )));
            }
            Some(Se3::from_quaternion_xyzw(&q, Vector3::zeros()).rot)
        }
        None => None,
    };
    let from_rpy = match g.rpy_cam_dvl_deg {
        Some(a) if a.iter().all(|x| x.is_finite()) => Some(rotation_from_rpy_deg(&a)),
        Some(_) => return Err(bad("rpy_cam_dvl_deg has a non-finite angle".into())),
        None => None,
    };
    let rotations: Vec<(&str, Matrix3<f64>)> = [
        ("T_cam_dvl", from_t.map(|t| t.rot)),
        ("quaternion_cam_dvl_xyzw", from_q),
        ("rpy_cam_dvl_deg", from_rpy),
    ]
    .into_iter()
    .filter_map(|(n, r)| r.map(|r| (n, r)))
    .collect();
    let Some(&(first, rot)) = rotations.first() else {
        return Err(bad(
            "no rotation: give T_cam_dvl, or quaternion_cam_dvl_xyzw or rpy_cam_dvl_deg with \
             lever_arm_cam_m"
                .into(),
        ));
    };
    for (name, r) in &rotations[1..] {
        // Agreement to 1e-4 rad: a printed quaternion or angles with a few digits still match.
        let d = (r.transpose() * rot - Matrix3::identity()).norm();
        if d > 1e-4 {
            return Err(bad(format!("{name} and {first} give different rotations")));
        }
    }
    let arm = match (from_t, g.lever_arm_cam_m) {
        (Some(t), Some(a)) => {
            let a = Vector3::from(a);
            if (a - t.trans).norm() > 1e-6 * (1.0 + a.norm()) {
                return Err(bad(
                    "lever_arm_cam_m is not the translation of T_cam_dvl".into()
                ));
            }
            t.trans
        }
        (Some(t), None) => t.trans,
        (None, Some(a)) => Vector3::from(a),
        (None, None) => {
            return Err(bad(format!(
                "{first} gives the rotation; lever_arm_cam_m (the DVL origin in camera \
                 coordinates, m) is needed too"
            )));
        }
    };
    if !arm.iter().all(|x| x.is_finite()) {
        return Err(bad("lever_arm_cam_m is not finite".into()));
    }
    let time_offset_s = g.time_offset_s.unwrap_or(0.0);
    let velocity_scale = g.velocity_scale.unwrap_or(1.0);
    if !time_offset_s.is_finite() {
        return Err(bad("time_offset_s is not finite".into()));
    }
    if !(velocity_scale.is_finite() && velocity_scale > 0.0) {
        return Err(bad("velocity_scale must be positive".into()));
    }
    Ok(CalibrationParams {
        t_cam_dvl: Se3::new(rot, arm),
        time_offset_s,
        velocity_scale,
    })
}
