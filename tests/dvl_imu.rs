//! The DVL calibrated against an IMU, with and without a camera: at the Cramér-Rao bound over
//! many simulated seeds (each error over its own std), and refusing an IMU that does not fit.

use dvlcal::calib::imu::dvl::calibrate_dvl_imu;
use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu_dvl};
use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{MotionKind, SimConfig, SimDataset, build_motion, simulate_with};
use dvlcal::types::CalibrationParams;
use dvlcal::types::imu::ImuSample;

/// A 60 s simulated recording (poses at 10 Hz, the A50 at its rate, a 200 Hz IMU with walking
/// biases) and the IMU's truth.
fn recording(seed: u64, motion: MotionKind) -> (SimDataset, Vec<ImuSample>, ImuSimConfig) {
    let cfg = SimConfig {
        seed,
        duration_s: 60.0,
        motion,
        ..SimConfig::default()
    };
    let m = build_motion(&cfg).expect("motion");
    let data = simulate_with(&cfg, m.as_ref()).expect("data");
    let imu_cfg = ImuSimConfig::default_truth();
    let imu = simulate_imu(m.as_ref(), &imu_cfg, 0.0, cfg.duration_s, seed).expect("imu");
    (data, imu.samples, imu_cfg)
}

/// The DVL's calibration relative to the IMU: `T_imu_dvl` and `t_imu = t_dvl + offset`.
fn dvl_in_imu(data: &SimDataset, imu: &ImuSimConfig) -> CalibrationParams {
    CalibrationParams {
        t_cam_dvl: imu.t_cam_imu.inverse() * data.truth.t_cam_dvl,
        time_offset_s: data.truth.time_offset_s - imu.time_offset_s,
        velocity_scale: data.truth.velocity_scale,
    }
}

/// Pooled RMS of err/std per group: rotation (3 components), lever arm (3), scale, offset.
fn pooled(z2: &[f64; 8], seeds: f64) -> [f64; 4] {
    [
        ((z2[0] + z2[1] + z2[2]) / (3.0 * seeds)).sqrt(),
        ((z2[3] + z2[4] + z2[5]) / (3.0 * seeds)).sqrt(),
        (z2[6] / seeds).sqrt(),
        (z2[7] / seeds).sqrt(),
    ]
}

/// For the RMS of a standard normal over `n` draws, `sqrt(chi2_n / n)` lies within 0.81..1.18
/// for 60 draws and 0.69..1.28 for 20 at 95 %; the upper bounds are widened to 1.3 and 1.45
/// for the estimator's own approximations (bins, the interpolated motion between knots).
fn assert_calibrated(label: &str, r: [f64; 4]) {
    for (name, v, lo, hi) in [
        ("rotation", r[0], 0.75, 1.3),
        ("lever arm", r[1], 0.75, 1.3),
        ("scale", r[2], 0.6, 1.45),
        ("offset", r[3], 0.6, 1.45),
    ] {
        assert!(
            (lo..=hi).contains(&v),
            "{label}: {name} err/std RMS {v:.2} outside {lo}..{hi} ({r:?})"
        );
    }
}

/// DVL + IMU, no camera: over 20 seeds each of `T_imu_dvl`, the clock offset on the IMU's
/// clock and the scale is off by about its own std.
#[test]
fn dvl_against_the_imu_alone_errors_match_their_std_over_twenty_seeds() {
    let seeds = 20u64;
    let mut z2 = [0.0f64; 8];
    let mut std_sum = [0.0f64; 8];
    for seed in 1..=seeds {
        let (data, samples, imu_cfg) = recording(seed, MotionKind::CalmThenRotate);
        let est = calibrate_dvl_imu(
            &data.dvl,
            &samples,
            &imu_cfg.noise,
            &CalibOptions::default(),
            &ImuOptions::default(),
        )
        .expect("calibration");
        assert!(est.converged, "seed {seed} did not converge");
        assert!(
            est.dvl_used * 10 >= est.dvl_total * 9,
            "seed {seed}: {} of {} DVL reports used",
            est.dvl_used,
            est.dvl_total
        );
        let e = difference(&est.params, &dvl_in_imu(&data, &imu_cfg));
        let s = est.std();
        for i in 0..8 {
            z2[i] += (e[i] / s[i]).powi(2);
            std_sum[i] += s[i];
        }
    }
    let r = pooled(&z2, seeds as f64);
    let n = seeds as f64;
    eprintln!(
        "DVL + IMU err/std RMS {r:.2?}; mean std {:.3} deg, {:.2} mm, {:.4}, {:.2} ms",
        std_sum[0].to_degrees() / n,
        1e3 * std_sum[3] / n,
        std_sum[6] / n,
        1e3 * std_sum[7] / n
    );
    assert_calibrated("DVL + IMU", r);
    // The bound is useful: a quarter of a degree, a few millimetres, a few milliseconds.
    assert!(std_sum[0].to_degrees() / n < 0.5 && std_sum[3] / n < 0.005 && std_sum[7] / n < 0.005);
}

/// The camera, the IMU and the DVL in one problem: the DVL's parameters are off by about their
/// std, and no part of the DVL's calibration is worse than the camera-only one's beyond what
/// 20 seeds can tell (RMS error at most 1.15 times).
#[test]
fn camera_imu_and_dvl_in_one_problem_at_their_std_and_no_worse_than_camera_only() {
    let seeds = 20u64;
    let mut z2 = [0.0f64; 8];
    let mut e2 = [[0.0f64; 4]; 2];
    for seed in 1..=seeds {
        let (data, samples, imu_cfg) = recording(seed, MotionKind::CalmThenRotate);
        let opts = CalibOptions::default();
        let cam = calibrate(&data.poses, &data.dvl, &opts).expect("camera-only");
        let joint = calibrate_camera_imu_dvl(
            &data.poses,
            &samples,
            &imu_cfg.noise,
            &data.dvl,
            &cam.params,
            &opts,
            &ImuOptions::default(),
        )
        .expect("joint");
        assert!(joint.converged, "seed {seed} did not converge");
        let p = joint.state.dvl.expect("the DVL's parameters");
        let s = joint.dvl_std().expect("the DVL's std");
        let ej = difference(&p, &data.truth);
        let ec = difference(&cam.params, &data.truth);
        for i in 0..8 {
            z2[i] += (ej[i] / s[i]).powi(2);
            let g = match i {
                0..=2 => 0,
                3..=5 => 1,
                6 => 2,
                _ => 3,
            };
            e2[0][g] += ec[i] * ec[i];
            e2[1][g] += ej[i] * ej[i];
        }
    }
    let r = pooled(&z2, seeds as f64);
    eprintln!(
        "joint err/std RMS {r:.2?}; RMSE ratio joint/camera-only {:.2?}",
        (0..4)
            .map(|g| (e2[1][g] / e2[0][g]).sqrt())
            .collect::<Vec<_>>()
    );
    assert_calibrated("camera + IMU + DVL", r);
    for (g, name) in ["rotation", "lever arm", "scale", "offset"]
        .iter()
        .enumerate()
    {
        let ratio = (e2[1][g] / e2[0][g]).sqrt();
        assert!(
            ratio <= 1.15,
            "{name}: joint RMSE {ratio:.2} times the camera-only one"
        );
    }
}

/// An accelerometer in g and an IMU of another recording are refused with a reason, never
/// calibrated into a plausible answer.
#[test]
fn an_imu_that_does_not_fit_the_dvl_is_refused_with_the_reason() {
    let (data, samples, imu_cfg) = recording(3, MotionKind::CalmThenRotate);
    let in_g: Vec<ImuSample> = samples
        .iter()
        .map(|s| ImuSample {
            accel: s.accel / 9.80665,
            ..*s
        })
        .collect();
    let e = calibrate_dvl_imu(
        &data.dvl,
        &in_g,
        &imu_cfg.noise,
        &CalibOptions::default(),
        &ImuOptions::default(),
    )
    .expect_err("an accelerometer in g");
    assert!(e.to_string().contains("not g"), "{e}");
    // Another recording's IMU (another seed's motion) on the same clock.
    let (_, other, _) = recording(4, MotionKind::Sinusoid);
    let e = calibrate_dvl_imu(
        &data.dvl,
        &other,
        &imu_cfg.noise,
        &CalibOptions::default(),
        &ImuOptions::default(),
    );
    match e {
        Err(e) => assert!(e.to_string().contains("IMU"), "{e}"),
        Ok(est) => panic!(
            "another recording's IMU calibrated: scale {:.3}, offset {:.3} s, noise factors {:?}",
            est.params.velocity_scale, est.params.time_offset_s, est.noise_factor
        ),
    }
}
