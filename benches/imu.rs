//! Time and peak memory of the IMU's calibrations against the recording's length.
//!
//! `cargo bench --bench imu [-- [--camera-imu] SECONDS...]` (default: 30 60 120 240). Poses at
//! 10 Hz (the calm-then-rotate motion), a 200 Hz IMU with the simulator's default noise and
//! biases, the simulator's DVL; one run each of the whole of `calibrate_camera_imu` (pose-only
//! fit, initial estimate, joint Gauss-Newton, the noise factors and the covariance), of
//! `calibrate_dvl_imu` (no camera: dead reckoning, the offset search, the same joint problem
//! with the DVL) and of `calibrate_camera_imu_dvl` (all three, from the truth as the DVL's
//! start); `--camera-imu` runs the first alone. Each run's peak memory is the process's
//! resident peak over the run (Linux: reset through `/proc/self/clear_refs` before it), which
//! includes the simulated recording. Prints a markdown table.

use std::time::Instant;

use dvlcal::calib::CalibOptions;
use dvlcal::calib::imu::dvl::calibrate_dvl_imu;
use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu, calibrate_camera_imu_dvl};
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{MotionKind, SimConfig, build_motion, simulate_with};

/// Resets the process's resident peak (where the kernel allows it).
fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The process's resident peak since the last reset, MB (`None` off Linux).
fn peak_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Runs `f`, returning its result, its time (s) and the resident peak over it (MB).
fn measured<T>(f: impl FnOnce() -> T) -> (T, f64, f64) {
    reset_peak();
    let start = Instant::now();
    let out = f();
    let t = start.elapsed().as_secs_f64();
    (out, t, peak_mb().unwrap_or(f64::NAN))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let camera_only = args.iter().any(|a| a == "--camera-imu");
    let mut durations: Vec<f64> = args.iter().filter_map(|a| a.parse().ok()).collect();
    if durations.is_empty() {
        durations = vec![30.0, 60.0, 120.0, 240.0];
    }
    println!(
        "| recording | IMU samples | knots | iterations | camera-IMU (s, MB) | DVL + IMU (s, MB) | camera + IMU + DVL (s, MB) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for duration in durations {
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
        let (est, t, mem) = measured(|| {
            calibrate_camera_imu(
                &data.poses,
                &imu.samples,
                &imu_cfg.noise,
                &ImuOptions::default(),
            )
            .expect("calibration")
        });
        let (mut dvl_cell, mut all_cell) = ("-".to_string(), "-".to_string());
        if !camera_only {
            let ((), t_dvl, mem_dvl) = measured(|| {
                calibrate_dvl_imu(
                    &data.dvl,
                    &imu.samples,
                    &imu_cfg.noise,
                    &CalibOptions::default(),
                    &ImuOptions::default(),
                )
                .map(|_| ())
                .expect("DVL + IMU")
            });
            let ((), t_all, mem_all) = measured(|| {
                calibrate_camera_imu_dvl(
                    &data.poses,
                    &imu.samples,
                    &imu_cfg.noise,
                    &data.dvl,
                    &data.truth,
                    &CalibOptions::default(),
                    &ImuOptions::default(),
                )
                .map(|_| ())
                .expect("camera + IMU + DVL")
            });
            dvl_cell = format!("{t_dvl:.2}, {mem_dvl:.0}");
            all_cell = format!("{t_all:.2}, {mem_all:.0}");
        }
        println!(
            "| {duration:.0} s | {} | {} | {} | {t:.2}, {mem:.0} | {dvl_cell} | {all_cell} |",
            imu.samples.len(),
            est.knots.len(),
            est.iterations
        );
    }
}
