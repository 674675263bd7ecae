//! Time of the IMU's calibrations against the recording's length.
//!
//! `cargo bench --bench imu`. Poses at 10 Hz (the calm-then-rotate motion), a 200 Hz IMU with
//! the simulator's default noise and biases, the simulator's DVL; three runs each: the whole
//! of `calibrate_camera_imu` (pose-only fit, initial estimate, joint Gauss-Newton, the noise
//! factors and the covariance), of `calibrate_dvl_imu` (no camera: dead reckoning, the offset
//! search, the same joint problem with the DVL) and of `calibrate_camera_imu_dvl` (all three,
//! from the truth as the DVL's start). Prints a markdown table.

use std::time::Instant;

use dvlcal::calib::CalibOptions;
use dvlcal::calib::imu::dvl::calibrate_dvl_imu;
use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu, calibrate_camera_imu_dvl};
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{MotionKind, SimConfig, build_motion, simulate_with};

fn main() {
    println!(
        "| recording | IMU samples | knots | bias nodes | iterations | camera-IMU (s) | DVL + IMU (s) | camera + IMU + DVL (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for duration in [30.0, 60.0, 120.0, 240.0] {
        let cfg = SimConfig {
            seed: 1,
            duration_s: duration,
            motion: MotionKind::CalmThenRotate,
            ..SimConfig::default()
        };
        let motion = build_motion(&cfg).expect("motion");
        let data = simulate_with(&cfg, motion.as_ref()).expect("data");
        let imu_cfg = ImuSimConfig::default_truth();
        let imu = simulate_imu(motion.as_ref(), &imu_cfg, 0.0, duration, 1).expect("imu");
        let start = Instant::now();
        let est = calibrate_camera_imu(
            &data.poses,
            &imu.samples,
            &imu_cfg.noise,
            &ImuOptions::default(),
        )
        .expect("calibration");
        let t = start.elapsed().as_secs_f64();
        let start = Instant::now();
        calibrate_dvl_imu(
            &data.dvl,
            &imu.samples,
            &imu_cfg.noise,
            &CalibOptions::default(),
            &ImuOptions::default(),
        )
        .expect("DVL + IMU");
        let t_dvl = start.elapsed().as_secs_f64();
        let start = Instant::now();
        calibrate_camera_imu_dvl(
            &data.poses,
            &imu.samples,
            &imu_cfg.noise,
            &data.dvl,
            &data.truth,
            &CalibOptions::default(),
            &ImuOptions::default(),
        )
        .expect("camera + IMU + DVL");
        let t_all = start.elapsed().as_secs_f64();
        println!(
            "| {duration:.0} s | {} | {} | {} | {} | {t:.2} | {t_dvl:.2} | {t_all:.2} |",
            imu.samples.len(),
            est.knots.len(),
            est.state.bias.values.len(),
            est.iterations
        );
    }
}
