//! Camera-IMU calibration on simulated data over several seeds: error, std and their ratio.
//! `cargo run --release --example imu_sim -- [SEEDS] [MOTION] [KNOTS_PER_POSE]`
//!
//! Environment: `DURATION` (s), `PREINT` (0 for the bins), `POSES_PER_KNOT`, `QCF` (a factor
//! on the motion prior's density, `ImuOptions::density_factor`, on top of
//! `JOINT_DENSITY_FACTOR`), `BIAS_NODES` (the most bias nodes of the first estimate, `ImuOptions::max_bias_nodes`),
//! `SIM_IMU_NOISE`, `SIM_IMU_WALK` and `SIM_POSE_NOISE` (factors on the simulated IMU's white
//! noise, on its biases' random walks and on the poses' noise; the noise the calibration is
//! told stays as stated, so at 0 what is left of an error is the method's own, not the
//! data's).

use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu};
use dvlcal::lie::so3;
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{MotionKind, SimConfig, build_motion, simulate_with};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let range = args.get(1).cloned().unwrap_or_else(|| "1-5".into());
    let (first, last) = match range.split_once('-') {
        Some((a, b)) => (a.parse()?, b.parse()?),
        None => (1u64, range.parse()?),
    };
    let width: f64 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(0.02);
    let motion = match args.get(2).map(String::as_str) {
        Some("prior") => MotionKind::Prior,
        Some("sinusoid") => MotionKind::Sinusoid,
        _ => MotionKind::CalmThenRotate,
    };
    let per: Option<usize> = args.get(3).and_then(|s| s.parse().ok());
    println!("seed  rot_err/std(x,y,z)       lever_err/std(x,y,z)     offset err/std  iters  time");
    let mut sums = [0.0f64; 7];
    let mut means = [0.0f64; 7];
    let factor = |name: &str| {
        std::env::var(name)
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
            .unwrap_or(1.0)
    };
    let (imu_noise, imu_walk, pose_noise) = (
        factor("SIM_IMU_NOISE"),
        factor("SIM_IMU_WALK"),
        factor("SIM_POSE_NOISE"),
    );
    let mut err2 = [0.0f64; 3];
    let mut stds = [0.0f64; 3];
    for seed in first..=last {
        let cfg = SimConfig {
            seed,
            duration_s: std::env::var("DURATION")
                .ok()
                .and_then(|s| s.parse().ok())
                .unwrap_or(60.0),
            motion,
            ..SimConfig::default()
        };
        let cfg = SimConfig {
            pose_sigma_pos_m: cfg.pose_sigma_pos_m * pose_noise,
            pose_sigma_rot_rad: cfg.pose_sigma_rot_rad * pose_noise,
            ..cfg
        };
        let m = build_motion(&cfg)?;
        let data = simulate_with(&cfg, m.as_ref())?;
        let imu_cfg = ImuSimConfig::default_truth();
        let mut sim_cfg = imu_cfg;
        let n = &mut sim_cfg.noise;
        n.accelerometer_noise_density *= imu_noise;
        n.gyroscope_noise_density *= imu_noise;
        n.accelerometer_random_walk *= imu_walk;
        n.gyroscope_random_walk *= imu_walk;
        let imu = simulate_imu(m.as_ref(), &sim_cfg, 0.0, cfg.duration_s, seed)?;
        let t0 = std::time::Instant::now();
        let opts = ImuOptions {
            knots_per_pose: per,
            bin_width_s: width,
            density_factor: std::env::var("QCF")
                .ok()
                .and_then(|s| s.parse().ok())
                .unwrap_or(1.0),
            preintegrate: std::env::var("PREINT").ok().map(|v| v != "0"),
            poses_per_knot: std::env::var("POSES_PER_KNOT")
                .ok()
                .and_then(|s| s.parse().ok()),
            max_bias_nodes: std::env::var("BIAS_NODES")
                .ok()
                .and_then(|s| s.parse().ok())
                .unwrap_or(ImuOptions::default().max_bias_nodes),
            ..ImuOptions::default()
        };
        let est = calibrate_camera_imu(&data.poses, &imu.samples, &imu_cfg.noise, &opts)?;
        let dt = t0.elapsed().as_secs_f64();
        let (srot, slev, soff) = est.std();
        let rot_err = so3::log(&(imu_cfg.t_cam_imu.rot.transpose() * est.state.t_cam_imu.rot));
        let lev_err = est.state.t_cam_imu.trans - imu_cfg.t_cam_imu.trans;
        let off_err = est.state.time_offset_s - imu_cfg.time_offset_s;
        let r: Vec<f64> = (0..3)
            .map(|i| rot_err[i] / srot[i])
            .chain((0..3).map(|i| lev_err[i] / slev[i]))
            .chain([off_err / soff])
            .collect();
        let shift: Vec<f64> = est.prior_shift.map_or(vec![0.0; 7], |p| {
            (0..3)
                .map(|i| p.rotation[i] / srot[i])
                .chain((0..3).map(|i| p.lever_arm[i] / slev[i]))
                .chain([p.time_offset_s / soff])
                .collect()
        });
        err2[0] += rot_err.norm_squared().to_degrees().to_degrees() / 3.0;
        err2[1] += lev_err.norm_squared() / 3.0;
        err2[2] += off_err * off_err;
        stds[0] += (srot.norm_squared() / 3.0).sqrt().to_degrees();
        stds[1] += (slev.norm_squared() / 3.0).sqrt();
        stds[2] += soff;
        for (s, x) in sums.iter_mut().zip(&r) {
            *s += x * x;
        }
        for (s, x) in means.iter_mut().zip(&r) {
            *s += x;
        }
        println!(
            "{seed:4}  {:6.2} {:6.2} {:6.2}   {:6.2} {:6.2} {:6.2}   {:6.2}   {:3} {:5.2}s  std rot {:.4} deg lever {:.2} mm off {:.3} ms; lever err {:.3} {:.3} {:.3} mm; bins {}/{} noise x{:.2} x{:.2}; other offsets {}; prior shift/std rot {:.2} {:.2} {:.2} lever {:.2} {:.2} {:.2} off {:.2}",
            r[0],
            r[1],
            r[2],
            r[3],
            r[4],
            r[5],
            r[6],
            est.iterations,
            dt,
            srot.norm().to_degrees(),
            slev.norm() * 1e3,
            soff * 1e3,
            lev_err[0] * 1e3,
            lev_err[1] * 1e3,
            lev_err[2] * 1e3,
            est.bins_used,
            est.bins_total,
            est.noise_factor.0,
            est.noise_factor.1,
            est.offset_alternatives_s.len(),
            shift[0],
            shift[1],
            shift[2],
            shift[3],
            shift[4],
            shift[5],
            shift[6]
        );
    }
    let n = (last - first + 1) as f64;
    println!(
        "RMS err/std: rot {:.2} {:.2} {:.2}  lever {:.2} {:.2} {:.2}  offset {:.2}",
        (sums[0] / n).sqrt(),
        (sums[1] / n).sqrt(),
        (sums[2] / n).sqrt(),
        (sums[3] / n).sqrt(),
        (sums[4] / n).sqrt(),
        (sums[5] / n).sqrt(),
        (sums[6] / n).sqrt()
    );
    println!(
        "RMS error per axis: rotation {:.4} deg, lever arm {:.2} mm, offset {:.3} ms; mean std per axis: {:.4} deg, {:.2} mm, {:.3} ms",
        (err2[0] / n).sqrt(),
        1e3 * (err2[1] / n).sqrt(),
        1e3 * (err2[2] / n).sqrt(),
        stds[0] / n,
        1e3 * stds[1] / n,
        1e3 * stds[2] / n
    );
    println!(
        "mean err/std: rot {:.2} {:.2} {:.2}  lever {:.2} {:.2} {:.2}  offset {:.2}",
        means[0] / n,
        means[1] / n,
        means[2] / n,
        means[3] / n,
        means[4] / n,
        means[5] / n,
        means[6] / n
    );
    let pooled =
        |a: usize, b: usize| ((sums[a..b].iter().sum::<f64>()) / (n * (b - a) as f64)).sqrt();
    println!(
        "pooled err/std RMS: rotation {:.2}, lever arm {:.2}, offset {:.2}",
        pooled(0, 3),
        pooled(3, 6),
        pooled(6, 7)
    );
    Ok(())
}
