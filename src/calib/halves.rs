//! The halves check: each half of the recording calibrated on its own (the trajectory held at
//! the result) and compared with the other; a parameter whose halves disagree by more than three
//! standard deviations has its standard deviation inflated to cover the difference, a warning,
//! and a weak verdict.

use super::joint::covariance::{AssembledJoint, part_linear_estimate};
use super::joint::problem::JointProblem;
use super::model::{self, DvlObs, NPARAM, PARAM_NAMES};
use super::options::CalibOptions;
use super::outcome::{HalvesCheck, Verdict, Verdicts};
use super::update::{FreeParams, ParamMat};
use crate::error::Result;
use crate::trajectory::Trajectory;
use crate::types::CalibrationParams;

/// Each half's estimate (see [`halves_estimates`]), when `opts` asks for honest standard
/// deviations: with the whole's residuals above the stated noise by half or more
/// (`normalized_cost`), each half's covariance is inflated as the whole's is.
#[allow(clippy::too_many_arguments)]
pub(crate) fn estimate(
    jp: &JointProblem,
    whole: &AssembledJoint,
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    free: FreeParams,
    normalized_cost: f64,
    opts: &CalibOptions,
) -> Result<Option<HalfEstimates>> {
    if !opts.honest_covariance {
        return Ok(None);
    }
    let noise_factor = if normalized_cost > 1.5 {
        normalized_cost
    } else {
        1.0
    };
    halves_estimates(jp, whole, traj, obs, idx, free, noise_factor)
}

/// Fewest samples in each half for the halves check.
const HALF_MIN: usize = 50;

/// Each half's problem spans its samples' knots and this much more on either side, seconds...
const HALF_MARGIN_S: f64 = 5.0;

/// ... and at least this many knots more.
const HALF_MARGIN_KNOTS: usize = 50;

/// The two halves' estimates of the halves check, before the comparison.
pub(crate) struct HalfEstimates {
    split_t: f64,
    first: (CalibrationParams, ParamMat),
    second: (CalibrationParams, ParamMat),
}

/// Each half of the samples `idx` (by DVL time) calibrated on its own, for [`compare_halves`].
///
/// Each half's estimate is the calibration part of one Gauss-Newton step on its joint problem
/// (the half's DVL reports and the poses of its span, with a margin) from the result, and its
/// covariance that problem's marginal one at the result (both from one factorisation; times
/// `noise_factor`, the inflation of the whole's for residuals above the stated noise): a half
/// that does not excite a parameter (a calm first half) gives it a large variance and no false
/// alarm. The halves' normal equations are taken from the whole's, `whole`, assembled at the
/// result ([`part_linear_estimate`]): only the knots near the cut and at the ends of each
/// half's span are assembled again.
fn halves_estimates(
    jp: &JointProblem,
    whole: &AssembledJoint,
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    free: FreeParams,
    noise_factor: f64,
) -> Result<Option<HalfEstimates>> {
    let mask = free.mask();
    if !mask.iter().any(|&m| m) {
        return Ok(None);
    }
    let params = whole.params();
    let mut by_time: Vec<usize> = idx.to_vec();
    by_time.sort_by(|&a, &b| obs[a].t.total_cmp(&obs[b].t));
    let n = by_time.len() / 2;
    if n < HALF_MIN {
        return Ok(None);
    }
    let (first_idx, second_idx) = by_time.split_at(n);
    let times = traj.times();
    let half = |part: &[usize]| -> Result<(CalibrationParams, ParamMat)> {
        // The knots the half's samples fall between, and a margin on either side: further knots
        // carry only poses and the prior, whose pull on the half's parameters has died out.
        let (t0, t1) = part
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &i| {
                let t = obs[i].t + params.time_offset_s;
                (a.min(t), b.max(t))
            });
        let lo = times.partition_point(|&t| t < t0 - HALF_MARGIN_S);
        let hi = times.partition_point(|&t| t <= t1 + HALF_MARGIN_S);
        let lo = lo.saturating_sub(HALF_MARGIN_KNOTS);
        let hi = (hi + HALF_MARGIN_KNOTS).min(times.len());
        let jh = jp.part(part, lo..hi);
        let knots = &traj.knots()[lo..hi];
        let (p, cov) = part_linear_estimate(jp, whole, &jh, knots, lo..hi, &mask)?;
        Ok((p, cov * noise_factor))
    };
    let first = half(first_idx)?;
    let second = half(second_idx)?;
    Ok(Some(HalfEstimates {
        split_t: 0.5 * (obs[first_idx[n - 1]].t + obs[second_idx[0]].t),
        first,
        second,
    }))
}

/// Compares the halves' estimates; where they differ by more than three standard deviations
/// the rows and columns of `covariance` are scaled so that the difference is one (the variance
/// the difference itself estimates).
pub(crate) fn compare_halves(
    h: HalfEstimates,
    free: FreeParams,
    covariance: &mut ParamMat,
) -> HalvesCheck {
    let mask = free.mask();
    let ((first, c1), (second, c2)) = (h.first, h.second);
    let d = model::difference(&second, &first);
    let mut difference = [0.0; NPARAM];
    let mut difference_std = [f64::INFINITY; NPARAM];
    let mut inflation = [1.0; NPARAM];
    let mut compared = [false; NPARAM];
    for k in 0..NPARAM {
        difference[k] = d[k];
        let var = c1[(k, k)] + c2[(k, k)];
        if !(mask[k] && var.is_finite() && var > 0.0) {
            continue;
        }
        difference_std[k] = var.sqrt();
        // A half that determines a parameter far worse than half the data should (a calm half
        // and the lever arm) is no test of it: its estimate is as weak as its linearised
        // variance is unreliable.
        let even = 2.0 * covariance[(k, k)].max(0.0);
        compared[k] =
            c1[(k, k)] <= HALF_VARIANCE_LIMIT * even && c2[(k, k)] <= HALF_VARIANCE_LIMIT * even;
        let z = d[k].abs() / difference_std[k];
        if compared[k] && z > 3.0 {
            inflation[k] = z;
        }
    }
    for k in 0..NPARAM {
        for j in 0..NPARAM {
            covariance[(k, j)] *= inflation[k] * inflation[j];
        }
    }
    HalvesCheck {
        split_t: h.split_t,
        first,
        second,
        difference,
        difference_std,
        compared,
        inflation,
    }
}

/// A half whose variance of a parameter exceeds this many times what half the data would give
/// on average (twice the whole's) does not take part in the comparison of that parameter.
const HALF_VARIANCE_LIMIT: f64 = 9.0;

/// A warning per parameter whose halves disagree.
pub(crate) fn halves_notes(h: &HalvesCheck) -> Vec<String> {
    (0..NPARAM)
        .filter(|&k| h.inflation[k] > 1.0)
        .map(|k| {
            let (name, f, unit) = PARAM_NAMES[k];
            format!(
                "the two halves of the recording disagree on the {name}: {:+.4} {unit} apart, \
                 {:.1} standard deviations; its standard deviation is inflated {:.1} times to \
                 cover the difference (correlated DVL errors, motion the model does not capture, \
                 or a calibration that changed during the recording)",
                h.difference[k] * f,
                h.z(k),
                h.inflation[k]
            )
        })
        .collect()
}

/// Verdicts of the parameters whose halves disagree, turned weak with the reason.
pub(crate) fn flag_inconsistent(v: &mut Verdicts, h: &HalvesCheck) {
    let groups: [(&mut Verdict, std::ops::Range<usize>, &str); 4] = [
        (&mut v.rotation, 0..3, "rotation"),
        (&mut v.lever_arm, 3..6, "lever arm"),
        (&mut v.velocity_scale, 6..7, "velocity scale"),
        (&mut v.time_offset, 7..8, "clock offset"),
    ];
    for (verdict, range, what) in groups {
        let worst = range.clone().map(|k| h.z(k)).fold(0.0, f64::max);
        if range.clone().any(|k| h.inflation[k] > 1.0) {
            verdict.ok = false;
            let reason = format!(
                "the {what} of the two halves of the recording differ by {worst:.1} standard \
                 deviations (the standard deviation was inflated to cover it)"
            );
            verdict.reason = if verdict.reason.is_empty() {
                reason
            } else {
                format!("{}; {reason}", verdict.reason)
            };
        }
    }
}
