//! Noise levels estimated, not trusted (docs/accuracy.md, "Misstated noise").
//!
//! `cargo bench --bench noise -- [SEEDS] [DURATION_S]` (defaults 20 seeds of 60 s of the
//! calm-then-rotate motion, DVL noise 1 cm/s). Each recording is calibrated with the DVL's noise
//! stated at 0.1, 1 and 10 times the true one (`--dvl-sigma`). For each statement it prints the
//! DVL's variance component (the data's variance over the stated, 100, 1 and 0.01 when found
//! right), how often the stated noise was replaced, and per parameter group the RMS of the
//! normalised errors `err / std` with a 95 % percentile-bootstrap interval over the seeds (1 when
//! the standard deviations are honest).
//!
//! `DVLCAL_BENCH_THREADS` sets the worker threads (default: all CPUs).

mod common;

use common::par_map;
use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::{MotionKind, SimConfig, simulate};

const TRUE_SIGMA: f64 = 0.01;

const GROUPS: [(&str, std::ops::Range<usize>); 4] = [
    ("rotation", 0..3),
    ("lever arm", 3..6),
    ("scale", 6..7),
    ("clock offset", 7..8),
];

struct Run {
    z: [f64; NPARAM],
    component: f64,
    applied: bool,
    ok: bool,
}

fn run(seed: u64, duration: f64, factor: f64) -> Option<Run> {
    let d = simulate(&SimConfig {
        seed: 3000 + seed,
        duration_s: duration,
        motion: MotionKind::CalmThenRotate,
        dvl_sigma: TRUE_SIGMA,
        ..SimConfig::default()
    })
    .ok()?;
    let o = calibrate(
        &d.poses,
        &d.dvl,
        &CalibOptions {
            dvl_sigma: Some(factor * TRUE_SIGMA),
            ..CalibOptions::default()
        },
    )
    .ok()?;
    let e = difference(&o.params, &d.truth);
    let mut z = [0.0; NPARAM];
    for k in 0..NPARAM {
        z[k] = e[k] / o.covariance[(k, k)].sqrt();
    }
    Some(Run {
        z,
        component: o.noise.dvl.total(),
        applied: o.noise.dvl.applied != 1.0,
        ok: o.status.is_ok(),
    })
}

/// RMS of `err / std` over the runs and the group's components, with a 95 % percentile-bootstrap
/// interval over the runs.
fn rms_z(runs: &[Run], range: &std::ops::Range<usize>) -> [f64; 3] {
    let sq: Vec<f64> = runs
        .iter()
        .map(|r| range.clone().map(|k| r.z[k] * r.z[k]).sum::<f64>() / range.len() as f64)
        .collect();
    common::rms_bootstrap(&sq, 11)
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let seeds: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(20);
    let duration: f64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(60.0);
    println!(
        "Threads: {}; {seeds} seeds of {duration} s, calm-then-rotate, true DVL noise {} m/s.\n",
        common::threads(),
        TRUE_SIGMA
    );
    println!(
        "| stated DVL noise | runs ok | variance component (median, range) | rescaled | \
         rotation | lever arm | scale | clock offset |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for factor in [0.1, 1.0, 10.0] {
        let all = par_map(seeds, |s| run(s, duration, factor));
        let runs: Vec<Run> = all.into_iter().flatten().collect();
        let ok: Vec<&Run> = runs.iter().filter(|r| r.ok).collect();
        let mut c: Vec<f64> = runs.iter().map(|r| r.component).collect();
        c.sort_by(f64::total_cmp);
        let cells: Vec<String> = GROUPS
            .iter()
            .map(|(_, range)| {
                let [p, lo, hi] = rms_z(&runs, range);
                format!("{p:.2} [{lo:.2}, {hi:.2}]")
            })
            .collect();
        println!(
            "| {factor} x true | {}/{seeds} | {:.3} ({:.3} to {:.3}) | {}/{} | {} |",
            ok.len(),
            c.get(c.len() / 2).copied().unwrap_or(f64::NAN),
            c.first().copied().unwrap_or(f64::NAN),
            c.last().copied().unwrap_or(f64::NAN),
            runs.iter().filter(|r| r.applied).count(),
            runs.len(),
            cells.join(" | ")
        );
    }
}
