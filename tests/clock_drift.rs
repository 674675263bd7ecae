//! A drifting DVL clock, estimated (`CalibOptions::clock_drift`, `--clock-drift`): 200 ppm over
//! ten minutes comes out within three standard deviations, the other parameters as well as
//! without drift; a steady clock gives a drift consistent with zero and the same calibration;
//! a drift the motion cannot tell from an offset, or a clock that stepped, is refused or said.

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, CalibrationOutcome, calibrate};
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::types::CalibrationParams;

fn config(seed: u64, ppm: f64, duration: f64) -> SimConfig {
    let mut cfg = SimConfig {
        seed,
        duration_s: duration,
        motion: MotionKind::Sinusoid,
        clock_drift_ppm: ppm,
        ..SimConfig::default()
    };
    cfg.truth.time_offset_s = 0.07;
    cfg
}

fn with_drift() -> CalibOptions {
    CalibOptions {
        clock_drift: true,
        ..CalibOptions::default()
    }
}

/// The truth in the estimator's model: the simulator's drift runs from the DVL time of the
/// first pose (`-offset`), the estimator's from its reference, where the offset has grown by
/// the drift over the time between the two.
fn truth_at(ds: &SimDataset, ppm: f64, reference_t_s: f64) -> CalibrationParams {
    let mut t = ds.truth;
    let sim_reference = -ds.truth.time_offset_s;
    t.time_offset_s += 1e-6 * ppm * (reference_t_s - sim_reference);
    t
}

/// Each parameter's error over its standard deviation.
fn z_scores(o: &CalibrationOutcome, truth: &CalibrationParams) -> Vec<f64> {
    let e = difference(&o.params, truth);
    (0..NPARAM)
        .map(|k| e[k] / o.covariance[(k, k)].sqrt())
        .collect()
}

#[test]
fn a_drift_of_200_ppm_over_ten_minutes_is_estimated_within_three_std() {
    for seed in 1..=3u64 {
        let ds = simulate(&config(seed, 200.0, 600.0)).expect("simulation");
        let o = calibrate(&ds.poses, &ds.dvl, &with_drift()).expect("calibration");
        let d = o.clock_drift.as_ref().expect("the drift estimated");
        let truth = truth_at(&ds, 200.0, d.reference_t_s);
        let z = z_scores(&o, &truth);
        println!(
            "seed {seed}: drift {:.2} +- {:.2} ppm in {} calibrations (last step {:.3}); z {z:.2?}",
            d.ppm, d.std_ppm, d.rounds, d.last_step_ppm
        );
        assert!(o.status.is_ok(), "seed {seed}: {:?}", o.status);
        assert!(
            (d.ppm - 200.0).abs() < 3.0 * d.std_ppm,
            "seed {seed}: {} +- {} ppm",
            d.ppm,
            d.std_ppm
        );
        // A usable std: a few ppm on ten minutes, not a bound that says nothing.
        assert!(d.std_ppm > 0.0 && d.std_ppm < 20.0, "{}", d.std_ppm);
        assert!(d.rounds >= 2 && d.rounds <= 4, "{} rounds", d.rounds);
        for (k, zk) in z.iter().enumerate() {
            assert!(zk.abs() < 3.0, "seed {seed}: parameter {k}: {zk:.2} std");
        }
        // The reference is the middle of the reports.
        let (first, last) = (ds.dvl[0].t, ds.dvl[ds.dvl.len() - 1].t);
        assert!((d.reference_t_s - 0.5 * (first + last)).abs() < 1e-9);
        // The thirds agree once the drift is modelled: no warning of a drifting offset.
        assert!(
            !o.warnings
                .iter()
                .any(|w| w.contains("the clock offset drifts")),
            "{:?}",
            o.warnings
        );
    }
}

#[test]
fn without_the_drift_modelled_the_warning_suggests_estimating_it() {
    let ds = simulate(&config(4, 200.0, 600.0)).expect("simulation");
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    assert!(o.clock_drift.is_none());
    let w = o
        .warnings
        .iter()
        .find(|w| w.contains("the clock offset drifts"))
        .unwrap_or_else(|| panic!("no drift warning: {:?}", o.warnings));
    assert!(w.contains("estimate the drift with clock_drift"), "{w}");
}

#[test]
fn a_steady_clock_gives_a_drift_consistent_with_zero_and_the_same_calibration() {
    for seed in 5..=6u64 {
        let ds = simulate(&config(seed, 0.0, 600.0)).expect("simulation");
        let plain = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("plain");
        let o = calibrate(&ds.poses, &ds.dvl, &with_drift()).expect("with drift");
        let d = o.clock_drift.as_ref().expect("the drift estimated");
        println!("seed {seed}: drift {:.2} +- {:.2} ppm", d.ppm, d.std_ppm);
        assert!(d.ppm.abs() < 3.0 * d.std_ppm, "{} +- {}", d.ppm, d.std_ppm);
        // Every parameter moves by less than half its std, and only the clock offset's std
        // grows noticeably (the drift is least correlated with the offset at the reference).
        let e = difference(&o.params, &plain.params);
        for k in 0..NPARAM {
            let (s0, s1) = (plain.covariance[(k, k)].sqrt(), o.covariance[(k, k)].sqrt());
            assert!(
                e[k].abs() < 0.5 * s0,
                "parameter {k}: moved {} (std {s0})",
                e[k]
            );
            assert!(
                s1 >= s0 * 0.999 && s1 < 1.5 * s0,
                "parameter {k}: std {s0} -> {s1}"
            );
        }
        let truth = truth_at(&ds, 0.0, d.reference_t_s);
        for (k, zk) in z_scores(&o, &truth).iter().enumerate() {
            assert!(zk.abs() < 3.0, "seed {seed}: parameter {k}: {zk:.2} std");
        }
    }
}
