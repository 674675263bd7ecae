//! Times a trajectory fit and queries on simulated poses, and optionally saves or compares the
//! queried twists and twist standard deviations.
//!
//! ```text
//! cargo run --release --example fit_timing -- <knots> [--save FILE | --compare FILE] [--repeat R]
//! ```
//!
//! The poses sample a lively sinusoidal motion (rotation rates up to ~2 rad/s, speeds ~0.5 m/s)
//! at 10 Hz with 2 mm / 2 mrad noise; the fit uses a fixed `Qc` (close to what the marginal
//! likelihood picks for these data), at most three Gauss-Newton iterations and computes the
//! covariance.

use std::time::Instant;

use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};
use dvlcal::trajectory::{FitOptions, Trajectory};
use nalgebra::Vector6;

/// CPU time (user + system, all threads) of this process in seconds, from `/proc/self/stat`
/// (`None` where that is not available). Less sensitive than wall time to other load.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// Queries per run (spread uniformly over the span).
const QUERIES: usize = 20_000;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: usize = args
        .first()
        .ok_or_else(|| anyhow::anyhow!("usage: fit_timing <knots> [--save F | --compare F]"))?
        .parse()?;
    let mut save = None;
    let mut compare = None;
    let mut repeat = if n <= 10_000 { 3 } else { 1 };
    let mut i = 1;
    while i < args.len() {
        match args[i].as_str() {
            "--save" => save = args.get(i + 1).cloned(),
            "--compare" => compare = args.get(i + 1).cloned(),
            "--repeat" => repeat = args.get(i + 1).map(|s| s.parse()).transpose()?.unwrap_or(1),
            other => anyhow::bail!("unknown argument {other}"),
        }
        i += 2;
    }

    let cfg = SimConfig {
        duration_s: (n - 1) as f64 / 10.0,
        camera_rate_hz: 10.0,
        motion: MotionKind::Sinusoid,
        ..Default::default()
    };
    let data = simulate(&cfg)?;
    let poses = data.poses;
    assert_eq!(poses.len(), n);
    let opts = FitOptions {
        qc: Some(Vector6::new(15.0, 15.0, 15.0, 300.0, 300.0, 300.0)),
        max_iterations: 3,
        covariance: true,
        ..Default::default()
    };

    let mut best = f64::INFINITY;
    let mut traj = None;
    let cpu0 = cpu_seconds();
    for _ in 0..repeat.max(1) {
        let t0 = Instant::now();
        let tr = Trajectory::fit(&poses, &opts)?;
        best = best.min(t0.elapsed().as_secs_f64());
        traj = Some(tr);
    }
    let traj = traj.expect("at least one fit");
    if let (Some(a), Some(b)) = (cpu0, cpu_seconds()) {
        println!(
            "fit cpu time {:.1} us/knot (mean over {repeat}, all threads)",
            (b - a) / (repeat.max(1) * n) as f64 * 1e6
        );
    }
    let rep = traj.report();
    println!(
        "knots {n}: fit {:.1} us/knot ({:.3} s, best of {repeat}), {} iterations, cost {:.6e}",
        best / n as f64 * 1e6,
        best,
        rep.iterations,
        rep.cost
    );

    let (a, b) = traj.span();
    let times: Vec<f64> = (0..QUERIES)
        .map(|i| a + (b - a) * (i as f64 + 0.5) / QUERIES as f64)
        .collect();
    let mut out = Vec::with_capacity(QUERIES * 12);
    let mut best_q = f64::INFINITY;
    for pass in 0..3 {
        let t0 = Instant::now();
        for &t in &times {
            let s = traj.query(t)?;
            if pass == 0 {
                let cov = s.twist_cov.expect("covariance requested");
                out.extend(s.twist.iter().copied());
                out.extend((0..6).map(|j| cov[(j, j)].sqrt()));
            } else {
                std::hint::black_box(&s);
            }
        }
        best_q = best_q.min(t0.elapsed().as_secs_f64());
    }
    println!("query {:.2} us", best_q / QUERIES as f64 * 1e6);

    if let Some(path) = save {
        let text: Vec<String> = out.iter().map(|v| format!("{v:.17e}")).collect();
        std::fs::write(&path, text.join("\n"))?;
        println!("saved {} values to {path}", out.len());
    }
    if let Some(path) = compare {
        let reference: Vec<f64> = std::fs::read_to_string(&path)?
            .lines()
            .map(|l| l.parse())
            .collect::<Result<_, _>>()?;
        anyhow::ensure!(reference.len() == out.len(), "length differs from {path}");
        // Columns 0..6: twist, 6..12: twist standard deviation. Differences are reported
        // relative to the largest magnitude of each column and element by element.
        for (name, cols) in [("twist", 0..6), ("twist std", 6..12)] {
            let (mut max_abs, mut max_rel_col, mut max_rel_elem) = (0.0f64, 0.0f64, 0.0f64);
            for c in cols {
                let col_ref = reference.iter().skip(c).step_by(12);
                let scale = col_ref.clone().fold(0.0f64, |m, v| m.max(v.abs()));
                for (r, o) in col_ref.zip(out.iter().skip(c).step_by(12)) {
                    let d = (r - o).abs();
                    max_abs = max_abs.max(d);
                    max_rel_col = max_rel_col.max(d / scale.max(f64::MIN_POSITIVE));
                    max_rel_elem = max_rel_elem.max(d / r.abs().max(1e-300));
                }
            }
            println!(
                "{name}: max abs diff {max_abs:.3e}, relative to column max {max_rel_col:.3e}, \
                 element-wise relative {max_rel_elem:.3e}"
            );
        }
    }
    Ok(())
}
