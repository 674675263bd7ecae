//! Bags as datasets, end to end through the command line: the rendered sample packed as the
//! bags users record (by `scripts/make_sample_bags.py` with the independent `rosbags` writer,
//! in `sample_data/bags/`) calibrates to the result of the same frames and DVL log read from
//! folders and files, and the motion-capture pose bag to the result of the TUM file.

mod tmp_common;
use tmp_common::TmpDir;

use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::eval::calibration_error;
use dvlcal::io::calib_yaml::{CalibrationFile, read_calib_yaml};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn sample(rel: &str) -> PathBuf {
    Path::new(ROOT).join("sample_data").join(rel)
}

fn fixture(rel: &str) -> PathBuf {
    Path::new(ROOT).join("tests/fixtures/bag_cases").join(rel)
}

/// Runs `dvlcal ARGS`; (success, stdout, stderr).
fn dvlcal(args: &[&str]) -> (bool, String, String) {
    let r = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(args)
        .output()
        .expect("run dvlcal");
    (
        r.status.success(),
        String::from_utf8_lossy(&r.stdout).into_owned(),
        String::from_utf8_lossy(&r.stderr).into_owned(),
    )
}

fn calibrate(dataset: &Path, extra: &[&str], out: &Path) -> (String, String) {
    let mut args = vec![
        "calibrate",
        dataset.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-progress",
    ];
    args.extend_from_slice(extra);
    let (ok, stdout, stderr) = dvlcal(&args);
    assert!(ok, "calibrate {}:\n{stdout}\n{stderr}", dataset.display());
    (stdout, stderr)
}

/// The image folder holding exactly the frames the sample bags keep, with the sample's
/// camchain, board and DVL log.
fn equivalent_folder(tmp: &Path) -> PathBuf {
    let dir = tmp.join("folder");
    let stereo = sample("stereo");
    let stamps = std::fs::read_to_string(sample("bags/frames.txt")).unwrap();
    for cam in ["cam0", "cam1"] {
        std::fs::create_dir_all(dir.join(cam)).unwrap();
        for s in stamps.lines().filter(|l| !l.trim().is_empty()) {
            let name = format!("{}.jpg", s.trim());
            std::fs::copy(stereo.join(cam).join(&name), dir.join(cam).join(&name)).unwrap();
        }
    }
    for f in ["camchain.yaml", "target.yaml", "dvl.jsonl"] {
        std::fs::copy(stereo.join(f), dir.join(f)).unwrap();
    }
    dir
}

/// Each parameter's difference between two results, in the first one's standard deviations.
fn difference_in_std(a: &CalibrationFile, b: &CalibrationFile) -> [f64; 8] {
    let ce = calibration_error(a, &b.to_params().unwrap()).unwrap();
    let std = ce.std.unwrap();
    let mut z = [0.0; 8];
    for k in 0..8 {
        z[k] = ce.error[k] / std[k];
    }
    z
}

fn estimates(f: &CalibrationFile) -> String {
    // The estimate and its uncertainty, not the provenance fields.
    let p = f.to_params().unwrap();
    format!("{p:?} {:?}", f.std)
}

fn chain_and_target() -> [String; 4] {
    let stereo = sample("stereo");
    [
        "--camchain".into(),
        stereo.join("camchain.yaml").display().to_string(),
        "--target".into(),
        stereo.join("target.yaml").display().to_string(),
    ]
}

#[test]
fn sqlite_bag_of_jpeg_images_and_odometry_gives_the_folders_result_to_the_digit() {
    let tmp = TmpDir::new("bag-sqlite");
    let folder = equivalent_folder(&tmp.0);
    let cc = chain_and_target();
    let cc: Vec<&str> = cc.iter().map(String::as_str).collect();
    let (stdout, stderr) = calibrate(&sample("bags/stereo_sqlite3"), &cc, &tmp.0.join("bag.yaml"));
    assert!(stdout.contains("42 of 42 frames"), "{stdout}\n{stderr}");
    calibrate(&folder, &[], &tmp.0.join("folder.yaml"));
    let a = read_calib_yaml(&tmp.0.join("bag.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("folder.yaml")).unwrap();
    // The same JPEG bytes, the same DVL reports at the same times (header stamp = the log's
    // time_of_validity): the same digits.
    assert_eq!(estimates(&a), estimates(&b));
}

#[test]
fn mcap_bag_of_raw_images_and_dvl_messages_agrees_with_the_folder() {
    let tmp = TmpDir::new("bag-mcap");
    let folder = equivalent_folder(&tmp.0);
    let cc = chain_and_target();
    let cc: Vec<&str> = cc.iter().map(String::as_str).collect();
    let (stdout, stderr) = calibrate(&sample("bags/stereo_mcap"), &cc, &tmp.0.join("bag.yaml"));
    assert!(stdout.contains("42 of 42 frames"), "{stdout}\n{stderr}");
    // Water Linked's driver also publishes ~/odom and its dead reckoning: the Dvl topic wins.
    assert!(stderr.contains("DVL from /dvl/velocity_report"), "{stderr}");
    calibrate(&folder, &[], &tmp.0.join("folder.yaml"));
    let a = read_calib_yaml(&tmp.0.join("bag.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("folder.yaml")).unwrap();
    // The bag's pixels are the JPEGs decoded by another decoder (grey levels differ by one
    // here and there), so the corners move by hundredths of a pixel: the results agree to a
    // small fraction of their uncertainty.
    let z = difference_in_std(&a, &b);
    assert!(z.iter().all(|v| v.abs() < 0.2), "{z:?}");
}

#[test]
fn ros1_bag_of_raw_images_and_a50_json_agrees_with_the_folder() {
    let tmp = TmpDir::new("bag-ros1");
    let folder = equivalent_folder(&tmp.0);
    let cc = chain_and_target();
    let cc: Vec<&str> = cc.iter().map(String::as_str).collect();
    let (stdout, stderr) = calibrate(&sample("bags/stereo_ros1.bag"), &cc, &tmp.0.join("bag.yaml"));
    assert!(stdout.contains("42 of 42 frames"), "{stdout}\n{stderr}");
    calibrate(&folder, &[], &tmp.0.join("folder.yaml"));
    let a = read_calib_yaml(&tmp.0.join("bag.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("folder.yaml")).unwrap();
    let z = difference_in_std(&a, &b);
    assert!(z.iter().all(|v| v.abs() < 0.2), "{z:?}");
}

#[test]
fn pose_bag_gives_the_tum_files_result_to_the_digit() {
    let tmp = TmpDir::new("bag-poses");
    let (_, stderr) = calibrate(&sample("bags/poses_mcap.mcap"), &[], &tmp.0.join("bag.yaml"));
    assert!(stderr.contains("camera poses from /mocap/rig/pose"), "{stderr}");
    calibrate(&sample("poses"), &[], &tmp.0.join("tum.yaml"));
    let a = read_calib_yaml(&tmp.0.join("bag.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("tum.yaml")).unwrap();
    assert_eq!(estimates(&a), estimates(&b));
}

#[test]
fn record_times_are_used_only_when_asked_and_move_the_clock_offset() {
    let tmp = TmpDir::new("bag-record");
    calibrate(&sample("bags/poses_mcap.mcap"), &[], &tmp.0.join("header.yaml"));
    calibrate(
        &sample("bags/poses_mcap.mcap"),
        &["--bag-time", "record"],
        &tmp.0.join("record.yaml"),
    );
    let a = read_calib_yaml(&tmp.0.join("header.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("record.yaml")).unwrap();
    let (pa, pb) = (a.to_params().unwrap(), b.to_params().unwrap());
    // Both clocks are late by 15-45 ms at random when record times are used: the offset moves
    // by less than the latency's spread, and the rest stays put.
    let d = (pa.time_offset_s - pb.time_offset_s).abs();
    assert!(d > 0.0 && d < 0.02, "offset moved by {d} s");
}

#[test]
fn bag_info_lists_topics_with_counts_rates_and_roles() {
    let (ok, stdout, stderr) = dvlcal(&["bag-info", sample("bags/stereo_mcap").to_str().unwrap()]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("ROS 2 bag (MCAP)"), "{stdout}");
    let line = |topic: &str| {
        stdout
            .lines()
            .find(|l| l.starts_with(topic))
            .unwrap_or_else(|| panic!("no {topic} in\n{stdout}"))
            .to_string()
    };
    assert!(line("/cam0/image_raw").contains("images cam0"), "{stdout}");
    assert!(line("/cam1/image_raw").contains("images cam1"), "{stdout}");
    assert!(line("/cam0/camera_info").contains("camera info cam0"), "{stdout}");
    let dvl = line("/dvl/velocity_report");
    assert!(dvl.contains("DVL") && dvl.contains("marine_acoustic_msgs/Dvl"), "{dvl}");
    assert!(line("/dvl/odom").trim_end().ends_with('-'), "{stdout}");
    assert!(line("/cam0/image_raw").contains(" 42 "), "{stdout}");
}

#[test]
fn two_candidates_for_a_role_are_an_error_naming_both_until_one_is_chosen() {
    let tmp = TmpDir::new("bag-roles");
    let out = tmp.0.join("c.yaml");
    let (ok, _, stderr) = dvlcal(&[
        "dvl-info",
        fixture("two_dvl.mcap").to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("/dvl_a/velocity_report")
            && stderr.contains("/dvl_b/velocity_report")
            && stderr.contains("--dvl-topic"),
        "{stderr}"
    );
    let (ok, stdout, stderr) = dvlcal(&[
        "dvl-info",
        fixture("two_dvl.mcap").to_str().unwrap(),
        "--dvl-topic",
        "/dvl_b/velocity_report",
    ]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("/dvl_b/velocity_report"), "{stdout}");

    let (ok, _, stderr) = dvlcal(&[
        "calibrate",
        fixture("pose_cov.mcap").to_str().unwrap(),
        "--dvl",
        sample("poses/dvl.jsonl").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("/vio/pose") && stderr.contains("/vio/odom") && stderr.contains("--pose-topic"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn zero_header_stamps_fall_back_to_the_record_time_with_a_warning() {
    let (ok, stdout, stderr) = dvlcal(&["dvl-info", fixture("zero_stamps.mcap").to_str().unwrap()]);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("5 messages of /dvl/odom have a zero header.stamp"),
        "{stdout}"
    );
}

#[test]
fn tf_poses_need_the_child_frame_named() {
    use dvlcal::io::bag::roles::BagOptions;
    use dvlcal::pipeline::{OpenBag, read_bag_poses};
    let path = fixture("tf_poses.mcap");
    let ob = OpenBag::open(&path, &BagOptions::default()).unwrap();
    let e = read_bag_poses(&ob).unwrap_err().to_string();
    assert!(e.contains("rig_a") && e.contains("rig_b") && e.contains("--pose-frame"), "{e}");
    let opts = BagOptions {
        pose_frame: Some("rig_b".into()),
        ..BagOptions::default()
    };
    let ob = OpenBag::open(&path, &opts).unwrap();
    let p = read_bag_poses(&ob).unwrap();
    assert_eq!(p.poses.len(), 20);
    assert!(p.source.contains("rig_b"), "{}", p.source);
}

#[test]
fn detect_reads_a_bag_and_writes_the_folders_poses() {
    let tmp = TmpDir::new("bag-detect");
    let folder = equivalent_folder(&tmp.0);
    let stereo = sample("stereo");
    let cc = [
        "--camchain",
        stereo.join("camchain.yaml").to_str().unwrap(),
        "--target",
        stereo.join("target.yaml").to_str().unwrap(),
    ]
    .map(str::to_string);
    let mut a: Vec<String> = vec!["detect".into(), "--bag".into()];
    a.push(sample("bags/stereo_sqlite3").display().to_string());
    a.extend(cc.iter().cloned());
    a.extend(["--out".into(), tmp.0.join("bag.txt").display().to_string()]);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let (ok, _, stderr) = dvlcal(&a);
    assert!(ok, "{stderr}");
    let mut b: Vec<String> = vec!["detect".into(), "--images".into()];
    b.push(folder.display().to_string());
    b.extend(cc.iter().cloned());
    b.extend(["--out".into(), tmp.0.join("folder.txt").display().to_string()]);
    let b: Vec<&str> = b.iter().map(String::as_str).collect();
    let (ok, _, stderr) = dvlcal(&b);
    assert!(ok, "{stderr}");
    let pa = std::fs::read_to_string(tmp.0.join("bag.txt")).unwrap();
    let pb = std::fs::read_to_string(tmp.0.join("folder.txt")).unwrap();
    assert_eq!(pa, pb);
    assert_eq!(pa.lines().filter(|l| !l.starts_with('#')).count(), 42);
}
