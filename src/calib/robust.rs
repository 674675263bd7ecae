//! Robust losses for the DVL and pose factors, and the statistics they rest on.
//!
//! Every factor's residual `r` with stated covariance `C` gives a squared whitened residual
//! `s = r^T C^-1 r`, chi-squared with `dof` degrees of freedom when the stated noise is right.
//! A robust loss replaces `s` by `rho(s)`; iteratively reweighted least squares minimises it by
//! weighting each factor's information with `w = rho'(s)` at the current estimate, which the
//! Gauss-Newton machinery already handles: a weighted factor is one with covariance `C / w`.
//!
//! Thresholds are set from the stated noise, scaled up when the residuals show that it was
//! stated too small ([`noise_scale`], from the median, which outliers do not move):
//! - Huber: `w = 1` for `s <= k^2`, `k / sqrt(s)` beyond, with `k^2` the 99 % quantile of
//!   chi-squared(dof): clean data are almost untouched, a gross error keeps a bounded pull.
//! - Cauchy: `w = 1 / (1 + s / c^2)`, `c^2 = dof * 2.3849^2` (95 % efficiency per component on
//!   Gaussian noise): a gross error's pull falls towards zero.
//!
//! A factor counts as an outlier when clean data would produce a residual as large with
//! probability below 1 % over the whole recording ([`outlier_threshold`]); the loss is applied
//! only when there is at least one, so a clean recording is calibrated exactly as under least
//! squares.

use super::setting::Setting;
use crate::error::{Error, Result};

/// The loss applied to the DVL and pose residuals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Loss {
    /// Least squares: every factor at full weight.
    L2,
    /// Huber: quadratic near zero, linear beyond the 99 % quantile of the clean residuals.
    Huber,
    /// Cauchy: logarithmic; gross errors lose their pull.
    #[default]
    Cauchy,
}

impl Loss {
    /// The loss of a name (`l2`, `huber`, `cauchy`); the error names the setting `loss`.
    pub fn parse(name: &str) -> Result<Loss> {
        match name.trim().to_ascii_lowercase().as_str() {
            "l2" | "least-squares" => Ok(Loss::L2),
            "huber" => Ok(Loss::Huber),
            "cauchy" => Ok(Loss::Cauchy),
            other => Err(Error::option(
                Setting::Loss.field(),
                format!("unknown loss '{other}' (expected l2, huber or cauchy)"),
            )),
        }
    }

    /// Its name, as [`Loss::parse`] takes it.
    pub fn name(&self) -> &'static str {
        match self {
            Loss::L2 => "l2",
            Loss::Huber => "huber",
            Loss::Cauchy => "cauchy",
        }
    }

    /// IRLS weight of a factor with squared whitened residual `s` (already divided by the noise
    /// scale) and `dof` components.
    pub fn weight(&self, s: f64, dof: usize) -> f64 {
        if !s.is_finite() {
            return 0.0;
        }
        match self {
            Loss::L2 => 1.0,
            Loss::Huber => {
                let k2 = chi2_quantile(0.99, dof);
                if s <= k2 { 1.0 } else { (k2 / s).sqrt() }
            }
            Loss::Cauchy => {
                let c2 = dof as f64 * CAUCHY_C * CAUCHY_C;
                1.0 / (1.0 + s / c2)
            }
        }
    }
}

/// Cauchy's scale per component for 95 % efficiency on Gaussian noise.
const CAUCHY_C: f64 = 2.3849;

/// `erfc(x)` for `x >= 0` (Chebyshev fit, relative error below 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// Survival function `P(X > x)` of chi-squared with `dof` degrees of freedom (closed forms of the
/// regularised upper incomplete gamma function at integer and half-integer order).
pub fn chi2_sf(x: f64, dof: usize) -> f64 {
    if x <= 0.0 || dof == 0 {
        return 1.0;
    }
    let h = 0.5 * x;
    let e = (-h).exp();
    if dof % 2 == 0 {
        // Q(m, h) = e^-h sum_{j<m} h^j / j!
        let mut term = 1.0;
        let mut sum = 1.0;
        for j in 1..dof / 2 {
            term *= h / j as f64;
            sum += term;
        }
        (e * sum).min(1.0)
    } else {
        // Q(m + 1/2, h) = erfc(sqrt h) + e^-h sum_{j<m} h^(j+1/2) / Gamma(j + 3/2)
        let mut sum = 0.0;
        let mut term = h.sqrt() / (0.5 * std::f64::consts::PI.sqrt()); // h^(1/2) / Gamma(3/2)
        for j in 0..(dof - 1) / 2 {
            sum += term;
            term *= h / (j as f64 + 1.5);
        }
        (erfc(h.sqrt()) + e * sum).min(1.0)
    }
}

/// The `p` quantile of chi-squared with `dof` degrees of freedom (bisection on [`chi2_sf`]).
pub fn chi2_quantile(p: f64, dof: usize) -> f64 {
    let q = 1.0 - p.clamp(1e-300, 1.0 - 1e-16);
    let (mut lo, mut hi) = (0.0, dof as f64 + 10.0);
    while chi2_sf(hi, dof) > q {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_sf(mid, dof) > q {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-10 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Squared whitened residual above which one of `n` factors with `dof` components is an outlier:
/// clean data exceed it with probability 1 % over all `n` (and at most 1e-3 for one factor).
pub fn outlier_threshold(n: usize, dof: usize) -> f64 {
    let p = (0.01 / n.max(1) as f64).min(1e-3);
    chi2_quantile(1.0 - p, dof)
}

/// How much larger the noise is than stated, as a variance ratio, from the median squared
/// whitened residual (outliers do not move it); at least 1, so a stated noise is never made
/// smaller. `leverage` is the fraction of the noise left in the residuals (1 for raw
/// measurements; less for residuals of a smoothed fit).
pub fn noise_scale(s: &[f64], dof: usize, leverage: f64) -> f64 {
    let mut v: Vec<f64> = s.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 1.0;
    }
    v.sort_by(f64::total_cmp);
    let median = v[v.len() / 2];
    (median / (chi2_quantile(0.5, dof) * leverage.clamp(1e-3, 1.0))).max(1.0)
}

/// A down-weighted factor, for the report's list of the worst.
#[derive(Clone, Debug, PartialEq)]
pub struct Outlier {
    /// Index of the DVL observation or pose.
    pub index: usize,
    /// Its time (DVL clock for DVL samples, camera clock for poses), seconds.
    pub t: f64,
    /// Its squared whitened residual over the noise scale: how many variances out it is.
    pub s: f64,
    /// Its weight in the final estimate.
    pub weight: f64,
}

/// What the robust loss did to one kind of factor.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RobustSummary {
    /// The loss applied (`L2` when none was, or when no factor was an outlier).
    pub applied: Option<Loss>,
    /// Factors judged.
    pub factors: usize,
    /// Factors beyond [`outlier_threshold`]: down-weighted.
    pub outliers: usize,
    /// The noise's variance over the stated one, as the residuals' median shows it (at least 1).
    pub noise_scale: f64,
    /// The threshold on the scaled squared residual.
    pub threshold: f64,
    /// The worst factors, largest residual first (at most [`WORST`]).
    pub worst: Vec<Outlier>,
}

/// How many of the worst factors a summary lists.
pub const WORST: usize = 10;

/// Weights of factors with squared whitened residuals `s` (stated noise) at times `t`, and what
/// was done. The loss applies only when some factor is an outlier; otherwise every weight is 1.
pub fn weigh(
    loss: Loss,
    s: &[f64],
    t: &[f64],
    dof: usize,
    leverage: f64,
) -> (Vec<f64>, RobustSummary) {
    let scale = noise_scale(s, dof, leverage);
    let threshold = outlier_threshold(s.len(), dof);
    let scaled: Vec<f64> = s.iter().map(|x| x / scale).collect();
    let outliers: Vec<usize> = (0..s.len())
        .filter(|&i| scaled[i].is_nan() || scaled[i] > threshold)
        .collect();
    let applied = (loss != Loss::L2 && !outliers.is_empty()).then_some(loss);
    let weights: Vec<f64> = match applied {
        Some(l) => scaled.iter().map(|&x| l.weight(x, dof)).collect(),
        None => vec![1.0; s.len()],
    };
    let mut worst = outliers.clone();
    worst.sort_by(|&a, &b| scaled[b].total_cmp(&scaled[a]));
    worst.truncate(WORST);
    let summary = RobustSummary {
        applied,
        factors: s.len(),
        outliers: outliers.len(),
        noise_scale: scale,
        threshold,
        worst: worst
            .into_iter()
            .map(|i| Outlier {
                index: i,
                t: t.get(i).copied().unwrap_or(f64::NAN),
                s: scaled[i],
                weight: weights[i],
            })
            .collect(),
    };
    (weights, summary)
}

/// Indices of DVL velocities that jump away from their neighbours: the deviation from the
/// component-wise median of the `2 * half + 1` reports around each (in time order) beyond
/// `factor` times the median deviation, and beyond `floor` m/s. The check needs no trajectory,
/// so it protects the initialisation, which sees the data before any residual exists.
pub fn velocity_spikes(
    t: &[f64],
    v: &[nalgebra::Vector3<f64>],
    half: usize,
    factor: f64,
    floor: f64,
) -> Vec<usize> {
    let n = v.len().min(t.len());
    if n < 2 * half + 1 {
        return Vec::new();
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
    let mut dev = vec![0.0; n];
    let mut window = Vec::with_capacity(2 * half + 1);
    for (pos, &i) in order.iter().enumerate() {
        // A window centred on the sample (narrower near the ends, where a one-sided window
        // would see the motion's trend as a jump).
        let h = half.min(pos).min(n - 1 - pos);
        let (lo, hi) = (pos - h, pos + h + 1);
        let mut median = nalgebra::Vector3::zeros();
        for c in 0..3 {
            window.clear();
            window.extend(order[lo..hi].iter().map(|&j| v[j][c]));
            window.sort_by(f64::total_cmp);
            median[c] = window[h];
        }
        dev[i] = (v[i] - median).norm();
    }
    let mut sorted: Vec<f64> = dev.iter().copied().filter(|d| d.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let typical = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let limit = (factor * typical).max(floor);
    (0..n)
        .filter(|&i| dev[i].is_nan() || dev[i] > limit)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_squared_matches_tabulated_values() {
        // Quantiles from standard tables.
        for (p, dof, q) in [
            (0.5, 3, 2.365_974),
            (0.99, 3, 11.344_867),
            (0.999, 3, 16.266_236),
            (0.5, 6, 5.348_121),
            (0.99, 6, 16.811_894),
            (0.95, 1, 3.841_459),
            (0.95, 2, 5.991_465),
        ] {
            let got = chi2_quantile(p, dof);
            assert!((got - q).abs() < 2e-5 * q, "dof {dof} p {p}: {got} vs {q}");
        }
    }

    #[test]
    fn weights_follow_the_losses() {
        assert_eq!(Loss::L2.weight(1e6, 3), 1.0);
        assert_eq!(Loss::Huber.weight(3.0, 3), 1.0);
        let k2 = chi2_quantile(0.99, 3);
        assert!((Loss::Huber.weight(4.0 * k2, 3) - 0.5).abs() < 1e-12);
        let c2 = 3.0 * CAUCHY_C * CAUCHY_C;
        assert!((Loss::Cauchy.weight(c2, 3) - 0.5).abs() < 1e-12);
        assert_eq!(Loss::Cauchy.weight(f64::NAN, 3), 0.0);
        assert!(Loss::parse("CAUCHY").is_ok());
        assert!(Loss::parse("tukey").is_err());
    }

    #[test]
    fn clean_residuals_are_left_alone_and_outliers_are_caught() {
        // A chi-squared(3) sample.
        let n = 3000;
        let mut rng = crate::rng::Rng::stream(7, 1);
        let mut s: Vec<f64> = (0..n).map(|_| rng.normal_vec3().norm_squared()).collect();
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let (w, sum) = weigh(Loss::Cauchy, &s, &t, 3, 1.0);
        assert_eq!(sum.applied, None);
        assert!(w.iter().all(|&x| x == 1.0));
        assert!(sum.noise_scale < 1.2, "{}", sum.noise_scale);
        s[17] = 900.0;
        s[2001] = 400.0;
        let (w, sum) = weigh(Loss::Cauchy, &s, &t, 3, 1.0);
        assert_eq!(sum.applied, Some(Loss::Cauchy));
        assert_eq!(sum.outliers, 2);
        assert_eq!(sum.worst[0].index, 17);
        assert_eq!(sum.worst[1].index, 2001);
        assert!(w[17] < 0.05 && w[2001] < 0.1);
        // Noise stated ten times too small: everything is scaled, nothing is an outlier.
        let big: Vec<f64> = s
            .iter()
            .take(1000)
            .map(|x| (x * 100.0).min(3000.0))
            .collect();
        let (_, sum) = weigh(Loss::Cauchy, &big[20..], &t, 3, 1.0);
        assert!(
            (sum.noise_scale - 100.0).abs() < 15.0,
            "{}",
            sum.noise_scale
        );
    }

    #[test]
    fn spikes_stand_out_from_smooth_velocities() {
        let t: Vec<f64> = (0..500).map(|i| i as f64 * 0.1).collect();
        let mut v: Vec<nalgebra::Vector3<f64>> = t
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let wobble = 0.003 * (((i * 7919) % 13) as f64 / 6.0 - 1.0);
                nalgebra::Vector3::new(0.3 * (0.5 * x).sin() + wobble, 0.1 * x.cos(), wobble)
            })
            .collect();
        v[100].x += 0.3;
        v[250].z -= 0.2;
        assert_eq!(velocity_spikes(&t, &v, 3, 8.0, 0.03), vec![100, 250]);
    }
}
