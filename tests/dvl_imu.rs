//! The DVL calibrated against an IMU, with and without a camera: at the Cramér-Rao bound over
//! many simulated seeds (each error over its own std), refusing an IMU that does not fit, and
//! the DVL + IMU mode of `dvlcal calibrate` (no camera data).

mod tmp_common;

use dvlcal::calib::imu::dvl::calibrate_dvl_imu;
use dvlcal::calib::imu::{CarriedDvl, ImuOptions, calibrate_camera_imu_carried};
use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::io::calib_yaml::read_calib_yaml;
use dvlcal::io::dvl_imu_result::read_dvl_imu_result_yaml;
use dvlcal::io::imu::truth::read_imu_truth;
use dvlcal::lie::{Se3, so3};
use dvlcal::pipeline::imu::{adopt_joint_dvl, joint_eligible};
use dvlcal::sim::imu::{ImuSimConfig, simulate_imu};
use dvlcal::sim::{
    Corruption, MotionKind, SimConfig, SimDataset, build_motion, corrupt, simulate_with,
};
use dvlcal::types::CalibrationParams;
use dvlcal::types::imu::ImuSample;
use nalgebra::{Matrix4, Vector3};
use std::path::Path;
use tmp_common::{TmpDir, dvlcal, dvlcal_ok, s};

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

/// DVL + IMU preintegrated, started from the same problem on every fifth knot (what an
/// hour-long recording does) or from the dead reckoning: one problem, one minimum. Gauss-Newton
/// stops within a tenth of a std of it either way, so the two agree within two tenths, and
/// their std and noise factors within 1 %.
#[test]
fn a_coarse_start_reaches_the_minimum_of_the_reckoned_one() {
    let (data, samples, imu_cfg) = recording(3, MotionKind::CalmThenRotate);
    let run = |coarse: bool| {
        let opts = ImuOptions {
            preintegrate: Some(true),
            coarse_start: Some(coarse),
            ..ImuOptions::default()
        };
        calibrate_dvl_imu(
            &data.dvl,
            &samples,
            &imu_cfg.noise,
            &CalibOptions::default(),
            &opts,
        )
        .expect("calibration")
    };
    let (plain, coarse) = (run(false), run(true));
    assert!(plain.converged && coarse.converged);
    let e = difference(&coarse.params, &plain.params);
    let (sp, sc) = (plain.std(), coarse.std());
    for i in 0..8 {
        assert!(
            e[i].abs() < 0.2 * sp[i],
            "parameter {i}: {} against std {}",
            e[i],
            sp[i]
        );
        assert!(
            (sc[i] / sp[i] - 1.0).abs() < 0.01,
            "std {i}: {} against {}",
            sc[i],
            sp[i]
        );
    }
    let (fp, fc) = (plain.noise_factor, coarse.noise_factor);
    for (a, b) in [(fp.0, fc.0), (fp.1, fc.1), (fp.2, fc.2)] {
        assert!(
            (a / b - 1.0).abs() < 0.01,
            "noise factors {fp:?} against {fc:?}"
        );
    }
}

/// The camera, the IMU and the DVL over seeds `1..=seeds` (with `ar1`: the DVL's noise
/// first-order autoregressive with that correlation time, s, the reports stating white noise),
/// as `dvlcal calibrate` runs them: the camera-only calibration, then the joint problem
/// carrying its findings on the DVL's noise, its values and std taken by `adopt_joint_dvl`.
/// Asserts that the std written are never larger than the camera-only ones; returns the
/// squared err/std of the written values and std per parameter, the squared errors per group
/// (rotation, lever arm, scale, offset) camera-only and written, the sum of written over
/// camera-only std per parameter, and the seeds whose joint std were written.
fn three_sensors(seeds: u64, ar1: Option<f64>) -> ([f64; 8], [[f64; 4]; 2], [f64; 8], usize) {
    let mut z2 = [0.0f64; 8];
    let mut e2 = [[0.0f64; 4]; 2];
    let mut ratio = [0.0f64; 8];
    let mut written = 0;
    for seed in 1..=seeds {
        let (mut data, samples, imu_cfg) = recording(seed, MotionKind::CalmThenRotate);
        if let Some(tau) = ar1 {
            let c = Corruption {
                dvl_ar1_tau_s: Some(tau),
                ..Corruption::default()
            };
            corrupt(&mut data, &c, SimConfig::default().dvl_sigma, seed).expect("AR(1) noise");
        }
        let opts = CalibOptions::default();
        let cam = calibrate(&data.poses, &data.dvl, &opts).expect("camera-only");
        assert!(
            joint_eligible(&cam, 1),
            "seed {seed}: the camera-only run is not eligible ({:?})",
            cam.status
        );
        let carried = CarriedDvl::from_outcome(&cam, &opts);
        let joint = calibrate_camera_imu_carried(
            &data.poses,
            &samples,
            &imu_cfg.noise,
            &carried,
            &ImuOptions::default(),
        )
        .expect("joint");
        assert!(joint.converged, "seed {seed} did not converge");
        let mut out = cam.clone();
        let (mut warnings, mut notes) = (Vec::new(), Vec::new());
        assert!(
            adopt_joint_dvl(&mut out, &joint, &opts, &mut warnings, &mut notes),
            "seed {seed}: {warnings:?}"
        );
        written += usize::from(notes.iter().any(|n| n.contains("and so do its std")));
        let ej = difference(&out.params, &data.truth);
        let ec = difference(&cam.params, &data.truth);
        for i in 0..8 {
            let (sw, sc) = (out.covariance[(i, i)].sqrt(), cam.covariance[(i, i)].sqrt());
            assert!(sw <= sc, "seed {seed}: parameter {i} std {sw} above {sc}");
            z2[i] += (ej[i] / sw).powi(2);
            ratio[i] += sw / sc;
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
    (z2, e2, ratio, written)
}

/// The camera, the IMU and the DVL in one problem: the DVL's parameters, with the std written
/// (the joint problem's, which carries the camera-only run's findings on the DVL's noise, when
/// none exceeds the camera-only one), are off by about their std over 20 seeds; the std written
/// are never above the camera-only ones, and no part of the DVL's calibration is worse than the
/// camera-only one's beyond what 20 seeds can tell (RMS error at most 1.15 times).
/// No group's RMS error with the joint problem (`e2[1]`, squared errors summed) above 1.15
/// times the camera-only one (`e2[0]`).
fn assert_no_worse_than_camera_only(e2: &[[f64; 4]; 2]) {
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

#[test]
fn camera_imu_and_dvl_in_one_problem_at_their_std_and_no_worse_than_camera_only() {
    let seeds = 20u64;
    let (z2, e2, ratio, written) = three_sensors(seeds, None);
    let r = pooled(&z2, seeds as f64);
    eprintln!(
        "joint err/std RMS {r:.2?}; RMSE ratio joint/camera-only {:.2?}; mean std ratio \
         {:.2?}; joint std written for {written} of {seeds} seeds",
        (0..4)
            .map(|g| (e2[1][g] / e2[0][g]).sqrt())
            .collect::<Vec<_>>(),
        ratio.map(|x| x / seeds as f64)
    );
    assert_calibrated("camera + IMU + DVL", r);
    assert_no_worse_than_camera_only(&e2);
    // White noise leaves nothing to doubt: the joint std are written for most seeds.
    assert!(written * 4 >= 3 * seeds as usize, "{written} of {seeds}");
}

/// The same with the DVL's noise correlated (first-order autoregressive, 1 s, at the A50's
/// rate; the reports state white noise): the camera-only run's whiteness inflation carried into
/// the joint problem keeps the written std from being too small (err/std RMS at most the upper
/// bounds of [`assert_calibrated`]; rotation, lever arm and scale within its range). The clock
/// offset's std stays conservative as the camera-only one is (about 0.5 and 0.6 err/std on
/// these seeds: the integrated autocorrelation time, one inflation for all parameters, is the
/// largest for the offset), so only its upper bound is asserted.
#[test]
fn camera_imu_and_dvl_with_correlated_dvl_noise_at_or_within_their_std() {
    let seeds = 20u64;
    let (z2, e2, ratio, written) = three_sensors(seeds, Some(1.0));
    let r = pooled(&z2, seeds as f64);
    eprintln!(
        "AR(1) 1 s: joint err/std RMS {r:.2?}; RMSE ratio joint/camera-only {:.2?}; mean std \
         ratio {:.2?}; joint std written for {written} of {seeds} seeds",
        (0..4)
            .map(|g| (e2[1][g] / e2[0][g]).sqrt())
            .collect::<Vec<_>>(),
        ratio.map(|x| x / seeds as f64)
    );
    assert_calibrated("camera + IMU + DVL, AR(1) noise", [r[0], r[1], r[2], 1.0]);
    assert!(r[3] <= 1.45, "offset err/std RMS {:.2}", r[3]);
    assert_no_worse_than_camera_only(&e2);
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

/// `calibrate` on a dataset folder with a DVL log and an IMU but no camera data writes
/// `T_imu_dvl`, the offset on the IMU's clock and the scale, each within 4 std of the truth
/// that `simulate` wrote (`T_cam_imu^-1 T_cam_dvl`, `t_imu = t_dvl + (offset_dvl -
/// offset_imu)`); options that only a camera run reads are refused, and a reader of camera
/// results refuses the file with what it is.
#[test]
fn calibrate_without_a_camera_writes_the_dvl_relative_to_the_imu() {
    let tmp = TmpDir::new("dvl_imu_cli");
    let ds = tmp.path("ds");
    dvlcal_ok(&[
        "simulate",
        "--imu",
        "--duration",
        "60",
        "--seed",
        "5",
        "--out",
        s(&ds),
    ]);
    std::fs::remove_file(ds.join("poses.txt")).expect("remove the camera poses");
    let out = tmp.path("out.yaml");
    // A Kalibr file an earlier camera run left beside the result: it cannot be this run's.
    let stale = tmp.path("out-camchain-imucam.yaml");
    std::fs::write(&stale, "cam0: {}\n").expect("stale export");
    let report = tmp.path("out.html");
    let stdout = dvlcal_ok(&[
        "calibrate",
        s(&ds),
        "--out",
        s(&out),
        "--report",
        s(&report),
    ]);
    assert!(
        stdout.contains("DVL + IMU: no camera data given"),
        "{stdout}"
    );
    assert!(
        stdout.contains(&format!("report {}", report.display())),
        "{stdout}"
    );
    let r = read_dvl_imu_result_yaml(&out).expect("result");
    let cam = read_calib_yaml(&ds.join("truth/calibration.yaml"))
        .expect("truth")
        .to_params()
        .expect("truth params");
    let imu = read_imu_truth(&ds.join("truth/imu.yaml")).expect("IMU truth");
    let truth = imu.t_cam_imu.inverse() * cam.t_cam_dvl;
    let m = Matrix4::from_fn(|i, j| r.t_imu_dvl[i][j]);
    let est = Se3::from_matrix(&m);
    let std = r.std.as_ref().expect("std");
    let (rot_s, lever_s) = (
        std.rotation_deg.expect("rotation std"),
        std.lever_arm_m.expect("lever std"),
    );
    // Rotation about the DVL frame's axes (a left perturbation of R_dvl_imu).
    let e_rot = so3::log(&(est.rot.transpose() * truth.rot)).map(f64::to_degrees);
    for i in 0..3 {
        assert!(
            e_rot[i].abs() < 4.0 * rot_s[i],
            "rotation {e_rot:?} deg, std {rot_s:?}"
        );
        let e = est.trans[i] - truth.trans[i];
        assert!(
            e.abs() < 4.0 * lever_s[i],
            "lever arm axis {i}: {e} m, std {}",
            lever_s[i]
        );
    }
    let off = cam.time_offset_s - imu.imu_time_offset_s;
    assert!((r.time_offset_s - off).abs() < 4.0 * std.time_offset_s.expect("offset std"));
    assert!(
        (r.velocity_scale - cam.velocity_scale).abs()
            < 4.0 * std.velocity_scale.expect("scale std")
    );
    let obs = r.observability.as_ref().expect("verdicts");
    assert_eq!(format!("{:?}", obs.lever_arm), "Ok");
    // The motion prior's share of the std, per parameter: on this simulated motion a small
    // part of them (a lever arm's move below its std), so no warning that it leads.
    let info = r.info.as_ref().expect("info");
    let shift = info
        .figures
        .dvl_prior_shift_per_parameter
        .as_ref()
        .expect("dvl_prior_shift_per_parameter");
    assert_eq!(shift.len(), 8, "{shift:?}");
    for i in 0..3 {
        assert!(shift[3 + i].abs() < lever_s[i], "{shift:?} {lever_s:?}");
    }
    assert!(
        !info.warnings.iter().any(|w| w.contains("motion prior")),
        "{:?}",
        info.warnings
    );
    exports_hold_the_dvl_in_the_imu(&tmp, &ds, &est, &stdout);
    // The report: its sections in order, the estimate as the result file has it, the verdicts
    // in words, and the result file itself.
    let html = std::fs::read_to_string(&report).expect("report");
    let mut at = 0;
    for id in dvlcal::report::DVL_IMU_SECTION_IDS {
        let pos = html[at..]
            .find(&format!("<section id=\"{id}\">"))
            .unwrap_or_else(|| panic!("section {id} missing or out of order"));
        at += pos;
    }
    let lever = format!(
        "[{:.4}, {:.4}, {:.4}]",
        r.t_imu_dvl[0][3], r.t_imu_dvl[1][3], r.t_imu_dvl[2][3]
    );
    assert!(html.contains(&lever), "no lever arm {lever} in the report");
    assert!(html.contains(&format!("{:.5} s", r.time_offset_s)));
    assert!(html.contains("Every estimated quantity is well determined"));
    let moved = format!(
        "the lever arm by [{:.2}, {:.2}, {:.2}] mm",
        shift[3] * 1e3,
        shift[4] * 1e3,
        shift[5] * 1e3
    );
    assert!(
        html.contains("id=\"dvl-imu-prior\"") && html.contains(&moved),
        "{moved} not in the report"
    );
    assert_eq!(html.matches("well determined</span>").count(), 4);
    assert!(html.contains("T_imu_dvl:"), "the result file is not shown");
    assert!(!stale.exists(), "the stale Kalibr file was left");
    // A camera run's option is refused; a camera result's reader names the file's kind.
    let refused = dvlcal(&[
        "calibrate",
        s(&ds),
        "--out",
        s(&tmp.path("r.yaml")),
        "--loss",
        "huber",
    ]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("DVL + IMU"));
    let e = read_calib_yaml(&out).expect_err("not a camera result");
    assert!(e.to_string().contains("a DVL + IMU result"), "{e}");
}

/// The ROS commands and the URDF beside a DVL + IMU result publish `est` (`T_imu_dvl`, read
/// from the result) as the DVL frame in the IMU frame, with the IMU's clock; the URDF is a robot
/// `check_urdf` (Debian's liburdfdom-tools) reads with the IMU as its root; there is no Kalibr
/// file (no camera). `--frames` names the two frames.
fn exports_hold_the_dvl_in_the_imu(tmp: &TmpDir, ds: &Path, est: &Se3, stdout: &str) {
    let (tf, urdf) = (tmp.path("out-tf.txt"), tmp.path("out-urdf.xml"));
    assert!(
        stdout.contains(&format!("{} and {}", tf.display(), urdf.display())),
        "{stdout}"
    );
    let text = std::fs::read_to_string(&tf).expect("tf export");
    let line = text
        .lines()
        .find(|l| l.starts_with("rosrun"))
        .unwrap_or_default();
    assert!(line.ends_with(" imu dvl"), "{text}");
    let v: Vec<f64> = line
        .split_whitespace()
        .skip(3)
        .take(7)
        .filter_map(|x| x.parse().ok())
        .collect();
    assert_eq!(v.len(), 7, "{line}");
    let back = Se3::from_quaternion_xyzw(&[v[3], v[4], v[5], v[6]], Vector3::new(v[0], v[1], v[2]));
    let d = (back.inverse() * *est).log().norm();
    assert!(d < 1e-9, "the tf export is {d} from T_imu_dvl: {line}");
    assert!(text.contains("the DVL frame in the IMU frame"), "{text}");
    assert!(text.contains("# clock: t_imu = t_dvl + "), "{text}");
    let parsed = check_urdf(&urdf);
    assert!(
        parsed.contains("root Link: imu has 1 child(ren)"),
        "{parsed}"
    );
    let xml = std::fs::read_to_string(&urdf).expect("URDF");
    assert!(
        xml.contains("(T_imu_dvl)") && xml.contains("robot's IMU link"),
        "{xml}"
    );
    // Named frames.
    let named = tmp.path("named.yaml");
    dvlcal_ok(&[
        "calibrate",
        s(ds),
        "--out",
        s(&named),
        "--frames",
        "base_imu,a50",
    ]);
    let text = std::fs::read_to_string(tmp.path("named-tf.txt")).expect("tf export");
    assert!(text.contains(" base_imu a50\n"), "{text}");
    let parsed = check_urdf(&tmp.path("named-urdf.xml"));
    assert!(parsed.contains("root Link: base_imu"), "{parsed}");
    assert!(!tmp.path("named-camchain-imucam.yaml").exists());
}

/// `check_urdf` on `urdf`: its output, after asserting it parsed.
fn check_urdf(urdf: &Path) -> String {
    let r = std::process::Command::new("check_urdf")
        .arg(urdf)
        .output()
        .unwrap_or_else(|e| panic!("check_urdf (Debian's liburdfdom-tools, make test-deps): {e}"));
    let out = String::from_utf8_lossy(&r.stdout).into_owned();
    assert!(
        r.status.success(),
        "check_urdf refused {}: {out}",
        urdf.display()
    );
    out
}

/// With a camera, an IMU and a DVL log, `calibrate` takes the DVL's values from the three
/// sensors together (a note says so, with the joint std), each within 4 of the std it writes
/// (the joint ones, or the camera-only ones when a joint one is larger) of the truth.
#[test]
fn calibrate_with_all_three_takes_the_dvls_values_from_the_joint_problem() {
    let tmp = TmpDir::new("dvl_imu_three");
    let ds = tmp.path("ds");
    dvlcal_ok(&[
        "simulate",
        "--imu",
        "--duration",
        "60",
        "--seed",
        "6",
        "--out",
        s(&ds),
    ]);
    let out = tmp.path("out.yaml");
    dvlcal_ok(&["calibrate", s(&ds), "--out", s(&out)]);
    let f = read_calib_yaml(&out).expect("result");
    let notes = f
        .info
        .as_ref()
        .map(|i| i.notes.join("\n"))
        .unwrap_or_default();
    assert!(notes.contains("calibrated together"), "{notes}");
    let est = f.to_params().expect("params");
    let truth = read_calib_yaml(&ds.join("truth/calibration.yaml"))
        .expect("truth")
        .to_params()
        .expect("truth params");
    let e = difference(&est, &truth);
    let std = f.std.as_ref().expect("std");
    let rs = std.rotation_deg.expect("rotation std");
    let ls = std.lever_arm_m.expect("lever std");
    for i in 0..3 {
        assert!(e[i].to_degrees().abs() < 4.0 * rs[i], "rotation {i}: {e:?}");
        assert!(e[3 + i].abs() < 4.0 * ls[i], "lever {i}: {e:?}");
    }
    assert!(e[6].abs() < 4.0 * std.velocity_scale.expect("scale std"));
    assert!(e[7].abs() < 4.0 * std.time_offset_s.expect("offset std"));
    assert!(f.t_cam_imu.is_some(), "the IMU's keys beside the DVL's");
    // The IMU's files are inputs of the run, digested in its provenance.
    let roles: Vec<String> = f
        .provenance
        .as_ref()
        .map(|p| p.inputs.iter().map(|i| i.role.clone()).collect())
        .unwrap_or_default();
    assert!(
        roles.iter().any(|r| r == "imu") && roles.iter().any(|r| r == "imu_noise"),
        "{roles:?}"
    );
}
