//! Clock offset and velocity scale from speed magnitudes (the paper's Sec. IV-C-1).
//!
//! On samples where the camera barely rotates, the lever-arm term `w x p` vanishes and the norm
//! removes the rotation, leaving `|v_dvl|^2 ~= kappa^2 |v_cam(t_dvl + delta)|^2`. With the noise
//! means removed (`tr Q_d` for the DVL, `tr Sigma_v` for the GP estimate) the objective
//!
//! `J(delta, kappa) = sum_i (a_i / kappa^2 - b_i(delta))^2`, `a_i = |v_dvl,i|^2 - tr Q_d,i`,
//! `b_i = |v_hat(t_i + delta)|^2 - tr Sigma_v(t_i + delta)`
//!
//! is quadratic in `u = 1 / kappa^2`, so for each candidate offset the scale is solved exactly
//! (the paper searches a small grid of scales instead). The clocks may be any distance apart:
//! first the global alignment ([`super::align`]) finds the lag over every lag at which the logs
//! overlap, then a grid search within [`OffsetOptions::window_s`] of it on all samples
//! (speed-magnitude correlation, robust but blurred by the lever arm), then on the calm subset
//! around that optimum, polished by golden-section search.

use super::align::{AlignOptions, ClockAlignment, align_clocks};
pub use super::model::DvlObs;
use super::setting::{Setting, SettingNames};
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

/// Settings of the offset search.
#[derive(Clone, Debug)]
pub struct OffsetOptions {
    /// Offsets allowed, seconds (`t_cam = t_dvl + offset`); `None`: any offset at which the logs
    /// overlap.
    pub range: Option<(f64, f64)>,
    /// Half-width of the fine search around the global alignment's lag, seconds.
    pub window_s: f64,
    /// The global alignment.
    pub align: AlignOptions,
    /// Angular speed below which a sample counts as calm, rad/s.
    pub calm_threshold: f64,
    /// Fewest calm samples for the calm-subset estimate.
    pub min_calm: usize,
    /// Grid step of the coarse search, seconds.
    pub coarse_step: f64,
    /// Samples used by the coarse search (spread evenly over the log).
    pub coarse_samples: usize,
    /// Samples used by the fine search (spread evenly over the calm subset).
    pub fine_samples: usize,
}

impl Default for OffsetOptions {
    fn default() -> Self {
        OffsetOptions {
            range: None,
            window_s: 1.0,
            align: AlignOptions::default(),
            calm_threshold: 0.05,
            min_calm: 30,
            coarse_step: 0.02,
            coarse_samples: 600,
            fine_samples: 3000,
        }
    }
}

impl OffsetOptions {
    /// Checks the search settings; the error names the setting in `names`' words.
    pub fn validate(&self, names: SettingNames) -> Result<()> {
        if let Some((lo, hi)) = self.range
            && !(lo.is_finite() && hi.is_finite() && lo < hi)
        {
            return Err(Error::option(
                names(Setting::OffsetRange),
                "takes two increasing values: min,max",
            ));
        }
        if !(self.window_s.is_finite() && self.window_s > 0.0) {
            return Err(Error::option(
                names(Setting::OffsetWindow),
                "must be a positive number of seconds",
            ));
        }
        if !(self.coarse_step.is_finite() && self.coarse_step > 0.0) {
            return Err(Error::option(
                names(Setting::OffsetCoarseStep),
                "must be a positive number of seconds",
            ));
        }
        Ok(())
    }
}

/// How the offset was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OffsetMethod {
    /// The paper's estimator on low-angular-velocity samples.
    CalmSubset,
    /// Too few calm samples: speed magnitudes of all samples (lever-arm motion is then noise).
    SpeedCorrelation,
}

impl OffsetMethod {
    /// How the result file's `clock_offset_init` names the search.
    pub fn words(self) -> &'static str {
        match self {
            OffsetMethod::CalmSubset => "global speed alignment, then calm subset",
            OffsetMethod::SpeedCorrelation => {
                "global speed alignment, then speed correlation (no calm segment)"
            }
        }
    }
}

/// Result of the offset search.
#[derive(Clone, Debug)]
pub struct OffsetResult {
    /// Estimated clock offset, seconds (`t_cam = t_dvl + offset`).
    pub offset: f64,
    /// Velocity scale `kappa` at that offset (dimensionless).
    pub scale: f64,
    /// How the offset was obtained.
    pub method: OffsetMethod,
    /// Indices (into the observations) of the calm samples at the chosen offset.
    pub calm: Vec<usize>,
    /// Objective of the final stage against the offset (normalised by its minimum).
    pub curve: Vec<(f64, f64)>,
    /// Objective of the coarse stage against the offset.
    pub coarse_curve: Vec<(f64, f64)>,
    /// Human-readable remarks (fallbacks, flat objectives, an ambiguous alignment).
    pub notes: Vec<String>,
    /// The global alignment the search started from.
    pub alignment: ClockAlignment,
    /// The offsets the fine search covered, seconds.
    pub searched: (f64, f64),
}

/// Samples per piece of work of [`objective`].
const OBJECTIVE_PIECE: usize = 512;

/// Value of the profiled objective and the scale that minimises it. `tr_sv[i]` is the trace of
/// the GP's velocity covariance at sample `i` (it changes little over the offsets searched, so
/// it is evaluated once).
fn objective(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    tr_sv: &[f64],
    delta: f64,
) -> Option<(f64, f64)> {
    // Pieces of samples on all cores, their sums added in order (the same on any core count).
    let pieces = crate::parallel::map_pieces(idx.len(), OBJECTIVE_PIECE, |r| {
        let (mut saa, mut sab, mut sbb) = (0.0, 0.0, 0.0);
        for &i in &idx[r] {
            let o = &obs[i];
            let twist = traj.twist(o.t + delta).ok()?;
            let v = twist.fixed_rows::<3>(0);
            let a = o.v.norm_squared() - o.cov.trace();
            let b = v.norm_squared() - tr_sv[i];
            saa += a * a;
            sab += a * b;
            sbb += b * b;
        }
        Some((saa, sab, sbb))
    });
    let (mut saa, mut sab, mut sbb) = (0.0, 0.0, 0.0);
    for piece in pieces {
        let (a, b, c) = piece?;
        saa += a;
        sab += b;
        sbb += c;
    }
    let n = idx.len();
    if n == 0 || saa <= 0.0 {
        return None;
    }
    // u = 1 / kappa^2 minimises sum (a u - b)^2; keep kappa within a physical range.
    let u = (sab / saa).clamp(1.0 / 4.0, 4.0);
    let j = (saa * u * u - 2.0 * sab * u + sbb) / n as f64;
    Some((j, 1.0 / u.sqrt()))
}

/// Best offset, the scale there, and the grid's objective curve.
type SearchResult = (f64, f64, Vec<(f64, f64)>);

/// Grid search then golden-section refinement of the offset on the samples `idx`.
fn search(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    tr_sv: &[f64],
    lo: f64,
    hi: f64,
    step: f64,
) -> Option<SearchResult> {
    let count = ((hi - lo) / step).ceil().max(1.0) as usize;
    let mut curve = Vec::with_capacity(count + 1);
    for k in 0..=count {
        let d = lo + (hi - lo) * k as f64 / count as f64;
        if let Some((j, _)) = objective(traj, obs, idx, tr_sv, d) {
            curve.push((d, j));
        }
    }
    let &(best, _) = curve.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
    let h = (hi - lo) / count as f64;
    let (mut a, mut b) = ((best - h).max(lo), (best + h).min(hi));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let f = |d: f64| {
        objective(traj, obs, idx, tr_sv, d)
            .map(|x| x.0)
            .unwrap_or(f64::INFINITY)
    };
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    while b - a > 1e-6 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    let offset = 0.5 * (a + b);
    let (_, scale) = objective(traj, obs, idx, tr_sv, offset)?;
    Some((offset, scale, curve))
}

/// At most `n` of `idx`, spread evenly.
fn spread(idx: &[usize], n: usize) -> Vec<usize> {
    let stride = idx.len().div_ceil(n.max(1)).max(1);
    idx.iter().step_by(stride).copied().collect()
}

/// Samples whose camera times stay inside the trajectory for every offset in `[lo, hi]`.
fn inside(traj: &Trajectory, obs: &[DvlObs], lo: f64, hi: f64) -> Vec<usize> {
    let (a, b) = traj.span();
    (0..obs.len())
        .filter(|&i| obs[i].t + lo >= a && obs[i].t + hi <= b)
        .collect()
}

/// Estimates the clock offset and velocity scale, with settings that
/// [`OffsetOptions::validate`] accepts; its notes name the settings in `names`' words.
pub fn estimate_offset(
    traj: &Trajectory,
    obs: &[DvlObs],
    opts: &OffsetOptions,
    names: SettingNames,
) -> Result<OffsetResult> {
    let alignment = align_clocks(traj, obs, opts.range, &opts.align)?;
    let (mut lo, mut hi) = (
        alignment.lag_s - opts.window_s,
        alignment.lag_s + opts.window_s,
    );
    if let Some((a, b)) = opts.range {
        (lo, hi) = (lo.max(a), hi.min(b));
    }
    let all = inside(traj, obs, lo, hi);
    if all.len() < 10 {
        let (a, b) = traj.span();
        return Err(Error::NoTimeOverlap(format!(
            "only {} DVL samples fall inside the camera time span [{a:.3}, {b:.3}] for every offset in \
             [{lo}, {hi}] s: the logs do not overlap in time (check the clocks or widen the offset range)",
            all.len()
        )));
    }
    let coarse_idx = spread(&all, opts.coarse_samples);
    // The coarse stage ignores the GP's velocity variance; the fine stage uses it.
    let mut tr_sv = vec![0.0; obs.len()];
    let (coarse_offset, coarse_scale, coarse_curve) =
        search(traj, obs, &coarse_idx, &tr_sv, lo, hi, opts.coarse_step).ok_or_else(|| {
            Error::Input("the DVL speeds are all zero or below their noise: no clock offset".into())
        })?;

    // Calm samples: slow rotation over the whole neighbourhood searched next.
    let margin = 5.0 * opts.coarse_step;
    let (flo, fhi) = (
        (coarse_offset - margin).max(lo),
        (coarse_offset + margin).min(hi),
    );
    let near = inside(traj, obs, flo, fhi);
    let is_calm = crate::parallel::map_indices(near.len(), 4096, |j| {
        [flo, coarse_offset, fhi].iter().all(|d| {
            traj.twist(obs[near[j]].t + d)
                .map(|w| w.fixed_rows::<3>(3).norm() < opts.calm_threshold)
                .unwrap_or(false)
        })
    });
    let calm: Vec<usize> = near
        .iter()
        .zip(is_calm)
        .filter_map(|(&i, c)| c.then_some(i))
        .collect();
    let mut notes = Vec::new();
    if alignment.ambiguous {
        notes.push(format!(
            "the clock offset is ambiguous: the speeds match almost as well ({:.3} against {:.3}) \
             at a clock offset of {:.3} s as at {:.3} s; periodic motion repeats itself, so vary \
             the speed irregularly (or give {} around the right offset)",
            alignment.second_correlation.unwrap_or(f64::NAN),
            alignment.correlation,
            alignment.second_lag_s.unwrap_or(f64::NAN),
            alignment.lag_s,
            names(Setting::OffsetRange)
        ));
    }
    if alignment.is_poor() {
        notes.push(format!(
            "the DVL and camera speeds correlate poorly at their best clock offset ({:.2}): the \
             logs may not be of the same recording",
            alignment.correlation
        ));
    }
    let (idx, method) = if calm.len() >= opts.min_calm {
        (calm.clone(), OffsetMethod::CalmSubset)
    } else {
        notes.push(format!(
            "only {} samples rotate slower than {} rad/s (need {}): the clock offset comes from \
             speed magnitudes of all samples, where the lever arm adds noise",
            calm.len(),
            opts.calm_threshold,
            opts.min_calm
        ));
        (near.clone(), OffsetMethod::SpeedCorrelation)
    };
    // The initial estimate needs no more than a few thousand samples; the refinement uses all.
    let idx = spread(&idx, opts.fine_samples);
    for &i in &idx {
        if let Ok(q) = traj.query(obs[i].t + coarse_offset)
            && let Some(c) = q.twist_cov
        {
            tr_sv[i] = c[(0, 0)] + c[(1, 1)] + c[(2, 2)];
        }
    }
    let (offset, scale, curve) = search(traj, obs, &idx, &tr_sv, flo, fhi, opts.coarse_step / 4.0)
        .unwrap_or((coarse_offset, coarse_scale, Vec::new()));
    let jmin = curve
        .iter()
        .map(|c| c.1)
        .fold(f64::INFINITY, f64::min)
        .max(1e-300);
    let jmax = curve.iter().map(|c| c.1).fold(0.0, f64::max);
    if jmax < 1.05 * jmin {
        notes.push(
            "the clock-offset objective is nearly flat: the speed did not change enough near the \
             calm samples; the refinement has to fix the offset"
                .into(),
        );
    }
    Ok(OffsetResult {
        offset,
        scale,
        method,
        calm,
        curve: curve.into_iter().map(|(d, j)| (d, j / jmin)).collect(),
        coarse_curve,
        notes,
        alignment,
        searched: (lo, hi),
    })
}
