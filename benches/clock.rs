//! Accuracy with clocks far apart and drifting, over seeds (docs/accuracy.md, "Clocks").
//!
//! `cargo bench --bench clock [-- SEEDS]` (default 20). For each DVL clock offset (2.5 s to
//! 1.7e9 s) the same 120 s calm-then-rotate recordings are calibrated with default options: the
//! share found by the global alignment (lag within 0.5 s), the share that passed the sanity
//! checks, the mean NEES of the 8 parameters (expectation 8) and the largest |error| / std. Then
//! the drift check: 600 s sinusoid recordings with 200 ppm drift (the apparent drift and how
//! often it is flagged) and without (false alarms). Last, the drift estimated
//! (`clock_drift`): the same recordings at 200, 50 and 0 ppm over SEEDS seeds, the drift's error
//! over its std, and the other parameters' NEES against the truth at the drift's reference
//! (beside the NEES of the same recordings without drift calibrated without the drift).

use std::time::Instant;

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, CalibrationOutcome, calibrate};
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::types::CalibrationParams;

fn main() {
    let seeds: u64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(20);
    println!(
        "| DVL clock offset (s) | seeds | aligned | status ok | mean NEES | largest abs(error)/std | mean time (s) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for &offset in &[0.07, 2.5, 37.0, -600.0, 1e8, 1.7e9] {
        let (mut aligned, mut ok, mut nees, mut worst, mut secs) = (0, 0, 0.0, 0.0f64, 0.0);
        for seed in 1..=seeds {
            let mut cfg = SimConfig {
                seed,
                duration_s: 120.0,
                motion: MotionKind::CalmThenRotate,
                ..SimConfig::default()
            };
            cfg.truth.time_offset_s = offset;
            let ds = simulate(&cfg).expect("simulation");
            let t0 = Instant::now();
            let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
            secs += t0.elapsed().as_secs_f64();
            let lag = o.init.as_ref().map(|i| i.offset.alignment.lag_s);
            aligned += usize::from(lag.is_some_and(|l| (l - offset).abs() < 0.5));
            ok += usize::from(o.status.is_ok());
            let e = difference(&o.params, &ds.truth);
            let info = o.covariance.try_inverse().expect("covariance");
            nees += (e.transpose() * info * e)[0];
            for k in 0..NPARAM {
                worst = worst.max((e[k] / o.covariance[(k, k)].sqrt()).abs());
            }
        }
        let n = seeds as f64;
        println!(
            "| {offset} | {seeds} | {aligned} | {ok} | {:.2} | {worst:.2} | {:.2} |",
            nees / n,
            secs / n
        );
    }

    println!();
    println!(
        "| clock drift (ppm) | seeds | flagged | mean apparent drift (ppm) | its spread (ppm) |"
    );
    println!("|---|---|---|---|---|");
    let drift_seeds = (seeds / 2).max(3);
    for &ppm in &[200.0, 0.0] {
        let mut flagged = 0;
        let mut found = Vec::new();
        for seed in 1..=drift_seeds {
            let cfg = SimConfig {
                seed,
                duration_s: 600.0,
                motion: MotionKind::Sinusoid,
                clock_drift_ppm: ppm,
                ..SimConfig::default()
            };
            let ds = simulate(&cfg).expect("simulation");
            let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
            let d = o.drift.expect("drift check");
            flagged += usize::from(d.significant);
            found.push(d.drift_ppm);
        }
        let m = found.iter().sum::<f64>() / found.len() as f64;
        let sd =
            (found.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (found.len() - 1) as f64).sqrt();
        println!("| {ppm} | {drift_seeds} | {flagged} | {m:.1} | {sd:.1} |");
    }

    drift_estimated(seeds);
}

/// The truth in the drift model's terms: the simulator's drift runs from the DVL time of the
/// first pose, the estimator's from its reference.
fn truth_at(ds: &SimDataset, ppm: f64, reference_t_s: f64) -> CalibrationParams {
    let mut t = ds.truth;
    t.time_offset_s += 1e-6 * ppm * (reference_t_s + ds.truth.time_offset_s);
    t
}

/// NEES of the eight parameters and their largest |error| / std.
fn nees_and_worst(o: &CalibrationOutcome, truth: &CalibrationParams) -> (f64, f64) {
    let e = difference(&o.params, truth);
    let info = o.covariance.try_inverse().expect("covariance");
    let worst = (0..NPARAM)
        .map(|k| (e[k] / o.covariance[(k, k)].sqrt()).abs())
        .fold(0.0, f64::max);
    ((e.transpose() * info * e)[0], worst)
}

fn drift_estimated(seeds: u64) {
    println!();
    println!(
        "| clock drift (ppm) | drift estimated | seeds | status ok | mean estimate (ppm) | mean std (ppm) | mean error/std | RMS error/std | mean NEES of the 8 | largest abs(error)/std of the 8 | calibrations | mean time (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    let with = CalibOptions {
        clock_drift: true,
        ..CalibOptions::default()
    };
    for (ppm, estimated) in [(200.0, true), (50.0, true), (0.0, true), (0.0, false)] {
        let opts = if estimated {
            with.clone()
        } else {
            CalibOptions::default()
        };
        let (mut ok, mut nees, mut worst, mut rounds, mut secs) = (0, 0.0, 0.0f64, 0, 0.0);
        let (mut est, mut std, mut z) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 1..=seeds {
            let cfg = SimConfig {
                seed,
                duration_s: 600.0,
                motion: MotionKind::Sinusoid,
                clock_drift_ppm: ppm,
                ..SimConfig::default()
            };
            let ds = simulate(&cfg).expect("simulation");
            let t0 = Instant::now();
            let o = calibrate(&ds.poses, &ds.dvl, &opts).expect("calibration");
            secs += t0.elapsed().as_secs_f64();
            ok += usize::from(o.status.is_ok());
            let reference = o.clock_drift.as_ref().map_or(0.0, |d| d.reference_t_s);
            if let Some(d) = &o.clock_drift {
                est.push(d.ppm);
                std.push(d.std_ppm);
                z.push((d.ppm - ppm) / d.std_ppm);
                rounds += d.rounds;
            }
            let (n, w) = nees_and_worst(&o, &truth_at(&ds, ppm, reference));
            nees += n;
            worst = worst.max(w);
        }
        let n = seeds as f64;
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let rms = (z.iter().map(|x| x * x).sum::<f64>() / z.len().max(1) as f64).sqrt();
        let cell = |x: f64, digits: usize| {
            if estimated {
                format!("{x:.digits$}")
            } else {
                "-".to_owned()
            }
        };
        println!(
            "| {ppm} | {} | {seeds} | {ok} | {} | {} | {} | {} | {:.2} | {worst:.2} | {} | {:.2} |",
            if estimated { "yes" } else { "no" },
            cell(mean(&est), 2),
            cell(mean(&std), 2),
            cell(mean(&z), 2),
            cell(rms, 2),
            nees / n,
            cell(rounds as f64 / n, 1),
            secs / n
        );
    }
}
