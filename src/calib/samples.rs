//! The samples a calibration rests on: the DVL reports that can be used, with their noise
//! ([`observe`]), and those whose camera time falls where the trajectory is measured
//! ([`usable_samples`]: inside the co-sensor's span, outside the gaps between its poses).

use nalgebra::Matrix3;

use super::model::DvlObs;
use super::options::CalibOptions;
use super::outcome::Counts;
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;
use crate::types::DvlSample;

/// The valid DVL reports as observations, and how many reported covariances were replaced.
pub(crate) struct Observed {
    /// One per valid report, in the log's order, on the camera epoch and the DVL clock.
    pub obs: Vec<DvlObs>,
    /// Reports whose covariance could not weigh them (weighted with the default noise).
    pub replaced: usize,
}

/// The DVL reports as observations; fails with fewer than ten valid ones.
pub(crate) fn observe(dvl: &[DvlSample], opts: &CalibOptions) -> Result<Observed> {
    let (obs, replaced) = observations(dvl, opts);
    if obs.len() < 10 {
        return Err(Error::TooFewSamples {
            what: "valid DVL velocity reports".into(),
            found: obs.len(),
            needed: 10,
        });
    }
    Ok(Observed { obs, replaced })
}

impl Observed {
    /// The warning about replaced covariances, if any were.
    pub(crate) fn warning(&self, opts: &CalibOptions) -> Option<String> {
        (self.replaced > 0).then(|| {
            format!(
                "{} DVL reports carry a covariance that is not symmetric positive definite \
                 (or nearly singular); they are weighted with the default noise of {} m/s instead",
                self.replaced, opts.default_dvl_sigma
            )
        })
    }
}

/// The samples the refinement uses: inside the trajectory's span at every offset within
/// `min(offset.window_s, 0.5)` s of `offset` (the refinement moves the offset), and outside the
/// gaps between poses. Counts what was left out in `counts` and warns of samples in gaps; fails
/// with fewer than ten.
pub(crate) fn usable_samples(
    traj: &Trajectory,
    obs: &[DvlObs],
    offset: f64,
    opts: &CalibOptions,
    counts: &mut Counts,
    warnings: &mut Vec<String>,
) -> Result<Vec<usize>> {
    let margin = opts.offset.window_s.min(0.5);
    let idx = usable(traj, obs, offset, margin);
    let gaps = pose_gaps(traj.times());
    counts.dvl_in_pose_gaps = obs.iter().filter(|o| in_gap(&gaps, o.t + offset)).count();
    counts.dvl_used = idx.len();
    counts.dvl_outside_span = obs.len() - idx.len() - counts.dvl_in_pose_gaps;
    if counts.dvl_in_pose_gaps > 0 {
        let total: f64 = gaps.iter().map(|g| g.1 - g.0).sum();
        warnings.push(format!(
            "{} DVL reports fall in {} gaps between camera poses ({total:.1} s in all, each at \
             least {:.2} s): left out, since the trajectory there is a guess",
            counts.dvl_in_pose_gaps,
            gaps.len(),
            pose_gap_threshold_s(traj.times())
        ));
    }
    if idx.len() < 10 {
        return Err(Error::NoTimeOverlap(format!(
            "only {} DVL samples fall inside the camera time span at offset {:.3} s",
            idx.len(),
            offset
        )));
    }
    Ok(idx)
}

/// Whether a reported velocity covariance can weigh its sample: finite, symmetric, positive
/// definite, and not nearly singular (smallest eigenvalue at least 1e-6 of the largest; a nearly
/// singular covariance would claim an almost exact velocity along some direction). Real A50 logs
/// hold covariances with slightly negative eigenvalues.
pub fn usable_covariance(c: &Matrix3<f64>) -> bool {
    if !c.iter().all(|x| x.is_finite()) {
        return false;
    }
    let max = c.amax();
    if max.is_nan() || max <= 0.0 || (c - c.transpose()).amax() > 1e-9 * max {
        return false;
    }
    let ev = c.symmetric_eigenvalues();
    ev.min() > 1e-6 * ev.max()
}

/// DVL observations with their noise, on the camera epoch, and how many reported covariances
/// were replaced by the default noise because they could not weigh their sample.
pub(crate) fn observations(dvl: &[DvlSample], opts: &CalibOptions) -> (Vec<DvlObs>, usize) {
    let mut replaced = 0;
    let obs = dvl
        .iter()
        .filter(|s| s.valid && s.v.iter().all(|x| x.is_finite()))
        .map(|s| {
            let cov = match (opts.dvl_sigma, &s.cov) {
                (Some(sd), _) => Matrix3::identity() * sd * sd,
                (None, Some(c)) if usable_covariance(c) => *c,
                (None, Some(_)) => {
                    replaced += 1;
                    Matrix3::identity() * opts.default_dvl_sigma.powi(2)
                }
                (None, None) => Matrix3::identity() * opts.default_dvl_sigma.powi(2),
            };
            DvlObs {
                t: s.t,
                v: s.v,
                cov,
            }
        })
        .collect();
    (obs, replaced)
}

/// Samples usable at offsets within `margin` of `offset`.
pub(crate) fn usable(traj: &Trajectory, obs: &[DvlObs], offset: f64, margin: f64) -> Vec<usize> {
    let (a, b) = traj.span();
    let gaps = pose_gaps(traj.times());
    (0..obs.len())
        .filter(|&i| obs[i].t + offset - margin >= a && obs[i].t + offset + margin <= b)
        .filter(|&i| !in_gap(&gaps, obs[i].t + offset))
        .collect()
}

/// The shortest interval between consecutive poses that counts as a gap: five median pose
/// intervals, and at least half a second. Inside a gap the trajectory is the motion prior's
/// extrapolation, not a measurement, and a DVL sample there would be compared with a guess.
pub fn pose_gap_threshold_s(times: &[f64]) -> f64 {
    let mut dt: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    dt.sort_by(f64::total_cmp);
    let median = dt.get(dt.len() / 2).copied().unwrap_or(0.0);
    (5.0 * median).max(0.5)
}

/// The gaps between consecutive poses (`times` sorted), as `(start, end)`.
pub fn pose_gaps(times: &[f64]) -> Vec<(f64, f64)> {
    let threshold = pose_gap_threshold_s(times);
    times
        .windows(2)
        .filter(|w| w[1] - w[0] >= threshold)
        .map(|w| (w[0], w[1]))
        .collect()
}

fn in_gap(gaps: &[(f64, f64)], t: f64) -> bool {
    let k = gaps.partition_point(|g| g.1 <= t);
    gaps.get(k).is_some_and(|g| g.0 < t && t < g.1)
}
