//! DVL + IMU without a camera on simulated data over several seeds: error, std and their
//! ratio. `cargo run --release --example dvl_imu_sim -- [SEEDS] [MOTION]`

use dvlcal::calib::imu::ImuOptions;
use dvlcal::calib::imu::dvl::calibrate_dvl_imu;
use dvlcal::calib::model::difference;
use dvlcal::calib::options::CalibOptions;
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{MotionKind, SimConfig, build_motion, simulate_with};
use dvlcal::types::CalibrationParams;

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
    let duration: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(60.0);
    println!("seed  err/std: rot x y z | lever x y z | scale | offset   iters  time  noise");
    let mut sq = [0.0f64; 8];
    let mut sd = [0.0f64; 8];
    let n = (last - first + 1) as f64;
    for seed in first..=last {
        let cfg = SimConfig {
            seed,
            duration_s: duration,
            motion,
            ..SimConfig::default()
        };
        let m = build_motion(&cfg)?;
        let data = simulate_with(&cfg, m.as_ref())?;
        let imu_cfg = ImuSimConfig::default_truth();
        let imu = simulate_imu(m.as_ref(), &imu_cfg, 0.0, cfg.duration_s, seed)?;
        let truth = CalibrationParams {
            t_cam_dvl: imu_cfg.t_cam_imu.inverse() * data.truth.t_cam_dvl,
            time_offset_s: data.truth.time_offset_s - imu_cfg.time_offset_s,
            velocity_scale: data.truth.velocity_scale,
        };
        let t0 = std::time::Instant::now();
        let est = calibrate_dvl_imu(
            &data.dvl,
            &imu.samples,
            &imu_cfg.noise,
            &CalibOptions::default(),
            &ImuOptions {
                preintegrate: std::env::var("PREINT").ok().map(|v| v != "0"),
                ..ImuOptions::default()
            },
        )?;
        let dt = t0.elapsed().as_secs_f64();
        let e = difference(&est.params, &truth);
        let s = est.std();
        print!("{seed:4} ");
        for i in 0..8 {
            print!(" {:6.2}", e[i] / s[i]);
            sq[i] += (e[i] / s[i]).powi(2);
            sd[i] += s[i];
        }
        println!(
            "   {:3} {:5.1}s  {:.2} {:.2} {:.2} conv {}",
            est.iterations,
            dt,
            est.noise_factor.0,
            est.noise_factor.1,
            est.noise_factor.2,
            est.converged
        );
    }
    print!("RMS  ");
    for v in sq {
        print!(" {:6.2}", (v / n).sqrt());
    }
    println!();
    print!("std  ");
    for (i, v) in sd.iter().enumerate() {
        let f = match i {
            0..=2 => 57.29578,
            6 => 1.0,
            _ => 1e3,
        };
        print!(" {:6.3}", v / n * f);
    }
    println!("   (deg, mm, -, ms)");
    Ok(())
}
