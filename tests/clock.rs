//! Clocks far apart: the global alignment finds any clock offset without help, and recordings
//! whose logs do not overlap, or overlap ambiguously, say so.

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};

fn recording(seed: u64, offset: f64, duration: f64, motion: MotionKind) -> SimDataset {
    let mut cfg = SimConfig {
        seed,
        duration_s: duration,
        motion,
        ..SimConfig::default()
    };
    cfg.truth.time_offset_s = offset;
    simulate(&cfg).expect("simulation")
}

/// Largest |error| / std over the eight parameters.
fn worst_z(ds: &SimDataset) -> (f64, dvlcal::CalibrationOutcome) {
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    let e = difference(&o.params, &ds.truth);
    let mut worst = 0.0f64;
    for k in 0..NPARAM {
        let sd = o.covariance[(k, k)].sqrt();
        worst = worst.max((e[k] / sd).abs());
    }
    (worst, o)
}

#[test]
fn any_clock_offset_is_found_without_help() {
    for &offset in &[2.5, 37.0, -600.0, 1e8, -1.7e9] {
        for seed in 1..=3u64 {
            let ds = recording(seed, offset, 120.0, MotionKind::CalmThenRotate);
            let (z, o) = worst_z(&ds);
            let a = &o
                .init
                .as_ref()
                .expect("UIC initialisation")
                .offset
                .alignment;
            println!(
                "offset {offset}: seed {seed}: lag {:.3} (corr {:.3}, second {:?}), estimate {:.5}, worst z {z:.2}",
                a.lag_s, a.correlation, a.second_correlation, o.params.time_offset_s
            );
            assert!(
                (a.lag_s - offset).abs() < 0.5,
                "lag {} for {offset}",
                a.lag_s
            );
            assert!(
                z < 4.0,
                "offset {offset} seed {seed}: an error of {z:.2} std"
            );
        }
    }
}
