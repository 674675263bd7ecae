//! Typed values passed between the stages of the pipeline, and the models the stages share: the
//! camera model ([`camera`]) and the board geometry ([`board`]). Pure values and math; no files.

pub mod board;
pub mod camera;
pub mod imu;
pub mod imu_units;

use nalgebra::{Matrix3, Matrix6, Vector3};

use crate::lie::Se3;

/// One measured camera pose, `T_world_cam`, on the camera clock.
#[derive(Clone, Debug)]
pub struct PoseMeasurement {
    /// Camera-clock time, seconds relative to the dataset epoch.
    pub t: f64,
    /// `T_world_cam`: maps camera-frame points into the world (board) frame.
    pub pose: Se3,
    /// Covariance of the right perturbation `T_meas = T_true * exp(n)`, `n = [rho; phi]`
    /// (translation first, metres and radians, camera frame). `None`: use the fit's default.
    pub cov: Option<Matrix6<f64>>,
}

/// One DVL velocity report.
#[derive(Clone, Debug)]
pub struct DvlSample {
    /// DVL-clock time of validity, seconds relative to the dataset epoch.
    pub t: f64,
    /// Measured velocity of the DVL origin in the DVL frame, m/s.
    pub v: Vector3<f64>,
    /// Covariance of `v`, (m/s)^2, when the report carries one.
    pub cov: Option<Matrix3<f64>>,
    /// The DVL's own validity flag.
    pub valid: bool,
}

/// The quantities a calibration estimates, named as in the result file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationParams {
    /// `T_cam_dvl`: maps DVL-frame points into the camera frame. Its translation is the lever arm
    /// `p_cam_dvl` (the DVL origin in camera coordinates); its rotation is `R_cam_dvl`.
    pub t_cam_dvl: Se3,
    /// `t_cam = t_dvl + time_offset_s`.
    pub time_offset_s: f64,
    /// DVL velocity scale `kappa`: `v_dvl = kappa * R_dvl_cam * (v_cam + w_cam x p_cam_dvl)`.
    pub velocity_scale: f64,
}

impl CalibrationParams {
    /// The parameters from the rotation `R_dvl_cam` (camera-frame vectors into the DVL frame),
    /// the lever arm `p_cam_dvl` (the DVL origin in camera coordinates, m), the velocity scale and
    /// the clock offset (s).
    pub fn from_r_dvl_cam(
        r_dvl_cam: Matrix3<f64>,
        lever_arm_cam_m: Vector3<f64>,
        velocity_scale: f64,
        time_offset_s: f64,
    ) -> CalibrationParams {
        CalibrationParams {
            t_cam_dvl: Se3::new(r_dvl_cam.transpose(), lever_arm_cam_m),
            time_offset_s,
            velocity_scale,
        }
    }

    /// `R_dvl_cam`: rotates camera-frame vectors into the DVL frame (the transpose of
    /// `t_cam_dvl`'s rotation).
    pub fn r_dvl_cam(&self) -> Matrix3<f64> {
        self.t_cam_dvl.rot.transpose()
    }

    /// The lever arm `p_cam_dvl`: the DVL origin in camera coordinates, m (`t_cam_dvl`'s
    /// translation; `lever_arm_cam_m` in the result file).
    pub fn lever_arm_cam_m(&self) -> Vector3<f64> {
        self.t_cam_dvl.trans
    }
}

/// Smallest step between poses, metres, that counts as motion on either side of a held pose
/// ([`held_pose_runs`]).
pub const HELD_POSE_MIN_STEP_M: f64 = 1e-3;
/// Smallest rotation between poses, radians, that counts as motion there.
pub const HELD_POSE_MIN_STEP_RAD: f64 = 1e-3;

/// The runs of held poses in `poses` (in time order): poses that repeat the pose before them
/// exactly (every number the same, at a later time) while the track moves into the hold and out
/// of it. That is a tracker holding its last value (a marker lost for a few frames, a camera
/// driver repeating a frame): the time is new, the pose is old, and the catch-up step after the
/// hold turns a steady motion into a stop and a lurch. Each range covers the repeats only; the
/// pose they repeat is a real measurement and is not in it. A hold at the end of the track (no
/// way out to judge) and one the track neither enters nor leaves moving (a rig at rest printed
/// at a coarse resolution) are not counted.
pub fn held_pose_runs(poses: &[PoseMeasurement]) -> Vec<std::ops::Range<usize>> {
    let same = |a: &PoseMeasurement, b: &PoseMeasurement| {
        a.pose.trans == b.pose.trans && a.pose.rot == b.pose.rot && b.t > a.t
    };
    let moved = |a: &PoseMeasurement, b: &PoseMeasurement| {
        let d = (b.pose.trans - a.pose.trans).norm();
        let angle = crate::lie::so3::log(&(a.pose.rot.transpose() * b.pose.rot)).norm();
        d > HELD_POSE_MIN_STEP_M || angle > HELD_POSE_MIN_STEP_RAD
    };
    let mut runs = Vec::new();
    let mut k = 1;
    while k < poses.len() {
        if !same(&poses[k - 1], &poses[k]) {
            k += 1;
            continue;
        }
        let start = k;
        while k < poses.len() && same(&poses[k - 1], &poses[k]) {
            k += 1;
        }
        // poses[start - 1] is the held pose; poses[k] (if any) the first one after the hold.
        let entered = start >= 2 && moved(&poses[start - 2], &poses[start - 1]);
        let left = k < poses.len() && moved(&poses[k - 1], &poses[k]);
        if entered && left {
            runs.push(start..k);
        }
    }
    runs
}

/// `poses` without the held poses of `runs` ([`held_pose_runs`]), and for each kept pose its
/// index in `poses`.
pub fn without_runs(
    poses: Vec<PoseMeasurement>,
    runs: &[std::ops::Range<usize>],
) -> (Vec<PoseMeasurement>, Vec<usize>) {
    let mut kept = Vec::with_capacity(poses.len());
    let mut index = Vec::with_capacity(poses.len());
    for (k, p) in poses.into_iter().enumerate() {
        if !runs.iter().any(|r| r.contains(&k)) {
            kept.push(p);
            index.push(k);
        }
    }
    (kept, index)
}

#[cfg(test)]
mod held_tests {
    use super::*;

    fn at(t: f64, x: f64, yaw: f64) -> PoseMeasurement {
        PoseMeasurement {
            t,
            pose: Se3::new(
                *nalgebra::Rotation3::from_euler_angles(0.0, 0.0, yaw).matrix(),
                Vector3::new(x, 0.0, 0.0),
            ),
            cov: None,
        }
    }

    /// A track at 0.1 m/s, 10 Hz, whose tracker held poses 5-7 (they repeat pose 4).
    fn track(held: std::ops::Range<usize>) -> Vec<PoseMeasurement> {
        (0..20)
            .map(|k| {
                let src = if held.contains(&k) { held.start - 1 } else { k };
                at(k as f64 * 0.1, src as f64 * 0.01, 0.0)
            })
            .collect()
    }

    #[test]
    fn a_hold_while_moving_is_found_and_dropped() {
        let poses = track(5..8);
        let runs = held_pose_runs(&poses);
        assert_eq!(runs, vec![5..8]);
        let (kept, index) = without_runs(poses, &runs);
        assert_eq!(kept.len(), 17);
        assert_eq!(&index[3..6], &[3, 4, 8]);
    }

    #[test]
    fn a_rig_at_rest_a_hold_at_the_end_and_a_moving_track_have_none() {
        // At rest: every pose the same.
        let rest: Vec<_> = (0..10).map(|k| at(k as f64 * 0.1, 1.0, 0.2)).collect();
        assert!(held_pose_runs(&rest).is_empty());
        // Held to the end.
        assert!(held_pose_runs(&track(15..20)).is_empty());
        // No repeat: nothing.
        assert!(held_pose_runs(&track(0..0)).is_empty());
        // A rig turning in place with a held pose counts (rotation is motion).
        let mut turning: Vec<_> = (0..10)
            .map(|k| at(k as f64 * 0.1, 0.0, k as f64 * 0.01))
            .collect();
        turning[6] = at(0.6, 0.0, 0.05);
        assert_eq!(held_pose_runs(&turning), vec![6..7]);
    }
}
