//! Camera-IMU calibration of a real recording: poses (TUM, with covariances beside them), an
//! EuRoC IMU CSV and its noise file (Kalibr's imu.yaml or EuRoC's sensor.yaml).
//! `cargo run --release --example imu_real -- POSES IMU_CSV NOISE_YAML [KNOTS_PER_POSE]`

use std::path::Path;

use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu};
use dvlcal::io::frames_csv::read_tum_with_covariances;
use dvlcal::io::imu::noise::read_imu_noise;
use dvlcal::io::imu::read_imu_csv;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    if a.len() < 4 {
        return Err("usage: imu_real POSES IMU_CSV NOISE_YAML [KNOTS_PER_POSE]".into());
    }
    let (tum, _) = read_tum_with_covariances(Path::new(&a[1]), None)?;
    let imu = read_imu_csv(Path::new(&a[2]), Some(tum.epoch))?;
    let noise = read_imu_noise(Path::new(&a[3]))?.noise;
    let opts = ImuOptions {
        knots_per_pose: a.get(4).and_then(|s| s.parse().ok()),
        ..ImuOptions::default()
    };
    let t0 = std::time::Instant::now();
    let est = calibrate_camera_imu(&tum.poses, &imu.samples, &noise, &opts)?;
    let (sr, sl, so) = est.std();
    println!(
        "{:.1} s, {} iterations, converged {}",
        t0.elapsed().as_secs_f64(),
        est.iterations,
        est.converged
    );
    println!("T_cam_imu:\n{}", est.state.t_cam_imu.to_matrix());
    println!(
        "rotation std {:?} deg; lever arm std {:?} mm; offset {:.5} s (std {:.5})",
        sr.map(f64::to_degrees).as_slice(),
        (sl * 1e3).as_slice(),
        est.state.time_offset_s,
        so
    );
    println!("gravity {:?}", est.state.gravity_world().as_slice());
    println!("noise factors (gyro, accelerometer) {:?}", est.noise_factor);
    Ok(())
}
