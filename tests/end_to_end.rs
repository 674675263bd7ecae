//! End to end on the rendered dataset shipped in `sample_data/stereo`: images + A50 log ->
//! calibration, checked against the simulation's truth with the reported uncertainty, and the
//! same digits whatever the number of threads.

mod tmp_common;
use tmp_common::TmpDir;

use std::path::Path;
use std::process::Command;

use dvlcal::eval::calibration_error;
use dvlcal::io::calib_yaml::read_calib_yaml;

const STEREO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/stereo");
/// The same kind of recording with a board printed the way Kalibr prints it.
const STEREO_KALIBR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/stereo_kalibr");

fn calibrate(out: &Path, threads: &str) -> String {
    calibrate_dir(STEREO, out, threads)
}

fn calibrate_dir(dir: &str, out: &Path, threads: &str) -> String {
    let r = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args([
            "calibrate",
            dir,
            "--out",
            out.to_str().unwrap(),
            "--threads",
            threads,
            "--no-progress",
        ])
        .output()
        .expect("run dvlcal");
    let stdout = String::from_utf8_lossy(&r.stdout).into_owned();
    assert!(
        r.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&r.stderr)
    );
    stdout
}

#[test]
fn rendered_dataset_calibrates_within_its_uncertainty_and_identically_on_any_thread_count() {
    let tmp = TmpDir::new("e2e-stereo");
    let one = tmp.0.join("one.yaml");
    let two = tmp.0.join("two.yaml");
    let stdout = calibrate(&two, "2");
    assert!(stdout.contains("images"), "{stdout}");
    calibrate(&one, "1");

    // Same inputs, same result to the last digit, whatever the thread count.
    let a = std::fs::read_to_string(&one).unwrap();
    let b = std::fs::read_to_string(&two).unwrap();
    assert_eq!(a, b, "results differ between 1 and 2 threads");

    within_uncertainty(STEREO, &two);
}

#[test]
fn kalibr_printed_board_calibrates_within_its_uncertainty() {
    let tmp = TmpDir::new("e2e-stereo-kalibr");
    let out = tmp.0.join("calibration.yaml");
    let stdout = calibrate_dir(STEREO_KALIBR, &out, "2");
    assert!(stdout.contains("201 of 201 frames"), "{stdout}");
    within_uncertainty(STEREO_KALIBR, &out);
}

/// Every parameter of the result within 3.5 of its standard deviations of the dataset's truth,
/// and every parameter observable.
fn within_uncertainty(dir: &str, result: &Path) {
    let est_file = read_calib_yaml(result).unwrap();
    let truth_file = Path::new(dir).join("truth").join("calibration.yaml");
    let truth = read_calib_yaml(&truth_file).unwrap().to_params().unwrap();
    let ce = calibration_error(&est_file, &truth).unwrap();
    let d = ce.error;
    let std = ce.std.expect("std in the result");
    let names = [
        "rot x", "rot y", "rot z", "lever x", "lever y", "lever z", "scale", "offset",
    ];
    let mut report = String::new();
    for k in 0..8 {
        report.push_str(&format!(
            "{}: err {:.3e} std {:.3e} z {:+.2}\n",
            names[k],
            d[k],
            std[k],
            d[k] / std[k]
        ));
    }
    eprintln!("{report}");
    // One dataset: each error within 3.5 standard deviations (eight parameters, so a 3.5 sigma
    // bound keeps the chance of a false alarm for a consistent estimator below 0.4 %).
    for k in 0..8 {
        assert!(std[k] > 0.0 && std[k].is_finite(), "{report}");
        assert!((d[k] / std[k]).abs() < 3.5, "{}:\n{report}", names[k]);
    }
    // And useful: the motion of the sample rotates, so every parameter is observable.
    let obs = est_file.observability.expect("observability");
    let text = serde_yaml::to_string(&obs).unwrap();
    assert!(!text.contains("weak"), "{text}");
}
