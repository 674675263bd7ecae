//! Whether the DVL residuals are white, and by how much their correlation in time reduces the
//! information they carry.
//!
//! The covariance of the calibration assumes independent DVL errors. Real ones are correlated
//! (the same bottom patch, the same beams, a filter inside the DVL): `n` correlated residuals
//! carry the information of about `n / tau` independent ones, with `tau` the integrated
//! autocorrelation time in samples, `tau = 1 + 2 sum_k rho(k)`. The sum is truncated at the
//! smallest window `M >= 5 tau(M)` (Sokal's automatic window), which keeps its variance down
//! without cutting off a slow decay. Under white noise the estimate scatters around 1 with
//! standard deviation about `sqrt(2 (2M + 1) / n)`; only an excess beyond three of those counts
//! as correlation.

use nalgebra::Vector3;

/// Lags beyond this many samples are not examined (about 3 minutes at 10 Hz).
const MAX_LAG: usize = 2000;
/// Lags always computed (for the report's plot) when the data allow.
const PLOT_LAGS: usize = 50;
/// Sokal's window constant.
const WINDOW_C: f64 = 5.0;

/// The autocorrelation of the residuals and what it implies.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Whiteness {
    /// Lags examined, seconds (the median sample interval times the lag in samples).
    pub lag_s: Vec<f64>,
    /// Autocorrelation per axis at each lag (lag 0 is 1).
    pub acf: [Vec<f64>; 3],
    /// Integrated autocorrelation time per axis, samples.
    pub tau: [f64; 3],
    /// The window the sums were truncated at, samples.
    pub window: usize,
    /// The standard deviation of a `tau` estimate under white noise.
    pub tau_noise: f64,
    /// Whether some axis is correlated beyond what white noise would show.
    pub correlated: bool,
    /// The factor the DVL information is divided by (the mean `tau` of the three axes, when
    /// correlated; otherwise 1).
    pub inflation: f64,
    /// Median interval between the residuals, seconds.
    pub sample_interval_s: f64,
}

/// Autocorrelation of the whitened residuals `r` (each axis divided by its stated standard
/// deviation) at times `t`, in time order. Pairs `k` samples apart that straddle a gap (more
/// than `1.5 k` median intervals apart) are left out of lag `k`.
pub fn whiteness(t: &[f64], r: &[Vector3<f64>]) -> Whiteness {
    let n = t.len().min(r.len());
    if n < 50 {
        return Whiteness {
            inflation: 1.0,
            tau: [1.0; 3],
            ..Whiteness::default()
        };
    }
    let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    dt.sort_by(f64::total_cmp);
    let step = dt[dt.len() / 2].max(1e-9);
    let max_lag = MAX_LAG.min(n / 10);
    let mut out = Whiteness {
        sample_interval_s: step,
        ..Whiteness::default()
    };
    let mut window = 0;
    for axis in 0..3 {
        let mean = r.iter().take(n).map(|x| x[axis]).sum::<f64>() / n as f64;
        let x: Vec<f64> = r.iter().take(n).map(|v| v[axis] - mean).collect();
        let var = x.iter().map(|v| v * v).sum::<f64>() / n as f64;
        let mut acf = Vec::with_capacity(max_lag + 1);
        acf.push(1.0);
        // Lags are computed until Sokal's window closes, and a margin beyond for the plot: the
        // cost is O(n M), not O(n max_lag).
        let mut tau_run = 1.0;
        let mut stop = max_lag;
        for k in 1..=max_lag {
            if k > stop {
                break;
            }
            let limit = 1.5 * k as f64 * step;
            let (mut sum, mut count) = (0.0, 0usize);
            for i in 0..n - k {
                if t[i + k] - t[i] <= limit {
                    sum += x[i] * x[i + k];
                    count += 1;
                }
            }
            let rho = if count > 0 && var > 0.0 {
                sum / count as f64 / var
            } else {
                0.0
            };
            acf.push(rho);
            tau_run += 2.0 * rho;
            if stop == max_lag && k as f64 >= WINDOW_C * tau_run {
                stop = (3 * k).max(PLOT_LAGS).min(max_lag);
            }
        }
        // Sokal's window.
        let mut tau = 1.0;
        let mut m = max_lag;
        for (k, rho) in acf.iter().enumerate().skip(1) {
            tau += 2.0 * rho;
            if k as f64 >= WINDOW_C * tau {
                m = k;
                break;
            }
        }
        out.tau[axis] = tau.max(1.0 / n as f64);
        window = window.max(m);
        out.acf[axis] = acf;
    }
    out.window = window;
    let lags = out.acf.iter().map(Vec::len).min().unwrap_or(0);
    for a in out.acf.iter_mut() {
        a.truncate(lags);
    }
    out.lag_s = (0..lags).map(|k| k as f64 * step).collect();
    out.tau_noise = (2.0 * (2.0 * window as f64 + 1.0) / n as f64).sqrt();
    // The mean over the axes: each axis's estimate is noisy (its standard deviation grows with
    // tau), and the information lost is an average over the directions the motion excites.
    let mean = out.tau.iter().sum::<f64>() / 3.0;
    out.correlated = mean > 1.0 + 3.0 * out.tau_noise / 3f64.sqrt();
    out.inflation = if out.correlated { mean.max(1.0) } else { 1.0 };
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn ar1(n: usize, a: f64, seed: u64) -> (Vec<f64>, Vec<Vector3<f64>>) {
        let mut rng = Rng::stream(seed, 1);
        let mut x = rng.normal_vec3();
        let t = (0..n).map(|i| i as f64 * 0.1).collect();
        let r = (0..n)
            .map(|_| {
                x = x * a + rng.normal_vec3() * (1.0 - a * a).sqrt();
                x
            })
            .collect();
        (t, r)
    }

    #[test]
    fn white_noise_is_white() {
        let (t, r) = ar1(5000, 0.0, 3);
        let w = whiteness(&t, &r);
        assert!(!w.correlated, "{w:?}");
        assert_eq!(w.inflation, 1.0);
        for tau in w.tau {
            assert!((tau - 1.0).abs() < 4.0 * w.tau_noise, "{tau}");
        }
    }

    #[test]
    fn ar1_noise_gives_its_correlation_time() {
        // AR(1) with a = exp(-0.1) (1 s at 10 Hz): tau = (1 + a) / (1 - a) = 20.0 samples.
        let a = (-0.1f64).exp();
        let (t, r) = ar1(20000, a, 5);
        let w = whiteness(&t, &r);
        assert!(w.correlated);
        for tau in w.tau {
            assert!((tau - 20.0).abs() < 4.0, "{tau}");
        }
        assert!((w.acf[0][10] - a.powi(10)).abs() < 0.06);
    }
}
