//! `calibrate`'s IMU inputs through the command line: `--imu FILE` and `--imu-noise FILE`
//! beside (or instead of) a dataset folder's own, the camera + IMU mode when no DVL log is
//! given, `--imu-noise` refused without an IMU stream, and a bag's `sensor_msgs/Imu` topic
//! calibrated beside its camera poses and DVL reports (a fixture written by rosbags:
//! tests/fixtures/imu_bags/README.md). Every estimate is checked against the simulator's truth,
//! within 4 of its own standard deviations.

mod tmp_common;

use std::path::Path;

use dvlcal::io::calib_yaml::read_calib_yaml;
use dvlcal::io::imu::truth::{ImuTruth, read_imu_truth};
use dvlcal::io::imu_result::read_imu_result_yaml;
use dvlcal::lie::{Se3, so3};
use nalgebra::{Matrix4, Vector3};
use tmp_common::{TmpDir, dvlcal, s};

/// The IMU's estimate: `T_cam_imu`, its clock offset and std (rotation deg, lever arm m,
/// offset s) from a result file's IMU keys.
struct ImuKeys {
    t: Se3,
    offset_s: f64,
    std_rot_deg: [f64; 3],
    std_lever_m: [f64; 3],
    std_offset_s: f64,
}

/// Each estimate against the truth, in its own std: all within 4; the largest ratio returned.
fn within_4_std(k: &ImuKeys, truth: &ImuTruth, what: &str) -> f64 {
    let rot = so3::log(&(truth.t_cam_imu.rot.transpose() * k.t.rot));
    let mut worst = 0.0f64;
    for i in 0..3 {
        let r = rot[i].to_degrees().abs() / k.std_rot_deg[i];
        let l = (k.t.trans[i] - truth.t_cam_imu.trans[i]).abs() / k.std_lever_m[i];
        assert!(r < 4.0, "{what}: rotation {i} off by {r:.2} std ({rot})");
        assert!(l < 4.0, "{what}: lever arm {i} off by {l:.2} std");
        worst = worst.max(r).max(l);
    }
    let o = (k.offset_s - truth.imu_time_offset_s).abs() / k.std_offset_s;
    assert!(o < 4.0, "{what}: offset off by {o:.2} std");
    let worst = worst.max(o);
    eprintln!("{what}: largest error {worst:.2} std");
    worst
}

fn from_rows(m: &[[f64; 4]; 4]) -> Se3 {
    Se3::from_matrix(&Matrix4::from_fn(|i, j| m[i][j]))
}

/// The IMU keys of a three-sensor result file.
fn keys_of_calibration(path: &Path) -> ImuKeys {
    let f = read_calib_yaml(path).expect("result");
    let std = f.std.and_then(|s| s.imu).expect("std.imu");
    ImuKeys {
        t: from_rows(&f.t_cam_imu.expect("T_cam_imu")),
        offset_s: f.imu_time_offset_s.expect("imu_time_offset_s"),
        std_rot_deg: std.rotation_deg,
        std_lever_m: std.lever_arm_m,
        std_offset_s: std.time_offset_s,
    }
}

fn simulate(tmp: &TmpDir, name: &str) -> std::path::PathBuf {
    let data = tmp.path(name);
    let out = dvlcal(&[
        "simulate",
        "--imu",
        "--duration",
        "40",
        "--seed",
        "9",
        "--out",
        s(&data),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    data
}

/// The folder's IMU files moved elsewhere and named with `--imu` and `--imu-noise`: the IMU is
/// calibrated beside the DVL as when they were in the folder; a stream named while the folder
/// has its own wins, and the folder's is listed as ignored.
#[test]
fn imu_files_named_on_the_command_line_are_calibrated_beside_the_dvl() {
    let tmp = TmpDir::new("imu-cli-named");
    let data = simulate(&tmp, "rec");
    let truth = read_imu_truth(&data.join("truth/imu.yaml")).expect("truth");
    let (csv, noise) = (tmp.path("elsewhere.csv"), tmp.path("noise.yaml"));
    std::fs::rename(data.join("imu0/data.csv"), &csv).expect("move the stream");
    std::fs::rename(data.join("imu.yaml"), &noise).expect("move the noise");
    let result = tmp.path("r.yaml");
    let out = dvlcal(&[
        "calibrate",
        s(&data),
        "--imu",
        s(&csv),
        "--imu-noise",
        s(&noise),
        "--out",
        s(&result),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("imu lever p_cam_imu"), "{stdout}");
    within_4_std(
        &keys_of_calibration(&result),
        &truth,
        "--imu FILE --imu-noise FILE",
    );
    let f = read_calib_yaml(&result).expect("result");
    let info = f.info.expect("info");
    assert_eq!(info.figures.imu_samples, Some(truth.samples));
    assert_eq!(info.figures.imu_file.as_deref(), Some(s(&csv)));

    // The folder has a stream of its own again (a copy, cut to its first half): the named one
    // wins, and the summary of the folder says which was ignored and why.
    std::fs::create_dir_all(data.join("imu0")).expect("imu0");
    let text = std::fs::read_to_string(&csv).expect("csv");
    let half: Vec<&str> = text.lines().take(text.lines().count() / 2).collect();
    std::fs::write(data.join("imu0/data.csv"), half.join("\n") + "\n").expect("half");
    let out = dvlcal(&[
        "calibrate",
        s(&data),
        "--imu",
        s(&csv),
        "--imu-noise",
        s(&noise),
        "--out",
        s(&result),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("ignored") && stdout.contains("the IMU stream named instead"),
        "{stdout}"
    );
    let f = read_calib_yaml(&result).expect("result");
    assert_eq!(
        f.info.expect("info").figures.imu_samples,
        Some(truth.samples)
    );
}

/// No DVL log: camera + IMU. The result file holds the IMU's keys within 4 std of the truth and
/// no DVL key; the exports carry the IMU alone; readers of DVL results refuse the file with a
/// message saying what it is.
#[test]
fn without_a_dvl_log_the_camera_and_imu_are_calibrated_alone() {
    let tmp = TmpDir::new("imu-cli-no-dvl");
    let data = simulate(&tmp, "rec");
    std::fs::remove_file(data.join("dvl.jsonl")).expect("remove the DVL log");
    let truth = read_imu_truth(&data.join("truth/imu.yaml")).expect("truth");
    let result = tmp.path("out/r.yaml");
    let report = tmp.path("out/r.html");
    let out = dvlcal(&[
        "calibrate",
        s(&data),
        "--out",
        s(&result),
        "--report",
        s(&report),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("camera + IMU: no DVL log given"),
        "{stdout}"
    );
    // The report: its sections in order, the IMU's estimate and verdicts, the result file.
    let html = std::fs::read_to_string(&report).expect("report");
    let mut at = 0;
    for id in dvlcal::report::CAMERA_IMU_SECTION_IDS {
        at += html[at..]
            .find(&format!("<section id=\"{id}\">"))
            .unwrap_or_else(|| panic!("section {id} missing or out of order"));
    }
    let written = read_imu_result_yaml(&result).expect("result");
    let lever = format!(
        "[{:.4}, {:.4}, {:.4}]",
        written.t_cam_imu[0][3], written.t_cam_imu[1][3], written.t_cam_imu[2][3]
    );
    assert!(html.contains(&lever), "no lever arm {lever} in the report");
    assert!(html.contains("id=\"imu-verdicts\""));
    assert!(html.contains("T_cam_imu:"), "the result file is not shown");
    let text = std::fs::read_to_string(&result).expect("result text");
    for key in [
        "T_cam_dvl",
        "time_offset_s:\n",
        "velocity_scale",
        "lever_arm_cam_m",
    ] {
        assert!(
            !text.lines().any(|l| l.starts_with(key.trim_end())),
            "{key} in {text}"
        );
    }
    let f = read_imu_result_yaml(&result).expect("camera + IMU result");
    let std = f.std.as_ref().expect("std.imu").imu.clone();
    let keys = ImuKeys {
        t: from_rows(&f.t_cam_imu),
        offset_s: f.imu_time_offset_s,
        std_rot_deg: std.rotation_deg,
        std_lever_m: std.lever_arm_m,
        std_offset_s: std.time_offset_s,
    };
    within_4_std(&keys, &truth, "camera + IMU");
    assert_eq!(
        f.observability
            .as_ref()
            .expect("observability")
            .imu
            .rotation,
        dvlcal::io::calib_yaml::Observability::Ok
    );
    let g = Vector3::from(f.imu_gravity_world_mps2.expect("gravity"));
    assert!((g - truth.gravity_world).norm() < 0.05, "{g}");
    assert!(f.imu_bias_start.is_some() && f.provenance.is_some());
    assert_eq!(
        f.info.expect("info").figures.imu_samples,
        Some(truth.samples)
    );

    // The exports: the IMU's static transform, a URDF with the camera and IMU links, and
    // Kalibr's camchain-imucam with the IMU in its slot and no DVL key.
    let tf = std::fs::read_to_string(tmp.path("out/r-tf.txt")).expect("tf");
    assert!(tf.contains("--frame-id cam0 --child-frame-id imu"), "{tf}");
    let urdf = std::fs::read_to_string(tmp.path("out/r-urdf.xml")).expect("urdf");
    assert!(urdf.contains("<child link=\"imu\"/>"), "{urdf}");
    assert!(!urdf.contains("<link name=\"dvl\"/>"), "{urdf}");
    let imucam = std::fs::read_to_string(tmp.path("out/r-camchain-imucam.yaml")).expect("imucam");
    let shift: f64 = imucam
        .lines()
        .find_map(|l| l.trim().strip_prefix("timeshift_cam_imu: "))
        .and_then(|v| v.parse().ok())
        .expect("timeshift_cam_imu");
    assert!((shift + f.imu_time_offset_s).abs() < 1e-9, "{shift}");
    assert!(imucam.contains("T_cam_imu:"), "{imucam}");
    assert!(
        !imucam.contains("T_cam_dvl") && !imucam.contains("dvl_"),
        "{imucam}"
    );

    // compare-calib reads DVL results: it refuses this one, saying why, without a panic.
    let out = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&result),
        "--truth",
        s(&data.join("truth/calibration.yaml")),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("camera + IMU result") && !err.contains("panicked"),
        "{err}"
    );

    // The DVL's settings are refused in this mode, and without the noise file the error says
    // what is missing.
    let out = dvlcal(&["calibrate", s(&data), "--out", s(&result), "--clock-drift"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--clock-drift") && err.contains("no DVL log"),
        "{err}"
    );
    std::fs::remove_file(data.join("imu.yaml")).expect("remove the noise");
    let out = dvlcal(&["calibrate", s(&data), "--out", s(&result)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("no DVL log") && err.contains("--imu-noise"),
        "{err}"
    );
}

/// `--imu-noise` with no IMU stream anywhere is refused: exit 2, naming the option.
#[test]
fn imu_noise_without_an_imu_stream_is_refused() {
    let tmp = TmpDir::new("imu-cli-noise-alone");
    let data = tmp.path("rec");
    let out = dvlcal(&[
        "simulate",
        "--duration",
        "20",
        "--seed",
        "3",
        "--out",
        s(&data),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let noise = tmp.path("imu.yaml");
    std::fs::write(
        &noise,
        "accelerometer_noise_density: 0.004\naccelerometer_random_walk: 0.0006\n\
         gyroscope_noise_density: 0.00034\ngyroscope_random_walk: 3.8e-5\nupdate_rate: 200.0\n",
    )
    .expect("noise");
    let result = tmp.path("r.yaml");
    let out = dvlcal(&[
        "calibrate",
        s(&data),
        "--imu-noise",
        s(&noise),
        "--out",
        s(&result),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--imu-noise") && err.contains("no --imu FILE"),
        "{err}"
    );
    assert!(!result.exists());
}

/// A bag with camera poses, the A50 driver's DVL reports and an Imu topic, written by rosbags
/// from a simulated recording: with `--imu-noise` the bag's IMU is calibrated beside the DVL,
/// within 4 std of the simulator's truth; without it, the DVL alone, with a warning saying
/// what to give.
#[test]
fn a_bags_imu_topic_is_calibrated_with_imu_noise() {
    let dir = Path::new("tests/fixtures/imu_bags");
    let bag = dir.join("cam_dvl_imu.mcap");
    let noise = dir.join("cam_dvl_imu_truth/imu.yaml");
    let truth = read_imu_truth(&dir.join("cam_dvl_imu_truth/truth/imu.yaml")).expect("truth");
    let tmp = TmpDir::new("imu-cli-bag");
    let result = tmp.path("r.yaml");
    let out = dvlcal(&[
        "calibrate",
        s(&bag),
        "--imu-noise",
        s(&noise),
        "--out",
        s(&result),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(
        stderr.contains("IMU from /imu/data (sensor_msgs/Imu)"),
        "{stderr}"
    );
    within_4_std(&keys_of_calibration(&result), &truth, "bag");
    let f = read_calib_yaml(&result).expect("result");
    assert_eq!(
        f.info.expect("info").figures.imu_samples,
        Some(truth.samples)
    );
    let dvl = read_calib_yaml(&dir.join("cam_dvl_imu_truth/truth/calibration.yaml")).expect("t");
    assert!((f.time_offset_s - dvl.time_offset_s).abs() < 0.02);

    let out = dvlcal(&["calibrate", s(&bag), "--out", s(&result), "--force"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let f = read_calib_yaml(&result).expect("result");
    assert!(f.t_cam_imu.is_none());
    let warnings = f.info.map(|i| i.warnings.join("\n")).unwrap_or_default();
    assert!(warnings.contains("--imu-noise"), "{warnings}");
}

/// The same recording without its pose topic (a bag of the A50 driver's reports and an Imu
/// topic, no camera data): given as the dataset or with `--dvl`, the DVL is calibrated against
/// the bag's IMU, `T_imu_dvl` (`T_cam_imu^-1 T_cam_dvl` of the truth), the clock offset on the
/// IMU's clock and the scale each within 4 std of the simulator's truth, with the exports in the
/// IMU's frame; an option only a camera run reads is refused (exit 2), also though the bag's
/// lack of camera data shows only once it is open.
#[test]
fn a_bag_without_camera_data_calibrates_the_dvl_against_its_imu() {
    use dvlcal::io::dvl_imu_result::read_dvl_imu_result_yaml;
    let dir = Path::new("tests/fixtures/imu_bags");
    let bag = dir.join("dvl_imu.mcap");
    let noise = dir.join("cam_dvl_imu_truth/imu.yaml");
    let imu = read_imu_truth(&dir.join("cam_dvl_imu_truth/truth/imu.yaml")).expect("truth");
    let dvl = read_calib_yaml(&dir.join("cam_dvl_imu_truth/truth/calibration.yaml")).expect("t");
    let dvl = dvl.to_params().expect("truth params");
    let truth = imu.t_cam_imu.inverse() * dvl.t_cam_dvl;
    let tmp = TmpDir::new("imu-cli-dvl-imu-bag");
    for (name, how) in [("dataset", None), ("dvl", Some("--dvl"))] {
        let result = tmp.path(&format!("{name}.yaml"));
        let mut args = vec!["calibrate"];
        args.extend(how);
        args.extend([s(&bag), "--imu-noise", s(&noise), "--out", s(&result)]);
        let out = dvlcal(&args);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stdout}{stderr}");
        assert!(
            stdout.contains("DVL + IMU: no camera data given"),
            "{stdout}"
        );
        assert!(stderr.contains("3000 messages read"), "{stderr}");
        let r = read_dvl_imu_result_yaml(&result).expect("result");
        let est = from_rows(&r.t_imu_dvl);
        let std = r.std.as_ref().expect("std");
        let (rs, ls) = (
            std.rotation_deg.expect("rot"),
            std.lever_arm_m.expect("lever"),
        );
        let e_rot = so3::log(&(est.rot.transpose() * truth.rot)).map(f64::to_degrees);
        for i in 0..3 {
            assert!(
                e_rot[i].abs() < 4.0 * rs[i],
                "{name}: rotation {e_rot:?}, std {rs:?}"
            );
            let e = est.trans[i] - truth.trans[i];
            assert!(
                e.abs() < 4.0 * ls[i],
                "{name}: lever {i}: {e} m, std {ls:?}"
            );
        }
        let off = dvl.time_offset_s - imu.imu_time_offset_s;
        let so = std.time_offset_s.expect("offset std");
        assert!(
            (r.time_offset_s - off).abs() < 4.0 * so,
            "{name}: offset {}",
            r.time_offset_s
        );
        let ss = std.velocity_scale.expect("scale std");
        assert!((r.velocity_scale - dvl.velocity_scale).abs() < 4.0 * ss);
        assert!(tmp.path(&format!("{name}-tf.txt")).exists());
        assert!(tmp.path(&format!("{name}-urdf.xml")).exists());
    }
    let out = dvlcal(&[
        "calibrate",
        s(&bag),
        "--imu-noise",
        s(&noise),
        "--out",
        s(&tmp.path("r.yaml")),
        "--loss",
        "huber",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--loss") && stderr.contains("DVL + IMU"),
        "{stderr}"
    );
    assert!(!tmp.path("r.yaml").exists());
}
