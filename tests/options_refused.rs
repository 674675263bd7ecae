//! Options that a run would not use are refused (exit status 2, a message that says why and what
//! to use instead), and inputs that would be misread are named: a camchain that leaves a camera
//! folder unused, DVL and pose times in another unit than the format's, a EuRoC ground-truth CSV
//! given as poses, a camera chain the other way round from its images.

use std::path::{Path, PathBuf};
use std::process::Output;

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir, dvlcal, s};

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("sample_data")
        .join(name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Runs `args`, asserts the usage-error status 2 and that stderr holds every one of `words`.
fn refused(args: &[&str], words: &[&str]) -> String {
    let o = dvlcal(args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    for w in words {
        assert!(e.contains(w), "{args:?}: {w:?} not in: {e}");
    }
    e
}

#[test]
fn calibrate_refuses_options_its_method_does_not_use() {
    let tmp = TmpDir::new("opt-method");
    let data = sample("poses");
    let truth = data.join("truth/calibration.yaml");
    let out = tmp.path("r.yaml");
    let (d, t, o) = (s(&data), s(&truth), s(&out));
    // --init with the default method (uic).
    refused(
        &["calibrate", d, "--init", t, "--out", o],
        &["--init", "--method uic", "--method bcd", "--method fixed"],
    );
    // --estimate-offset without --method fixed.
    refused(
        &["calibrate", d, "--estimate-offset", "--out", o],
        &["--estimate-offset", "--method fixed"],
    );
    refused(
        &[
            "calibrate",
            d,
            "--method",
            "bcd",
            "--init",
            t,
            "--estimate-offset",
            "--out",
            o,
        ],
        &["--estimate-offset", "estimate the clock offset anyway"],
    );
    // The closed form only UIC computes.
    refused(
        &[
            "calibrate",
            d,
            "--method",
            "bcd",
            "--init",
            t,
            "--biased",
            "--out",
            o,
        ],
        &["--biased", "--method uic"],
    );
    // Held extrinsics take no prior; a held clock offset takes no range.
    refused(
        &[
            "calibrate",
            d,
            "--method",
            "fixed",
            "--init",
            t,
            "--rotation-prior",
            "0,0,0",
            "--out",
            o,
        ],
        &["--rotation-prior does nothing with --method fixed", "held"],
    );
    refused(
        &[
            "calibrate",
            d,
            "--method",
            "fixed",
            "--init",
            t,
            "--offset-range",
            "-1,1",
            "--out",
            o,
        ],
        &["--offset-range", "--estimate-offset"],
    );
    // The broad default prior a lever-arm prior replaces.
    refused(
        &[
            "calibrate",
            d,
            "--lever-arm-prior",
            "0,0.2,-0.1",
            "--default-lever-arm-sigma",
            "2",
            "--out",
            o,
        ],
        &["--default-lever-arm-sigma", "--lever-arm-prior replaces it"],
    );
    assert!(
        !out.exists(),
        "nothing is written for a refused command line"
    );
    // With --estimate-offset, --offset-range is used: not refused.
    let r = dvlcal(&[
        "calibrate",
        d,
        "--method",
        "fixed",
        "--init",
        t,
        "--estimate-offset",
        "--offset-range",
        "-1,1",
        "--out",
        o,
    ]);
    assert_ne!(r.status.code(), Some(2), "{}", stderr(&r));
    assert!(out.exists(), "{}", stderr(&r));
}

#[test]
fn calibrate_refuses_bag_and_image_options_for_inputs_that_are_neither() {
    let tmp = TmpDir::new("opt-inputs");
    let data = sample("poses");
    let out = tmp.path("r.yaml");
    let (d, o) = (s(&data), s(&out));
    for (opt, value) in [
        ("--image-topics", "/cam0/image_raw"),
        ("--pose-topic", "/pose"),
        ("--pose-frame", "camera"),
    ] {
        refused(
            &["calibrate", d, opt, value, "--out", o],
            &[opt, "poses.txt", "--bag BAG"],
        );
    }
    refused(
        &["calibrate", d, "--dvl-topic", "/dvl/json_data", "--out", o],
        &["--dvl-topic", "dvl.jsonl", "not a bag"],
    );
    // --bag-time at its default is not given; written out it is refused.
    refused(
        &["calibrate", d, "--bag-time", "header", "--out", o],
        &["--bag-time", "no input here is a bag", "--dvl-time"],
    );
    // A camchain and a board beside a pose file.
    let stereo = sample("stereo");
    let poses = data.join("poses.txt");
    let dvl = data.join("dvl.jsonl");
    refused(
        &[
            "calibrate",
            "--poses",
            s(&poses),
            "--dvl",
            s(&dvl),
            "--camchain",
            s(&stereo.join("camchain.yaml")),
            "--out",
            o,
        ],
        &["--camchain is read with images", "--images DIR"],
    );
    // Detection settings without images.
    for (opt, value) in [
        ("--decimate", "1"),
        ("--min-corners", "12"),
        ("--pair-tolerance-ms", "5"),
        ("--pixel-sigma", "0.5"),
    ] {
        refused(
            &["calibrate", d, opt, value, "--out", o],
            &[opt, "without images"],
        );
    }
    assert!(!out.exists());
}

#[test]
fn a_pose_topic_named_wins_over_a_bags_images() {
    let tmp = TmpDir::new("opt-pose-topic");
    let bag = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bags/none.mcap");
    let out = tmp.path("r.yaml");
    // The bag holds images (cam0) and /pose: without --pose-topic the images would be used,
    // which need a board.
    let plain = dvlcal(&["calibrate", s(&bag), "--out", s(&out)]);
    assert!(stderr(&plain).contains("--target"), "{}", stderr(&plain));
    let named = dvlcal(&[
        "calibrate",
        s(&bag),
        "--pose-topic",
        "/pose",
        "--out",
        s(&out),
    ]);
    let e = stderr(&named);
    assert!(
        e.contains("camera poses from") && e.contains("/pose"),
        "{e}"
    );
    assert!(!e.contains("--target"), "{e}");
    // Both topics at once: refused by the parser.
    let both = dvlcal(&[
        "calibrate",
        s(&bag),
        "--pose-topic",
        "/pose",
        "--image-topics",
        "/cam0/image_raw",
        "--out",
        s(&out),
    ]);
    assert_eq!(both.status.code(), Some(2), "{}", stderr(&both));
    assert!(
        stderr(&both).contains("cannot be used with"),
        "{}",
        stderr(&both)
    );
}

#[test]
fn image_commands_offer_and_take_only_the_options_they_use() {
    let tmp = TmpDir::new("opt-images");
    for sub in ["calibrate-cameras", "detect"] {
        let help = stdout(&dvlcal(&[sub, "--help"]));
        assert!(help.contains("--image-topics"), "{sub}: {help}");
        for unused in ["--pose-topic", "--pose-frame", "--dvl-topic"] {
            assert!(!help.contains(unused), "{sub} offers {unused}: {help}");
        }
    }
    let stereo = sample("stereo");
    let out = tmp.path("chain.yaml");
    refused(
        &[
            "calibrate-cameras",
            "--images",
            s(&stereo),
            "--target",
            s(&stereo.join("target.yaml")),
            "--image-topics",
            "/cam0/image_raw",
            "--out",
            s(&out),
        ],
        &["--image-topics", "folder", "--bag BAG"],
    );
    refused(
        &[
            "detect",
            "--images",
            s(&stereo),
            "--camchain",
            s(&stereo.join("camchain.yaml")),
            "--target",
            s(&stereo.join("target.yaml")),
            "--bag-time",
            "record",
            "--out",
            s(&tmp.path("p.txt")),
        ],
        &["--bag-time", "--images"],
    );
    // simulate's threads render images.
    let sim = dvlcal(&["simulate", "--out", s(&tmp.path("sim")), "--threads", "2"]);
    assert_eq!(sim.status.code(), Some(2), "{}", stderr(&sim));
    assert!(stderr(&sim).contains("--images"), "{}", stderr(&sim));
}

#[test]
fn dvl_info_evaluate_and_fit_refuse_options_they_would_not_use() {
    let tmp = TmpDir::new("opt-others");
    let data = sample("poses");
    let log = data.join("dvl.jsonl");
    refused(
        &["dvl-info", s(&log), "--dvl-topic", "/dvl/json_data"],
        &["--dvl-topic", "dvl.jsonl is not a bag"],
    );
    let truth = data.join("truth/calibration.yaml");
    for extra in [
        &["--guess", s(&truth)][..],
        &["--loss", "huber"][..],
        &["--clock-drift"][..],
    ] {
        let mut args = vec!["evaluate", s(&data), "--calib", s(&truth)];
        args.extend_from_slice(extra);
        refused(&args, &[extra[0], "--cross-validate"]);
    }
    // --pose-sigma beside poses that all carry a covariance.
    let poses = tmp.path("p.txt");
    let mut tum = String::from("# t tx ty tz qx qy qz qw\n");
    let cov_names: Vec<String> = (0..6)
        .flat_map(|i| (i..6).map(move |j| format!("c{i}{j}")))
        .collect();
    let mut table = format!(
        "t,tags,corners,rms_px,rejected,sigma_px,{}\n",
        cov_names.join(",")
    );
    for k in 0..40 {
        let t = 1_700_000_000.0 + 0.1 * k as f64;
        let x = 0.01 * k as f64;
        tum.push_str(&format!("{t:.3} {x} 0 0 0 0 0 1\n"));
        table.push_str(&format!(
            "{t:.3},10,40,0.2,0,0.2,1e-6,0,0,0,0,0,1e-6,0,0,0,0,1e-6,0,0,0,1e-6,0,0,1e-6,0,1e-6\n"
        ));
    }
    std::fs::write(&poses, tum).unwrap();
    std::fs::write(tmp.path("p.txt.frames.csv"), table).unwrap();
    let twist = tmp.path("t.csv");
    let ok = dvlcal(&["fit-trajectory", "--poses", s(&poses), "--out", s(&twist)]);
    assert!(ok.status.success(), "{}", stderr(&ok));
    assert!(stdout(&ok).contains("pose covariances"), "{}", stdout(&ok));
    refused(
        &[
            "fit-trajectory",
            "--poses",
            s(&poses),
            "--pose-sigma",
            "0.001,0.001",
            "--out",
            s(&twist),
        ],
        &["--pose-sigma", "p.txt.frames.csv"],
    );
}

#[test]
fn a_sound_speed_the_log_states_is_not_taken_silently() {
    let tmp = TmpDir::new("opt-sound");
    let data = sample("poses");
    let dir = tmp.path("ds");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(data.join("poses.txt"), dir.join("poses.txt")).unwrap();
    let log = std::fs::read_to_string(data.join("dvl.jsonl")).unwrap();
    let reply = r#"{"response_to":"get_config","success":true,"error_message":"","result":{"speed_of_sound":1480.0,"mounting_rotation_offset":0.0,"acoustic_enabled":true},"format":"json_v3.1","type":"response"}"#;
    std::fs::write(dir.join("dvl.jsonl"), format!("{reply}\n{log}")).unwrap();
    let r = dvlcal(&[
        "calibrate",
        s(&dir),
        "--dvl-sound-speed",
        "1500",
        "--out",
        s(&tmp.path("r.yaml")),
    ]);
    let e = stderr(&r);
    assert!(
        e.contains("--dvl-sound-speed 1500 m/s not used") && e.contains("1480 m/s"),
        "{e}"
    );
}

/// The first `n` images of each of the sample's cameras, symlinked into `dir/camK`.
fn stereo_subset(dir: &Path, n: usize, cams: &[(&str, &str)]) {
    let stereo = sample("stereo");
    for (from, to) in cams {
        let mut names: Vec<_> = std::fs::read_dir(stereo.join(from))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        let d = dir.join(to);
        std::fs::create_dir_all(&d).unwrap();
        for name in names.iter().take(n) {
            std::os::unix::fs::symlink(stereo.join(from).join(name), d.join(name)).unwrap();
        }
    }
}

#[test]
fn a_camchain_without_cam1_beside_cam1_images_says_they_are_not_used() {
    let tmp = TmpDir::new("opt-mono");
    let stereo = sample("stereo");
    let dir = tmp.path("mono");
    stereo_subset(&dir, 251, &[("cam0", "cam0"), ("cam1", "cam1")]);
    let chain = std::fs::read_to_string(stereo.join("camchain.yaml")).unwrap();
    let cam0_only = &chain[..chain.find("cam1:").unwrap()];
    std::fs::write(dir.join("camchain.yaml"), cam0_only).unwrap();
    std::fs::copy(stereo.join("target.yaml"), dir.join("target.yaml")).unwrap();
    std::fs::copy(stereo.join("dvl.jsonl"), dir.join("dvl.jsonl")).unwrap();
    let out = tmp.path("r.yaml");
    let r = dvlcal(&["calibrate", s(&dir), "--out", s(&out), "--no-progress"]);
    let e = stderr(&r);
    let folder = dir.join("cam1").display().to_string();
    let said = format!("{folder}: 251 images not used: the camera chain has cam0 alone");
    assert!(e.contains(&said), "{e}");
    assert!(e.contains("poses come from cam0 alone"), "{e}");
    // Carried into the result file's warnings (which the report shows with the result file).
    let yaml = std::fs::read_to_string(&out).unwrap_or_else(|_| panic!("no result: {e}"));
    let warnings = &yaml[yaml.find("  warnings:").expect("warnings in the result")..];
    let first_list = &warnings[..warnings.find("  notes:").unwrap_or(warnings.len())];
    assert!(first_list.contains("251 images not used"), "{yaml}");
}

#[test]
fn a_three_camera_chain_says_which_cameras_the_poses_come_from() {
    let tmp = TmpDir::new("opt-three");
    let stereo = sample("stereo");
    let dir = tmp.path("three");
    stereo_subset(&dir, 30, &[("cam0", "cam0"), ("cam1", "cam1")]);
    let chain = std::fs::read_to_string(stereo.join("camchain.yaml")).unwrap();
    let cam1 = &chain[chain.find("cam1:").unwrap()..];
    let three = format!("{chain}{}", cam1.replacen("cam1:", "cam2:", 1));
    std::fs::write(tmp.path("chain3.yaml"), three).unwrap();
    let r = dvlcal(&[
        "detect",
        "--images",
        s(&dir),
        "--camchain",
        s(&tmp.path("chain3.yaml")),
        "--target",
        s(&stereo.join("target.yaml")),
        "--out",
        s(&tmp.path("p.txt")),
        "--no-progress",
    ]);
    let e = stderr(&r);
    assert!(r.status.success(), "{e}");
    assert!(
        e.contains(
            "no cam2 folder; poses from cam0 and cam1 (stereo), cam2 of the camera chain not used"
        ),
        "{e}"
    );
    assert!(!e.contains("cam0 alone"), "{e}");
}

/// `detect` on the first 40 frames of the sample with `chain` (its text) and the camera
/// folders mapped by `cams`: the error it gives.
fn detect_error(tmp: &TmpDir, name: &str, chain: &str, cams: &[(&str, &str)]) -> String {
    let stereo = sample("stereo");
    let dir = tmp.path(name);
    stereo_subset(&dir, 40, cams);
    let chain_path = tmp.path(&format!("{name}.yaml"));
    std::fs::write(&chain_path, chain).unwrap();
    let r = dvlcal(&[
        "detect",
        "--images",
        s(&dir),
        "--camchain",
        s(&chain_path),
        "--target",
        s(&stereo.join("target.yaml")),
        "--out",
        s(&tmp.path(&format!("{name}.txt"))),
        "--no-progress",
    ]);
    assert_eq!(r.status.code(), Some(1), "{}", stderr(&r));
    stderr(&r)
}

/// The two-camera `chain` (text) with cam1's `T_cn_cnm1` replaced by its inverse.
fn inverted_baseline(chain: &str) -> String {
    let at = chain.find("T_cn_cnm1:").unwrap();
    let rows: Vec<&str> = chain[at..].lines().skip(1).take(3).collect();
    let m: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            let inner = &r[r.find('[').unwrap() + 1..r.find(']').unwrap()];
            inner
                .split(',')
                .map(|x| x.trim().parse().unwrap())
                .collect()
        })
        .collect();
    // [R t]^-1 = [R^T, -R^T t].
    let mut out = chain.to_string();
    for (i, row) in rows.iter().enumerate() {
        let t: f64 = -(0..3).map(|k| m[k][i] * m[k][3]).sum::<f64>();
        let new = format!("  - [{}, {}, {}, {t}]", m[0][i], m[1][i], m[2][i]);
        out = out.replacen(row, &new, 1);
    }
    out
}

#[test]
fn a_camera_chain_the_other_way_round_is_named_when_stereo_fails() {
    let tmp = TmpDir::new("opt-order");
    let chain = std::fs::read_to_string(sample("stereo").join("camchain.yaml")).unwrap();
    let straight = [("cam0", "cam0"), ("cam1", "cam1")];
    // The baseline's sign flipped (the sample's cam1 is 0.11 m to the right: x = -0.11).
    assert!(chain.contains("-0.11]"));
    let e = detect_error(
        &tmp,
        "negated",
        &chain.replace("-0.11]", "0.11]"),
        &straight,
    );
    assert!(
        e.contains("px RMS") && e.contains("its translation negated"),
        "{e}"
    );
    assert!(
        e.contains("wrong sign") && !e.contains("check the intrinsics"),
        "{e}"
    );
    // T_cn_cnm1 written the other way round: its inverse.
    let e = detect_error(&tmp, "inverted", &inverted_baseline(&chain), &straight);
    assert!(
        e.contains("T_cn_cnm1 inverted: ") && e.contains("invert it"),
        "{e}"
    );
    // The image folders swapped.
    let e = detect_error(
        &tmp,
        "swapped",
        &chain,
        &[("cam0", "cam1"), ("cam1", "cam0")],
    );
    assert!(e.contains("with cam0 and cam1 swapped"), "{e}");
    assert!(e.contains("swap the cam0 and cam1 folders"), "{e}");
    // The chain as it should be: no such error.
    let stereo = sample("stereo");
    let dir = tmp.path("ok");
    stereo_subset(&dir, 40, &straight);
    let r = dvlcal(&[
        "detect",
        "--images",
        s(&dir),
        "--camchain",
        s(&stereo.join("camchain.yaml")),
        "--target",
        s(&stereo.join("target.yaml")),
        "--out",
        s(&tmp.path("ok.txt")),
        "--no-progress",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
}

#[test]
fn dvl_times_in_seconds_name_the_field_the_unit_and_the_line() {
    let tmp = TmpDir::new("opt-dvl-seconds");
    let text = std::fs::read_to_string(sample("poses").join("dvl.jsonl")).unwrap();
    // time_of_validity written as seconds with a fraction, from the third line on.
    let mut out = String::new();
    for (k, line) in text.lines().enumerate() {
        let mut v: serde_json::Value = serde_json::from_str(line).unwrap();
        if k >= 2
            && let Some(t) = v.get("time_of_validity").and_then(|t| t.as_i64())
        {
            v["time_of_validity"] = serde_json::json!(t as f64 / 1e6);
        }
        out.push_str(&v.to_string());
        out.push('\n');
    }
    let log = tmp.path("sec.jsonl");
    std::fs::write(&log, out).unwrap();
    let r = dvlcal(&["dvl-info", s(&log), "--strict"]);
    let e = stderr(&r);
    assert_eq!(r.status.code(), Some(1), "{e}");
    assert!(e.contains("sec.jsonl:3"), "{e}");
    assert!(e.contains("'time_of_validity' is 1"), "{e}");
    assert!(
        e.contains("microseconds since 1970") && e.contains("Unix seconds"),
        "{e}"
    );
    assert!(!e.contains("expected i64"), "{e}");
    // Lenient: the lines are skipped and counted under that reason.
    let r = dvlcal(&["dvl-info", s(&log)]);
    let o = stdout(&r) + &stderr(&r);
    assert!(o.contains("time not in integer microseconds"), "{o}");
}

#[test]
fn serial_times_with_a_fraction_name_the_unit() {
    let tmp = TmpDir::new("opt-serial-seconds");
    // A wrz sentence whose time_of_validity is in seconds; its checksum made right.
    let body = "wrz,0.120,-0.010,0.002,y,1.52,0.002,1e-5;0;0;0;1e-5;0;0;0;1e-5,\
                1700000000.25,1700000000.26,100.0,0";
    let crc = body.bytes().fold(0u8, |mut c, b| {
        c ^= b;
        for _ in 0..8 {
            c = if c & 0x80 != 0 {
                (c << 1) ^ 0x07
            } else {
                c << 1
            };
        }
        c
    });
    let log = tmp.path("serial.txt");
    std::fs::write(&log, format!("{body}*{crc:02x}\n")).unwrap();
    let r = dvlcal(&["dvl-info", s(&log), "--strict"]);
    let e = stderr(&r);
    assert!(e.contains("serial.txt:1"), "{e}");
    assert!(e.contains("'time_of_validity' is 1700000000.25"), "{e}");
    assert!(e.contains("Unix seconds"), "{e}");
}

/// A pose time (seconds) as a file writes it.
type TimeText = dyn Fn(f64) -> String;

/// The sample's pose file with its times rewritten by `time` (seconds -> text).
fn poses_with_times(tmp: &TmpDir, name: &str, time: &dyn Fn(f64) -> String) -> PathBuf {
    let text = std::fs::read_to_string(sample("poses").join("poses.txt")).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with('#') {
            out.push_str(line);
        } else {
            let (t, rest) = line.split_once(' ').unwrap();
            out.push_str(&format!("{} {rest}", time(t.parse().unwrap())));
        }
        out.push('\n');
    }
    let p = tmp.path(name);
    std::fs::write(&p, out).unwrap();
    p
}

#[test]
fn pose_times_in_another_unit_are_named_with_the_conversion() {
    let tmp = TmpDir::new("opt-tum-units");
    let dvl = sample("poses").join("dvl.jsonl");
    let cases: [(&str, &TimeText, &str, &str); 3] = [
        (
            "ns.txt",
            &|t| format!("{}", (t * 1e9).round() as i64),
            "nanoseconds",
            "1e9",
        ),
        (
            "ms.txt",
            &|t| format!("{:.3}", t * 1e3),
            "milliseconds",
            "1e3",
        ),
        (
            "us.txt",
            &|t| format!("{}", (t * 1e6).round() as i64),
            "microseconds",
            "1e6",
        ),
    ];
    for (name, time, unit, div) in cases {
        let poses = poses_with_times(&tmp, name, time);
        let r = dvlcal(&[
            "calibrate",
            "--poses",
            s(&poses),
            "--dvl",
            s(&dvl),
            "--out",
            s(&tmp.path("r.yaml")),
        ]);
        let e = stderr(&r);
        assert_eq!(r.status.code(), Some(1), "{e}");
        // The first pose's line (line 1 is the header).
        assert!(e.contains(&format!("{name}:2:")), "{e}");
        assert!(e.contains(&format!("appear to be in {unit}")), "{e}");
        assert!(e.contains("a Unix time"), "{e}");
        assert!(
            e.contains(&format!("divide the first column by {div}")),
            "{e}"
        );
    }
    // Seconds read as they are.
    let poses = poses_with_times(&tmp, "s.txt", &|t| format!("{t:.6}"));
    let twist = tmp.path("t.csv");
    let r = dvlcal(&["fit-trajectory", "--poses", s(&poses), "--out", s(&twist)]);
    assert!(r.status.success(), "{}", stderr(&r));
}

#[test]
fn a_euroc_ground_truth_csv_given_as_poses_is_named() {
    let tmp = TmpDir::new("opt-euroc");
    let gt = tmp.path("data.csv");
    let mut text = String::from(
        "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], \
         q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x \
         [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], \
         b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n",
    );
    for k in 0..50i64 {
        text.push_str(&format!(
            "{},4.68,-1.78,0.84,0.53,-0.15,-0.83,-0.08,-0.02,0.01,0.04,-0.003,0.02,0.08,-0.02,0.11,0.07\n",
            1_403_636_580_838_555_648 + 5_000_000 * k
        ));
    }
    std::fs::write(&gt, &text).unwrap();
    let r = dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&gt),
        "--out",
        s(&tmp.path("t.csv")),
    ]);
    let e = stderr(&r);
    assert_eq!(r.status.code(), Some(1), "{e}");
    assert!(
        e.contains("data.csv:1: this is a EuRoC ground-truth CSV"),
        "{e}"
    );
    assert!(e.contains("nanoseconds") && e.contains("w first"), "{e}");
    assert!(e.contains("body") && e.contains("T_BS"), "{e}");
    // vicon0's eight columns would otherwise pass for TUM.
    let vicon = tmp.path("vicon.csv");
    let lines: Vec<String> = text
        .lines()
        .map(|l| l.split(',').take(8).collect::<Vec<_>>().join(","))
        .collect();
    std::fs::write(&vicon, lines.join("\n")).unwrap();
    let r = dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&vicon),
        "--out",
        s(&tmp.path("t.csv")),
    ]);
    assert!(
        stderr(&r).contains("EuRoC ground-truth CSV"),
        "{}",
        stderr(&r)
    );
}
