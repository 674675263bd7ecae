//! The motion prior's jerk density along the recording, chosen with the calibration.
//!
//! The trajectory's fit chooses one jerk density `Qc` for the whole recording from the poses
//! alone. A vehicle's motion is calm for a while, then turns or speeds up in bursts: one
//! density smooths the bursts, and the velocities there (which observe the lever arm and the
//! clock best) come out too small. So, once the calibration has converged, the recording is cut
//! into stretches of [`STRETCH_S`] seconds and each stretch's density is scaled by its own
//! factor, one for the translational and one for the rotational part:
//!
//! - **The evidence of each stretch.** At the joint estimate (poses, DVL, calibration), the GP
//!   prior's terms over a stretch have the cost `c` and take `t` of the problem's degrees of
//!   freedom, `tr(H^-1 J^T W J)` over their terms. Scaling their density by `f` is a variance
//!   component: the Laplace evidence of poses and DVL together is largest where `f = f0 c /
//!   (m - t)` (`m` the terms' dimension: nine per interval and part), and its logarithm, as a
//!   function of `u = ln f`, is close to `-(r/4) (u - u_hat)^2` with `r = m - t` the stretch's
//!   redundancy.
//! - **The penalty.** Neighbouring stretches' log factors differ by a Gaussian step of standard
//!   deviation [`STEP_STD_LN`]: a stretch whose terms the data barely check (small `r`) takes
//!   its neighbours' density, and one noisy stretch cannot pull its density far. The penalised
//!   estimate solves one tridiagonal system per part, so the cost is linear in the recording's
//!   length.
//! - **Only upwards.** A factor is at least 1: a stretch may be given more freedom than the
//!   whole recording's density, never less. The evidence of the positions would lower the
//!   density in calm stretches, but that smooths the velocities at the edges of the bursts
//!   next to them: on a replayed flight (`benches/real_motion.rs`) factors free in both
//!   directions made the lever arm's bias worse (6 to 10 mm), raised only they made it smaller,
//!   and the whole recording's density raised tenfold removed it.
//! - **The rounds.** The calibration is refined again under the new densities (from where it
//!   ended), and the factors estimated again, until no log factor moves by more than
//!   [`SETTLED_LN`] (at most [`ROUNDS`] refinements).
//! - **The choice.** The varying density is kept only when the Laplace evidence of poses and
//!   DVL under it exceeds the constant density's by more than its effective number of
//!   parameters plus [`MARGIN`] (the free factors' degrees of freedom, the trace of the
//!   penalised fit's hat matrix): motion that the constant density describes keeps it, and its
//!   result is exactly the one without this stage.

use std::ops::Range;

use super::cosensor::CoSensorFit;
use super::joint::redundancy::{PriorShare, prior_shares};
use super::joint::steps::joint_log_evidence;
pub use super::outcome::{MotionPriorCheck, Stretch};
use super::refinement::Pass;
use crate::error::Result;
use crate::trajectory::{JerkDensity, Trajectory};
use crate::types::CalibrationParams;

/// Length of a stretch with its own density factors, seconds.
pub const STRETCH_S: f64 = 2.0;
/// Standard deviation of the step of a log factor from one stretch to the next (a factor of
/// 10 over two stretches is one standard deviation away).
pub const STEP_STD_LN: f64 = 1.151_292_546_497_023;
/// Rounds stop once no log factor moves by more than this ...
pub const SETTLED_LN: f64 = 0.05;
/// ... or after this many refinements under new densities.
pub const ROUNDS: usize = 4;
/// The evidence must exceed the constant density's by the effective number of factors plus
/// this much (log units).
pub const MARGIN: f64 = 2.0;
/// The weight that holds a stretch's log factor at 0 (the base density).
const HELD_WEIGHT: f64 = 1e12;

/// The intervals between the knots at `times`, cut into stretches of about `len_s` seconds (by
/// each interval's start; the last stretch takes a remainder shorter than half a stretch).
pub fn stretches(times: &[f64], len_s: f64) -> Vec<Range<usize>> {
    let n = times.len().saturating_sub(1);
    let mut out: Vec<Range<usize>> = Vec::new();
    if n == 0 {
        return out;
    }
    let mut start = 0;
    for k in 1..n {
        if times[k] - times[start] >= len_s {
            out.push(start..k);
            start = k;
        }
    }
    let tail = start..n;
    match out.last_mut() {
        Some(last) if times[n] - times[start] < 0.5 * len_s => last.end = n,
        _ => out.push(tail),
    }
    out
}

/// Solves the symmetric tridiagonal system `T x = b` (diagonal `a`, off-diagonal `c`) and gives
/// the diagonal of `T^-1` too.
fn tridiagonal(a: &[f64], c: &[f64], b: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = a.len();
    // Forward elimination (`d` the pivots), back substitution.
    let mut d = vec![0.0; n];
    let mut y = vec![0.0; n];
    for i in 0..n {
        let (prev_d, prev_y) = if i == 0 {
            (1.0, 0.0)
        } else {
            (d[i - 1], y[i - 1])
        };
        let off = if i == 0 { 0.0 } else { c[i - 1] };
        d[i] = a[i] - off * off / prev_d;
        y[i] = b[i] - off * prev_y / prev_d;
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let next = if i + 1 < n { c[i] * x[i + 1] } else { 0.0 };
        x[i] = (y[i] - next) / d[i];
    }
    // Pivots of the elimination from the other end; `(T^-1)_ii = 1 / (d_i + e_i - a_i)`.
    let mut e = vec![0.0; n];
    for i in (0..n).rev() {
        e[i] = if i + 1 < n {
            a[i] - c[i] * c[i] / e[i + 1]
        } else {
            a[i]
        };
    }
    let diag = (0..n).map(|i| 1.0 / (d[i] + e[i] - a[i])).collect();
    (x, diag)
}

/// The penalised log factors of one round: per stretch and part, the new log factor and its
/// standard deviation, with the stretches' redundancies and the effective number of
/// parameters. `current` holds the log factors the shares were computed under.
pub(crate) fn penalised(
    shares: &[PriorShare],
    ranges: &[Range<usize>],
    current: &[[f64; 2]],
) -> Penalised {
    let m = ranges.len();
    let mut u = vec![[0.0; 2]; m];
    let mut std = vec![[0.0; 2]; m];
    let mut red = vec![[0.0; 2]; m];
    let mut effective = 0.0;
    let step_w = 1.0 / (STEP_STD_LN * STEP_STD_LN);
    for part in 0..2 {
        let (mut w, mut target) = (vec![0.0; m], vec![0.0; m]);
        for (j, r) in ranges.iter().enumerate() {
            let (cost, taken) = shares[r.clone()].iter().fold((0.0, 0.0), |(c, t), s| {
                (c + s.cost[part], t + s.taken[part])
            });
            let redundancy = 9.0 * r.len() as f64 - taken;
            red[j][part] = redundancy;
            if redundancy > 0.5 && cost > 0.0 && cost.is_finite() {
                w[j] = 0.5 * redundancy;
                target[j] = current[j][part] + (cost / redundancy).ln();
            }
        }
        // `(W + L / s^2) u = W u_hat` with `u >= 0`: stretches that would go below the base
        // density are held at it (an active set, grown until no free stretch is below), and a
        // faint pull to 0 keeps a recording no stretch of which checks the prior at the base.
        let mut held = vec![false; m];
        let (x, diag) = loop {
            let a: Vec<f64> = (0..m)
                .map(|j| {
                    let links = usize::from(j > 0) + usize::from(j + 1 < m);
                    let data = if held[j] { HELD_WEIGHT } else { w[j] };
                    data + links as f64 * step_w + 1e-6
                })
                .collect();
            let c = vec![-step_w; m.saturating_sub(1)];
            let b: Vec<f64> = (0..m)
                .map(|j| if held[j] { 0.0 } else { w[j] * target[j] })
                .collect();
            let (x, diag) = tridiagonal(&a, &c, &b);
            let mut grown = false;
            for j in 0..m {
                if !held[j] && x[j] < 0.0 {
                    held[j] = true;
                    grown = true;
                }
            }
            if !grown {
                break (x, diag);
            }
        };
        for j in 0..m {
            u[j][part] = if held[j] { 0.0 } else { x[j].max(0.0) };
            std[j][part] = diag[j].max(0.0).sqrt();
            if !held[j] {
                effective += w[j] * diag[j];
            }
        }
    }
    Penalised {
        u,
        std,
        red,
        effective,
    }
}

/// One round's penalised estimate: per stretch and part, the log factor, its standard
/// deviation and the stretch's redundancy; and the free factors' effective number.
pub(crate) struct Penalised {
    pub u: Vec<[f64; 2]>,
    pub std: Vec<[f64; 2]>,
    pub red: Vec<[f64; 2]>,
    pub effective: f64,
}

/// The density of `base` with the stretches' log factors `u` on their intervals.
fn density_of(base: &JerkDensity, ranges: &[Range<usize>], u: &[[f64; 2]]) -> JerkDensity {
    let n = ranges.last().map_or(0, |r| r.end);
    let mut factors = vec![[1.0; 2]; n];
    for (r, u) in ranges.iter().zip(u) {
        for f in &mut factors[r.clone()] {
            *f = [u[0].exp(), u[1].exp()];
        }
    }
    JerkDensity::varying(base.base(), factors)
}

/// Laplace log evidence of poses and DVL at `pass`'s result, the DVL reports weighted as in
/// `weighting`, with the `log det Q_k` of its density relative to the base.
fn evidence(fit: &CoSensorFit, pass: &Pass, weighting: &Pass, idx: &[usize]) -> Result<f64> {
    let r = &pass.reweighted.refined;
    let jp = weighting.joint_problem(fit, &r.trajectory, idx)?;
    let free = pass.setup.free.mask();
    let density = r.trajectory.density();
    let relative = density.log_det_relative(r.trajectory.knots().len().saturating_sub(1));
    Ok(joint_log_evidence(jp, &r.trajectory, &r.params, &free, 1.0)? - 0.5 * relative)
}

/// Chooses the density along the recording for the converged `first` pass (see the module
/// documentation); `rerun` refines the calibration again from a trajectory (carrying the new
/// density) and a calibration. Returns the pass kept and what the choice found.
pub(crate) fn choose(
    fit: &CoSensorFit,
    first: Pass,
    idx: &[usize],
    rerun: &mut dyn FnMut(Trajectory, CalibrationParams) -> Result<Pass>,
) -> Result<(Pass, MotionPriorCheck)> {
    let base = first.reweighted.refined.trajectory.density().clone();
    let ranges = stretches(first.reweighted.refined.trajectory.times(), STRETCH_S);
    let mut u = vec![[0.0; 2]; ranges.len()];
    let mut latest: Option<Pass> = None;
    let mut rounds = 0;
    let (std, red, effective) = loop {
        let shares = {
            let pass = latest.as_ref().unwrap_or(&first);
            let r = &pass.reweighted.refined;
            let jp = pass.joint_problem(fit, &r.trajectory, idx)?;
            prior_shares(&jp, r.trajectory.knots(), &r.params)?
        };
        let Penalised {
            u: next,
            std,
            red,
            effective,
        } = penalised(&shares, &ranges, &u);
        let moved = next
            .iter()
            .zip(&u)
            .flat_map(|(a, b)| [(a[0] - b[0]).abs(), (a[1] - b[1]).abs()])
            .fold(0.0, f64::max);
        u = next;
        if moved <= SETTLED_LN || rounds == ROUNDS {
            break (std, red, effective);
        }
        let r = &latest.as_ref().unwrap_or(&first).reweighted.refined;
        let (traj, params) = (
            r.trajectory.with_density(density_of(&base, &ranges, &u)),
            r.params,
        );
        let again = rerun(traj, params)?;
        latest = Some(again.continuing(first.setup.start, first.setup.pose_only.clone()));
        rounds += 1;
    };
    let mut gain = 0.0;
    let applied = match &latest {
        Some(pass) => {
            gain = evidence(fit, pass, &first, idx)? - evidence(fit, &first, &first, idx)?;
            gain > effective + MARGIN
        }
        None => false,
    };
    let times = first.reweighted.refined.trajectory.times();
    let check = MotionPriorCheck {
        stretches: ranges
            .iter()
            .enumerate()
            .map(|(j, r)| Stretch {
                span_s: (times[r.start], times[r.end]),
                intervals: r.clone(),
                factor: [u[j][0].exp(), u[j][1].exp()],
                std_ln: std[j],
                redundancy: red[j],
            })
            .collect(),
        applied,
        rounds,
        evidence_gain: gain,
        effective_parameters: effective,
    };
    let kept = match latest {
        Some(pass) if applied => pass,
        _ => first,
    };
    Ok((kept, check))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretches_cover_every_interval_once() {
        let times: Vec<f64> = (0..=53).map(|k| k as f64 * 0.1).collect();
        let r = stretches(&times, 2.0);
        assert_eq!(r, vec![0..20, 20..40, 40..53]);
        // A remainder under half a stretch joins the last one.
        let times: Vec<f64> = (0..=45).map(|k| k as f64 * 0.1).collect();
        assert_eq!(stretches(&times, 2.0), vec![0..20, 20..45]);
        assert_eq!(stretches(&times[..1], 2.0), Vec::<Range<usize>>::new());
    }

    #[test]
    fn tridiagonal_solve_and_inverse_diagonal_match_dense() {
        let a = [4.0, 5.0, 3.0, 6.0];
        let c = [-1.0, -2.0, -0.5];
        let b = [1.0, 2.0, 3.0, 4.0];
        let (x, diag) = tridiagonal(&a, &c, &b);
        let mut t = nalgebra::Matrix4::<f64>::zeros();
        for i in 0..4 {
            t[(i, i)] = a[i];
            if i < 3 {
                t[(i, i + 1)] = c[i];
                t[(i + 1, i)] = c[i];
            }
        }
        let inv = t.try_inverse().unwrap();
        let xd = inv * nalgebra::Vector4::from_column_slice(&b);
        for i in 0..4 {
            assert!((x[i] - xd[i]).abs() < 1e-12);
            assert!((diag[i] - inv[(i, i)]).abs() < 1e-12);
        }
    }

    /// Shares whose cost over redundancy is `ratio` on every interval of a stretch.
    fn shares(ratios: &[f64], per_stretch: usize, taken: f64) -> Vec<PriorShare> {
        ratios
            .iter()
            .flat_map(|&q| {
                let c = q * (9.0 - taken);
                std::iter::repeat_n(
                    PriorShare {
                        cost: [c, c],
                        taken: [taken, taken],
                    },
                    per_stretch,
                )
            })
            .collect()
    }

    #[test]
    fn a_burst_raises_its_stretch_and_one_barely_checked_stretch_follows_its_neighbours() {
        let ranges: Vec<Range<usize>> = (0..5).map(|j| j * 20..(j + 1) * 20).collect();
        // Well checked: the middle stretch's terms cost ten times their redundancy.
        let s = shares(&[1.0, 1.0, 10.0, 1.0, 1.0], 20, 1.0);
        let Penalised {
            u,
            std,
            red,
            effective: eff,
        } = penalised(&s, &ranges, &[[0.0; 2]; 5]);
        assert!((red[2][0] - 160.0).abs() < 1e-9);
        assert!((u[2][0] - 10f64.ln()).abs() < 0.05, "{:?}", u);
        assert!(u[0][0].abs() < 0.05 && u[4][1].abs() < 0.05, "{:?}", u);
        assert!(std[2][0] < 0.15 && std[2][0] > 0.05, "{:?}", std);
        // Five free factors per part, nearly all determined by their data.
        assert!((eff - 10.0).abs() < 0.5, "{eff}");
        // Barely checked (redundancy 0.2 per interval), the middle stretch's high ratio is
        // pulled well towards its neighbours'.
        let mut s = shares(&[1.0, 1.0, 1.0, 1.0, 1.0], 20, 1.0);
        for x in &mut s[40..60] {
            *x = PriorShare {
                cost: [2.0, 2.0],
                taken: [8.8, 8.8],
            };
        }
        let u = penalised(&s, &ranges, &[[0.0; 2]; 5]).u;
        assert!(u[2][0] < 2.0 && u[2][0] > 0.0, "{:?}", u);
        // Under factors already applied, the same costs give the same stretch estimate.
        let s = shares(&[1.0, 1.0, 1.0, 1.0, 1.0], 20, 1.0);
        let u = penalised(&s, &ranges, &[[0.7; 2]; 5]).u;
        assert!(u.iter().all(|x| (x[0] - 0.7).abs() < 1e-3), "{:?}", u);
    }

    #[test]
    fn a_calm_stretch_stays_at_the_base_density_and_does_not_pull_its_neighbours_down() {
        let ranges: Vec<Range<usize>> = (0..5).map(|j| j * 20..(j + 1) * 20).collect();
        let s = shares(&[1.0, 0.01, 10.0, 0.01, 1.0], 20, 1.0);
        let Penalised {
            u, effective: eff, ..
        } = penalised(&s, &ranges, &[[0.0; 2]; 5]);
        assert_eq!(u[1], [0.0, 0.0]);
        assert_eq!(u[3], [0.0, 0.0]);
        // The burst between them is pulled down by the held neighbours only through the
        // penalty, as by neighbours at the base.
        let free = penalised(
            &shares(&[1.0, 1.0, 10.0, 1.0, 1.0], 20, 1.0),
            &ranges,
            &[[0.0; 2]; 5],
        )
        .u;
        assert!((u[2][0] - free[2][0]).abs() < 0.02, "{:?} {:?}", u, free);
        assert!(u[0][0] < 0.05 && u[4][0] < 0.05);
        // Held stretches are not counted among the free parameters.
        assert!(eff < 6.5, "{eff}");
    }
}
