//! Accuracy of estimates against known truth.

pub mod odometry;

use nalgebra::{Vector3, Vector6};

use crate::error::{Error, Result};

/// A twist estimate or truth at one time: `[v; w]`, its per-component standard deviations (zero
/// for truth) and the time.
#[derive(Clone, Debug)]
pub struct TwistSample {
    pub t: f64,
    pub twist: Vector6<f64>,
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
