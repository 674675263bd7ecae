//! The command line on clocks far apart and on results that fail their sanity checks: exit
//! status, message, `status:` in the result file, exports only for a trustworthy result (or with
//! `--force`); guesses in their minimal forms; the DVL's sound speed from its configuration reply.

mod tmp_common;

use std::path::Path;

use dvlcal::io::calib_yaml::{ResultStatus, read_calib_yaml, read_calibration_guess};
use dvlcal::io::dvl::{DvlReadOptions, read_dvl_log};
use tmp_common::{TmpDir, dvlcal, s};

fn simulate(dir: &Path, seed: &str, offset: &str) {
    let out = dvlcal(&[
        "simulate",
        "--out",
        s(dir),
        "--seed",
        seed,
        "--duration",
        "90",
        "--time-offset",
        offset,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_dvl_clock_37_s_off_calibrates_with_no_flag() {
    let tmp = TmpDir::new("clock-cli-37");
    let d = tmp.0.join("run");
    simulate(&d, "4", "37.0");
    let out_yaml = tmp.0.join("out/calibration.yaml");
    let out = dvlcal(&["calibrate", s(&d), "--out", s(&out_yaml)]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let f = read_calib_yaml(&out_yaml).expect("result");
    assert_eq!(f.status, Some(ResultStatus::Ok));
    assert!((f.time_offset_s - 37.0).abs() < 0.01, "{}", f.time_offset_s);
    assert!(tmp.0.join("out/calibration-tf.txt").exists());
    let text = std::fs::read_to_string(&out_yaml).expect("yaml");
    assert!(text.contains("status: ok"), "{text}");
    assert!(text.contains("clock_alignment_lag_s"), "{text}");
}

#[test]
fn a_failed_calibration_exits_non_zero_and_writes_no_exports() {
    let tmp = TmpDir::new("clock-cli-failed");
    let d = tmp.0.join("run");
    let other = tmp.0.join("other");
    simulate(&d, "5", "0.07");
    simulate(&other, "6", "0.07");
    // The DVL log of another recording.
    std::fs::copy(other.join("dvl.jsonl"), d.join("dvl.jsonl")).expect("copy");
    let out_yaml = tmp.0.join("out/calibration.yaml");
    // A stale export of an earlier run must not survive a failed one.
    std::fs::create_dir_all(tmp.0.join("out")).expect("out");
    std::fs::write(tmp.0.join("out/calibration-tf.txt"), "stale").expect("stale");
    let out = dvlcal(&["calibrate", s(&d), "--out", s(&out_yaml)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "{stdout}");
    assert!(stderr.contains("the calibration failed"), "{stderr}");
    assert!(stdout.contains("CALIBRATION FAILED"), "{stdout}");
    let text = std::fs::read_to_string(&out_yaml).expect("the result file is written");
    assert!(text.starts_with("# dvlcal"), "{text}");
    assert!(text.contains("status: failed"), "{text}");
    assert!(text.contains("failure:"), "{text}");
    assert!(!tmp.0.join("out/calibration-tf.txt").exists());
    assert!(!tmp.0.join("out/calibration-camchain-imucam.yaml").exists());
    // A failed result is no guess.
    let e = read_calibration_guess(&out_yaml).unwrap_err().to_string();
    assert!(e.contains("failed"), "{e}");
    // --force writes the exports, and still fails.
    let out = dvlcal(&["calibrate", s(&d), "--out", s(&out_yaml), "--force"]);
    assert!(!out.status.success());
    assert!(tmp.0.join("out/calibration-tf.txt").exists());
    assert!(tmp.0.join("out/calibration-camchain-imucam.yaml").exists());
}

#[test]
fn guesses_in_their_minimal_forms() {
    let tmp = TmpDir::new("clock-cli-guess");
    let w = |name: &str, text: &str| {
        let p = tmp.0.join(name);
        std::fs::write(&p, text).expect("write");
        p
    };
    // Half a turn about x as a quaternion, as roll, and as a matrix: the same rotation.
    let q = read_calibration_guess(&w(
        "q.yaml",
        "quaternion_cam_dvl_xyzw: [1, 0, 0, 0]\nlever_arm_cam_m: [0.1, 0.2, 0.3]\n",
    ))
    .expect("quaternion");
    let r = read_calibration_guess(&w(
        "r.yaml",
        "rpy_cam_dvl_deg: [180, 0, 0]\nlever_arm_cam_m: [0.1, 0.2, 0.3]\ntime_offset_s: 0.5\n",
    ))
    .expect("rpy");
    let t = read_calibration_guess(&w(
        "t.yaml",
        "T_cam_dvl:\n  - [1, 0, 0, 0.1]\n  - [0, -1, 0, 0.2]\n  - [0, 0, -1, 0.3]\n  - [0, 0, 0, 1]\n",
    ))
    .expect("matrix");
    for g in [&q, &r, &t] {
        assert!((g.t_cam_dvl.rot - t.t_cam_dvl.rot).norm() < 1e-12);
        assert!((g.lever_arm_cam_m() - t.lever_arm_cam_m()).norm() < 1e-12);
        assert_eq!(g.velocity_scale, 1.0);
    }
    assert_eq!(q.time_offset_s, 0.0);
    assert_eq!(r.time_offset_s, 0.5);
    // A rotation without a lever arm, disagreeing forms, and no rotation at all.
    let e = read_calibration_guess(&w("a.yaml", "rpy_cam_dvl_deg: [0, 0, 90]\n"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("lever_arm_cam_m"), "{e}");
    let e = read_calibration_guess(&w(
        "b.yaml",
        "rpy_cam_dvl_deg: [0, 0, 90]\nquaternion_cam_dvl_xyzw: [0, 0, 0, 1]\nlever_arm_cam_m: [0, 0, 0]\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("different rotations"), "{e}");
    let e = read_calibration_guess(&w("c.yaml", "lever_arm_cam_m: [0, 0, 0]\n"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no rotation"), "{e}");

    // A guess without a clock offset for a recording whose DVL clock is 37 s off: the data give
    // the offset, and the warning says so.
    let d = tmp.0.join("run");
    simulate(&d, "7", "37.0");
    let truth = read_calib_yaml(&d.join("truth/calibration.yaml")).expect("truth");
    let q = truth.quaternion_cam_dvl_xyzw;
    let l = truth.lever_arm_cam_m;
    let guess = w(
        "guess.yaml",
        &format!(
            "quaternion_cam_dvl_xyzw: [{}, {}, {}, {}]\nlever_arm_cam_m: [{}, {}, {}]\n",
            q[0], q[1], q[2], q[3], l[0], l[1], l[2]
        ),
    );
    let out_yaml = tmp.0.join("bcd.yaml");
    let out = dvlcal(&[
        "calibrate",
        s(&d),
        "--method",
        "bcd",
        "--init",
        s(&guess),
        "--out",
        s(&out_yaml),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("the guess's clock offset"), "{stdout}");
    let f = read_calib_yaml(&out_yaml).expect("result");
    assert!((f.time_offset_s - 37.0).abs() < 0.01, "{}", f.time_offset_s);
}

#[test]
fn the_dvl_sound_speed_comes_from_its_configuration_reply() {
    let tmp = TmpDir::new("clock-cli-sound");
    let d = tmp.0.join("run");
    simulate(&d, "8", "0.07");
    let log = d.join("dvl.jsonl");
    let mut text = std::fs::read_to_string(&log).expect("log");
    text.insert_str(
        0,
        "{\"response_to\":\"get_config\",\"success\":true,\"error_message\":\"\",\"result\":\
         {\"speed_of_sound\":1475,\"acoustic_enabled\":true,\"dark_mode\":false,\
         \"mounting_rotation_offset\":0},\"format\":\"json_v3\",\"type\":\"response\"}\r\n",
    );
    std::fs::write(&log, text).expect("write");
    let parsed = read_dvl_log(&log, &DvlReadOptions::default()).expect("log");
    assert_eq!(parsed.stats.sound_speed_mps, Some(1475.0));
    assert!(
        parsed
            .stats
            .sound_speed_source
            .as_deref()
            .unwrap_or("")
            .ends_with(":1")
    );
    let out_yaml = tmp.0.join("c.yaml");
    let out = dvlcal(&["calibrate", s(&d), "--out", s(&out_yaml)]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(
        stdout.contains("the DVL assumes a sound speed of 1475 m/s"),
        "{stdout}"
    );
    let yaml = std::fs::read_to_string(&out_yaml).expect("yaml");
    assert!(yaml.contains("water_sound_speed_mps"), "{yaml}");

    // The serial form: wrc,speed_of_sound,mounting_rotation_offset,acoustic_enabled,dark_mode.
    let serial = tmp.0.join("serial.txt");
    let mut lines = String::new();
    lines.push_str(&dvlcal::io::dvl::a50::with_checksum("wrc,1480,20,n,y"));
    for r in std::fs::read_to_string(&log).expect("log").lines().skip(1) {
        let rep = dvlcal::io::dvl::a50::parse_velocity_report(r).expect("report");
        lines.push_str(&dvlcal::io::dvl::a50::wrz_sentence(&rep));
    }
    std::fs::write(&serial, lines).expect("write");
    let parsed = read_dvl_log(&serial, &DvlReadOptions::default()).expect("serial log");
    assert_eq!(parsed.stats.sound_speed_mps, Some(1480.0));
}

#[test]
fn clock_drift_estimates_the_drift_into_the_result_and_against_the_simulators_truth() {
    let tmp = TmpDir::new("clock-cli-drift");
    let d = tmp.0.join("run");
    let out = dvlcal(&[
        "simulate",
        "--out",
        s(&d),
        "--seed",
        "3",
        "--duration",
        "300",
        "--motion",
        "sinusoid",
        "--clock-drift",
        "200",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth = read_calib_yaml(&d.join("truth/calibration.yaml")).expect("truth");
    assert_eq!(truth.clock_drift_ppm, Some(200.0));

    // Without the drift estimated, the warning says how to.
    let plain = tmp.0.join("plain/calibration.yaml");
    let out = dvlcal(&["calibrate", s(&d), "--out", s(&plain)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&plain).expect("yaml");
    assert!(
        text.contains("estimate the drift with --clock-drift"),
        "{text}"
    );
    assert!(!text.contains("clock_drift_ppm"), "{text}");

    let res = tmp.0.join("drift/calibration.yaml");
    let out = dvlcal(&["calibrate", s(&d), "--clock-drift", "--out", s(&res)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&res).expect("yaml");
    let f = read_calib_yaml(&res).expect("result");
    let ppm = f.clock_drift_ppm.expect("clock_drift_ppm");
    let std = f
        .std
        .as_ref()
        .and_then(|s| s.clock_drift_ppm)
        .expect("its std");
    let reference = f.clock_reference_t_dvl_s.expect("clock_reference_t_dvl_s");
    assert!((ppm - 200.0).abs() < 3.0 * std, "{ppm} +- {std}\n{text}");
    // The offset at the estimator's reference, from the truth's at its own.
    let truth_ref = truth.clock_reference_t_dvl_s.expect("truth reference");
    let offset = truth.time_offset_s + 200e-6 * (reference - truth_ref);
    let offset_std = f
        .std
        .as_ref()
        .and_then(|s| s.time_offset_s)
        .expect("offset std");
    assert!(
        (f.time_offset_s - offset).abs() < 3.0 * offset_std,
        "{} vs {offset} (std {offset_std})",
        f.time_offset_s
    );
    // The reference is on the log's own clock (Unix seconds for the simulator's A50 log), in
    // the middle of the recording.
    assert!(
        reference > 1e9 && (reference - truth_ref - 150.0).abs() < 2.0,
        "{reference}"
    );
    // The main keys in order, the drift after the scale.
    let keys: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with(['#', ' ', '-']))
        .map(|l| l.split(':').next().unwrap_or(""))
        .take(10)
        .collect();
    assert_eq!(
        keys[6..],
        [
            "velocity_scale",
            "clock_drift_ppm",
            "clock_reference_t_dvl_s",
            "std"
        ],
        "{text}"
    );
    assert!(!text.contains("the clock offset drifts"), "{text}");
}
