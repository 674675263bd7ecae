//! The command line as users type it, through the built program: negative numbers in options,
//! outputs in folders that do not exist yet (created, or refused before the work starts), and
//! `detect` then `calibrate --poses` giving the digits of `calibrate` on the images.

use std::path::Path;
use std::process::Output;

use dvlcal::io::calib_yaml::read_calib_yaml;

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir as TempDir, dvlcal, s};

/// stdout and stderr of a run that must succeed.
fn ok(out: Output) -> String {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "dvlcal failed:\n{text}");
    text
}

/// stderr of a run that must fail.
fn fails(out: Output) -> String {
    assert!(!out.status.success(), "dvlcal succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn sample(part: &str) -> String {
    format!("{}/sample_data/stereo/{part}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn negative_numbers_are_taken_as_typed() {
    let dir = TempDir::new("negative");
    let sim = dir.path("sim");
    let text = ok(dvlcal(&[
        "simulate",
        "--out",
        s(&sim),
        "--time-offset",
        "-0.4",
        "--duration",
        "20",
        "--seed",
        "2",
    ]));
    assert!(text.contains("201 poses"), "{text}");
    let truth = read_calib_yaml(&sim.join("truth/calibration.yaml")).unwrap();
    assert_eq!(truth.time_offset_s, -0.4);

    // The result goes two folders deep into a folder that does not exist yet.
    let out = dir.path("new/deeper/calibration.yaml");
    ok(dvlcal(&[
        "calibrate",
        s(&sim),
        "--offset-range",
        "-0.5,0.5",
        "--lever-arm-prior",
        "-0.1,0.2,-0.3:0.5",
        "--rotation-prior",
        "-90,0,-90:30",
        "--out",
        s(&out),
    ]));
    let result = read_calib_yaml(&out).unwrap();
    assert!(
        (result.time_offset_s + 0.4).abs() < 0.02,
        "{}",
        result.time_offset_s
    );
    // Both priors reached the calibration with their sigmas.
    let yaml = std::fs::read_to_string(&out).unwrap();
    assert!(yaml.contains("prior 500.0 mm"), "{yaml}");
    assert!(yaml.contains("prior 30.00 deg"), "{yaml}");
    assert!(dir.path("new/deeper/calibration-tf.txt").is_file());

    // A range that excludes the true offset is taken as typed, and the result says the offset
    // ended at its edge.
    let narrow = dir.path("narrow.yaml");
    let e = fails(dvlcal(&[
        "calibrate",
        s(&sim),
        "--offset-range",
        "-0.3,-0.1",
        "--out",
        s(&narrow),
    ]));
    assert!(
        e.contains("the offsets searched [-0.3000, -0.1000] s"),
        "{e}"
    );

    // A bad value is refused by name, not taken for an option.
    let e = fails(dvlcal(&[
        "calibrate",
        s(&sim),
        "--lever-arm-prior",
        "-0.1,x,0.3",
    ]));
    assert!(
        e.contains("invalid value '-0.1,x,0.3' for '--lever-arm-prior"),
        "{e}"
    );
    let e = fails(dvlcal(&["simulate", "--out", s(&sim), "--seed", "-1"]));
    assert!(e.contains("invalid value '-1' for '--seed"), "{e}");
}

#[test]
fn every_writer_creates_its_output_folder() {
    let dir = TempDir::new("folders");
    let sim = dir.path("sim");
    ok(dvlcal(&["simulate", "--out", s(&sim), "--duration", "12"]));

    let twist = dir.path("fit/twist.csv");
    let poses = sim.join("poses.txt");
    ok(dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&poses),
        "--out",
        s(&twist),
    ]));
    assert!(std::fs::read_to_string(&twist).unwrap().lines().count() > 100);

    let svg = dir.path("board/board.svg");
    let target = sample("target.yaml");
    ok(dvlcal(&["board", "--target", &target, "--out", s(&svg)]));
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<?xml"));

    let table = dir.path("evaluate/odometry.md");
    let truth = sim.join("truth/calibration.yaml");
    let text = ok(dvlcal(&[
        "evaluate",
        "--calib",
        s(&truth),
        s(&sim),
        "--out",
        s(&table),
    ]));
    assert!(text.contains("wrote"), "{text}");
    assert!(std::fs::read_to_string(&table).unwrap().contains("ATE"));

    // record-dvl creates the log's folder before it connects (here to a port nobody serves).
    let log = dir.path("record/a50.jsonl");
    let e = fails(dvlcal(&[
        "record-dvl",
        "--tcp",
        "127.0.0.1:9",
        "--out",
        s(&log),
        "--duration",
        "0.3",
        "--reconnect-delay",
        "0.1",
    ]));
    assert!(e.contains("nothing was recorded"), "{e}");
    assert!(dir.path("record").is_dir());
}

#[test]
fn an_output_that_cannot_be_written_is_refused_before_the_work() {
    let dir = TempDir::new("refused");
    // A regular file where a folder would have to be.
    let file = dir.path("file");
    std::fs::write(&file, "x").unwrap();
    let blocked = file.join("out/result.yaml");
    let images = sample("");
    let (camchain, target) = (sample("camchain.yaml"), sample("target.yaml"));
    for args in [
        vec!["calibrate", &images, "--out", s(&blocked)],
        vec![
            "detect",
            "--images",
            &images,
            "--camchain",
            &camchain,
            "--target",
            &target,
        ],
        vec![
            "calibrate-cameras",
            "--images",
            &images,
            "--target",
            &target,
        ],
    ] {
        let mut args = args.clone();
        if args[0] != "calibrate" {
            args.extend(["--out", s(&blocked)]);
        }
        let out = dvlcal(&args);
        let e = fails(out.clone());
        assert!(e.contains("--out") && e.contains("cannot write"), "{e}");
        // Nothing was detected or calibrated first.
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(!stdout.contains("frames/s"), "{}: {stdout}", args[0]);
    }
    let e = fails(dvlcal(&[
        "calibrate",
        &images,
        "--report",
        s(&blocked.with_extension("html")),
        "--out",
        s(&dir.path("ok.yaml")),
    ]));
    assert!(e.contains("--report") && e.contains("cannot write"), "{e}");
    let e = fails(dvlcal(&["board", "--target", &target, "--out", s(&dir.0)]));
    assert!(e.contains("is a folder"), "{e}");
}

/// A result YAML, read.
fn estimates(path: &Path) -> dvlcal::io::calib_yaml::CalibrationFile {
    read_calib_yaml(path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn detect_then_calibrate_equals_calibrate_on_the_images() {
    let dir = TempDir::new("two-steps");
    let images = sample("");
    let one = dir.path("one/calibration.yaml");
    ok(dvlcal(&[
        "calibrate",
        &images,
        "--out",
        s(&one),
        "--no-progress",
    ]));

    // detect into a folder that does not exist yet.
    let poses = dir.path("det/poses.txt");
    let (camchain, target) = (sample("camchain.yaml"), sample("target.yaml"));
    let text = ok(dvlcal(&[
        "detect",
        "--images",
        &images,
        "--camchain",
        &camchain,
        "--target",
        &target,
        "--out",
        s(&poses),
        "--no-progress",
    ]));
    let frames = dir.path("det/poses.txt.frames.csv");
    assert!(text.contains("poses.txt.frames.csv"), "{text}");

    let two = dir.path("two/calibration.yaml");
    let text = ok(dvlcal(&[
        "calibrate",
        &images,
        "--poses",
        s(&poses),
        "--out",
        s(&two),
    ]));
    assert!(text.contains("(covariances "), "{text}");
    assert!(
        text.contains("pose covariances from") && text.contains("(251 rows, one per pose)"),
        "{text}"
    );

    // The same digits: estimates, standard deviations and verdicts.
    let (a, b) = (estimates(&one), estimates(&two));
    assert_eq!(a.t_cam_dvl, b.t_cam_dvl);
    assert_eq!(a.quaternion_cam_dvl_xyzw, b.quaternion_cam_dvl_xyzw);
    assert_eq!(a.lever_arm_cam_m, b.lever_arm_cam_m);
    assert_eq!(a.time_offset_s, b.time_offset_s);
    assert_eq!(a.velocity_scale, b.velocity_scale);
    assert_eq!(a.std, b.std);
    assert!(a.std.is_some());
    assert_eq!(a.observability, b.observability);
    // Each result records where its pose covariances came from.
    let info = |p: &Path| std::fs::read_to_string(p).unwrap();
    assert!(info(&one).contains("pose_covariances: the image pipeline"));
    assert!(info(&two).contains("pose_covariances: ") && info(&two).contains("frames.csv\n"));

    // Without the table the poses carry no covariances, and the output says so.
    let bare = dir.path("bare/poses.txt");
    std::fs::create_dir_all(bare.parent().unwrap()).unwrap();
    std::fs::copy(&poses, &bare).unwrap();
    let dvl = sample("dvl.jsonl");
    let three = dir.path("three.yaml");
    let text = ok(dvlcal(&[
        "calibrate",
        "--poses",
        s(&bare),
        "--dvl",
        &dvl,
        "--out",
        s(&three),
    ]));
    assert!(text.contains("carries no covariances"), "{text}");
    assert_ne!(estimates(&three).time_offset_s, a.time_offset_s);
    assert!(info(&three).contains("pose_covariances: 'none: the pose noise was estimated"));

    // A table that does not match the poses is an error naming the table and its line.
    let table = std::fs::read_to_string(&frames).unwrap();
    let rows: Vec<&str> = table.lines().collect();
    let calibrate_with = |content: String| {
        std::fs::write(&frames, content).unwrap();
        fails(dvlcal(&[
            "calibrate",
            "--poses",
            s(&poses),
            "--dvl",
            &dvl,
            "--out",
            s(&three),
        ]))
    };
    // The last row removed: 2 comment/header lines, then 250 rows.
    let e = calibrate_with(rows[..rows.len() - 1].join("\n"));
    assert!(e.contains("poses.txt.frames.csv:252"), "{e}");
    assert!(e.contains("250 rows for the 251 poses"), "{e}");
    // A malformed number on the row of the tenth pose (line 12).
    let mut bad: Vec<String> = rows.iter().map(|r| r.to_string()).collect();
    let mut fields: Vec<&str> = rows[11].split(',').collect();
    fields[10] = "1.2.3";
    bad[11] = fields.join(",");
    let e = calibrate_with(bad.join("\n"));
    assert!(e.contains("poses.txt.frames.csv:12"), "{e}");
    assert!(e.contains("c04: '1.2.3' is not a number"), "{e}");
}
