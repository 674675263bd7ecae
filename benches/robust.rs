//! Calibration on damaged recordings: spikes, bad poses, gaps and correlated DVL noise
//! (docs/accuracy.md, "Damaged recordings").
//!
//! `cargo bench --bench robust -- [SEEDS] [DURATION_S]` (defaults 40 seeds of 60 s of the
//! calm-then-rotate motion, 10 Hz poses of 2 mm / 0.11 deg, 10 Hz DVL of 1 cm/s). Each scenario
//! damages the same simulated recordings with `dvlcal::sim::corrupt` and calibrates them twice:
//! "before" is least squares with the covariance as the model states it (`--loss l2`, no
//! whiteness or halves check), "after" the defaults. For each parameter group it prints the RMSE
//! (with a 95 % percentile-bootstrap interval over the seeds), its ratio to the clean recordings'
//! RMSE under the defaults, and the RMS of the normalised errors `err / std` over the group's
//! components (1 when the standard deviations are honest).
//!
//! `DVLCAL_BENCH_THREADS` sets the worker threads (default: all CPUs).

mod common;

use common::par_map;
use dvlcal::calib::model::difference;
use dvlcal::calib::robust::Loss;
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::rng::Rng;
use dvlcal::sim::{Corruption, MotionKind, SimConfig, corrupt, simulate};

const DVL_SIGMA: f64 = 0.01;

/// Errors and normalised errors of one run, per component (`[dphi; dp; dkappa; ddelta]`).
#[derive(Clone, Copy)]
struct Run {
    err: [f64; 8],
    z: [f64; 8],
    downweighted: (usize, usize),
    flagged: bool,
}

const GROUPS: [(&str, std::ops::Range<usize>, f64, &str); 4] = [
    ("rotation", 0..3, 57.295_779_513_082_32, "deg"),
    ("lever arm", 3..6, 1e3, "mm"),
    ("scale", 6..7, 1e3, "1e-3"),
    ("clock offset", 7..8, 1e3, "ms"),
];

fn run(seed: u64, duration: f64, damage: &Corruption, after: bool) -> Option<Run> {
    let opts = if after {
        CalibOptions::default()
    } else {
        CalibOptions {
            loss: Loss::L2,
            honest_covariance: false,
            default_lever_arm_sigma_m: None,
            ..CalibOptions::default()
        }
    };
    run_with(seed, duration, damage, &opts)
}

fn run_with(seed: u64, duration: f64, damage: &Corruption, opts: &CalibOptions) -> Option<Run> {
    let cfg = SimConfig {
        seed: 1000 + seed,
        duration_s: duration,
        motion: MotionKind::CalmThenRotate,
        dvl_sigma: DVL_SIGMA,
        ..SimConfig::default()
    };
    let mut ds = simulate(&cfg).ok()?;
    corrupt(&mut ds, damage, DVL_SIGMA, 5000 + seed).ok()?;
    let o = match calibrate(&ds.poses, &ds.dvl, opts) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("seed {seed}: {e}");
            return None;
        }
    };
    let d = difference(&o.params, &ds.truth);
    let mut err = [0.0; 8];
    let mut z = [0.0; 8];
    for k in 0..8 {
        err[k] = d[k];
        z[k] = d[k] / o.covariance[(k, k)].max(1e-300).sqrt();
    }
    Some(Run {
        err,
        z,
        downweighted: (o.counts.dvl_downweighted, o.counts.poses_downweighted),
        flagged: o
            .halves
            .as_ref()
            .is_some_and(|h| h.inflation.iter().any(|&f| f > 1.0)),
    })
}

/// RMS over the runs of the group's error norm, and a 95 % percentile-bootstrap interval.
fn rmse(runs: &[Run], range: &std::ops::Range<usize>, seed: u64) -> (f64, f64, f64) {
    let sq: Vec<f64> = runs
        .iter()
        .map(|r| range.clone().map(|k| r.err[k] * r.err[k]).sum())
        .collect();
    let n = sq.len();
    let mean = |v: &dyn Fn(usize) -> f64| (0..n).map(v).sum::<f64>() / n as f64;
    let point = mean(&|i| sq[i]).sqrt();
    let mut rng = Rng::stream(seed, 99);
    let mut boot: Vec<f64> = (0..2000)
        .map(|_| {
            let picks: Vec<usize> = (0..n)
                .map(|_| ((rng.uniform_in(0.0, 1.0) * n as f64) as usize).min(n - 1))
                .collect();
            (picks.iter().map(|&i| sq[i]).sum::<f64>() / n as f64).sqrt()
        })
        .collect();
    boot.sort_by(f64::total_cmp);
    (point, boot[50], boot[1949])
}

fn rms_z(runs: &[Run], range: &std::ops::Range<usize>) -> f64 {
    let mut s = 0.0;
    let mut n = 0;
    for r in runs {
        for k in range.clone() {
            s += r.z[k] * r.z[k];
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let seeds: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(40);
    let duration: f64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(60.0);
    let outliers = Corruption {
        dvl_spike_fraction: 0.03,
        dvl_spike_mps: 0.3,
        pose_outlier_fraction: 0.01,
        pose_outlier_pos_m: 0.05,
        pose_outlier_rot_rad: 3f64.to_radians(),
        ..Corruption::default()
    };
    let ar1 = |tau: f64| Corruption {
        dvl_ar1_tau_s: Some(tau),
        ..Corruption::default()
    };
    let gaps = Corruption {
        dvl_gaps: vec![(0.2 * duration, 8.0), (0.7 * duration, 5.0)],
        pose_gaps: vec![(0.4 * duration, 3.0), (0.85 * duration, 2.0)],
        ..Corruption::default()
    };
    let scenarios: Vec<(String, Corruption)> = vec![
        ("clean".into(), Corruption::default()),
        (
            "3 % spikes 0.3 m/s + 1 % bad poses 5 cm / 3 deg".into(),
            outliers,
        ),
        ("AR(1) DVL noise, 0.5 s".into(), ar1(0.5)),
        ("AR(1) DVL noise, 1 s".into(), ar1(1.0)),
        ("AR(1) DVL noise, 2 s".into(), ar1(2.0)),
        ("AR(1) DVL noise, 5 s".into(), ar1(5.0)),
        ("gaps: DVL 8 s + 5 s, poses 3 s + 2 s".into(), gaps),
    ];
    println!(
        "{seeds} seeds of {duration} s, calm-then-rotate, DVL 1 cm/s at 10 Hz, poses 2 mm / 0.11 deg at 10 Hz\n"
    );
    let mut clean_rmse = [0.0; 4];
    let outlier_case = scenarios[1].1.clone();
    for (si, (name, damage)) in scenarios.iter().enumerate() {
        let start = std::time::Instant::now();
        let before: Vec<Run> = par_map(seeds, |s| run(s, duration, damage, false))
            .into_iter()
            .flatten()
            .collect();
        let after: Vec<Run> = par_map(seeds, |s| run(s, duration, damage, true))
            .into_iter()
            .flatten()
            .collect();
        println!("### {name}\n");
        println!(
            "runs: {} before, {} after; down-weighted per run (after): {:.1} DVL reports, {:.1} \
             poses; halves disagreeing: {} of {} runs ({:.0} s)\n",
            before.len(),
            after.len(),
            after.iter().map(|r| r.downweighted.0).sum::<usize>() as f64
                / after.len().max(1) as f64,
            after.iter().map(|r| r.downweighted.1).sum::<usize>() as f64
                / after.len().max(1) as f64,
            after.iter().filter(|r| r.flagged).count(),
            after.len(),
            start.elapsed().as_secs_f64()
        );
        println!(
            "| parameter | RMSE before [95 % CI] | RMSE after [95 % CI] | after / clean | RMS err/std before | RMS err/std after |"
        );
        println!("|---|---|---|---|---|---|");
        for (g, (label, range, f, unit)) in GROUPS.iter().enumerate() {
            let (b, bl, bh) = rmse(&before, range, si as u64);
            let (a, al, ah) = rmse(&after, range, si as u64 + 100);
            if si == 0 {
                clean_rmse[g] = a;
            }
            println!(
                "| {label} ({unit}) | {:.3} [{:.3}, {:.3}] | {:.3} [{:.3}, {:.3}] | {:.2} | {:.2} | {:.2} |",
                b * f,
                bl * f,
                bh * f,
                a * f,
                al * f,
                ah * f,
                a / clean_rmse[g].max(1e-300),
                rms_z(&before, range),
                rms_z(&after, range)
            );
        }
        println!();
    }
    // The two robust losses on the outlier scenario, with the rest of the defaults.
    println!("### Cauchy against Huber loss ({})\n", scenarios[1].0);
    println!(
        "| parameter | Cauchy RMSE [95 % CI] | Huber RMSE [95 % CI] | Huber / Cauchy | RMS err/std Cauchy | RMS err/std Huber |"
    );
    println!("|---|---|---|---|---|---|");
    let by_loss = |loss: Loss| -> Vec<Run> {
        let opts = CalibOptions {
            loss,
            ..CalibOptions::default()
        };
        par_map(seeds, |s| run_with(s, duration, &outlier_case, &opts))
            .into_iter()
            .flatten()
            .collect()
    };
    let (cauchy, huber) = (by_loss(Loss::Cauchy), by_loss(Loss::Huber));
    for (label, range, f, unit) in GROUPS.iter() {
        let (c, cl, ch) = rmse(&cauchy, range, 500);
        let (h, hl, hh) = rmse(&huber, range, 600);
        println!(
            "| {label} ({unit}) | {:.3} [{:.3}, {:.3}] | {:.3} [{:.3}, {:.3}] | {:.2} | {:.2} | {:.2} |",
            c * f,
            cl * f,
            ch * f,
            h * f,
            hl * f,
            hh * f,
            h / c.max(1e-300),
            rms_z(&cauchy, range),
            rms_z(&huber, range)
        );
    }
    println!();
}
