//! The result file of a camera + IMU calibration (no DVL log given): the IMU's keys of the
//! result file (`T_cam_imu`, `imu_time_offset_s`, gravity, the biases at the start, `std.imu`,
//! `observability.imu`) with `status`, `info` and `provenance`, and no DVL keys. The keys and
//! sections are those of [`super::calib_yaml`]'s result file, so a reader of the IMU's keys
//! reads either; a reader of the DVL's keys refuses this one with a message saying what it is
//! ([`super::calib_yaml::read_calib_yaml`]).

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::calib_yaml::{
    CalibrationFile, CalibrationInfo, ImuBiasFile, ImuObservability, ImuStd, ResultStatus,
};
use super::provenance::Provenance;
use super::result_text::{flow, read_result_text, write_result_text};
use crate::error::Result;

/// The `std` section of a camera + IMU result: the IMU's alone.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuOnlyStd {
    /// The IMU's standard deviations.
    pub imu: ImuStd,
}

/// The `observability` section of a camera + IMU result: the IMU's alone.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuOnlyObservability {
    /// The IMU's verdicts.
    pub imu: ImuObservability,
}

/// A camera + IMU result file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuResultFile {
    /// `ok` or `failed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub status: Option<ResultStatus>,
    /// Why the calibration failed (empty unless `status` is `failed`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failure: Vec<String>,
    /// `T_cam_imu`: maps IMU-frame points into the camera frame; rows of the 4x4 matrix.
    #[serde(rename = "T_cam_imu")]
    pub t_cam_imu: [[f64; 4]; 4],
    /// `t_cam = t_imu + imu_time_offset_s`.
    pub imu_time_offset_s: f64,
    /// Gravity in the world (board) frame as the IMU measured it, m/s^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_gravity_world_mps2: Option<[f64; 3]>,
    /// The IMU's biases at the start of the recording.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_bias_start: Option<ImuBiasFile>,
    /// The IMU's standard deviations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std: Option<ImuOnlyStd>,
    /// The IMU's verdicts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observability: Option<ImuOnlyObservability>,
    /// How the result was obtained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub info: Option<CalibrationInfo>,
    /// Version, command line, time and input digests of the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<Provenance>,
}

impl ImuResultFile {
    /// The IMU's keys of a result file `f` (its DVL keys left out); `None` when `f` holds no
    /// IMU calibration.
    pub fn from_calibration_file(f: &CalibrationFile) -> Option<ImuResultFile> {
        Some(ImuResultFile {
            status: f.status,
            failure: f.failure.clone(),
            t_cam_imu: f.t_cam_imu?,
            imu_time_offset_s: f.imu_time_offset_s?,
            imu_gravity_world_mps2: f.imu_gravity_world_mps2,
            imu_bias_start: f.imu_bias_start.clone(),
            std: f
                .std
                .as_ref()
                .and_then(|s| s.imu.clone())
                .map(|imu| ImuOnlyStd { imu }),
            observability: f
                .observability
                .as_ref()
                .and_then(|o| o.imu.clone())
                .map(|imu| ImuOnlyObservability { imu }),
            info: f.info.clone(),
            provenance: f.provenance.clone(),
        })
    }
}

const HEADER: &str = "\
# dvlcal calibration result: camera + IMU (no DVL log given, so no DVL keys).
# T_cam_imu maps IMU-frame points into the camera frame: p_cam = R_cam_imu p_imu + t_cam_imu.
# Matrices are listed by rows. Clocks: t_cam = t_imu + imu_time_offset_s.
";

/// Writes the camera + IMU result file atomically: a comment header, the main keys (the matrix
/// one row per line), then the sections. Non-finite numbers in the main keys are refused.
pub fn write_imu_result_yaml(path: &Path, c: &ImuResultFile) -> Result<()> {
    let mut main = c
        .t_cam_imu
        .iter()
        .flatten()
        .chain(std::iter::once(&c.imu_time_offset_s));
    if main.any(|x| !x.is_finite()) {
        return Err(super::non_finite(
            path,
            "an IMU calibration value".to_string(),
        ));
    }
    let mut s = String::new();
    let _ = writeln!(s, "T_cam_imu:");
    for row in &c.t_cam_imu {
        let _ = writeln!(s, "  - {}", flow(row));
    }
    let _ = writeln!(s, "imu_time_offset_s: {:?}", c.imu_time_offset_s);
    if let Some(g) = &c.imu_gravity_world_mps2 {
        let _ = writeln!(s, "imu_gravity_world_mps2: {}", flow(g));
    }
    if let Some(b) = &c.imu_bias_start {
        let _ = writeln!(s, "imu_bias_start:");
        let _ = writeln!(s, "  gyro_radps: {}", flow(&b.gyro_radps));
        let _ = writeln!(s, "  accel_mps2: {}", flow(&b.accel_mps2));
    }
    #[derive(Serialize)]
    struct Tail<'a> {
        #[serde(skip_serializing_if = "Option::is_none")]
        std: &'a Option<ImuOnlyStd>,
        #[serde(skip_serializing_if = "Option::is_none")]
        observability: &'a Option<ImuOnlyObservability>,
        #[serde(skip_serializing_if = "Option::is_none")]
        info: &'a Option<CalibrationInfo>,
        #[serde(skip_serializing_if = "Option::is_none")]
        provenance: &'a Option<Provenance>,
    }
    let tail = Tail {
        std: &c.std,
        observability: &c.observability,
        info: &c.info,
        provenance: &c.provenance,
    };
    write_result_text(path, HEADER, &c.status, &c.failure, &s, &tail)
}

/// Reads a camera + IMU result file (or the IMU's keys of any result file: the DVL's are
/// ignored). Errors name the file, and the line where the YAML parser reports one.
pub fn read_imu_result_yaml(path: &Path) -> Result<ImuResultFile> {
    read_result_text(path)
}
