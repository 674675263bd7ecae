//! Accuracy with clocks far apart and drifting, over seeds (docs/accuracy.md, "Clocks").
//!
//! `cargo bench --bench clock [-- SEEDS]` (default 20). For each DVL clock offset (2.5 s to
//! 1.7e9 s) the same 120 s calm-then-rotate recordings are calibrated with default options: the
//! share found by the global alignment (lag within 0.5 s), the share that passed the sanity
//! checks, the mean NEES of the 8 parameters (expectation 8) and the largest |error| / std. Then
//! the drift check: 600 s sinusoid recordings with 200 ppm drift (the apparent drift and how
//! often it is flagged) and without (false alarms).

use std::time::Instant;

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};

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
}
