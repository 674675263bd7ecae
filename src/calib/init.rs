//! Stages 2 and 3: where the refinement starts. For UIC, the clock offset and velocity scale
//! from speed magnitudes ([`estimate_offset`]), then rotation, lever arm and scale in closed form
//! at that offset ([`closed_form()`]); for a guess, the guess with its clock offset checked
//! against the data.

use nalgebra::Vector3;

use super::closed_form::{ClosedForm, ClosedFormRow, closed_form, search_rotation};
use super::model::{DvlObs, predict};
use super::offset::{OffsetOptions, OffsetResult, estimate_offset};
use super::options::{CalibOptions, Method, WARM_WINDOW_S};
use super::outcome::{InitReport, WarmStartUse};
use super::robust::{self, Loss};
use super::samples::usable;
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;
use crate::types::CalibrationParams;

/// Stages 2 and 3: the parameters the refinement starts from. For UIC the clock offset and
/// scale from speed magnitudes ([`estimate_offset`]), then rotation, lever arm and scale in closed
/// form at that offset ([`closed_form()`]); for BCD and fixed extrinsics the user's guess. The
/// offset search's notes go to `warnings`. Also returns how many velocity spikes were left out
/// of the initialisation.
pub fn initialise(
    traj: &Trajectory,
    obs: &[DvlObs],
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
) -> Result<(CalibrationParams, Option<InitReport>, usize)> {
    // A DVL that measured nothing explains every later failure: say so first.
    let still = obs.iter().filter(|o| o.v.norm() < 1e-4).count();
    if !obs.is_empty() && still == obs.len() {
        return Err(Error::Input(format!(
            "the DVL reports zero velocity in all {} samples used: it measured no motion (out \
             of the water, no bottom lock, or a log of a vehicle at rest); there is nothing to \
             calibrate against",
            obs.len()
        )));
    }
    // Velocities that jump away from their neighbours are left out of the initialisation: the
    // speed search and the closed form are least squares and would follow them.
    let (screened, keep) = screen_spikes(obs, opts);
    let spikes_screened = obs.len() - keep.len();
    let obs = &screened[..];
    let (params, init) = match &opts.method {
        Method::Uic => {
            let near = match &opts.warm_start {
                Some(w) => offset_near(traj, obs, opts, w.time_offset_s),
                None => None,
            };
            let searched_again = opts.warm_start.is_some() && near.is_none();
            let mut off = match near {
                Some(off) => off,
                None => estimate_offset(traj, obs, &opts.offset, opts.names)?,
            };
            warnings.extend(off.notes.iter().cloned());
            for c in off.calm.iter_mut() {
                *c = keep[*c];
            }
            let idx = usable(traj, obs, off.offset, 0.0);
            let rows = closed_form_rows(traj, obs, &idx, off.offset)?;
            let cf = trimmed_closed_form(&rows, opts.bias_corrected)?;
            // A closed form the velocities do not determine (motion along one direction of the
            // camera frame) is replaced by the best rotation, with a note.
            let searched = search_rotation(&rows, &cf);
            if let Some(s) = &searched {
                warnings.push(format!(
                    "the camera's velocity spans too few directions for the closed-form rotation: \
                     it fits the DVL velocities {:.1} times worse (RMS {:.4} m/s) than a rotation \
                     {:.0} deg from it (RMS {:.4} m/s), which the refinement started from; record \
                     motion along and about more axes of the vehicle",
                    s.closed_form_rms / s.rms.max(1e-12),
                    s.closed_form_rms,
                    s.angle_deg,
                    s.rms
                ));
            }
            let uic = CalibrationParams {
                time_offset_s: off.offset,
                ..searched.as_ref().map_or(cf.params, |s| s.params)
            };
            // The last solution starts the refinement unless it fits the velocities clearly
            // worse than the data's own start (a solution gone astray is not carried on). The
            // closed form minimises nearly this cost, so the warm start always costs a little
            // more; an estimate within its std of the closed form's costs some eight noise
            // variances more over thousands of rows, far inside the margin.
            let (params, warm) = match &opts.warm_start {
                Some(w) => {
                    let warm = CalibrationParams {
                        time_offset_s: off.offset,
                        ..*w
                    };
                    let better =
                        rows_cost(&rows, &warm) <= WARM_COST_MARGIN * rows_cost(&rows, &uic);
                    let used = match (searched_again, better) {
                        (true, _) => WarmStartUse::SearchedAgain,
                        (false, true) => WarmStartUse::Started,
                        (false, false) => WarmStartUse::OffsetOnly,
                    };
                    (if better { warm } else { uic }, used)
                }
                None => (uic, WarmStartUse::None),
            };
            (
                params,
                Some(InitReport {
                    offset: off,
                    closed_form: cf,
                    rotation_search: searched,
                    params,
                    warm,
                }),
            )
        }
        Method::Bcd(g) => (clock_checked(traj, obs, opts, g, warnings), None),
        Method::Fixed {
            guess,
            estimate_offset: true,
        } => (clock_checked(traj, obs, opts, guess, warnings), None),
        Method::Fixed { guess, .. } => (*guess, None),
    };
    Ok((params, init, spikes_screened))
}

/// The clock offset searched within [`WARM_WINDOW_S`] of `offset` (and inside the offsets
/// allowed); `None` when that search fails or ends within a coarse step of the window's edge, where
/// the right offset may lie outside it (the whole search is then needed).
fn offset_near(
    traj: &Trajectory,
    obs: &[DvlObs],
    opts: &CalibOptions,
    offset: f64,
) -> Option<OffsetResult> {
    let (mut lo, mut hi) = (offset - WARM_WINDOW_S, offset + WARM_WINDOW_S);
    if let Some((a, b)) = opts.offset.range {
        (lo, hi) = (lo.max(a), hi.min(b));
    }
    if lo >= hi {
        return None;
    }
    let search = OffsetOptions {
        range: Some((lo, hi)),
        ..opts.offset.clone()
    };
    let off = estimate_offset(traj, obs, &search, opts.names).ok()?;
    // The edges the user's range imposes are real bounds; only the window's own are not.
    let step = opts.offset.coarse_step;
    let clear_of_lo = lo > offset - WARM_WINDOW_S || off.offset > lo + step;
    let clear_of_hi = hi < offset + WARM_WINDOW_S || off.offset < hi - step;
    (clear_of_lo && clear_of_hi).then_some(off)
}

/// A warm start starts the refinement when its velocity residuals' sum of squares is at most
/// this factor times the closed form's.
const WARM_COST_MARGIN: f64 = 1.1;

/// Sum of squared differences between the DVL velocities of `rows` and those `p` predicts from
/// their twists.
fn rows_cost(rows: &[ClosedFormRow], p: &CalibrationParams) -> f64 {
    rows.iter()
        .map(|r| (r.v_dvl - predict(p, &r.twist)).norm_squared())
        .sum()
}

/// Most twist covariances the closed form's rows are given from (see [`closed_form_rows`]).
const CLOSED_FORM_COVARIANCES: usize = 4096;

/// The closed form's rows of the samples `idx` at the clock offset `offset`: each sample's DVL
/// velocity and the camera's twist at its camera time, with a twist covariance.
///
/// The closed form uses the covariances only through their sum (the bias term) and their mean
/// (the angular rate's noise variance), and a covariance costs several times a twist. Up to
/// [`CLOSED_FORM_COVARIANCES`] samples every row gets its own. Beyond that the rows are cut
/// into that many runs of consecutive samples and every row of a run is given the covariance
/// at one member of the run, at a place that moves irregularly from run to run: sums over the
/// rows then estimate the exact ones closely, however the sample times fall between the knots
/// (the covariance changes with that phase, and a regular stride could keep hitting one
/// phase), and the covariance's slow changes along the recording (down-weighted poses, gaps)
/// still show run by run. The cost stops growing with the recording.
fn closed_form_rows(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    offset: f64,
) -> Result<Vec<ClosedFormRow>> {
    let n = idx.len();
    let runs = n.min(CLOSED_FORM_COVARIANCES);
    let covariances: Vec<nalgebra::Matrix6<f64>> = crate::parallel::map_indices(runs, 256, |r| {
        let (a, b) = (r * n / runs, (r + 1) * n / runs);
        // The member at the fractional part of r times the golden ratio of the run (a Weyl
        // sequence: spread evenly and never periodic, so the members fall at every phase).
        let at = ((r as f64 * GOLDEN_RATIO).fract() * (b - a) as f64) as usize;
        let j = a + at.min(b - a - 1);
        let q = traj.query(obs[idx[j]].t + offset)?;
        Ok(q.twist_cov.unwrap_or_else(nalgebra::Matrix6::zeros))
    })
    .into_iter()
    .collect::<Result<_>>()?;
    crate::parallel::map_indices(n, 2048, |j| {
        let i = idx[j];
        // The run holding row j: the last r with r n / runs <= j.
        let r = ((j + 1) * runs).div_ceil(n) - 1;
        Ok(ClosedFormRow {
            v_dvl: obs[i].v,
            twist: traj.twist(obs[i].t + offset)?,
            twist_cov: covariances[r],
        })
    })
    .into_iter()
    .collect()
}

/// `(1 + sqrt 5) / 2`.
const GOLDEN_RATIO: f64 = 1.618_033_988_749_895;

/// The observations without the velocity spikes [`robust::velocity_spikes`] finds (none are
/// removed under the least-squares loss), and the index in `obs` of each kept one.
fn screen_spikes(obs: &[DvlObs], opts: &CalibOptions) -> (Vec<DvlObs>, Vec<usize>) {
    let spikes = if opts.loss == Loss::L2 {
        Vec::new()
    } else {
        let t: Vec<f64> = obs.iter().map(|o| o.t).collect();
        let v: Vec<Vector3<f64>> = obs.iter().map(|o| o.v).collect();
        robust::velocity_spikes(&t, &v, SPIKE_HALF_WINDOW, SPIKE_FACTOR, SPIKE_FLOOR_MPS)
    };
    // Screening more than a tenth would be judging the motion, not spikes.
    if spikes.is_empty() || spikes.len() * 10 > obs.len() {
        return (obs.to_vec(), (0..obs.len()).collect());
    }
    let mut keep = Vec::with_capacity(obs.len() - spikes.len());
    let mut k = 0;
    for i in 0..obs.len() {
        if spikes.get(k) == Some(&i) {
            k += 1;
        } else {
            keep.push(i);
        }
    }
    (keep.iter().map(|&i| obs[i].clone()).collect(), keep)
}

/// Reports on each side of a DVL velocity that the spike screen compares it with.
const SPIKE_HALF_WINDOW: usize = 3;

/// A spike deviates from its neighbours' median by this many times the median deviation...
const SPIKE_FACTOR: f64 = 8.0;

/// ...and by at least this much, m/s.
const SPIKE_FLOOR_MPS: f64 = 0.02;

/// The closed form, solved again without the rows whose residual is more than five robust
/// standard deviations out (bad twists from bad poses, spikes the screen missed) when they are
/// few (at most a fifth).
fn trimmed_closed_form(rows: &[ClosedFormRow], bias_corrected: bool) -> Result<ClosedForm> {
    let cf = closed_form(rows, bias_corrected)?;
    let d: Vec<f64> = rows
        .iter()
        .map(|r| (r.v_dvl - predict(&cf.params, &r.twist)).norm())
        .collect();
    let mut sorted = d.clone();
    sorted.sort_by(f64::total_cmp);
    // The median norm of a 3-D standard normal vector is 1.538.
    let sigma = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0) / 1.538;
    let kept: Vec<ClosedFormRow> = rows
        .iter()
        .zip(&d)
        .filter(|&(_, &x)| x <= 5.0 * sigma)
        .map(|(r, _)| r.clone())
        .collect();
    if kept.len() == rows.len() || kept.len() * 5 < rows.len() * 4 {
        return Ok(cf);
    }
    closed_form(&kept, bias_corrected)
}

/// The guess, with its clock offset replaced by the data's when the two are farther apart than
/// the fine search reaches (a guess without an offset, or clocks that moved): the refinement
/// only moves the offset locally. When the data give no clear offset the guess is kept.
fn clock_checked(
    traj: &Trajectory,
    obs: &[DvlObs],
    opts: &CalibOptions,
    guess: &CalibrationParams,
    warnings: &mut Vec<String>,
) -> CalibrationParams {
    match estimate_offset(traj, obs, &opts.offset, opts.names) {
        Ok(off) if (off.offset - guess.time_offset_s).abs() > opts.offset.window_s => {
            warnings.push(format!(
                "the guess's clock offset {:.3} s is {:.3} s from the one the speeds give, \
                 {:.3} s: the refinement started from the latter",
                guess.time_offset_s,
                off.offset - guess.time_offset_s,
                off.offset
            ));
            CalibrationParams {
                time_offset_s: off.offset,
                ..*guess
            }
        }
        _ => *guess,
    }
}

#[cfg(test)]
mod closed_form_rows_tests {
    use super::*;
    use crate::calib::samples::observations;
    use crate::sim::{MotionKind, SimConfig, simulate};
    use crate::trajectory::FitOptions;
    use nalgebra::{Matrix6, Vector6};

    /// 30 min of the lively motion, DVL at 8 Hz (14400 reports, three times
    /// [`CLOSED_FORM_COVARIANCES`]), its fitted trajectory, the observations and the usable ones.
    fn data() -> (Trajectory, Vec<DvlObs>, Vec<usize>, f64) {
        let cfg = SimConfig {
            duration_s: 1800.0,
            seed: 11,
            dvl_rate_hz: 8.0,
            motion: MotionKind::Sinusoid,
            ..SimConfig::default()
        };
        let sim = simulate(&cfg).expect("simulation");
        let traj = Trajectory::fit(&sim.poses, &FitOptions::default()).expect("fit");
        let (obs, _) = observations(&sim.dvl, &CalibOptions::default());
        let offset = sim.truth.time_offset_s;
        let idx = usable(&traj, &obs, offset, 0.0);
        (traj, obs, idx, offset)
    }

    fn bias(covs: impl Iterator<Item = Matrix6<f64>>) -> Matrix6<f64> {
        let s = Matrix6::from_diagonal(&Vector6::new(1.0, 1.0, 1.0, -1.0, -1.0, -1.0));
        covs.map(|c| s * c * s).sum()
    }

    #[test]
    fn rows_carry_exact_twists_and_covariances_that_sum_to_the_exact_bias() {
        let (traj, obs, idx, offset) = data();
        assert!(idx.len() > 3 * CLOSED_FORM_COVARIANCES, "{}", idx.len());
        let exact: Vec<_> = idx
            .iter()
            .map(|&i| traj.query(obs[i].t + offset).expect("query"))
            .collect();
        // Up to the limit every row has its own covariance, to the last bit.
        let few = &idx[..3000];
        let rows = closed_form_rows(&traj, &obs, few, offset).expect("rows");
        for (r, q) in rows.iter().zip(&exact) {
            assert_eq!(r.twist, q.twist);
            assert_eq!(Some(r.twist_cov), q.twist_cov);
        }
        // Beyond it the twists are still every row's own, and the bias term (the sum of the
        // covariances) is within a percent of the exact one (0.04 % here).
        let rows = closed_form_rows(&traj, &obs, &idx, offset).expect("rows");
        assert!(rows.iter().zip(&exact).all(|(r, q)| r.twist == q.twist));
        let shared = rows
            .iter()
            .zip(&exact)
            .filter(|(r, q)| Some(r.twist_cov) != q.twist_cov)
            .count();
        assert!(shared > idx.len() / 2, "{shared} rows share a covariance");
        let b_rows = bias(rows.iter().map(|r| r.twist_cov));
        let b_exact = bias(exact.iter().map(|q| q.twist_cov.expect("covariance")));
        let rel = (b_rows - b_exact).norm() / b_exact.norm();
        assert!(rel < 0.01, "bias term off by {rel}");
        // Every fourth report (8 Hz against knots at 10 Hz) falls at one phase between the
        // knots: a regular stride of 4 misses by 9 to 28 % here.
        for phase in 0..4 {
            let strided = bias(
                exact
                    .iter()
                    .skip(phase)
                    .step_by(4)
                    .map(|q| q.twist_cov.expect("covariance")),
            ) * 4.0;
            let off = (strided - b_exact).norm() / b_exact.norm();
            assert!(off > 5.0 * rel, "phase {phase}: {off} against {rel}");
        }
        // The angular rate's noise variance, the mean of the angular diagonal.
        let w = |c: &Matrix6<f64>| (c[(3, 3)] + c[(4, 4)] + c[(5, 5)]) / 3.0;
        let m_rows: f64 = rows.iter().map(|r| w(&r.twist_cov)).sum::<f64>();
        let m_exact: f64 = exact
            .iter()
            .map(|q| w(&q.twist_cov.expect("cov")))
            .sum::<f64>();
        assert!(
            ((m_rows - m_exact) / m_exact).abs() < 0.01,
            "{m_rows} vs {m_exact}"
        );
    }
}
