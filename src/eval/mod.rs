//! Accuracy of estimates against known truth, and an independent reference estimator
//! ([`spline_baseline`]) to compare the calibration with.
//!
//! [`camera`]: the accuracy of a camera calibration (ray pixel error, extrinsic and baseline
//! errors) and OpenCV's stereo calibration as its reference.

pub mod camera;
pub mod odometry;
pub mod spline_baseline;

use nalgebra::{Vector3, Vector6};

use crate::error::{Error, Result};

/// A twist estimate or truth at one time: `[v; w]`, its per-component standard deviations (zero
/// for truth) and the time.
#[derive(Clone, Debug)]
pub struct TwistSample {
    /// Time of the sample, seconds relative to the epoch.
    pub t: f64,
    /// Body twist `[v; w]`, m/s and rad/s.
    pub twist: Vector6<f64>,
    /// Standard deviation of each twist component (zero for truth).
    pub std: Vector6<f64>,
}

/// Summary of twist errors.
#[derive(Clone, Debug)]
pub struct TwistErrors {
    /// Samples compared.
    pub count: usize,
    /// Root-mean-square error per component `[vx vy vz wx wy wz]`.
    pub rms: Vector6<f64>,
    /// RMS of the linear-velocity error norm (m/s) and of the angular-velocity error norm (rad/s).
    pub rms_v: f64,
    /// RMS of the angular-velocity error norm, rad/s.
    pub rms_w: f64,
    /// Mean of `(error / std)^2` per component: 1 when the reported deviations are honest.
    pub mean_normalized_sq: Vector6<f64>,
}

/// Compares estimates with truth sample by sample; the two lists must hold the same times (to
/// 1 us).
pub fn twist_errors(estimate: &[TwistSample], truth: &[TwistSample]) -> Result<TwistErrors> {
    if estimate.len() != truth.len() || estimate.is_empty() {
        return Err(Error::Input(format!(
            "estimate has {} rows and truth {}: they must match one to one",
            estimate.len(),
            truth.len()
        )));
    }
    let mut sq = Vector6::zeros();
    let mut nsq = Vector6::zeros();
    let (mut ev, mut ew) = (0.0, 0.0);
    for (i, (e, t)) in estimate.iter().zip(truth).enumerate() {
        if (e.t - t.t).abs() > 1e-6 {
            return Err(Error::Input(format!(
                "row {}: estimate time {} differs from truth time {}",
                i + 1,
                e.t,
                t.t
            )));
        }
        let d = e.twist - t.twist;
        sq += d.component_mul(&d);
        ev += Vector3::new(d[0], d[1], d[2]).norm_squared();
        ew += Vector3::new(d[3], d[4], d[5]).norm_squared();
        for c in 0..6 {
            if e.std[c] > 0.0 {
                nsq[c] += (d[c] / e.std[c]).powi(2);
            } else {
                nsq[c] = f64::NAN;
            }
        }
    }
    let n = estimate.len() as f64;
    Ok(TwistErrors {
        count: estimate.len(),
        rms: (sq / n).map(f64::sqrt),
        rms_v: (ev / n).sqrt(),
        rms_w: (ew / n).sqrt(),
        mean_normalized_sq: nsq / n,
    })
}

/// The error of a calibration file against a reference, in the estimator's parameter order
/// (`calib::model::difference`: rotation (rad, about the DVL axes), lever arm (m), scale,
/// offset (s)), with the file's standard deviations in the same order when it has them.
#[derive(Clone, Debug)]
pub struct CalibrationError {
    /// Estimate minus reference in the estimator's coordinates (rad, m, -, s).
    pub error: nalgebra::SVector<f64, { crate::calib::model::NPARAM }>,
    /// The file's standard deviations in the same order and units, when it has them.
    pub std: Option<nalgebra::SVector<f64, { crate::calib::model::NPARAM }>>,
}

impl CalibrationError {
    /// Each error over its standard deviation (`None` without standard deviations; a zero
    /// deviation gives an infinite or NaN ratio).
    pub fn normalized(&self) -> Option<nalgebra::SVector<f64, { crate::calib::model::NPARAM }>> {
        self.std.map(|s| self.error.component_div(&s))
    }
}

/// Compares `estimate` (a result file) with `truth`.
pub fn calibration_error(
    estimate: &crate::io::calib_yaml::CalibrationFile,
    truth: &crate::types::CalibrationParams,
) -> Result<CalibrationError> {
    use crate::calib::model::difference;
    let error = difference(&estimate.to_params()?, truth);
    let std = estimate.std.as_ref().map(|s| {
        nalgebra::SVector::<f64, { crate::calib::model::NPARAM }>::from_column_slice(&[
            s.rotation_deg[0].to_radians(),
            s.rotation_deg[1].to_radians(),
            s.rotation_deg[2].to_radians(),
            s.lever_arm_m[0],
            s.lever_arm_m[1],
            s.lever_arm_m[2],
            s.velocity_scale,
            s.time_offset_s,
        ])
    });
    Ok(CalibrationError { error, std })
}
