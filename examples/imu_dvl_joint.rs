//! Camera + IMU + DVL in one problem against the DVL's camera-only calibration, on simulated
//! data over several seeds: each DVL parameter's RMS error, err/std and std, camera-only and
//! as `dvlcal calibrate` writes them with all three sensors (the joint problem carrying the
//! camera-only run's findings on the DVL's noise; its std written when none exceeds the
//! camera-only one). With a third argument, the DVL's noise is first-order autoregressive with
//! that correlation time in seconds (the reports still state white noise).
//! `cargo run --release --example imu_dvl_joint -- [SEEDS] [MOTION] [AR1_TAU_S]`

use dvlcal::calib::imu::{CarriedDvl, ImuOptions, calibrate_camera_imu_carried};
use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::pipeline::imu::adopt_joint_dvl;
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{Corruption, MotionKind, SimConfig, build_motion, corrupt, simulate_with};

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
    let ar1: Option<f64> = args.get(3).map(|a| a.parse()).transpose()?;
    let n = (last - first + 1) as f64;
    // Per parameter: squared error, squared err/std and std; camera-only, then as written.
    let mut e2 = [[0.0f64; 8]; 2];
    let mut z2 = [[0.0f64; 8]; 2];
    let mut std_sum = [[0.0f64; 8]; 2];
    let mut written = 0;
    for seed in first..=last {
        let cfg = SimConfig {
            seed,
            duration_s: 60.0,
            motion,
            ..SimConfig::default()
        };
        let m = build_motion(&cfg)?;
        let mut data = simulate_with(&cfg, m.as_ref())?;
        if let Some(tau) = ar1 {
            let c = Corruption {
                dvl_ar1_tau_s: Some(tau),
                ..Corruption::default()
            };
            corrupt(&mut data, &c, cfg.dvl_sigma, seed)?;
        }
        let imu_cfg = ImuSimConfig::default_truth();
        let imu = simulate_imu(m.as_ref(), &imu_cfg, 0.0, cfg.duration_s, seed)?;
        let opts = CalibOptions::default();
        let cam = calibrate(&data.poses, &data.dvl, &opts)?;
        let carried = CarriedDvl::from_outcome(&cam, &opts);
        let joint = calibrate_camera_imu_carried(
            &data.poses,
            &imu.samples,
            &imu_cfg.noise,
            &carried,
            &ImuOptions {
                preintegrate: std::env::var("PREINT").ok().map(|v| v != "0"),
                poses_per_knot: std::env::var("POSES_PER_KNOT")
                    .ok()
                    .and_then(|s| s.parse().ok()),
                ..ImuOptions::default()
            },
        )?;
        let mut out = cam.clone();
        let (mut warnings, mut notes) = (Vec::new(), Vec::new());
        adopt_joint_dvl(&mut out, &joint, &opts, &mut warnings, &mut notes);
        let took = notes.iter().any(|n| n.contains("and so do its std"));
        written += usize::from(took);
        print!(
            "{seed:4} tau {:5.1} halves {:3.1} dvl noise {:.2} {}  cam",
            carried.information_divided_by,
            carried.std_factor.iter().fold(1.0f64, |a, b| a.max(*b)),
            joint.dvl_noise_factor,
            if took { "written" } else { "kept   " }
        );
        for (k, o) in [&cam, &out].into_iter().enumerate() {
            let e = difference(&o.params, &data.truth);
            if k == 1 {
                print!("  out");
            }
            for i in 0..8 {
                let s = o.covariance[(i, i)].sqrt();
                print!(" {:6.2}", e[i] / s);
                e2[k][i] += e[i] * e[i];
                z2[k][i] += (e[i] / s).powi(2);
                std_sum[k][i] += s;
            }
        }
        println!();
        for w in warnings.iter().chain(notes.iter().filter(|_| !took)) {
            println!("     {w}");
        }
    }
    let unit = [57.29578, 57.29578, 57.29578, 1e3, 1e3, 1e3, 1.0, 1e3];
    for (name, k) in [("camera-only", 0), ("written", 1)] {
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
    print!("mean std written/camera-only");
    for (w, c) in std_sum[1].iter().zip(&std_sum[0]) {
        print!(" {:5.2}", w / c);
    }
    println!();
    println!(
        "(RMSE in deg, deg, deg, mm, mm, mm, -, ms); joint std written for {written} of {n} seeds"
    );
    Ok(())
}
