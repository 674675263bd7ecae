//! Input that must not be taken on trust: DVL covariances that cannot weigh a sample, velocities
//! out of any physical range, byte-order marks, and a closed standard output.

use dvlcal::calib::{CalibOptions, calibrate, usable_covariance};
use dvlcal::io::dvl::{DvlReadOptions, read_dvl_log};
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
