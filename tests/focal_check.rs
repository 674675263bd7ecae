//! The camchain's focal lengths checked against the recording: the rendered recording of
//! `sample_data/stereo` calibrated with its own camchain (no warning), with both cameras' focal
//! lengths 2 % long, and with cam1's alone 2 % long (a warning naming the camera each time).

mod tmp_common;
use tmp_common::{TmpDir, dvlcal, s, sample};

use std::path::{Path, PathBuf};

use dvlcal::io::calib_yaml::read_calib_yaml;

const STEREO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/stereo");

/// A dataset folder with `sample_data/stereo`'s parts and its camchain with the focal lengths of
/// the cameras `long` multiplied by `factor`.
fn dataset(tmp: &TmpDir, long: &[usize], factor: f64) -> PathBuf {
    let chain = move |text: &str| {
        let mut chain = text.to_owned();
        for (cam, (fu, fv)) in [(0, (458.0, 457.0)), (1, (457.5, 456.2))] {
            if long.contains(&cam) {
                let from = format!("intrinsics: [{fu:?}, {fv:?},");
                assert!(chain.contains(&from), "{from} not in the camchain");
                chain = chain.replace(
                    &from,
                    &format!("intrinsics: [{:?}, {:?},", fu * factor, fv * factor),
                );
            }
        }
        chain
    };
    sample(tmp, STEREO, "data", &[("camchain.yaml", &chain)])
}

/// Calibrates `dir`; returns what the program printed and the result's focal length factors
/// and their standard deviations.
fn calibrate(dir: &Path, out: &Path) -> (String, Vec<f64>, Vec<f64>) {
    let r = dvlcal(&[
        "calibrate",
        s(dir),
        "--out",
        s(out),
        "--threads",
        "2",
        "--no-progress",
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(r.status.success(), "{stdout}\n{stderr}");
    let f = read_calib_yaml(out).expect("result");
    let fig = f.info.expect("info").figures;
    let scales = fig.focal_length_scale.expect("focal_length_scale");
    let stds = fig.focal_length_scale_std.expect("focal_length_scale_std");
    (
        stdout + &stderr,
        scales.into_iter().map(|x| x.expect("measured")).collect(),
        stds.into_iter().map(|x| x.expect("measured")).collect(),
    )
}

#[test]
fn the_camchain_the_images_were_rendered_with_passes_the_check() {
    let tmp = TmpDir::new("focal-clean");
    let d = dataset(&tmp, &[], 1.0);
    let (text, scales, stds) = calibrate(&d, &tmp.path("out/calibration.yaml"));
    println!("{scales:?} +- {stds:?}");
    assert!(!text.contains("focal length measures"), "{text}");
    for (k, (f, sd)) in scales.iter().zip(&stds).enumerate() {
        // Within the floor for the corners' bias under distortion (see vision::focal).
        assert!((f - 1.0).abs() < 3.0 * sd, "cam{k}: {f} +- {sd}");
        assert!(*sd < 0.01, "cam{k}: the recording measures it to {sd}");
    }
}

#[test]
fn focal_lengths_two_percent_long_are_named_per_camera() {
    for long in [&[0usize, 1][..], &[1][..]] {
        let tmp = TmpDir::new("focal-long");
        let d = dataset(&tmp, long, 1.02);
        let (text, scales, stds) = calibrate(&d, &tmp.path("out/calibration.yaml"));
        println!("long {long:?}: {scales:?} +- {stds:?}");
        for cam in 0..2 {
            let named = text.contains(&format!("cam{cam}'s focal length measures"));
            assert_eq!(
                named,
                long.contains(&cam),
                "cam{cam} (long: {long:?}): {text}"
            );
            // The recording measures the camchain's focal length 2 % long as 98 % of it.
            let expect = if long.contains(&cam) { 1.0 / 1.02 } else { 1.0 };
            assert!(
                (scales[cam] - expect).abs() < 3.0 * stds[cam],
                "cam{cam}: {} +- {}, expected {expect}",
                scales[cam],
                stds[cam]
            );
        }
        assert!(text.contains("recalibrate the camera"), "{text}");
    }
}
