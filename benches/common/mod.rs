//! What the Monte Carlo benchmarks share: the worker count and a seed-parallel map.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Worker threads: `DVLCAL_BENCH_THREADS`, or all CPUs.
pub fn threads() -> usize {
    std::env::var("DVLCAL_BENCH_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1)
}

/// Runs `f(seed)` for seeds `0..n` on a few threads; results in seed order.
pub fn par_map<T: Send>(n: usize, f: impl Fn(u64) -> T + Sync) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<T>>> = Mutex::new((0..n).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..threads().min(n) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n {
                        break;
                    }
                    let r = f(i as u64);
                    if let Ok(mut o) = out.lock() {
                        o[i] = Some(r);
                    }
                }
            });
        }
    });
    let results: Vec<Option<T>> = out.into_inner().unwrap_or_default();
    assert!(results.iter().all(Option::is_some), "every seed ran");
    results.into_iter().flatten().collect()
}

/// The RMS over runs of `sq` (one mean square per run) with a 95 % percentile-bootstrap interval
/// over the runs (2000 resamples, seeded by `seed`): `[rms, low, high]`.
#[allow(dead_code)]
pub fn rms_bootstrap(sq: &[f64], seed: u64) -> [f64; 3] {
    let n = sq.len();
    if n == 0 {
        return [f64::NAN; 3];
    }
    let point = (sq.iter().sum::<f64>() / n as f64).sqrt();
    let mut rng = dvlcal::rng::Rng::stream(seed, 77);
    let mut boot: Vec<f64> = (0..2000)
        .map(|_| {
            let s: f64 = (0..n)
                .map(|_| sq[((rng.uniform_in(0.0, 1.0) * n as f64) as usize).min(n - 1)])
                .sum();
            (s / n as f64).sqrt()
        })
        .collect();
    boot.sort_by(f64::total_cmp);
    [point, boot[50], boot[1949]]
}
