//! The odometry check (DVL dead reckoning against camera positions) and the dataset-folder
//! handling of `calibrate` and `evaluate`.

mod tmp_common;
use tmp_common::TmpDir;

use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::eval::odometry::{OdometryOptions, dvl_odometry};
use dvlcal::io::dataset::{DatasetOverrides, discover};
use dvlcal::lie::{Se3, so3};
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::types::{CalibrationParams, PoseMeasurement};
use nalgebra::Vector3;

fn sim(seed: u64, motion: MotionKind, duration: f64) -> SimDataset {
    simulate(&SimConfig {
        seed,
        motion,
        duration_s: duration,
        ..SimConfig::default()
    })
    .expect("simulation")
}

/// The simulation's poses without noise, so that the check measures the dead reckoning alone.
fn true_poses(ds: &SimDataset) -> Vec<PoseMeasurement> {
    ds.true_poses_in(&Se3::identity())
}

fn perturbed(
    c: &CalibrationParams,
    rot_deg: f64,
    lever_m: f64,
    offset_s: f64,
) -> CalibrationParams {
    let r = so3::exp(&Vector3::new(0.0, 0.0, rot_deg.to_radians()));
    CalibrationParams {
        t_cam_dvl: Se3::new(
            c.t_cam_dvl.rot * r,
            c.t_cam_dvl.trans + Vector3::new(lever_m, 0.0, 0.0),
        ),
        time_offset_s: c.time_offset_s + offset_s,
        velocity_scale: c.velocity_scale,
    }
}

#[test]
fn odometry_with_the_true_calibration_drifts_only_by_the_dvl_noise() {
    let opts = OdometryOptions::default();
    for seed in [1, 2, 3] {
        let ds = sim(seed, MotionKind::CalmThenRotate, 60.0);
        let poses = true_poses(&ds);
        let r = dvl_odometry(&poses, &ds.dvl, &ds.truth, &opts).unwrap();
        assert_eq!(r.gaps, 0);
        // Only the poses before the first DVL report (shifted by the 70 ms offset) and after the
        // last one are left out, and counted.
        assert_eq!(r.estimated.len() + r.outside_dvl_span, poses.len());
        assert!(r.outside_dvl_span <= 2, "{}", r.outside_dvl_span);
        eprintln!("seed {seed}: ATE {:.4} m, RPE {:.4} m", r.ate_m, r.rpe_m);
        // 1 cm/s white DVL noise integrated at 10 Hz over 60 s: a random walk of about
        // 0.01 * sqrt(60 * 0.1) = 2.5 cm per axis at the end, plus interpolation error.
        assert!(r.ate_m < 0.08, "seed {seed}: ATE {:.4} m", r.ate_m);
        assert!(r.rpe_m < 0.02, "seed {seed}: RPE {:.4} m", r.rpe_m);
        assert!(r.rpe_pairs > poses.len() - 20, "{} pairs", r.rpe_pairs);
    }
}

#[test]
fn odometry_penalises_each_kind_of_calibration_error() {
    let ds = sim(4, MotionKind::CalmThenRotate, 60.0);
    let poses = true_poses(&ds);
    let opts = OdometryOptions::default();
    let good = dvl_odometry(&poses, &ds.dvl, &ds.truth, &opts).unwrap();
    for (what, c) in [
        ("rotation 5 deg", perturbed(&ds.truth, 5.0, 0.0, 0.0)),
        ("lever arm 20 cm", perturbed(&ds.truth, 0.0, 0.2, 0.0)),
        ("clock offset 150 ms", perturbed(&ds.truth, 0.0, 0.0, 0.15)),
    ] {
        let bad = dvl_odometry(&poses, &ds.dvl, &c, &opts).unwrap();
        assert!(
            bad.rpe_m > 1.5 * good.rpe_m,
            "{what}: RPE {:.4} vs {:.4}",
            bad.rpe_m,
            good.rpe_m
        );
    }
}

#[test]
fn odometry_restarts_across_gaps_and_counts_them() {
    let ds = sim(5, MotionKind::CalmThenRotate, 30.0);
    let poses = true_poses(&ds);
    // Remove the DVL reports of 10..14 s.
    let dvl: Vec<_> = ds
        .dvl
        .iter()
        .filter(|s| !(10.0..14.0).contains(&s.t))
        .cloned()
        .collect();
    let r = dvl_odometry(&poses, &dvl, &ds.truth, &OdometryOptions::default()).unwrap();
    assert!(r.gaps >= 35 && r.gaps <= 45, "{} gaps", r.gaps);
    assert_eq!(*r.segment.last().unwrap(), r.gaps);
    // No DVL at all over the poses: an error, not a number.
    let e = dvl_odometry(&poses, &dvl[..1], &ds.truth, &OdometryOptions::default()).unwrap_err();
    assert!(matches!(e, dvlcal::Error::NoTimeOverlap(_)), "{e:?}");
    assert!(e.to_string().contains("no camera interval"), "{e}");
    let e = dvl_odometry(&poses[..1], &dvl, &ds.truth, &OdometryOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            dvlcal::Error::TooFewSamples {
                found: 1,
                needed: 2,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        e.to_string()
            .contains("camera poses for the odometry check"),
        "{e}"
    );
}

fn dvlcal(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(args)
        .output()
        .expect("run dvlcal")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn simulate_dir(dir: &Path, seed: u64, duration: f64) {
    let r = dvlcal(&[
        "simulate",
        "--out",
        s(dir),
        "--seed",
        &seed.to_string(),
        "--duration",
        &duration.to_string(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn discovery_finds_a_simulated_dataset_and_names_competing_files() {
    let tmp = TmpDir::new("eval-discover");
    let d = tmp.0.join("a");
    simulate_dir(&d, 3, 20.0);
    let f = discover(&d, &DatasetOverrides::default()).unwrap();
    assert_eq!(f.poses.as_deref(), Some(d.join("poses.txt").as_path()));
    assert_eq!(f.dvl.as_deref(), Some(d.join("dvl.jsonl").as_path()));
    assert!(f.images.is_none() && f.camchain.is_none());

    // A second DVL log competes: the error names both.
    std::fs::copy(d.join("dvl.jsonl"), d.join("other.json")).unwrap();
    let e = discover(&d, &DatasetOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("DVL log") && e.contains("dvl.jsonl") && e.contains("other.json"),
        "{e}"
    );
    // Naming one settles it.
    let f = discover(
        &d,
        &DatasetOverrides {
            dvl: Some(d.join("other.json")),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(f.dvl.as_deref(), Some(d.join("other.json").as_path()));
    std::fs::remove_file(d.join("other.json")).unwrap();

    // An unreadable YAML (not UTF-8) is listed as ignored, with the reason, not fatal.
    std::fs::write(d.join("broken.yaml"), [0xff, 0xfe, 0x00, 0x41]).unwrap();
    let f = discover(&d, &DatasetOverrides::default()).unwrap();
    assert!(
        f.ignored
            .iter()
            .any(|(p, why)| p.ends_with("broken.yaml") && why.starts_with("unreadable")),
        "{:?}",
        f.ignored
    );
    std::fs::remove_file(d.join("broken.yaml")).unwrap();

    // Images beside a pose file: ambiguous.
    std::fs::create_dir_all(d.join("cam0")).unwrap();
    let e = discover(&d, &DatasetOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("--images or --poses"), "{e}");
    std::fs::remove_dir_all(d.join("cam0")).unwrap();

    // No DVL log, a missing folder.
    std::fs::remove_file(d.join("dvl.jsonl")).unwrap();
    let e = discover(&d, &DatasetOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("no DVL log"), "{e}");
    let e = discover(&d.join("nope"), &DatasetOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a folder"), "{e}");
}

#[test]
fn calibrate_a_folder_then_cross_validate_three() {
    let tmp = TmpDir::new("eval-cross");
    let dirs: Vec<PathBuf> = (0..3).map(|k| tmp.0.join(format!("traj{k}"))).collect();
    for (k, d) in dirs.iter().enumerate() {
        simulate_dir(d, 20 + k as u64, 40.0);
    }
    // calibrate DATASET_DIR writes the YAML and both exports.
    let out = tmp.0.join("res").join("cal.yaml");
    let r = dvlcal(&["calibrate", s(&dirs[0]), "--out", s(&out)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(
        stdout.contains("dataset") && stdout.contains("poses.txt"),
        "{stdout}"
    );
    for f in [
        "cal.yaml",
        "cal-tf.txt",
        "cal-camchain-imucam.yaml",
        "cal-urdf.xml",
    ] {
        assert!(tmp.0.join("res").join(f).is_file(), "{f} missing");
    }
    // compare-calib against the truth: the clock error it prints is the files' difference.
    let truth_yaml = dirs[0].join("truth").join("calibration.yaml");
    let r = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&out),
        "--truth",
        s(&truth_yaml),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let text = String::from_utf8_lossy(&r.stdout);
    let est = dvlcal::io::calib_yaml::read_calib_yaml(&out).unwrap();
    let tru = dvlcal::io::calib_yaml::read_calib_yaml(&truth_yaml).unwrap();
    let want = format!(
        "clock      {:+.2} ms",
        1e3 * (est.time_offset_s - tru.time_offset_s)
    );
    assert!(text.contains(&want), "{want}\n{text}");
    assert!(text.contains("largest error"), "{text}");

    // The calibration checked on the other datasets, and the truth as a guess for the
    // baselines of the cross-validation.
    let guess = dirs[0].join("truth").join("calibration.yaml");
    let table = tmp.0.join("table.md");
    let r = dvlcal(&[
        "evaluate",
        "--calib",
        s(&out),
        "--cross-validate",
        "--guess",
        s(&guess),
        "--out",
        s(&table),
        s(&dirs[0]),
        s(&dirs[1]),
        s(&dirs[2]),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let md = std::fs::read_to_string(&table).unwrap();
    for row in [
        "| UIC |",
        "| BCD (from guess) |",
        "| Guess, estimated offset |",
        "| Guess, its own offset |",
        "traj0 → traj1 ATE",
        "traj2 → traj1 ATE",
        "| traj2 |",
    ] {
        assert!(md.contains(row), "missing {row}:\n{md}");
    }
    // UIC's mean ATE is within reach of the truth's (held fixed with its own offset).
    let mean_ate = |name: &str| -> f64 {
        let line = md.lines().find(|l| l.starts_with(name)).unwrap();
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let cell = cells[cells.len() - 3];
        cell.split_whitespace().next().unwrap().parse().unwrap()
    };
    let uic = mean_ate("| UIC |");
    let truth = mean_ate("| Guess, its own offset |");
    assert!(uic < 1.5 * truth + 0.01, "UIC {uic} vs truth {truth}\n{md}");

    // One dataset without --calib: a clear error.
    let r = dvlcal(&["evaluate", s(&dirs[0])]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("two or more datasets"));
}

const REAL_LOGS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/a50-ros-driver");

#[test]
fn discovery_recognises_real_a50_logs_and_bags() {
    // The folder of real driver logs: four candidate DVL logs (and four bags), no camera data.
    let e = discover(Path::new(REAL_LOGS), &DatasetOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("DVL log") && e.contains("dvl_circle.jsonl") && e.contains("dvl.jsonl"),
        "{e}"
    );
    // With the JSON logs named away, the four bags compete: named too.
    let e = discover(
        Path::new(REAL_LOGS),
        &DatasetOverrides {
            dvl: Some(Path::new(REAL_LOGS).join("dvl.jsonl")),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("bag") && e.contains("dvl_circle.bag"), "{e}");
    // A bag beside a pose file is found as the DVL log; a README is ignored with a reason.
    let tmp = TmpDir::new("eval-bag");
    let d = tmp.0.join("run");
    simulate_dir(&d, 9, 5.0);
    std::fs::remove_file(d.join("dvl.jsonl")).unwrap();
    std::fs::copy(
        Path::new(REAL_LOGS).join("dvl_circle.bag"),
        d.join("dvl.bag"),
    )
    .unwrap();
    std::fs::copy(Path::new(REAL_LOGS).join("README.md"), d.join("README.md")).unwrap();
    let f = discover(&d, &DatasetOverrides::default()).unwrap();
    assert_eq!(f.dvl.as_deref(), Some(d.join("dvl.bag").as_path()));
    // The pose file gives the camera data; the bag only the DVL's.
    assert!(f.poses.is_some() && f.bag.is_none());
    assert!(
        f.ignored.iter().any(|(p, _)| p.ends_with("README.md")),
        "{:?}",
        f.ignored
    );
}
