//! The IMU as the stages see it: its samples, its noise as Kalibr states it, and the model of
//! what a rigidly mounted IMU measures on a moving camera. Pure values and math; no files.

use nalgebra::{Matrix3, Vector3, Vector6};

use crate::lie::Se3;

/// Standard gravity, m/s^2: the magnitude used unless a calibration is given another.
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// One IMU sample, in the IMU frame, on the IMU clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuSample {
    /// IMU-clock time, seconds relative to the dataset epoch.
    pub t: f64,
    /// Angular rate of the IMU frame, rad/s, IMU frame (the gyro's bias included).
    pub gyro: Vector3<f64>,
    /// Specific force, m/s^2, IMU frame: the acceleration of the IMU origin less gravity, so
    /// that an IMU at rest reads +g upwards (the accelerometer's bias included).
    pub accel: Vector3<f64>,
}

/// The IMU's noise, in Kalibr's `imu.yaml` terms (continuous-time densities).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuNoise {
    /// White noise of the accelerometer, m/s^2/sqrt(Hz).
    pub accelerometer_noise_density: f64,
    /// Random walk of the accelerometer's bias, m/s^3/sqrt(Hz).
    pub accelerometer_random_walk: f64,
    /// White noise of the gyro, rad/s/sqrt(Hz).
    pub gyroscope_noise_density: f64,
    /// Random walk of the gyro's bias, rad/s^2/sqrt(Hz).
    pub gyroscope_random_walk: f64,
    /// Sample rate, Hz.
    pub update_rate: f64,
}

impl ImuNoise {
    /// The standard deviation of one gyro sample, rad/s (`density * sqrt(rate)`).
    pub fn gyro_sample_std(&self) -> f64 {
        self.gyroscope_noise_density * self.update_rate.sqrt()
    }

    /// The standard deviation of one accelerometer sample, m/s^2.
    pub fn accel_sample_std(&self) -> f64 {
        self.accelerometer_noise_density * self.update_rate.sqrt()
    }
}

/// The IMU's slowly varying biases at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuBias {
    /// Gyro bias, rad/s.
    pub gyro: Vector3<f64>,
    /// Accelerometer bias, m/s^2.
    pub accel: Vector3<f64>,
}

/// What an IMU mounted at `T_cam_imu` measures, without noise or bias, when the camera is at
/// `pose` (`T_world_cam`) with body twist `twist` (`[v; w]`, camera frame) changing at
/// `twist_rate`, and gravity is `gravity_world` (the world-frame acceleration of a falling
/// body, pointing down): `(gyro, specific force)`, both in the IMU frame.
///
/// With `R = R_cam_imu` and `p = p_cam_imu`: the gyro reads `R^T w`; the accelerometer reads
/// `R^T (v' + w x v + w' x p + w x (w x p) - R_world_cam^T g)`, where `v' + w x v` is the
/// camera origin's acceleration in the camera frame.
pub fn imu_measurement(
    pose: &Se3,
    twist: &Vector6<f64>,
    twist_rate: &Vector6<f64>,
    t_cam_imu: &Se3,
    gravity_world: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let v = twist.fixed_rows::<3>(0).into_owned();
    let w = twist.fixed_rows::<3>(3).into_owned();
    let dv = twist_rate.fixed_rows::<3>(0).into_owned();
    let dw = twist_rate.fixed_rows::<3>(3).into_owned();
    let p = &t_cam_imu.trans;
    let r_imu_cam: Matrix3<f64> = t_cam_imu.rot.transpose();
    let accel_cam = dv + w.cross(&v) + dw.cross(p) + w.cross(&w.cross(p));
    let gravity_cam = pose.rot.transpose() * gravity_world;
    (r_imu_cam * w, r_imu_cam * (accel_cam - gravity_cam))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::so3;

    /// The model against finite differences of the IMU origin's world position: the specific
    /// force is `R_world_imu^T (p_world_imu'' - g)` and the rate `R_world_imu^T R_world_imu'`.
    #[test]
    fn the_model_matches_the_second_derivative_of_the_imus_position() {
        // A pose that moves with a twist growing linearly in time: T(t) = T0 exp(t a + t^2/2 b)
        // is not exact for a varying twist, so integrate a constant-twist motion plus a
        // quadratic translation in the world frame instead, and differentiate numerically.
        let t0 = Se3::new(
            so3::exp(&Vector3::new(0.3, -0.2, 0.5)),
            Vector3::new(1.0, 2.0, 3.0),
        );
        let w = Vector3::new(0.4, -0.7, 0.2);
        let acc_world = Vector3::new(0.3, -0.1, 0.25);
        let vel_world = Vector3::new(0.2, 0.5, -0.3);
        let pose_at = |t: f64| {
            Se3::new(
                t0.rot * so3::exp(&(w * t)),
                t0.trans + vel_world * t + acc_world * (0.5 * t * t),
            )
        };
        let t_cam_imu = Se3::new(
            so3::exp(&Vector3::new(1.2, 0.1, -0.4)),
            Vector3::new(0.1, -0.25, 0.05),
        );
        let g = Vector3::new(0.1, 0.2, -STANDARD_GRAVITY);
        let t = 0.7;
        let pose = pose_at(t);
        // Body twist: v = R^T p', w as given (constant); its rate: v' = R^T p'' - w x v.
        let pdot = vel_world + acc_world * t;
        let v = pose.rot.transpose() * pdot;
        let dv = pose.rot.transpose() * acc_world - w.cross(&v);
        let twist = Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z);
        let rate = Vector6::new(dv.x, dv.y, dv.z, 0.0, 0.0, 0.0);
        let (gyro, accel) = imu_measurement(&pose, &twist, &rate, &t_cam_imu, &g);

        let h = 1e-4;
        let imu_pos = |s: f64| (pose_at(s) * t_cam_imu).trans;
        let ddp = (imu_pos(t + h) - imu_pos(t) * 2.0 + imu_pos(t - h)) / (h * h);
        let r_world_imu = (pose * t_cam_imu).rot;
        let want_accel = r_world_imu.transpose() * (ddp - g);
        let dr = ((pose_at(t + h) * t_cam_imu).rot - (pose_at(t - h) * t_cam_imu).rot) / (2.0 * h);
        let want_gyro = crate::lie::vee(&(r_world_imu.transpose() * dr));
        assert!(
            (accel - want_accel).norm() < 1e-5,
            "{accel} vs {want_accel}"
        );
        assert!((gyro - want_gyro).norm() < 1e-7, "{gyro} vs {want_gyro}");
    }

    #[test]
    fn a_resting_imu_reads_gravity_upwards() {
        let z = Vector6::zeros();
        let (gyro, accel) = imu_measurement(
            &Se3::identity(),
            &z,
            &z,
            &Se3::identity(),
            &Vector3::new(0.0, 0.0, -STANDARD_GRAVITY),
        );
        assert_eq!(gyro, Vector3::zeros());
        assert!((accel - Vector3::new(0.0, 0.0, STANDARD_GRAVITY)).norm() < 1e-12);
    }
}
