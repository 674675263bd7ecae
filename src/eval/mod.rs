//! Accuracy of estimates against known truth, and an independent reference estimator
//! ([`spline_baseline`]) to compare the calibration with.
//!
//! [`camera`]: the accuracy of a camera calibration (ray pixel error, extrinsic and baseline
//! errors) and OpenCV's stereo calibration as its reference.

pub mod camera;
pub mod odometry;
pub mod spline_baseline;

use crate::io::calib_yaml::Observability;
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
    /// The file's standard deviations in the same order and units, when it has them (NaN for a
    /// parameter held fixed).
    pub std: Option<nalgebra::SVector<f64, { crate::calib::model::NPARAM }>>,
    /// What the file says determined each parameter, in the same order (`None` for a file
    /// without an `observability` section). A parameter written with a standard deviation of
    /// exactly zero (files of earlier versions, for held parameters) counts as
    /// [`Observability::Fixed`].
    pub state: [Option<Observability>; crate::calib::model::NPARAM],
    /// The reasons the file records for a failed calibration (`status: failed`), joined by
    /// "; " (a placeholder when the file gives none); `None` when the estimate did not fail.
    pub failure: Option<String>,
}

impl CalibrationError {
    /// Each error over its standard deviation (`None` without standard deviations; NaN for a
    /// parameter held fixed).
    pub fn normalized(&self) -> Option<nalgebra::SVector<f64, { crate::calib::model::NPARAM }>> {
        self.std.map(|s| self.error.component_div(&s))
    }

    /// An error naming `path` and the recorded reasons when the estimate is a failed
    /// calibration (`status: failed`): its differences are not those of a result.
    pub fn refuse_failed(&self, path: &std::path::Path) -> Result<()> {
        match &self.failure {
            Some(why) => Err(Error::Input(format!(
                "{} is a failed calibration (status: failed): {why}",
                path.display()
            ))),
            None => Ok(()),
        }
    }

    /// Whether parameter `k` was held at a given value rather than estimated: its error is a
    /// difference of inputs, not of a measurement.
    pub fn held(&self, k: usize) -> bool {
        self.state[k] == Some(Observability::Fixed)
    }
}

/// Compares `estimate` (a result file) with `truth`.
pub fn calibration_error(
    estimate: &crate::io::calib_yaml::CalibrationFile,
    truth: &crate::types::CalibrationParams,
) -> Result<CalibrationError> {
    use crate::calib::model::{NPARAM, difference};
    let error = difference(&estimate.to_params()?, truth);
    let nan3 = [f64::NAN; 3];
    let std = estimate.std.as_ref().map(|s| {
        let r = s.rotation_deg.unwrap_or(nan3);
        let l = s.lever_arm_m.unwrap_or(nan3);
        nalgebra::SVector::<f64, NPARAM>::from_column_slice(&[
            r[0].to_radians(),
            r[1].to_radians(),
            r[2].to_radians(),
            l[0],
            l[1],
            l[2],
            s.velocity_scale.unwrap_or(f64::NAN),
            s.time_offset_s.unwrap_or(f64::NAN),
        ])
    });
    let mut state = [None; NPARAM];
    if let Some(o) = &estimate.observability {
        for (k, st) in state.iter_mut().enumerate() {
            *st = Some(match k {
                0..3 => o.rotation,
                3..6 => o.lever_arm,
                6 => o.velocity_scale,
                _ => o.time_offset,
            });
        }
    }
    if let Some(sd) = &std {
        for (k, st) in state.iter_mut().enumerate() {
            // No standard deviation, or one of exactly zero (written for held parameters
            // before the `fixed` state existed): nothing was measured.
            if sd[k].is_nan() || sd[k] == 0.0 {
                *st = Some(Observability::Fixed);
            }
        }
    }
    let failure =
        (estimate.status == Some(crate::io::calib_yaml::ResultStatus::Failed)).then(|| {
            if estimate.failure.is_empty() {
                "the file records no reason (no `failure` entries)".to_owned()
            } else {
                estimate.failure.join("; ")
            }
        });
    Ok(CalibrationError {
        error,
        std,
        state,
        failure,
    })
}
