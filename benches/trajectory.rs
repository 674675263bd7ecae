//! Time of the trajectory fit and of queries for 1k, 10k and 100k poses.
//!
//! `cargo bench --bench trajectory`. Poses: the lively sinusoid at 10 Hz with 2 mm / 2 mrad
//! noise (no covariance on the poses). For each size: (a) the fit with Qc and noise given, (b) the
//! fit with both estimated by marginal likelihood, (c) N queries at random times with the twist
//! covariance. Small sizes are repeated and the median is reported. Prints a markdown table.

use std::time::Instant;

use dvlcal::rng::Rng;
use dvlcal::sim::motion::SinusoidMotion;
use dvlcal::sim::{SimConfig, simulate_with};
use dvlcal::trajectory::{FitOptions, Trajectory};
use nalgebra::Vector6;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let sizes: [(usize, usize); 3] = [(1_000, 7), (10_000, 3), (100_000, 1)];
    let mut results = Vec::new();
    for (n, reps) in sizes {
        let duration = (n - 1) as f64 / 10.0;
        let motion = SinusoidMotion::lively(duration).expect("motion");
        let cfg = SimConfig {
            duration_s: duration,
            ..SimConfig::default()
        };
        let mut poses = simulate_with(&cfg, &motion).expect("simulate").poses;
        poses.iter_mut().for_each(|p| p.cov = None);
        assert_eq!(poses.len(), n);
        let given = FitOptions {
            qc: Some(Vector6::new(14.0, 14.0, 14.0, 280.0, 280.0, 280.0)),
            pose_sigma: Some((0.002, 0.002)),
            ..FitOptions::default()
        };
        let (mut ta, mut tb, mut tc) = (Vec::new(), Vec::new(), Vec::new());
        for rep in 0..reps {
            let t0 = Instant::now();
            let traj = Trajectory::fit(&poses, &given).expect("fit");
            ta.push(t0.elapsed().as_secs_f64());
            let t0 = Instant::now();
            let est = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
            tb.push(t0.elapsed().as_secs_f64());
            std::hint::black_box(est.report().qc);
            let (a, b) = traj.span();
            let mut rng = Rng::new(rep as u64);
            let times: Vec<f64> = (0..n).map(|_| rng.uniform_in(a, b)).collect();
            let t0 = Instant::now();
            let mut acc = 0.0;
            for &t in &times {
                let s = traj.query(t).expect("query");
                acc += s.twist[0] + s.twist_cov.expect("covariance")[(0, 0)];
            }
            tc.push(t0.elapsed().as_secs_f64());
            std::hint::black_box(acc);
        }
        let r = (n, reps, median(ta), median(tb), median(tc));
        eprintln!("N = {n}: {:.3} s, {:.3} s, {:.3} s", r.2, r.3, r.4);
        results.push(r);
    }
    println!(
        "| poses | runs | (a) fit, Qc given | us/pose | (b) fit, Qc estimated | us/pose | (c) N queries with cov | us/query | ratio (a) / (b) / (c) to previous size |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut prev: Option<(f64, f64, f64)> = None;
    for &(n, reps, a, b, c) in &results {
        let per = |x: f64| x / n as f64 * 1e6;
        let ratio = match prev {
            Some((pa, pb, pc)) => format!("{:.1} / {:.1} / {:.1}", a / pa, b / pb, c / pc),
            None => "-".into(),
        };
        println!(
            "| {n} | {reps} | {a:.3} s | {:.1} | {b:.3} s | {:.1} | {c:.3} s | {:.1} | {ratio} |",
            per(a),
            per(b),
            per(c)
        );
        prev = Some((a, b, c));
    }
}
