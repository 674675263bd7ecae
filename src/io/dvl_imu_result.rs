//! The result file of a DVL + IMU calibration (no camera): `T_imu_dvl` (DVL points into the
//! IMU frame), `time_offset_s` (`t_imu = t_dvl + time_offset_s`), `velocity_scale`, the IMU's
//! biases at the start, and `std`, `observability`, `info` and `provenance` as in the camera's
//! result file (their lever arm in the IMU frame). A reader of `T_cam_dvl` refuses it with a
//! message saying what it is ([`super::calib_yaml::read_calib_yaml`]).

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::calib_yaml::{
    CalibrationInfo, CalibrationStd, ImuBiasFile, ObservabilityFlags, ResultStatus,
};
use super::provenance::Provenance;
use super::result_text::{flow, read_result_text, write_result_text};
use crate::error::Result;

/// A DVL + IMU result file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DvlImuResultFile {
    /// `ok` or `failed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub status: Option<ResultStatus>,
    /// Why the calibration failed (empty unless `status` is `failed`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failure: Vec<String>,
    /// `T_imu_dvl`: maps DVL-frame points into the IMU frame; rows of the 4x4 matrix.
    #[serde(rename = "T_imu_dvl")]
    pub t_imu_dvl: [[f64; 4]; 4],
    /// `t_imu = t_dvl + time_offset_s`.
    pub time_offset_s: f64,
    /// The DVL's velocity scale factor.
    pub velocity_scale: f64,
    /// The IMU's biases at the start of the recording.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_bias_start: Option<ImuBiasFile>,
    /// Standard deviations (rotation about the DVL frame's axes, lever arm in the IMU frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std: Option<CalibrationStd>,
    /// Verdicts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observability: Option<ObservabilityFlags>,
    /// How the result was obtained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub info: Option<CalibrationInfo>,
    /// Version, command line, time and input digests of the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<Provenance>,
}

const HEADER: &str = "\
# dvlcal calibration result: DVL + IMU (no camera).
# T_imu_dvl maps DVL-frame points into the IMU frame: p_imu = R_imu_dvl p_dvl + t_imu_dvl.
# Matrices are listed by rows. Clocks: t_imu = t_dvl + time_offset_s.
";

/// Writes the DVL + IMU result file atomically: a comment header, the main keys (the matrix
/// one row per line), then the sections. Non-finite numbers in the main keys are refused.
pub fn write_dvl_imu_result_yaml(path: &Path, c: &DvlImuResultFile) -> Result<()> {
    let mut main = c
        .t_imu_dvl
        .iter()
        .flatten()
        .chain([&c.time_offset_s, &c.velocity_scale]);
    if main.any(|x| !x.is_finite()) {
        return Err(super::non_finite(
            path,
            "a DVL-IMU calibration value".into(),
        ));
    }
    let mut s = String::from("T_imu_dvl:\n");
    for row in &c.t_imu_dvl {
        let _ = writeln!(s, "  - {}", flow(row));
    }
    let _ = writeln!(s, "time_offset_s: {:?}", c.time_offset_s);
    let _ = writeln!(s, "velocity_scale: {:?}", c.velocity_scale);
    if let Some(b) = &c.imu_bias_start {
        let _ = writeln!(s, "imu_bias_start:");
        let _ = writeln!(s, "  gyro_radps: {}", flow(&b.gyro_radps));
        let _ = writeln!(s, "  accel_mps2: {}", flow(&b.accel_mps2));
    }
    #[derive(Serialize)]
    struct Tail<'a> {
        #[serde(skip_serializing_if = "Option::is_none")]
        std: &'a Option<CalibrationStd>,
        #[serde(skip_serializing_if = "Option::is_none")]
        observability: &'a Option<ObservabilityFlags>,
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

/// Reads a DVL + IMU result file. Errors name the file, and the line where the YAML parser
/// reports one.
pub fn read_dvl_imu_result_yaml(path: &Path) -> Result<DvlImuResultFile> {
    read_result_text(path)
}
