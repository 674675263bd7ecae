//! Bags as datasets, end to end through the command line: the rendered bag recording packed as
//! the bags users record (by `scripts/make_sample_bags.py` with the independent `rosbags` writer,
//! in `sample_data/bags/`) calibrates to within 3 std of its truth from every bag, and to the
//! result of the same frames and DVL log read from a folder; the motion-capture pose bag
//! calibrates to the result of the TUM file.

mod tmp_common;
use tmp_common::TmpDir;

use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::io::calib_yaml::{CalibrationFile, read_calib_yaml};
use dvlcal::io::camchain::read_camchain;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn sample(rel: &str) -> PathBuf {
    Path::new(ROOT).join("sample_data").join(rel)
}

/// A file of the bag recording (`sample_data/bags/recording/`).
fn recording(rel: &str) -> PathBuf {
    sample("bags/recording").join(rel)
}

/// Stereo frames in every image bag: the whole 13 s recording at 10 Hz.
const FRAMES: usize = 131;

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

/// The image folder of the bag recording: its JPEG files, taken out of the sqlite3 bag with
/// SQLite and a plain byte search (not dvlcal's bag reader), named by their CDR header stamps,
/// with the recording's camchain, board and DVL log.
fn equivalent_folder(tmp: &Path) -> PathBuf {
    let dir = tmp.join("folder");
    let db = rusqlite::Connection::open(sample("bags/stereo_sqlite3/stereo_sqlite3.db3")).unwrap();
    let mut q = db
        .prepare("SELECT t.name, m.data FROM messages m JOIN topics t ON m.topic_id = t.id")
        .unwrap();
    let rows = q
        .query_map([], |r| {
            Ok((r.get::<_, String>(0)?, r.get::<_, Vec<u8>>(1)?))
        })
        .unwrap();
    let mut written = 0;
    for row in rows {
        let (topic, data) = row.unwrap();
        let cam = match topic.as_str() {
            "/stereo/left/image_raw/compressed" => "cam0",
            "/stereo/right/image_raw/compressed" => "cam1",
            _ => continue,
        };
        // CDR, little endian: a 4-byte encapsulation header, then header.stamp (sec, nanosec).
        assert_eq!(data[..2], [0, 1], "{topic}: not little-endian CDR");
        let sec = i32::from_le_bytes(data[4..8].try_into().unwrap()) as i64;
        let nsec = u32::from_le_bytes(data[8..12].try_into().unwrap()) as i64;
        // The JPEG file is the message's last field: from its start-of-image marker to the end.
        let start = data
            .windows(3)
            .position(|w| w == [0xFF, 0xD8, 0xFF])
            .expect("a JPEG in the message");
        assert_eq!(data[data.len() - 2..], [0xFF, 0xD9], "{topic}: JPEG cut");
        std::fs::create_dir_all(dir.join(cam)).unwrap();
        let name = format!("{}.jpg", sec * 1_000_000_000 + nsec);
        std::fs::write(dir.join(cam).join(name), &data[start..]).unwrap();
        written += 1;
    }
    assert_eq!(written, 2 * FRAMES);
    for f in ["camchain.yaml", "target.yaml", "dvl.jsonl"] {
        std::fs::copy(recording(f), dir.join(f)).unwrap();
    }
    dir
}

fn estimates(f: &CalibrationFile) -> String {
    // The estimate and its uncertainty, not the provenance fields.
    let p = f.to_params().unwrap();
    format!("{p:?} {:?}", f.std)
}

fn chain_and_target() -> [String; 4] {
    [
        "--camchain".into(),
        recording("camchain.yaml").display().to_string(),
        "--target".into(),
        recording("target.yaml").display().to_string(),
    ]
}

/// What users are shown first: every sample bag calibrates, and `compare-calib` finds every
/// estimated parameter within 3 std of the truth the data were made with.
#[test]
fn every_sample_bag_calibrates_to_within_3_std_of_its_truth() {
    let tmp = TmpDir::new("bag-truth");
    let cc = chain_and_target();
    let cc: Vec<&str> = cc.iter().map(String::as_str).collect();
    let truth_stereo = recording("truth/calibration.yaml");
    let truth_poses = sample("poses/truth/calibration.yaml");
    for (k, (bag, extra, truth)) in [
        ("bags/stereo_mcap", &cc[..], &truth_stereo),
        ("bags/stereo_sqlite3", &cc[..], &truth_stereo),
        ("bags/stereo_ros1.bag", &cc[..], &truth_stereo),
        ("bags/poses_mcap.mcap", &[][..], &truth_poses),
    ]
    .into_iter()
    .enumerate()
    {
        let out = tmp.0.join(format!("c{k}.yaml"));
        let (stdout, stderr) = calibrate(&sample(bag), extra, &out);
        assert!(!stderr.contains("warning"), "{bag}:\n{stdout}\n{stderr}");
        let (ok, stdout, stderr) = dvlcal(&[
            "compare-calib",
            "--estimate",
            out.to_str().unwrap(),
            "--truth",
            truth.to_str().unwrap(),
        ]);
        assert!(ok, "{bag}: {stdout}\n{stderr}");
        assert!(
            stdout.contains("every estimated parameter within 3 std"),
            "{bag}: {stdout}"
        );
    }
}

#[test]
fn sqlite_bag_of_jpeg_images_and_odometry_gives_the_folders_result_to_the_digit() {
    let tmp = TmpDir::new("bag-sqlite");
    let cc = chain_and_target();
    let cc: Vec<&str> = cc.iter().map(String::as_str).collect();
    let (stdout, stderr) = calibrate(&sample("bags/stereo_sqlite3"), &cc, &tmp.0.join("bag.yaml"));
    assert!(
        stdout.contains(&format!("{FRAMES} of {FRAMES} frames")),
        "{stdout}\n{stderr}"
    );
    let folder = equivalent_folder(&tmp.0);
    calibrate(&folder, &[], &tmp.0.join("folder.yaml"));
    let a = read_calib_yaml(&tmp.0.join("bag.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("folder.yaml")).unwrap();
    // The same JPEG bytes, the same DVL reports at the same times (header stamp = the log's
    // time_of_validity): the same digits.
    assert_eq!(estimates(&a), estimates(&b));
}

/// `dvlcal detect` on `args`, the poses it wrote (TUM lines without comments).
fn detect(args: &[String], out: &Path) -> Vec<[f64; 8]> {
    let mut a: Vec<String> = vec!["detect".into()];
    a.extend(args.iter().cloned());
    a.extend(chain_and_target());
    a.extend([
        "--out".into(),
        out.display().to_string(),
        "--no-progress".into(),
    ]);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let (ok, _, stderr) = dvlcal(&a);
    assert!(ok, "{stderr}");
    std::fs::read_to_string(out)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            v.try_into().unwrap()
        })
        .collect()
}

/// Per frame of `dvlcal detect`'s `<out>.frames.csv`: the std of the position and of the
/// rotation (root of the trace of each 3x3 block of the pose covariance).
fn frame_stds(poses: &Path) -> Vec<[f64; 2]> {
    let csv = std::fs::read_to_string(format!("{}.frames.csv", poses.display())).unwrap();
    csv.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            // t tags corners rms rejected sigma, then c00 c01 .. c05 c11 .. c55.
            [
                (v[6] + v[12] + v[17]).sqrt(),
                (v[21] + v[24] + v[26]).sqrt(),
            ]
        })
        .collect()
}

/// `dvlcal detect` on a bag and on the folder of the same JPEG files. The compressed-image
/// bags hold the files themselves: the same poses to the last bit (`exact`). The raw-image bag
/// holds the JPEGs decoded by another decoder (grey levels differ by one here and there): each
/// pose moves by a small fraction of its own uncertainty.
fn bag_gives_the_folders_poses(bag: &str, tag: &str, exact: bool) {
    let tmp = TmpDir::new(tag);
    let folder = equivalent_folder(&tmp.0);
    let pa = detect(
        &["--bag".into(), sample(bag).display().to_string()],
        &tmp.0.join("bag.txt"),
    );
    let pb = detect(
        &["--images".into(), folder.display().to_string()],
        &tmp.0.join("folder.txt"),
    );
    assert_eq!(pa.len(), FRAMES);
    assert_eq!(pa.len(), pb.len());
    if exact {
        assert_eq!(pa, pb);
        return;
    }
    let stds = frame_stds(&tmp.0.join("folder.txt"));
    assert_eq!(stds.len(), FRAMES);
    let mut worst = [0.0f64; 2];
    let mut moves = Vec::new();
    for ((a, b), s) in pa.iter().zip(&pb).zip(&stds) {
        assert_eq!(a[0], b[0], "frame times differ");
        let dt = ((a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2) + (a[3] - b[3]).powi(2)).sqrt();
        let dot: f64 = (4..8).map(|k| a[k] * b[k]).sum();
        let angle = 2.0 * dot.abs().min(1.0).acos();
        worst = [worst[0].max(dt / s[0]), worst[1].max(angle / s[1])];
        moves.push(dt);
    }
    moves.sort_by(f64::total_cmp);
    // Measured: median 4 um; the worst frame (the board half out of view) 0.55 std.
    assert!(
        moves[FRAMES / 2] < 2e-5,
        "median move {} m",
        moves[FRAMES / 2]
    );
    assert!(
        worst[0] < 1.0 && worst[1] < 1.0,
        "worst moves {worst:?} (in std of position, rotation)"
    );
}

#[test]
fn mcap_bag_of_raw_images_gives_the_folders_poses() {
    bag_gives_the_folders_poses("bags/stereo_mcap", "bag-mcap", false);
}

#[test]
fn ros1_bag_of_compressed_images_gives_the_folders_poses_exactly() {
    bag_gives_the_folders_poses("bags/stereo_ros1.bag", "bag-ros1", true);
}

/// Every DVL topic kind of the sample bags reads to the samples of the JSON log it was made
/// from: the same times (header stamp = time_of_validity, or the JSON's own), velocities and
/// covariances.
#[test]
fn dvl_messages_of_every_bag_read_as_the_json_log() {
    use dvlcal::io::dvl::{DvlReadOptions, read_dvl_log};
    let reference = read_dvl_log(&recording("dvl.jsonl"), &DvlReadOptions::default()).unwrap();
    for (bag, topic) in [
        ("bags/stereo_mcap", "/dvl/velocity_report"),
        ("bags/stereo_sqlite3", "/dvl/odom"),
        ("bags/stereo_ros1.bag", "/dvl/json_data"),
    ] {
        let log = read_dvl_log(&sample(bag), &DvlReadOptions::default()).unwrap();
        assert!(
            log.stats
                .topic
                .as_deref()
                .is_some_and(|t| t.starts_with(topic)),
            "{bag}: {:?}",
            log.stats.topic
        );
        assert_eq!(log.epoch, reference.epoch, "{bag}");
        assert_eq!(log.samples.len(), reference.samples.len(), "{bag}");
        for (a, b) in log.samples.iter().zip(&reference.samples) {
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "{bag}");
        }
    }
}

#[test]
fn pose_bag_gives_the_tum_files_result_to_the_digit() {
    let tmp = TmpDir::new("bag-poses");
    let (_, stderr) = calibrate(
        &sample("bags/poses_mcap.mcap"),
        &[],
        &tmp.0.join("bag.yaml"),
    );
    assert!(
        stderr.contains("camera poses from /mocap/rig/pose"),
        "{stderr}"
    );
    calibrate(&sample("poses"), &[], &tmp.0.join("tum.yaml"));
    let a = read_calib_yaml(&tmp.0.join("bag.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("tum.yaml")).unwrap();
    assert_eq!(estimates(&a), estimates(&b));
}

#[test]
fn record_times_are_used_only_when_asked_and_move_the_clock_offset() {
    let tmp = TmpDir::new("bag-record");
    calibrate(
        &sample("bags/poses_mcap.mcap"),
        &[],
        &tmp.0.join("header.yaml"),
    );
    calibrate(
        &sample("bags/poses_mcap.mcap"),
        &["--bag-time", "record"],
        &tmp.0.join("record.yaml"),
    );
    let a = read_calib_yaml(&tmp.0.join("header.yaml")).unwrap();
    let b = read_calib_yaml(&tmp.0.join("record.yaml")).unwrap();
    let (pa, pb) = (a.to_params().unwrap(), b.to_params().unwrap());
    // Poses and DVL alike are late by 15-45 ms at random when record times are used: the mean
    // latency cancels in the offset, the jitter moves it a little.
    let d = (pa.time_offset_s - pb.time_offset_s).abs();
    assert!(d > 1e-6 && d < 0.002, "offset moved by {d} s");
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
    assert!(
        line("/cam0/camera_info").contains("camera info cam0"),
        "{stdout}"
    );
    let dvl = line("/dvl/velocity_report");
    assert!(
        dvl.contains("DVL") && dvl.contains("marine_acoustic_msgs/Dvl"),
        "{dvl}"
    );
    assert!(line("/dvl/odom").trim_end().ends_with('-'), "{stdout}");
    assert!(
        line("/cam0/image_raw").contains(&format!(" {FRAMES} ")),
        "{stdout}"
    );
}

#[test]
fn two_candidates_for_a_role_are_an_error_naming_both_until_one_is_chosen() {
    let tmp = TmpDir::new("bag-roles");
    let out = tmp.0.join("c.yaml");
    let (ok, _, stderr) = dvlcal(&["dvl-info", fixture("two_dvl.mcap").to_str().unwrap()]);
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
        stderr.contains("/vio/pose")
            && stderr.contains("/vio/odom")
            && stderr.contains("--pose-topic"),
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
    use dvlcal::io::bag::open::OpenBag;
    use dvlcal::io::bag::poses::read_bag_poses;
    use dvlcal::io::bag::roles::BagOptions;
    let path = fixture("tf_poses.mcap");
    let ob = OpenBag::open(&path, &BagOptions::default()).unwrap();
    let e = read_bag_poses(&ob).unwrap_err().to_string();
    assert!(
        e.contains("rig_a") && e.contains("rig_b") && e.contains("--pose-frame"),
        "{e}"
    );
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
fn unknown_image_encodings_are_counted_and_named_never_reinterpreted() {
    use dvlcal::io::bag::frames::plan_frames;
    use dvlcal::io::bag::open::OpenBag;
    use dvlcal::io::bag::roles::BagOptions;
    use dvlcal::pipeline::{VisionOptions, poses_from_bag};
    use dvlcal::types::camera::{Camchain, Camera, Distortion};
    let ob = OpenBag::open(&fixture("bad_encoding.mcap"), &BagOptions::default()).unwrap();
    let plan = plan_frames(&ob, 2_000_000).unwrap();
    assert_eq!(plan.frames.len(), 7);
    assert_eq!(plan.sizes, vec![(4, 3)]);
    let chain = Camchain::mono(Camera {
        fu: 4.0,
        fv: 4.0,
        pu: 2.0,
        pv: 1.5,
        distortion: Distortion::None,
        width: 4,
        height: 3,
    });
    let opts = VisionOptions {
        threads: Some(2),
        ..VisionOptions::default()
    };
    let run = poses_from_bag(&ob, &plan, chain, &sample("stereo/target.yaml"), &opts).unwrap();
    // Three mono8 images decoded (no board in 4x3 pixels), four refused by name.
    assert_eq!(run.stats.images, 3, "{:?}", run.stats.problems);
    assert_eq!(run.stats.unreadable, 4, "{:?}", run.stats.problems);
    let p = run.stats.problems.join("\n");
    assert_eq!(p.matches("32FC1").count(), 2, "{p}");
    assert_eq!(p.matches("yuv422").count(), 2, "{p}");
    assert!(p.contains("/cam0/image_raw message 2"), "{p}");
    assert!(run.require_poses().is_err());
}

#[test]
fn calibrate_cameras_from_a_bag_gives_the_folders_camchain() {
    let tmp = TmpDir::new("bag-cameras");
    let target = recording("target.yaml");
    let run = |src: &[&str], out: &Path| {
        let mut a = vec!["calibrate-cameras"];
        a.extend_from_slice(src);
        a.extend_from_slice(&[
            "--target",
            target.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--no-progress",
        ]);
        let (ok, stdout, stderr) = dvlcal(&a);
        assert!(ok, "{stdout}\n{stderr}");
        read_camchain(out).unwrap()
    };
    let bag = sample("bags/stereo_sqlite3");
    let a = run(&["--bag", bag.to_str().unwrap()], &tmp.0.join("bag.yaml"));
    let folder = equivalent_folder(&tmp.0);
    let b = run(
        &["--images", folder.to_str().unwrap()],
        &tmp.0.join("folder.yaml"),
    );
    assert_eq!(a.cams, b.cams);
    assert_eq!(a.t_cn_c0, b.t_cn_c0);
    // The chain names the bag's topics.
    assert_eq!(
        a.topics[1].as_deref(),
        Some("/stereo/right/image_raw/compressed")
    );
}

#[test]
fn a_bag_cut_short_gives_the_frames_before_the_cut_and_says_so() {
    let tmp = TmpDir::new("bag-cut");
    let whole = std::fs::read(sample("bags/stereo_mcap/stereo_mcap.mcap")).unwrap();
    let cut = tmp.0.join("cut.mcap");
    std::fs::write(&cut, &whole[..whole.len() * 6 / 10]).unwrap();
    let mut args = vec![
        "detect".to_string(),
        "--bag".into(),
        cut.display().to_string(),
    ];
    args.extend(chain_and_target());
    args.extend([
        "--out".into(),
        tmp.0.join("poses.txt").display().to_string(),
        "--no-progress".into(),
    ]);
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let (ok, stdout, stderr) = dvlcal(&a);
    assert!(ok, "{stdout}\n{stderr}");
    let poses = std::fs::read_to_string(tmp.0.join("poses.txt")).unwrap();
    let n = poses.lines().filter(|l| !l.starts_with('#')).count();
    assert!(
        (10..FRAMES).contains(&n),
        "{n} poses from a bag cut at 60 %"
    );
    assert!(
        stderr.contains("warning: ") && stderr.contains("cut.mcap"),
        "{stderr}"
    );
    // And a bag with nothing dvlcal can use is an error that lists what it holds.
    let (ok, _, stderr) = dvlcal(&[
        "calibrate",
        fixture("twist.db3").to_str().unwrap(),
        "--out",
        tmp.0.join("c.yaml").to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("no image or pose topic") && stderr.contains("/dvl/twist"),
        "{stderr}"
    );
}

#[test]
fn camera_info_gives_a_single_cameras_model() {
    use dvlcal::io::bag::camera_info::camera_from_info;
    use dvlcal::io::bag::open::OpenBag;
    use dvlcal::io::bag::roles::BagOptions;

    let opts = BagOptions {
        image_topics: Some(vec!["/cam1/image_raw".into()]),
        ..BagOptions::default()
    };
    let ob = OpenBag::open(&sample("bags/stereo_mcap"), &opts).unwrap();
    let cam = camera_from_info(&ob, 0)
        .unwrap()
        .expect("a CameraInfo beside /cam1/image_raw");
    let chain = read_camchain(&recording("camchain.yaml")).unwrap();
    assert_eq!(cam, chain.cams[1]);
}

#[test]
fn a_folder_holding_a_bag_is_a_dataset_and_evaluate_takes_a_bag() {
    let tmp = TmpDir::new("bag-in-folder");
    let dir = tmp.0.join("run");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(sample("bags/poses_mcap.mcap"), dir.join("run.mcap")).unwrap();
    let out = tmp.0.join("c.yaml");
    let (stdout, _) = calibrate(&dir, &[], &out);
    assert!(
        stdout.contains("bag ") && stdout.contains("run.mcap"),
        "{stdout}"
    );
    let (ok, stdout, stderr) = dvlcal(&[
        "evaluate",
        "--calib",
        out.to_str().unwrap(),
        sample("bags/poses_mcap.mcap").to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(stdout.contains("ATE"), "{stdout}");
}

#[test]
fn pose_messages_bring_their_covariances_into_the_child_frame() {
    use dvlcal::io::bag::open::OpenBag;
    use dvlcal::io::bag::poses::{read_bag_poses, ros_pose_covariance};
    use dvlcal::io::bag::roles::BagOptions;
    use dvlcal::lie::{Se3, so3};
    use dvlcal::rng::Rng;
    use nalgebra::{Matrix6, Vector3, Vector6};

    // The fixture's writer (rosbags) gave both topics a diagonal of 4e-6: 2 mm and 2 mrad,
    // the same in every frame.
    for topic in ["/vio/pose", "/vio/odom"] {
        let ob = OpenBag::open(
            &fixture("pose_cov.mcap"),
            &BagOptions {
                pose_topic: Some(topic.into()),
                ..BagOptions::default()
            },
        )
        .unwrap();
        let p = read_bag_poses(&ob).unwrap();
        assert!(p.covariances, "{topic}");
        assert_eq!(p.poses.len(), 20);
        for pose in &p.poses {
            let c = pose.cov.expect("a covariance");
            assert!(
                (c - Matrix6::identity() * 4e-6).amax() < 1e-18,
                "{topic}: {c}"
            );
        }
    }

    // The conversion against sampling: errors drawn as ROS states them (position and rotation
    // about the parent's axes, correlated), applied to the pose, and read back as the right
    // perturbation `log(T^-1 T')`; their covariance is the converted one.
    let t = Se3::new(
        so3::exp(&Vector3::new(0.4, -1.1, 0.7)),
        Vector3::new(1.0, -2.0, 0.5),
    );
    let mut l = Matrix6::zeros();
    for i in 0..6 {
        for j in 0..=i {
            l[(i, j)] = if i == j {
                1e-3 * (1.0 + i as f64)
            } else {
                2e-4 * (i + 2 * j) as f64
            };
        }
    }
    let ros = l * l.transpose();
    let mut c = [0.0; 36];
    for i in 0..6 {
        for j in 0..6 {
            c[6 * i + j] = ros[(i, j)];
        }
    }
    let ours = ros_pose_covariance(&c, &t).expect("usable");
    let mut rng = Rng::new(3);
    let n = 20_000;
    let mut emp = Matrix6::zeros();
    for _ in 0..n {
        let z = Vector6::from_fn(|_, _| rng.normal());
        let e = l * z;
        let dp = Vector3::new(e[0], e[1], e[2]);
        let dth = Vector3::new(e[3], e[4], e[5]);
        let moved = Se3::new(so3::exp(&dth) * t.rot, t.trans + dp);
        let r = (t.inverse() * moved).log();
        emp += r * r.transpose();
    }
    emp /= n as f64;
    for i in 0..6 {
        for j in 0..6 {
            let sd = (ours[(i, i)] * ours[(j, j)] / n as f64).sqrt() * 1.5;
            assert!(
                (emp[(i, j)] - ours[(i, j)]).abs() < 4.0 * sd,
                "({i}, {j}): sampled {} against {}",
                emp[(i, j)],
                ours[(i, j)]
            );
        }
    }
    // ROS's -1 for an unknown part is no covariance.
    c[35] = -1.0;
    assert!(ros_pose_covariance(&c, &t).is_none());
    assert!(ros_pose_covariance(&[0.0; 36], &t).is_none());
}

/// Frames too far apart for the motion (one in six of the recording, 1.7 Hz, during rotations
/// of about 1 rad/s) fail with that cause first, not with its symptoms alone (a lever arm that
/// looks unobserved, DVL reports that look like outliers).
#[test]
fn frames_too_sparse_for_the_motion_are_named_as_the_cause() {
    let tmp = TmpDir::new("bag-sparse");
    let folder = equivalent_folder(&tmp.0);
    for cam in ["cam0", "cam1"] {
        let mut names: Vec<_> = std::fs::read_dir(folder.join(cam))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        names.sort();
        for (k, p) in names.iter().enumerate() {
            if k % 6 != 0 {
                std::fs::remove_file(p).unwrap();
            }
        }
    }
    let out = tmp.0.join("c.yaml");
    let (ok, stdout, stderr) = dvlcal(&[
        "calibrate",
        folder.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-progress",
    ]);
    assert!(!ok, "{stdout}\n{stderr}");
    let all = format!("{stdout}\n{stderr}");
    let first_reason = all
        .lines()
        .skip_while(|l| !l.starts_with("CALIBRATION FAILED"))
        .nth(1)
        .unwrap_or_default();
    assert!(
        first_reason.contains("too sparse for the motion") && first_reason.contains("0.60 s apart"),
        "{all}"
    );
    // The full recording at 10 Hz raises no such warning.
    let cc = chain_and_target();
    let cc: Vec<&str> = cc.iter().map(String::as_str).collect();
    let (stdout, stderr) = calibrate(&sample("bags/stereo_sqlite3"), &cc, &out);
    assert!(!format!("{stdout}{stderr}").contains("too sparse"));
}
