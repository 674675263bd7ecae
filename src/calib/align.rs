//! Global clock alignment: the lag between the DVL's clock and the camera's, searched over every
//! lag at which the two logs overlap, however far apart the clocks are.
//!
//! Both logs are reduced to speed magnitudes on one time grid: `|v_dvl|` on the DVL clock (its
//! samples averaged per grid cell) and `|v_cam|` of the fitted trajectory on the camera clock.
//! Speeds do not depend on the unknown rotation; the lever-arm term `|w x p|` does not vanish,
//! so only the camera cells where the camera turns slowly are compared when there are enough of
//! them. The two series then match at the true lag up to the scale. Their normalised cross-correlation, computed
//! over the overlapping cells only (masked, so gaps and logs of different lengths are handled), is
//! formed for all lags at once with FFTs: six correlations of masked series give, per lag, the
//! overlap count and the sums of `x`, `y`, `x^2`, `y^2` and `x y`.
//!
//! Each lag is scored by the evidence of its correlation, `atanh(r) sqrt(n)` over its `n`
//! overlapping cells, so that a lag at which only part of the logs overlaps cannot win on a
//! chance match of a short stretch. Among lags whose evidence is nearly the best (periodic
//! motion), the one with the largest overlap is taken. The best lag (`t_cam = t_dvl + lag`) seeds the fine offset
//! search. The second-best peak (the
//! best correlation farther than [`AlignOptions::peak_separation_s`] from the first) measures the
//! lag's uniqueness: periodic motion repeats the speed pattern and gives a second peak almost as
//! high, which is reported as ambiguous.

use super::correlate::Correlator;
use super::model::DvlObs;
use super::setting::Setting;
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

/// Settings of the global alignment.
#[derive(Clone, Debug, PartialEq)]
pub struct AlignOptions {
    /// Grid step of the speed series, s; `None`: the DVL's median sample interval, at least
    /// 0.02 s and at most 0.5 s.
    pub step_s: Option<f64>,
    /// Shortest overlap of the two logs at which a lag is considered, s.
    pub min_overlap_s: f64,
    /// Shortest overlap as a fraction of the shorter log (so that a lag at which only a sliver of
    /// the logs overlaps cannot win by chance).
    pub min_overlap_fraction: f64,
    /// Peaks closer than this to the best lag belong to it, s.
    pub peak_separation_s: f64,
    /// A second peak whose correlation is at least this fraction of the best makes the lag
    /// ambiguous.
    pub ambiguity_ratio: f64,
    /// Angular speed below which a camera cell is calm, rad/s: the lever arm then adds little
    /// to the DVL's speed.
    pub calm_rad_s: f64,
    /// Fewest calm cells, as a fraction of the camera's cells, for the comparison to use only
    /// calm cells (otherwise all cells are compared).
    pub min_calm_fraction: f64,
    /// Longest series handled (cells); a log longer than this at the grid step is an error
    /// rather than an allocation of unbounded size.
    pub max_cells: usize,
}

impl Default for AlignOptions {
    fn default() -> Self {
        AlignOptions {
            step_s: None,
            min_overlap_s: 10.0,
            min_overlap_fraction: 0.3,
            peak_separation_s: 2.0,
            ambiguity_ratio: 0.9,
            calm_rad_s: 0.1,
            min_calm_fraction: 0.2,
            max_cells: 1 << 24,
        }
    }
}

/// The result of the global alignment.
#[derive(Clone, Debug, PartialEq)]
pub struct ClockAlignment {
    /// The best lag, s: `t_cam = t_dvl + lag`.
    pub lag_s: f64,
    /// Normalised cross-correlation of the speeds at the best lag (1: identical shapes).
    pub correlation: f64,
    /// Evidence of the best lag, `atanh(r) sqrt(n)`.
    pub score: f64,
    /// The best lag outside the first peak, s, when there is one.
    pub second_lag_s: Option<f64>,
    /// Its correlation.
    pub second_correlation: Option<f64>,
    /// Its evidence.
    pub second_score: Option<f64>,
    /// Whether only the camera's calm cells were compared.
    pub calm_only: bool,
    /// Overlap of the two logs at the best lag, s.
    pub overlap_s: f64,
    /// Grid step used, s.
    pub step_s: f64,
    /// Lags considered (those with enough overlap, within the allowed range).
    pub lags_considered: usize,
    /// The second peak is nearly as high as the first: periodic motion or too little variation
    /// of the speed.
    pub ambiguous: bool,
    /// Correlation against lag, thinned to at most a few thousand points (every local maximum
    /// of a thinned stretch kept) for plotting.
    pub curve: Vec<(f64, f64)>,
}

/// Speed correlation at the best lag below which the two logs are probably not of the same
/// recording.
pub const POOR_CORRELATION: f64 = 0.3;

impl ClockAlignment {
    /// The speeds correlate poorly even at the best lag ([`POOR_CORRELATION`]).
    pub fn is_poor(&self) -> bool {
        self.correlation < POOR_CORRELATION
    }

    /// Best over second-best evidence (infinite without a second peak).
    pub fn uniqueness(&self) -> f64 {
        match self.second_score {
            Some(c) if c > 0.0 => self.score / c,
            _ => f64::INFINITY,
        }
    }
}

/// Median interval between consecutive sample times.
fn median_interval(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

/// Finds the lag between the DVL clock and the camera clock over every lag at which the DVL
/// samples `obs` and the trajectory `traj` overlap (within `range`, `t_cam = t_dvl + lag`, when
/// given).
///
/// Errors: no lag with enough overlap ([`Error::NoTimeOverlap`]), no variation of the speed in
/// either log, or a log too long for the grid ([`AlignOptions::max_cells`]).
pub fn align_clocks(
    traj: &Trajectory,
    obs: &[DvlObs],
    range: Option<(f64, f64)>,
    opts: &AlignOptions,
) -> Result<ClockAlignment> {
    if obs.len() < 10 {
        return Err(Error::TooFewSamples {
            what: "valid DVL velocity reports for the clock alignment".into(),
            found: obs.len(),
            needed: 10,
        });
    }
    let dvl_t: Vec<f64> = obs.iter().map(|o| o.t).collect();
    let (d0, d1) = dvl_t
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| {
            (a.min(t), b.max(t))
        });
    let step = match opts.step_s {
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return Err(Error::option(
                Setting::AlignStep.field(),
                format!("must be a positive number of seconds, got {s}"),
            ));
        }
        None => {
            let mut sorted = dvl_t.clone();
            sorted.sort_by(f64::total_cmp);
            median_interval(&sorted).unwrap_or(0.1).clamp(0.02, 0.5)
        }
    };
    let (c0, c1) = traj.span();
    let cells = |span: f64| (span / step).floor() as usize + 1;
    let (nd, nc) = (cells(d1 - d0), cells(c1 - c0));
    if nd > opts.max_cells || nc > opts.max_cells {
        return Err(Error::Input(format!(
            "the DVL log spans {:.0} s and the camera {:.0} s: too long for the clock alignment at \
             {step} s steps (at most {} cells); cut the DVL log to the recording",
            d1 - d0,
            c1 - c0,
            opts.max_cells
        )));
    }

    // DVL speeds per cell (the mean of the samples in it), on the DVL clock.
    let mut ysum = vec![0.0; nd];
    let mut ycount = vec![0u32; nd];
    for o in obs {
        let j = (((o.t - d0) / step).round() as usize).min(nd - 1);
        ysum[j] += o.v.norm();
        ycount[j] += 1;
    }
    let md: Vec<f64> = ycount.iter().map(|&n| f64::from(n.min(1))).collect();
    let y: Vec<f64> = ysum
        .iter()
        .zip(&ycount)
        .map(|(s, &n)| if n > 0 { s / f64::from(n) } else { 0.0 })
        .collect();

    // Camera speeds at the cell times, on the camera clock. Cells far from every pose (gaps in
    // the camera data, where the trajectory only interpolates) are left out.
    let knots = traj.times();
    let pose_dt = median_interval(knots).unwrap_or(step);
    let reach = (5.0 * pose_dt).max(1.0);
    let cam = crate::parallel::map_indices(nc, 4096, |i| {
        let t = (c0 + i as f64 * step).min(c1);
        let k = knots.partition_point(|&x| x < t);
        let near = [k.checked_sub(1), (k < knots.len()).then_some(k)]
            .into_iter()
            .flatten()
            .any(|k| (knots[k] - t).abs() <= reach);
        if !near {
            return None;
        }
        traj.state(t).ok().map(|s| {
            (
                s.twist.fixed_rows::<3>(0).norm(),
                s.twist.fixed_rows::<3>(3).norm(),
            )
        })
    });
    let valid = cam.iter().filter(|c| c.is_some()).count();
    let calm = cam
        .iter()
        .filter(|c| c.is_some_and(|(_, w)| w < opts.calm_rad_s))
        .count();
    let calm_only = calm as f64 >= opts.min_calm_fraction * valid as f64
        && calm as f64 * step >= opts.min_overlap_s;
    let mc: Vec<f64> = cam
        .iter()
        .map(|c| match c {
            Some((_, w)) if !calm_only || *w < opts.calm_rad_s => 1.0,
            _ => 0.0,
        })
        .collect();
    let x: Vec<f64> = cam.iter().map(|c| c.map_or(0.0, |(v, _)| v)).collect();

    let m = (nc + nd).next_power_of_two();
    let cor = Correlator::new(m);
    let sq = |v: &[f64], w: &[f64]| -> Vec<f64> { v.iter().zip(w).map(|(a, b)| a * b).collect() };
    let (mcx, mdy) = (sq(&mc, &x), sq(&md, &y));
    let (mcxx, mdyy) = (sq(&mc, &sq(&x, &x)), sq(&md, &sq(&y, &y)));
    let f = cor.forward(&[&mc, &md, &mcx, &mdy, &mcxx, &mdyy]);
    let (a1, b1, a2, b2, a3, b3) = (&f[0], &f[1], &f[2], &f[3], &f[4], &f[5]);
    let c = cor.correlate(&[(a1, b1), (a2, b1), (a1, b2), (a3, b1), (a1, b3), (a2, b2)]);
    let (n, sx, sy, sxx, syy, sxy) = (&c[0], &c[1], &c[2], &c[3], &c[4], &c[5]);

    // Shift s = i - j (camera cell minus DVL cell) is at index s mod m; its lag is
    // (c0 - d0) + s * step.
    let shorter = (mc.iter().sum::<f64>()).min(md.iter().sum::<f64>());
    let min_count = (opts.min_overlap_s / step)
        .max(opts.min_overlap_fraction * shorter)
        .max(10.0);
    let mut lags: Vec<(f64, f64, f64, f64)> = Vec::new(); // (lag, correlation, overlap, score)
    let first = -(nd as i64 - 1);
    for s in first..nc as i64 {
        let k = s.rem_euclid(m as i64) as usize;
        let lag = (c0 - d0) + s as f64 * step;
        if let Some((lo, hi)) = range
            && !(lag >= lo && lag <= hi)
        {
            continue;
        }
        let cnt = n[k].round();
        if cnt < min_count {
            continue;
        }
        let vx = sxx[k] - sx[k] * sx[k] / cnt;
        let vy = syy[k] - sy[k] * sy[k] / cnt;
        let cov = sxy[k] - sx[k] * sy[k] / cnt;
        let den = (vx * vy).sqrt();
        if !(den.is_finite() && den > 1e-12 * cnt) {
            continue;
        }
        let r = (cov / den).clamp(-0.999_999, 0.999_999);
        lags.push((lag, r, cnt, r.atanh() * cnt.sqrt()));
    }
    // The strongest evidence; among lags nearly as strong (periodic motion), the one at which
    // the logs overlap most: at the true offset the shorter log usually lies wholly inside the
    // longer one.
    let top = lags.iter().map(|l| l.3).fold(f64::NEG_INFINITY, f64::max);
    let Some(&(best_lag, best, best_cnt, best_score)) = lags
        .iter()
        .filter(|l| l.3 >= opts.ambiguity_ratio * top)
        .max_by(|a, b| a.2.total_cmp(&b.2).then(a.3.total_cmp(&b.3)))
    else {
        return Err(Error::NoTimeOverlap(format!(
            "the camera trajectory ({:.1} s, camera clock {} .. {} s) and the DVL log ({:.1} s, DVL \
             clock {} .. {} s) do not overlap by {:.0} s or more at any clock offset{}, or their \
             speeds do not vary: check that both logs are of the same recording",
            c1 - c0,
            c0,
            c1,
            d1 - d0,
            d0,
            d1,
            min_count * step,
            match range {
                Some((lo, hi)) => format!(" in [{lo}, {hi}] s"),
                None => String::new(),
            }
        )));
    };
    let second = lags
        .iter()
        .filter(|l| (l.0 - best_lag).abs() > opts.peak_separation_s)
        .max_by(|a, b| a.3.total_cmp(&b.3))
        .copied();
    let ambiguous = second.is_some_and(|s| s.3 > 0.0 && s.3 >= opts.ambiguity_ratio * best_score);
    Ok(ClockAlignment {
        lag_s: best_lag,
        correlation: best,
        score: best_score,
        second_lag_s: second.map(|s| s.0),
        second_correlation: second.map(|s| s.1),
        second_score: second.map(|s| s.3),
        calm_only,
        overlap_s: best_cnt * step,
        step_s: step,
        lags_considered: lags.len(),
        ambiguous,
        curve: thin(&lags, 4000),
    })
}

/// At most about `max` points of `(lag, correlation, ..)`: the maximum of each of `max / 2`
/// stretches and the minimum, in lag order.
fn thin(lags: &[(f64, f64, f64, f64)], max: usize) -> Vec<(f64, f64)> {
    if lags.len() <= max {
        return lags.iter().map(|l| (l.0, l.1)).collect();
    }
    let per = lags.len().div_ceil(max / 2);
    let mut out = Vec::with_capacity(max + 2);
    for chunk in lags.chunks(per) {
        let hi = chunk.iter().max_by(|a, b| a.1.total_cmp(&b.1));
        let lo = chunk.iter().min_by(|a, b| a.1.total_cmp(&b.1));
        if let (Some(hi), Some(lo)) = (hi, lo) {
            let (a, b) = if hi.0 <= lo.0 { (hi, lo) } else { (lo, hi) };
            out.push((a.0, a.1));
            if b.0 != a.0 {
                out.push((b.0, b.1));
            }
        }
    }
    out
}
