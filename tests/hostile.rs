//! Input that must not be taken on trust: DVL covariances that cannot weigh a sample, velocities
//! out of any physical range, byte-order marks, a closed standard output, image names in other
//! units, JPEGs cut short, and messages that must name the real cause.

use dvlcal::calib::{CalibOptions, calibrate, usable_covariance};
use dvlcal::io::camchain::read_camchain;
use dvlcal::io::dvl::{DvlReadOptions, read_dvl_log};
use dvlcal::io::target::read_board;
use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};
use nalgebra::Matrix3;

const REAL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/a50-ros-driver");

#[test]
fn real_a50_covariances_that_are_not_positive_definite_are_recognised() {
    let log = read_dvl_log(
        std::path::Path::new(&format!("{REAL}/dvl_circle.jsonl")),
        &DvlReadOptions {
            include_invalid: true,
            ..DvlReadOptions::default()
        },
    )
    .expect("real log");
    let bad = log
        .samples
        .iter()
        .filter(|s| s.cov.is_some_and(|c| !usable_covariance(&c)))
        .count();
    let smallest = log
        .samples
        .iter()
        .filter_map(|s| s.cov)
        .map(|c| c.symmetric_eigenvalues().min())
        .fold(f64::INFINITY, f64::min);
    println!("dvl_circle: {bad} unusable covariances; smallest eigenvalue {smallest:e}");
    assert!(smallest < 0.0);
    assert!(bad >= 1);
    // A plain diagonal covariance is fine; a symmetric indefinite one and a nearly singular one
    // are not.
    assert!(usable_covariance(&(Matrix3::identity() * 1e-4)));
    assert!(!usable_covariance(&Matrix3::new(
        1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, -1e-8
    )));
    assert!(!usable_covariance(&Matrix3::new(
        1e-4, 1e-4, 0.0, 1e-4, 1e-4, 0.0, 0.0, 0.0, 1e-4
    )));
    assert!(!usable_covariance(&Matrix3::new(
        1e-4, 5e-5, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-4
    )));
}

#[test]
fn unusable_covariances_are_replaced_counted_and_do_not_bias_the_result() {
    let ds = simulate(&SimConfig {
        seed: 21,
        duration_s: 90.0,
        motion: MotionKind::CalmThenRotate,
        ..SimConfig::default()
    })
    .expect("simulation");
    let clean = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("clean");
    let mut dvl = ds.dvl.clone();
    // Every fifth report: an indefinite covariance (as real A50 output has) or a nearly singular
    // one that would claim millimetre-per-second-free knowledge along one direction.
    let indefinite = Matrix3::new(1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, -7.8e-8);
    let singular = Matrix3::new(1e-4, 1e-4, 0.0, 1e-4, 1e-4, 0.0, 0.0, 0.0, 1e-4);
    let mut changed = 0;
    for (i, s) in dvl.iter_mut().enumerate() {
        if i % 5 == 0 {
            s.cov = Some(if i % 10 == 0 { indefinite } else { singular });
            changed += 1;
        }
    }
    let o = calibrate(&ds.poses, &dvl, &CalibOptions::default()).expect("calibration");
    assert_eq!(o.counts.dvl_covariance_replaced, changed);
    assert!(
        o.warnings.iter().any(|w| w.contains("positive definite")),
        "{:?}",
        o.warnings
    );
    // The replaced reports are weighted with the same 1 cm/s the simulation used: the result is
    // the clean one.
    let d = dvlcal::calib::model::difference(&o.params, &clean.params);
    assert!(d.norm() < 1e-9, "{d}");
    assert!(o.std.rotation_deg.min() > 0.01, "{:?}", o.std);
}

mod tmp_common;

/// A 40 s simulated dataset folder (poses and an A50 log) written into `dir`.
fn simulate_into(dir: &std::path::Path, seed: u64) {
    let req = dvlcal::pipeline::SimulateRequest {
        config: SimConfig {
            seed,
            duration_s: 40.0,
            ..SimConfig::default()
        },
        images: None,
        note: String::new(),
    };
    dvlcal::pipeline::write_simulated_dataset(dir, &req, &|_, _| {}).expect("simulate");
}

#[test]
fn a_velocity_out_of_range_is_a_counted_rejection_and_byte_order_marks_are_harmless() {
    use dvlcal::io::dvl::a50::{parse_velocity_report, velocity_report_line};
    let tmp = tmp_common::TmpDir::new("hostile-range");
    let d = tmp.0.join("run");
    simulate_into(&d, 22);
    let log = d.join("dvl.jsonl");
    let text = std::fs::read_to_string(&log).expect("log");
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    // Line 5: a velocity of 1e300 m/s.
    let mut r = parse_velocity_report(&lines[4]).expect("report");
    r.vx = 1e300;
    lines[4] = velocity_report_line(&r).trim_end().to_string();
    // A byte-order mark before the first line, as Windows editors write it.
    let mut out = String::from('\u{feff}');
    for l in &lines {
        out.push_str(l);
        out.push_str("\r\n");
    }
    std::fs::write(&log, out).expect("write");
    let parsed = read_dvl_log(&log, &DvlReadOptions::default()).expect("log");
    assert_eq!(
        parsed.stats.rejected_lines, 1,
        "{:?}",
        parsed.stats.rejected
    );
    assert_eq!(parsed.stats.rejected[0].line, 5);
    assert_eq!(parsed.stats.rejected[0].reason, "velocity out of range");
    assert_eq!(parsed.samples.len(), lines.len() - 1);
    // Strict mode stops there, naming the file and line.
    let e = read_dvl_log(
        &log,
        &DvlReadOptions {
            strict: true,
            ..DvlReadOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("dvl.jsonl:5"), "{e}");
    // The folder (with the marked log, and a marked pose file) still calibrates.
    let poses = d.join("poses.txt");
    let p = std::fs::read_to_string(&poses).expect("poses");
    std::fs::write(&poses, format!("\u{feff}{p}")).expect("write");
    let files = dvlcal::pipeline::dataset_files(Some(&d), &Default::default()).expect("files");
    let data = dvlcal::pipeline::Dataset::load(
        files,
        &Default::default(),
        &DvlReadOptions::default(),
        &mut |_| {},
    )
    .expect("dataset");
    let log = data.dvl().expect("DVL log");
    let o = calibrate(&data.poses, &log.samples, &CalibOptions::default()).expect("calibrate");
    assert!(o.status.is_ok(), "{:?}", o.status);
}

#[test]
fn a_closed_standard_output_ends_the_program_quietly() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};
    let tmp = tmp_common::TmpDir::new("hostile-pipe");
    let d = tmp.0.join("run");
    simulate_into(&d, 23);
    // `dvlcal calibrate DIR | head -1`: the reader goes away after the first line.
    let mut child = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(["calibrate", d.to_str().expect("utf-8"), "--out"])
        .arg(tmp.0.join("c.yaml"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run dvlcal");
    let mut first = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut first)
        .expect("first line");
    assert!(first.starts_with("dataset"), "{first}");
    let out = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn camera_chains_and_boards_in_the_wrong_units_or_shape_are_refused() {
    let tmp = tmp_common::TmpDir::new("hostile-geometry");
    let cam = |pu: f64, r11: f64, tx: f64| {
        format!(
            "cam0:\n  camera_model: pinhole\n  intrinsics: [460, 460, {pu}, 240]\n  \
             distortion_model: radtan\n  distortion_coeffs: [0, 0, 0, 0]\n  resolution: [752, 480]\n\
             cam1:\n  camera_model: pinhole\n  intrinsics: [460, 460, 376, 240]\n  \
             distortion_model: radtan\n  distortion_coeffs: [0, 0, 0, 0]\n  resolution: [752, 480]\n  \
             T_cn_cnm1:\n  - [{r11}, 0, 0, {tx}]\n  - [0, 1, 0, 0]\n  - [0, 0, 1, 0]\n  - [0, 0, 0, 1]\n"
        )
    };
    let load = |name: &str, text: String| {
        let p = tmp.0.join(name);
        std::fs::write(&p, text).expect("write");
        read_camchain(&p).map(|_| ()).map_err(|e| e.to_string())
    };
    load("good.yaml", cam(376.0, 1.0, -0.11)).expect("a good chain");
    let e = load("pp.yaml", cam(900.0, 1.0, -0.11)).unwrap_err();
    assert!(
        e.contains("principal point") && e.contains("pp.yaml:"),
        "{e}"
    );
    let e = load("det.yaml", cam(376.0, -1.0, -0.11)).unwrap_err();
    assert!(e.contains("reflection"), "{e}");
    let e = load("mm.yaml", cam(376.0, 1.0, -110.0)).unwrap_err();
    assert!(e.contains("millimetres"), "{e}");
    let e = load(
        "nan.yaml",
        cam(376.0, 1.0, -0.11).replacen("[460, 460, 376, 240]", "[.nan, 460, 376, 240]", 1),
    )
    .unwrap_err();
    assert!(e.contains("not all finite"), "{e}");

    let board = |name: &str, text: &str| {
        let p = tmp.0.join(name);
        std::fs::write(&p, text).expect("write");
        read_board(&p).map(|_| ()).map_err(|e| e.to_string())
    };
    board(
        "b.yaml",
        "rows: 6\ncols: 6\ntag_size: 0.088\nspacing: 0.3\n",
    )
    .expect("a good board");
    let e = board(
        "mm_board.yaml",
        "rows: 6\ncols: 6\ntag_size: 88\nspacing: 0.3\n",
    )
    .unwrap_err();
    assert!(e.contains("millimetres"), "{e}");
    let e = board(
        "kalibr_mm.yaml",
        "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 88\ntagSpacing: 0.3\n",
    )
    .unwrap_err();
    assert!(e.contains("millimetres"), "{e}");
    let e = board(
        "huge.yaml",
        "rows: 100000\ncols: 100000\ntag_size: 0.01\nspacing: 0.3\n",
    )
    .unwrap_err();
    assert!(e.contains("at most"), "{e}");
}

#[test]
fn no_file_of_the_user_is_lost() {
    use std::process::Command;
    let tmp = tmp_common::TmpDir::new("hostile-files");
    let d = tmp.0.join("run");
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_dvlcal"))
            .args(args)
            .output()
            .expect("run dvlcal")
    };
    let sim = run(&[
        "simulate",
        "--out",
        d.to_str().expect("utf-8"),
        "--duration",
        "40",
    ]);
    assert!(sim.status.success());
    // simulate into a folder that holds files: refused without --force.
    let again = run(&[
        "simulate",
        "--out",
        d.to_str().expect("utf-8"),
        "--duration",
        "40",
    ]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    let log = d.join("dvl.jsonl");
    let before = std::fs::read(&log).expect("log");
    // --out naming the DVL log: refused, the log untouched.
    let out = run(&[
        "calibrate",
        d.to_str().expect("utf-8"),
        "--out",
        log.to_str().expect("utf-8"),
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("refusing to overwrite"), "{stderr}");
    assert_eq!(std::fs::read(&log).expect("log"), before);
    // An output that is a device is never replaced by a regular file; a symbolic link is
    // written through.
    let e = dvlcal::io::write_atomic(std::path::Path::new("/dev/null"), b"x").unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    assert!(!std::fs::metadata("/dev/null").expect("null").is_file());
    let target = tmp.0.join("target.txt");
    std::fs::write(&target, "old").expect("write");
    let link = tmp.0.join("link.txt");
    std::os::unix::fs::symlink(&target, &link).expect("symlink");
    dvlcal::io::write_atomic(&link, b"new").expect("write through");
    assert!(
        std::fs::symlink_metadata(&link)
            .expect("link")
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read_to_string(&target).expect("target"), "new");
}

#[test]
fn a_log_that_yields_nothing_says_why() {
    let tmp = tmp_common::TmpDir::new("hostile-empty");
    let p = tmp.0.join("all_bad.jsonl");
    // Every line broken in the same way (a unit mix-up of a logger: velocities in mm/s).
    let mut text = String::new();
    for i in 0..5 {
        text.push_str(&format!(
            "{{\"time\": 100.0, \"vx\": {}.0, \"vy\": 0.0, \"vz\": 0.0, \"fom\": 0.01, \
             \"altitude\": 1.0, \"velocity_valid\": true, \"status\": 0, \
             \"format\": \"json_v3\", \"type\": \"velocity\", \
             \"time_of_validity\": {}, \"time_of_transmission\": {}}}\n",
            200 + i,
            1_700_000_000_000_000i64 + i * 100_000,
            1_700_000_000_040_000i64 + i * 100_000
        ));
    }
    std::fs::write(&p, text).expect("write");
    let e = read_dvl_log(&p, &DvlReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("5 velocity out of range"), "{e}");
    assert!(e.contains("first at line 1"), "{e}");
}

#[test]
fn poses_that_do_not_reproject_fail_detection_with_a_hint() {
    let tmp = tmp_common::TmpDir::new("hostile-rms");
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_data/stereo");
    let d = tmp.0.join("few");
    for cam in ["cam0", "cam1"] {
        std::fs::create_dir_all(d.join(cam)).expect("mkdir");
        let mut names: Vec<_> = std::fs::read_dir(src.join(cam))
            .expect("images")
            .map(|e| e.expect("entry").file_name())
            .collect();
        names.sort();
        for n in names.iter().take(5) {
            std::fs::copy(src.join(cam).join(n), d.join(cam).join(n)).expect("copy");
        }
    }
    // The intrinsics of another camera: focal lengths a quarter too long.
    let chain = std::fs::read_to_string(src.join("camchain.yaml"))
        .expect("camchain")
        .replace("[458.0, 457.0,", "[572.5, 571.25,");
    let chain_path = tmp.0.join("wrong.yaml");
    std::fs::write(&chain_path, chain).expect("write");
    let run = dvlcal::pipeline::poses_from_images(
        &d,
        &chain_path,
        &src.join("target.yaml"),
        &Default::default(),
    )
    .expect("the run itself");
    println!(
        "reprojection RMS with wrong intrinsics: {:.2} px",
        run.stats.rms_px
    );
    let e = run.require_poses().unwrap_err().to_string();
    assert!(e.contains("intrinsics"), "{e}");
    // The right intrinsics pass.
    let good = dvlcal::pipeline::poses_from_images(
        &d,
        &src.join("camchain.yaml"),
        &src.join("target.yaml"),
        &Default::default(),
    )
    .expect("run");
    good.require_poses().expect("good poses");
}

#[test]
fn time_stamps_in_the_wrong_unit_are_pointed_out() {
    let tmp = tmp_common::TmpDir::new("hostile-units");
    let p = tmp.0.join("ms.jsonl");
    // time_of_validity in milliseconds where the format has microseconds: 10 Hz looks like 10 kHz.
    let mut text = String::new();
    for i in 0..50i64 {
        text.push_str(&format!(
            "{{\"time\": 100.0, \"vx\": 0.1, \"vy\": 0.0, \"vz\": 0.0, \"fom\": 0.01, \
             \"altitude\": 1.0, \"velocity_valid\": true, \"status\": 0, \
             \"format\": \"json_v3\", \"type\": \"velocity\", \
             \"time_of_validity\": {}, \"time_of_transmission\": {}}}\n",
            1_700_000_000_000i64 + i * 100,
            1_700_000_000_040i64 + i * 100
        ));
    }
    std::fs::write(&p, text).expect("write");
    let log = read_dvl_log(&p, &DvlReadOptions::default()).expect("log");
    assert!(
        log.stats
            .warnings
            .iter()
            .any(|w| w.contains("milliseconds")),
        "{:?}",
        log.stats.warnings
    );
}

#[test]
fn image_names_in_other_units_are_read_as_such_and_said() {
    use dvlcal::io::images::scan_images;
    let tmp = tmp_common::TmpDir::new("hostile-names");
    let d = &tmp.0;
    let touch = |p: std::path::PathBuf| {
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, b"").unwrap();
    };
    // cam0 in Unix milliseconds (13 digits), cam1 in decimal seconds, 20 Hz.
    let t0_ms = 1_700_000_000_000i64;
    for k in 0..10i64 {
        let ms = t0_ms + 50 * k;
        touch(d.join("cam0").join(format!("{ms}.png")));
        touch(
            d.join("cam1")
                .join(format!("{}.{:06}.png", ms / 1000, (ms % 1000) * 1000)),
        );
    }
    let (frames, st) = scan_images(d, 2, 1_000_000).unwrap();
    assert_eq!(frames.len(), 10);
    assert_eq!(st.complete, 10, "{st:?}");
    assert_eq!(frames[3].t_ns, (t0_ms + 150) * 1_000_000);
    assert!(
        st.warnings
            .iter()
            .any(|w| w.contains("cam0") && w.contains("milliseconds") && w.contains("20.000 Hz")),
        "{:?}",
        st.warnings
    );
    // Microseconds (16 digits), alone.
    let us = d.join("us");
    for k in 0..5i64 {
        touch(
            us.join("cam0")
                .join(format!("{}.jpg", 1_700_000_000_000_000 + 100_000 * k)),
        );
    }
    let (frames, st) = scan_images(&us, 1, 0).unwrap();
    assert_eq!(frames[1].t_ns, 1_700_000_000_100_000_000);
    assert!(
        st.warnings.iter().any(|w| w.contains("microseconds")),
        "{st:?}"
    );
    // Nanoseconds, Unix or relative, need no word.
    let ns = d.join("ns");
    for k in 0..5i64 {
        touch(ns.join("cam0").join(format!(
            "{}.png",
            1_700_000_000_000_000_000 + 50_000_000 * k
        )));
        touch(
            ns.join("rel")
                .join("cam0")
                .join(format!("{}.png", 50_000_000 * k)),
        );
    }
    for dir in [ns.clone(), ns.join("rel")] {
        let (frames, st) = scan_images(&dir, 1, 0).unwrap();
        assert_eq!(frames[1].t_ns - frames[0].t_ns, 50_000_000);
        assert!(st.warnings.is_empty(), "{st:?}");
    }
    // A decimal name with more than nanosecond digits is not a stamp: ignored and counted.
    touch(ns.join("cam0").join("1700000000.0000000001.png"));
    let (_, st) = scan_images(&ns, 1, 0).unwrap();
    assert_eq!(st.ignored, 1);
}

#[test]
fn a_jpeg_cut_short_is_refused_not_half_decoded() {
    use dvlcal::io::image::load_gray;
    let tmp = tmp_common::TmpDir::new("hostile-jpeg");
    let img = image::GrayImage::from_fn(160, 120, |x, y| {
        image::Luma([((x * 7 + y * 3) % 256) as u8])
    });
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 90)
        .encode_image(&img)
        .unwrap();
    let whole = tmp.0.join("whole.jpg");
    std::fs::write(&whole, &jpeg).unwrap();
    assert_eq!(load_gray(&whole).unwrap().dimensions(), (160, 120));
    // Padding after the end marker, as some cameras write, is fine.
    let padded = tmp.0.join("padded.jpg");
    let mut p = jpeg.clone();
    p.extend_from_slice(&[0u8; 16]);
    std::fs::write(&padded, &p).unwrap();
    assert!(load_gray(&padded).is_ok());
    for frac in [0.3, 0.6, 0.9, 0.999] {
        let cut = tmp.0.join(format!("cut-{frac}.jpg"));
        std::fs::write(&cut, &jpeg[..(jpeg.len() as f64 * frac) as usize]).unwrap();
        let e = load_gray(&cut).unwrap_err().to_string();
        assert!(e.contains("cut-") && e.contains("cut short"), "{e}");
    }
}

#[test]
fn messages_name_the_real_cause() {
    // A DVL that reports zero velocity throughout (out of the water, no bottom lock) is the
    // DVL's problem, not the camera's.
    let ds = simulate(&SimConfig {
        seed: 5,
        duration_s: 40.0,
        ..SimConfig::default()
    })
    .expect("simulation");
    let mut dvl = ds.dvl.clone();
    for s in &mut dvl {
        s.v = nalgebra::Vector3::zeros();
    }
    let e = calibrate(&ds.poses, &dvl, &CalibOptions::default())
        .expect_err("zero DVL velocities calibrated")
        .to_string();
    assert!(e.contains("DVL") && !e.contains("camera velocity"), "{e}");
    // A DVL velocity along one axis only: also the DVL's.
    for s in &mut dvl {
        s.v = nalgebra::Vector3::new(0.2, 0.0, 0.0);
    }
    let e = calibrate(&ds.poses, &dvl, &CalibOptions::default())
        .expect_err("constant DVL velocities calibrated")
        .to_string();
    assert!(e.contains("DVL"), "{e}");

    // NaN intrinsics are named as not numbers, whichever way YAML spells them.

    let tmp = tmp_common::TmpDir::new("hostile-nan");
    for nan in [".nan", ".NaN", "nan", "NaN", ".inf"] {
        let p = tmp.0.join("chain.yaml");
        std::fs::write(
            &p,
            format!(
                "cam0:\n  camera_model: pinhole\n  intrinsics: [{nan}, 460, 376, 240]\n  \
                 distortion_model: radtan\n  distortion_coeffs: [0, 0, 0, 0]\n  resolution: [752, 480]\n"
            ),
        )
        .unwrap();
        let e = read_camchain(&p).unwrap_err().to_string();
        assert!(
            e.contains("chain.yaml") && !e.contains("must be [fu, fv, pu, pv]"),
            "{nan}: {e}"
        );
        assert!(e.contains("finite") || e.contains("number"), "{nan}: {e}");
    }
}

#[test]
fn distortion_that_folds_the_image_is_refused() {
    let tmp = tmp_common::TmpDir::new("hostile-fold");
    let chain = |model: &str, k: [f64; 4]| {
        let p = tmp.0.join("chain.yaml");
        std::fs::write(
            &p,
            format!(
                "cam0:\n  camera_model: pinhole\n  intrinsics: [458.654, 457.296, 367.215, 248.375]\n  \
                 distortion_model: {model}\n  distortion_coeffs: {k:?}\n  resolution: [752, 480]\n"
            ),
        )
        .unwrap();
        read_camchain(&p).map(|_| ()).map_err(|e| e.to_string())
    };
    // EuRoC's cam0 (radtan) and TUM-VI's cam0 (equidistant, scaled to this image) are real lenses.
    chain(
        "radtan",
        [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05],
    )
    .unwrap();
    chain("equidistant", [0.0034823, 0.0007150, -0.0020532, 0.0002029]).unwrap();
    // Barrel distortion strong enough to turn back inside the image; a k1 in the wrong slot of
    // an equidistant model; both fold the image over.
    for (model, k) in [
        ("radtan", [-1.5, 0.0, 0.0, 0.0]),
        ("radtan", [-0.9, 0.1, 0.0, 0.0]),
        ("equidistant", [-0.5, 0.0, 0.0, 0.0]),
    ] {
        let e = chain(model, k).expect_err("a folding lens accepted");
        assert!(
            e.contains("chain.yaml") && e.contains("fold"),
            "{model} {k:?}: {e}"
        );
    }
}
