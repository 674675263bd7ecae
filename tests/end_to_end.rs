//! End to end on the rendered dataset shipped in `sample_data/stereo`: images + A50 log ->
//! calibration, checked against the simulation's truth with the reported uncertainty, and the
//! same digits whatever the number of threads.

mod tmp_common;
mod truth_common;
use tmp_common::TmpDir;

use std::path::Path;
use std::process::Command;

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

    // Same inputs, same result to the last digit, whatever the thread count (the provenance
    // differs: command line and time; its input digests do not).
    let read = |p: &Path| {
        let text = std::fs::read_to_string(p).unwrap();
        let (result, provenance) = text.split_once("\nprovenance:\n").expect("provenance");
        let digests = provenance
            .lines()
            .filter(|l| l.trim_start().starts_with("sha256:"))
            .collect::<Vec<_>>()
            .join("\n");
        (result.to_owned(), digests)
    };
    let (a, b) = (read(&one), read(&two));
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
    let a = truth_common::against_truth(Path::new(dir), result);
    // One dataset: each error within 3.5 standard deviations (eight parameters, so a 3.5 sigma
    // bound keeps the chance of a false alarm for a consistent estimator below 0.4 %).
    truth_common::assert_within(&a, 3.5);
    let est_file = a.file;
    // And useful: the motion of the sample rotates, so every parameter is observable.
    let obs = est_file.observability.expect("observability");
    let text = serde_yaml::to_string(&obs).unwrap();
    assert!(!text.contains("weak"), "{text}");
}
