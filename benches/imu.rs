//! Time of the camera-IMU calibration against the recording's length.
//!
//! `cargo bench --bench imu`. Poses at 10 Hz (the calm-then-rotate motion), a 200 Hz IMU with
//! the simulator's default noise and biases; the whole of `calibrate_camera_imu` (pose-only
//! fit, initial estimate, joint Gauss-Newton, the noise factors and the covariance). Prints a
//! markdown table.

use std::time::Instant;

use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu};
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{MotionKind, SimConfig, build_motion, simulate_with};

fn main() {
    println!("| recording | IMU samples | knots | bias nodes | iterations | time (s) |");
    println!("|---|---|---|---|---|---|");
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
        println!(
            "| {duration:.0} s | {} | {} | {} | {} | {t:.2} |",
            imu.samples.len(),
            est.knots.len(),
            est.state.bias.values.len(),
            est.iterations
        );
    }
}
