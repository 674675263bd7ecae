//! Camera + IMU + DVL in one problem against the DVL's camera-only calibration, on simulated
//! data over several seeds: each DVL parameter's RMS error and err/std both ways.
//! `cargo run --release --example imu_dvl_joint -- [SEEDS] [MOTION]`

use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu_dvl};
use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{MotionKind, SimConfig, build_motion, simulate_with};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let range = args.get(1).cloned().unwrap_or_else(|| "1-5".into());
    let (first, last) = match range.split_once('-') {
        Some((a, b)) => (a.parse()?, b.parse()?),
        None => (1u64, range.parse()?),
    };
    let motion = match args.get(2).map(String::as_str) {
        Some("prior") => MotionKind::Prior,
        Some("sinusoid") => MotionKind::Sinusoid,
        _ => MotionKind::CalmThenRotate,
    };
    let n = (last - first + 1) as f64;
    // Per parameter: squared error and squared err/std, camera-only then joint.
    let mut e2 = [[0.0f64; 8]; 2];
    let mut z2 = [[0.0f64; 8]; 2];
    for seed in first..=last {
        let cfg = SimConfig {
            seed,
            duration_s: 60.0,
            motion,
            ..SimConfig::default()
        };
        let m = build_motion(&cfg)?;
        let data = simulate_with(&cfg, m.as_ref())?;
        let imu_cfg = ImuSimConfig::default_truth();
        let imu = simulate_imu(m.as_ref(), &imu_cfg, 0.0, cfg.duration_s, seed)?;
        let opts = CalibOptions::default();
        let cam = calibrate(&data.poses, &data.dvl, &opts)?;
        let joint = calibrate_camera_imu_dvl(
            &data.poses,
            &imu.samples,
            &imu_cfg.noise,
            &data.dvl,
            &cam.params,
            &opts,
            &ImuOptions::default(),
        )?;
        let jp = joint.state.dvl.ok_or("no DVL in the joint state")?;
        let js = joint.dvl_std().ok_or("no DVL std")?;
        let ec = difference(&cam.params, &data.truth);
        let ej = difference(&jp, &data.truth);
        print!("{seed:4} cam");
        for i in 0..8 {
            let sc = cam.covariance[(i, i)].sqrt();
            print!(" {:6.2}", ec[i] / sc);
            e2[0][i] += ec[i] * ec[i];
            z2[0][i] += (ec[i] / sc).powi(2);
            e2[1][i] += ej[i] * ej[i];
            z2[1][i] += (ej[i] / js[i]).powi(2);
        }
        print!("  joint");
        for i in 0..8 {
            print!(" {:6.2}", ej[i] / js[i]);
        }
        println!("  dvl noise {:.2}", joint.dvl_noise_factor);
    }
    let unit = [57.29578, 57.29578, 57.29578, 1e3, 1e3, 1e3, 1.0, 1e3];
    for (name, k) in [("camera-only", 0), ("joint", 1)] {
        print!("{name:12} RMSE");
        for (e, u) in e2[k].iter().zip(unit) {
            print!(" {:8.4}", (e / n).sqrt() * u);
        }
        print!("   err/std RMS");
        for z in &z2[k] {
            print!(" {:5.2}", (z / n).sqrt());
        }
        println!();
    }
    println!("(RMSE in deg, deg, deg, mm, mm, mm, -, ms)");
    Ok(())
}
