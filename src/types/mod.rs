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
