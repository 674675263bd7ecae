//! Camera-IMU calibration of a real recording: poses (TUM, with covariances beside them) and an
//! EuRoC IMU CSV. `cargo run --release --example imu_real -- POSES IMU_CSV [KNOTS_PER_POSE]`

use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu};
use dvlcal::io::frames_csv::read_tum_with_covariances;
use dvlcal::types::imu::{ImuNoise, ImuSample};
use nalgebra::Vector3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    let (tum, _) = read_tum_with_covariances(std::path::Path::new(&a[1]), None)?;
    let epoch_ns = tum.epoch.sec as i128 * 1_000_000_000;
    let mut samples = Vec::new();
    for line in std::fs::read_to_string(&a[2])?.lines() {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let ns: i128 = f[0].parse()?;
        let v: Vec<f64> = f[1..7]
            .iter()
            .map(|x| x.parse())
            .collect::<Result<_, _>>()?;
        samples.push(ImuSample {
            t: (ns - epoch_ns) as f64 * 1e-9,
            gyro: Vector3::new(v[0], v[1], v[2]),
            accel: Vector3::new(v[3], v[4], v[5]),
        });
    }
    let noise = ImuNoise {
        accelerometer_noise_density: a.get(4).and_then(|s| s.parse().ok()).unwrap_or(0.002),
        accelerometer_random_walk: 0.003,
        gyroscope_noise_density: a.get(5).and_then(|s| s.parse().ok()).unwrap_or(1.6968e-4),
        gyroscope_random_walk: 1.9393e-5,
        update_rate: 200.0,
    };
    let per: Option<usize> = a.get(3).and_then(|s| s.parse().ok());
    let t0 = std::time::Instant::now();
    let est = calibrate_camera_imu(
        &tum.poses,
        &samples,
        &noise,
        &ImuOptions {
            knots_per_pose: per,
            ..ImuOptions::default()
        },
    )?;
    let (sr, sl, so) = est.std();
    println!(
        "time {:.1}s iterations {} converged {}",
        t0.elapsed().as_secs_f64(),
        est.iterations,
        est.converged
    );
    println!("T_cam_imu rot:\n{}", est.state.t_cam_imu.rot);
    println!(
        "lever {:?} std mm {:?}",
        est.state.t_cam_imu.trans.as_slice(),
        (sl * 1e3).as_slice()
    );
    println!("offset {:.5} s std {:.5}", est.state.time_offset_s, so);
    println!("rot std deg {:?}", sr.map(f64::to_degrees).as_slice());
    println!("gravity {:?}", est.state.gravity_world().as_slice());
    println!("bias0 {:?}", est.state.bias.values[0]);
    let m = 6.0 * est.bins_used as f64;
    println!(
        "cost {:.0} over {} residuals (ratio {:.2}); noise factors {:?}",
        est.cost,
        m,
        est.cost / m,
        est.noise_factor
    );
    Ok(())
}
