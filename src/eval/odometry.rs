//! The odometry check of a calibration: dead reckoning from DVL velocities and the camera's
//! orientation, compared with the camera's positions.
//!
//! Between consecutive camera poses at `T1 < T2` the DVL's mean velocity over the interval (the
//! reports shifted to the camera clock by the time offset and interpolated linearly) is turned
//! into a world-frame displacement of the DVL origin with the camera orientation and `R_cam_dvl`,
//! and divided by the scale. The camera position follows from the DVL origin through the lever
//! arm:
//!
//! `p2 = p1 + R_w_c(Tm) R_cam_dvl v_mean dT / kappa + (R_w_c(T1) - R_w_c(T2)) p_cam_dvl`
//!
//! where `Tm` is the interval's middle (its orientation interpolated on SO(3)). Dead reckoning
//! starts at the first camera position; where the DVL has no reports within `max_gap_s` of an
//! interval it restarts at the camera position (counted as a new segment, never hidden).
//!
//! Errors: ATE is the RMS of the position errors over all camera times; RPE the RMS of the
//! errors of the displacements over `rpe_delta_s`, for every pose that has a partner that much
//! later within one segment.

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::lie::so3;
use crate::types::{CalibrationParams, DvlSample, PoseMeasurement};

/// Settings of the odometry check.
#[derive(Clone, Debug)]
pub struct OdometryOptions {
    /// Time between the poses of one RPE pair, seconds.
    pub rpe_delta_s: f64,
    /// Longest stretch without DVL reports bridged by interpolation, seconds.
    pub max_gap_s: f64,
}

impl Default for OdometryOptions {
    fn default() -> Self {
        OdometryOptions {
            rpe_delta_s: 1.0,
            max_gap_s: 0.5,
        }
    }
}

impl OdometryOptions {
    /// Checks the settings; the error names the option.
    pub fn validate(&self) -> Result<()> {
        if !(self.rpe_delta_s.is_finite() && self.rpe_delta_s > 0.0) {
            return Err(Error::option("--rpe-delta", "must be positive"));
        }
        if !(self.max_gap_s.is_finite() && self.max_gap_s > 0.0) {
            return Err(Error::option("--max-gap", "must be positive"));
        }
        Ok(())
    }
}

/// The result of the odometry check.
#[derive(Clone, Debug)]
pub struct Odometry {
    /// Camera times (s), the dead-reckoned camera positions and the measured ones.
    pub t: Vec<f64>,
    /// Dead-reckoned camera positions in the world frame, m.
    pub estimated: Vec<Vector3<f64>>,
    /// Measured camera positions (translation of `T_world_cam`), m.
    pub measured: Vec<Vector3<f64>>,
    /// Segment number of every pose (0 for the first stretch, +1 at each restart).
    pub segment: Vec<usize>,
    /// Absolute trajectory error: RMS of the position errors over all poses checked, m.
    pub ate_m: f64,
    /// Relative pose error: RMS of the displacement errors over `rpe_delta_s`, m (NaN without
    /// pairs).
    pub rpe_m: f64,
    /// RPE pairs used.
    pub rpe_pairs: usize,
    /// Camera intervals without DVL reports close enough (each restarts dead reckoning).
    pub gaps: usize,
    /// Poses before the first or after the last DVL report (camera clock), not checked.
    pub outside_dvl_span: usize,
    /// Valid DVL reports used, and reports left out (flagged invalid or non-finite).
    pub dvl_used: usize,
    /// DVL reports left out (flagged invalid or non-finite).
    pub dvl_skipped: usize,
    /// Length of the camera path, metres.
    pub path_length_m: f64,
}

/// DVL velocities on the camera clock, in time order, for interpolation.
struct DvlSeries {
    t: Vec<f64>,
    v: Vec<Vector3<f64>>,
}

impl DvlSeries {
    /// The mean of the linearly interpolated velocity over `[a, b]` (trapezoid over the
    /// reports inside plus the interpolated ends), or `None` when a stretch longer than
    /// `max_gap` without reports touches the interval.
    fn mean(&self, a: f64, b: f64, max_gap: f64) -> Option<Vector3<f64>> {
        let n = self.t.len();
        if n < 2 || a < self.t[0] || b > self.t[n - 1] {
            return None;
        }
        // First report after a (k) and last report before b.
        let k = self.t.partition_point(|&x| x <= a);
        let at = |x: f64| -> Option<Vector3<f64>> {
            let j = self.t.partition_point(|&s| s <= x).clamp(1, n - 1);
            let (t0, t1) = (self.t[j - 1], self.t[j]);
            if t1 - t0 > max_gap {
                return None;
            }
            let u = if t1 > t0 { (x - t0) / (t1 - t0) } else { 0.0 };
            Some(self.v[j - 1] * (1.0 - u) + self.v[j] * u)
        };
        let mut pts: Vec<(f64, Vector3<f64>)> = vec![(a, at(a)?)];
        let mut j = k;
        while j < n && self.t[j] < b {
            pts.push((self.t[j], self.v[j]));
            j += 1;
        }
        pts.push((b, at(b)?));
        for w in pts.windows(2) {
            if w[1].0 - w[0].0 > max_gap {
                return None;
            }
        }
        let dt = b - a;
        if dt <= 0.0 {
            return Some(pts[0].1);
        }
        let area: Vector3<f64> = pts
            .windows(2)
            .map(|w| (w[0].1 + w[1].1) * (0.5 * (w[1].0 - w[0].0)))
            .sum();
        Some(area / dt)
    }
}

fn rms(sum_sq: f64, n: usize) -> f64 {
    if n == 0 {
        f64::NAN
    } else {
        (sum_sq / n as f64).sqrt()
    }
}

/// Dead-reckons the camera positions from the DVL and compares them with the camera's.
///
/// Errors: fewer than two poses, or no interval covered by DVL reports.
pub fn dvl_odometry(
    poses: &[PoseMeasurement],
    dvl: &[DvlSample],
    calib: &CalibrationParams,
    opts: &OdometryOptions,
) -> Result<Odometry> {
    opts.validate()?;
    if poses.len() < 2 {
        return Err(Error::TooFewSamples {
            what: "camera poses for the odometry check".into(),
            found: poses.len(),
            needed: 2,
        });
    }
    if !(calib.velocity_scale.is_finite() && calib.velocity_scale > 0.0) {
        return Err(Error::Input(format!(
            "velocity scale {} is not a positive number",
            calib.velocity_scale
        )));
    }
    let mut series: Vec<(f64, Vector3<f64>)> = dvl
        .iter()
        .filter(|s| s.valid && s.t.is_finite() && s.v.iter().all(|x| x.is_finite()))
        .map(|s| (s.t + calib.time_offset_s, s.v))
        .collect();
    let dvl_used = series.len();
    series.sort_by(|a, b| a.0.total_cmp(&b.0));
    let series = DvlSeries {
        t: series.iter().map(|s| s.0).collect(),
        v: series.iter().map(|s| s.1).collect(),
    };
    // Only poses inside the DVL's time span (on the camera clock) are dead-reckoned.
    let (first, last) = match (series.t.first(), series.t.last()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => (f64::INFINITY, f64::NEG_INFINITY),
    };
    let all = poses;
    let poses: Vec<&PoseMeasurement> = all.iter().filter(|p| p.t >= first && p.t <= last).collect();
    let outside_dvl_span = all.len() - poses.len();
    if poses.len() < 2 {
        return Err(Error::NoTimeOverlap(format!(
            "no camera interval is covered by DVL reports ({} valid reports, {} of {} poses in              their time span; check the clock offset and that both logs overlap in time)",
            dvl_used,
            poses.len(),
            all.len()
        )));
    }
    let r_cam_dvl: Matrix3<f64> = calib.t_cam_dvl.rot;
    let lever = calib.t_cam_dvl.trans;
    let inv_scale = 1.0 / calib.velocity_scale;

    let n = poses.len();
    let mut est = Vec::with_capacity(n);
    let mut segment = Vec::with_capacity(n);
    let mut seg = 0usize;
    let mut gaps = 0usize;
    let mut covered = 0usize;
    let mut path = 0.0;
    est.push(poses[0].pose.trans);
    segment.push(0);
    for w in poses.windows(2) {
        let (p1, p2) = (w[0], w[1]);
        path += (p2.pose.trans - p1.pose.trans).norm();
        let dt = p2.t - p1.t;
        let prev = est[est.len() - 1];
        match series.mean(p1.t, p2.t, opts.max_gap_s) {
            Some(v) if dt > 0.0 => {
                let (r1, r2) = (p1.pose.rot, p2.pose.rot);
                let rm = r1 * so3::exp(&(0.5 * so3::log(&(r1.transpose() * r2))));
                let step = rm * r_cam_dvl * v * (dt * inv_scale) + (r1 - r2) * lever;
                est.push(prev + step);
                covered += 1;
            }
            _ => {
                gaps += 1;
                seg += 1;
                est.push(p2.pose.trans);
            }
        }
        segment.push(seg);
    }
    if covered == 0 {
        return Err(Error::NoTimeOverlap(format!(
            "no camera interval is covered by DVL reports ({} valid reports; check the clock \
             offset and that both logs overlap in time)",
            dvl_used
        )));
    }
    let measured: Vec<Vector3<f64>> = poses.iter().map(|p| p.pose.trans).collect();
    let ate_sq: f64 = est
        .iter()
        .zip(&measured)
        .map(|(e, m)| (e - m).norm_squared())
        .sum();
    let t: Vec<f64> = poses.iter().map(|p| p.t).collect();
    let (mut rpe_sq, mut pairs) = (0.0, 0usize);
    for i in 0..n {
        let target = t[i] + opts.rpe_delta_s;
        let j = t.partition_point(|&x| x < target);
        if j >= n || segment[j] != segment[i] {
            continue;
        }
        // The pose nearest to the target time, if within half a step of it.
        let half = 0.5 * (t[j] - t[j.saturating_sub(1).max(i)]).max(1e-9);
        if (t[j] - target).abs() > half.max(0.05 * opts.rpe_delta_s) {
            continue;
        }
        let de = est[j] - est[i];
        let dm = measured[j] - measured[i];
        rpe_sq += (de - dm).norm_squared();
        pairs += 1;
    }
    Ok(Odometry {
        t,
        estimated: est,
        measured,
        segment,
        ate_m: rms(ate_sq, n),
        rpe_m: rms(rpe_sq, pairs),
        rpe_pairs: pairs,
        gaps,
        outside_dvl_span,
        dvl_used,
        dvl_skipped: dvl.len() - dvl_used,
        path_length_m: path,
    })
}
