//! Whether the co-sensor's poses are dense enough for the trajectory to follow the motion.
//!
//! The trajectory between two poses is the smoothest one the jerk prior allows. When the camera
//! turns a large angle between consecutive poses (poses a few tenths of a second apart during
//! rotations of about 1 rad/s, or frames dropped), the fit cuts the corners: its angular rate is
//! far below the true one. Every later check then sees the symptoms, not the cause: a lever arm
//! that looks unobserved ("the rotation rate is mostly noise"), DVL reports that look like
//! outliers, scales that disagree between halves. This check names the cause first.

use crate::lie::so3;
use crate::types::PoseMeasurement;

/// The turn between consecutive poses (at the 90th percentile of the pairs) above which the fit
/// cannot follow the rotation: 0.3 rad (17 deg). At 10 Hz that is a rotation rate of 3 rad/s
/// most of the time; the sample recordings turn about 0.1 rad between frames.
pub const MAX_TURN_RAD: f64 = 0.3;

/// Poses too sparse for the motion they record.
#[derive(Clone, Debug, PartialEq)]
pub struct SparsePoses {
    /// Poses checked.
    pub poses: usize,
    /// Median time between consecutive poses, seconds.
    pub median_interval_s: f64,
    /// The turn between consecutive poses that one pair in ten exceeds, radians.
    pub turn_p90_rad: f64,
}

impl SparsePoses {
    /// The rotation rate the poses would follow with a turn of [`MAX_TURN_RAD`] between them.
    fn rate_needed_hz(&self) -> f64 {
        (self.turn_p90_rad / MAX_TURN_RAD) / self.median_interval_s
    }

    /// The warning, and the first reason of the failed calibration.
    pub fn reason(&self) -> String {
        format!(
            "the camera poses are too sparse for the motion: {} poses {:.2} s apart (median, \
             {:.1} Hz) while the camera turns {:.2} rad ({:.0} deg) between consecutive poses \
             (one pair in ten turns more); the trajectory cannot follow rotations that fast, so \
             its rotation rate and velocities are wrong, and the DVL then looks inconsistent. \
             Give poses at {:.0} Hz at least (10 Hz or more is usual; no frames dropped), or \
             rotate more slowly",
            self.poses,
            self.median_interval_s,
            1.0 / self.median_interval_s,
            self.turn_p90_rad,
            self.turn_p90_rad.to_degrees(),
            self.rate_needed_hz().ceil()
        )
    }
}

/// The check on poses in time order: `None` when consecutive poses turn less than
/// [`MAX_TURN_RAD`] at the 90th percentile (or there are fewer than 3 poses to judge).
pub fn sparse_poses(poses: &[PoseMeasurement]) -> Option<SparsePoses> {
    if poses.len() < 3 {
        return None;
    }
    let mut turns: Vec<f64> = poses
        .windows(2)
        .map(|w| so3::log(&(w[0].pose.rot.transpose() * w[1].pose.rot)).norm())
        .collect();
    let mut intervals: Vec<f64> = poses.windows(2).map(|w| w[1].t - w[0].t).collect();
    turns.sort_by(f64::total_cmp);
    intervals.sort_by(f64::total_cmp);
    let turn_p90_rad = turns[(turns.len() * 9) / 10];
    let median_interval_s = intervals[intervals.len() / 2];
    (turn_p90_rad > MAX_TURN_RAD && median_interval_s > 0.0).then_some(SparsePoses {
        poses: poses.len(),
        median_interval_s,
        turn_p90_rad,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::Se3;

    /// Poses turning about z at `rate` rad/s, `dt` apart.
    fn turning(rate: f64, dt: f64, n: usize) -> Vec<PoseMeasurement> {
        (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                PoseMeasurement {
                    t,
                    pose: Se3::exp(&nalgebra::Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, rate * t)),
                    cov: None,
                }
            })
            .collect()
    }

    #[test]
    fn one_rad_per_second_is_followed_at_10_hz_not_at_1_7_hz() {
        assert_eq!(sparse_poses(&turning(1.0, 0.1, 100)), None);
        let s = sparse_poses(&turning(1.0, 0.6, 40)).expect("sparse");
        assert!((s.median_interval_s - 0.6).abs() < 1e-12);
        assert!((s.turn_p90_rad - 0.6).abs() < 1e-9);
        // 0.6 rad per 0.6 s needs 0.3 rad per pose: 2 poses per 0.6 s, 3.3 Hz, said as 4.
        assert!(s.reason().contains("at 4 Hz at least"), "{}", s.reason());
    }

    #[test]
    fn a_few_large_turns_across_a_tracking_loss_are_no_sparse_recording() {
        let mut p = turning(0.5, 0.1, 100);
        // A 2 s gap after the 50th pose, across which the camera turned 1 rad about x.
        let turn = Se3::exp(&nalgebra::Vector6::new(0.0, 0.0, 0.0, 1.0, 0.0, 0.0));
        for m in p.iter_mut().skip(50) {
            m.t += 2.0;
            m.pose = turn * m.pose;
        }
        assert_eq!(sparse_poses(&p), None);
    }
}
