//! Choice of the GP hyperparameters from the data.
//!
//! The power spectral density of jerk `Qc` (one value for the three translational and one for
//! the three rotational components) and, for poses that carry no covariance, the pose noise
//! standard deviations are chosen by maximising the Laplace approximation of the marginal
//! likelihood of the poses:
//!
//! `log p(y) ~= -1/2 cost(x*) - 1/2 log det A(x*) - 1/2 sum_k log det Q_k - 1/2 sum_k log det R_k`
//!
//! where `x*` is the MAP trajectory for the candidate hyperparameters, `A` the Gauss-Newton
//! information matrix there, `Q_k` the prior covariances between knots and `R_k` the pose
//! covariances (the first knot has a flat prior, a constant that does not depend on the
//! hyperparameters). The search (Nelder-Mead in log space) runs on a few windows of consecutive
//! knots spread over the data, so its cost does not grow with the length of the recording.

use nalgebra::Vector6;

use super::blocktri::BlockTridiagonal;
use super::density::JerkDensity;
use super::factors::PoseFactors;
use super::gp::Knot;
use super::solver::{
    GaussNewtonOptions, Problem, STEP_DECREMENT, gauss_newton, initial_knots,
    measurement_information, step,
};
use crate::error::Result;
use crate::lie::so3;
use crate::types::PoseMeasurement;

/// Search bounds of the jerk power spectral density.
pub const Q_MIN: f64 = 1e-10;
pub const Q_MAX: f64 = 1e6;
/// Search bounds of the pose noise standard deviations (m or rad).
pub const SIGMA_MIN: f64 = 1e-7;
pub const SIGMA_MAX: f64 = 1.0;

/// Hyperparameters used by a fit.
#[derive(Clone, Debug)]
pub struct Hyper {
    pub qc: Vector6<f64>,
    pub pose_sigma: (f64, f64),
    pub qc_estimated: bool,
    pub pose_sigma_estimated: bool,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Robust pose-noise estimate from third differences of positions and second differences of
/// incremental rotations (white noise of standard deviation s gives third differences of
/// standard deviation sqrt(20) s; smooth motion contributes little at camera rates).
pub fn noise_from_differences(poses: &[PoseMeasurement]) -> (f64, f64) {
    let mut dp = Vec::new();
    for w in poses.windows(4) {
        let d = w[3].pose.trans - w[2].pose.trans * 3.0 + w[1].pose.trans * 3.0 - w[0].pose.trans;
        dp.extend(d.iter().map(|x| x.abs()));
    }
    let incr: Vec<_> = poses
        .windows(2)
        .map(|w| so3::log(&(w[0].pose.rot.transpose() * w[1].pose.rot)))
        .collect();
    let mut dr = Vec::new();
    for w in incr.windows(3) {
        let d = w[2] - w[1] * 2.0 + w[0];
        dr.extend(d.iter().map(|x| x.abs()));
    }
    let k = 1.0 / (0.6745 * 20f64.sqrt());
    ((median(dp) * k).max(1e-6), (median(dr) * k).max(1e-6))
}

/// Windows `[start, end)` of knots used for the search.
fn windows(n: usize, budget: usize) -> Vec<(usize, usize)> {
    let budget = budget.max(20);
    if n <= budget {
        return vec![(0, n)];
    }
    let count = 4;
    let len = (budget / count).max(20);
    (0..count)
        .map(|i| {
            let start = (n - len) * i / (count - 1);
            (start, start + len)
        })
        .collect()
}

struct Window<'a> {
    poses: &'a [PoseMeasurement],
    times: Vec<f64>,
    /// The window's poses as factors (their information set for each candidate).
    factors: PoseFactors,
    knots: Vec<Knot>,
    converged_once: bool,
    /// The storage of the window's last system (the first fit's, then each candidate's),
    /// assembled into again: assembly writes every block.
    spare: Option<BlockTridiagonal>,
}

/// Parameters searched: `[ln q_trans, ln q_rot]` and, when estimated, `[ln s_pos, ln s_rot]`.
fn unpack(p: &[f64], fixed_sigma: Option<(f64, f64)>) -> (Vector6<f64>, (f64, f64)) {
    let (qt, qr) = (p[0].exp(), p[1].exp());
    let qc = Vector6::new(qt, qt, qt, qr, qr, qr);
    let sigma = fixed_sigma.unwrap_or_else(|| (p[2].exp(), p[3].exp()));
    (qc, sigma)
}

/// Log marginal likelihood (Laplace approximation) of one window, up to a constant.
///
/// The window's knots are the MAP of the previous candidate, which lies close to this
/// candidate's MAP; one Gauss-Newton step reaches it, and the cost there is the minimum of the
/// quadratic model, `cost - rhs^T A^-1 rhs` (exact for a linear problem).
fn window_log_likelihood(w: &mut Window, qc: &Vector6<f64>, sigma: (f64, f64)) -> Result<f64> {
    w.factors
        .set_information(measurement_information(w.poses, sigma)?);
    let density = JerkDensity::constant(*qc);
    let problem = Problem {
        times: &w.times,
        cosensor: &w.factors,
        density: &density,
    };
    if !w.converged_once {
        let opts = GaussNewtonOptions {
            max_iterations: 5,
            stop_decrement: STEP_DECREMENT,
            factor: false,
            storage: w.spare.take(),
        };
        let solved = gauss_newton(&problem, w.knots.clone(), opts)?;
        w.knots = solved.knots;
        w.spare = solved.spare;
        w.converged_once = true;
    }
    let n_knots = w.knots.len();
    let mut sys = w
        .spare
        .take()
        .filter(|s| s.len() == n_knots)
        .unwrap_or_else(|| BlockTridiagonal::zeros(n_knots));
    let cost = problem.assemble_into(&w.knots, &mut sys);
    let rhs = sys.rhs.clone();
    let factor = sys.factor()?;
    let dx = factor.solve();
    let decrease: f64 = dx.iter().zip(&rhs).map(|(d, r)| d.dot(r)).sum();
    let n = w.times.len() as f64;
    let log_det_q = (n - 1.0) * 3.0 * qc.iter().map(|q| q.ln()).sum::<f64>();
    let log_det_r: f64 = w
        .factors
        .information()
        .iter()
        .map(|i| -i.determinant().max(1e-300).ln())
        .sum();
    let ll = -0.5 * ((cost - decrease) + factor.log_det() + log_det_q + log_det_r);
    w.spare = Some(factor.into_system());
    w.knots = step(&w.knots, &dx, 1.0);
    Ok(ll)
}

/// Minimises `f` by Nelder-Mead from `x0` with initial steps `step`.
fn nelder_mead(
    f: &mut dyn FnMut(&[f64]) -> f64,
    x0: &[f64],
    step: f64,
    max_evals: usize,
    x_tol: f64,
) -> Vec<f64> {
    let d = x0.len();
    let mut pts: Vec<Vec<f64>> = vec![x0.to_vec()];
    for i in 0..d {
        let mut p = x0.to_vec();
        p[i] += step;
        pts.push(p);
    }
    let mut vals: Vec<f64> = pts.iter().map(|p| f(p)).collect();
    let mut evals = d + 1;
    while evals < max_evals {
        let mut idx: Vec<usize> = (0..=d).collect();
        idx.sort_by(|&a, &b| vals[a].total_cmp(&vals[b]));
        pts = idx.iter().map(|&i| pts[i].clone()).collect();
        vals = idx.iter().map(|&i| vals[i]).collect();
        let size = pts[1..]
            .iter()
            .map(|p| {
                p.iter()
                    .zip(&pts[0])
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        if size < x_tol {
            break;
        }
        let centroid: Vec<f64> = (0..d)
            .map(|j| pts[..d].iter().map(|p| p[j]).sum::<f64>() / d as f64)
            .collect();
        let along = |t: f64| -> Vec<f64> {
            centroid
                .iter()
                .zip(&pts[d])
                .map(|(c, w)| c + t * (c - w))
                .collect()
        };
        let xr = along(1.0);
        let fr = f(&xr);
        evals += 1;
        if fr < vals[0] {
            let xe = along(2.0);
            let fe = f(&xe);
            evals += 1;
            if fe < fr {
                pts[d] = xe;
                vals[d] = fe;
            } else {
                pts[d] = xr;
                vals[d] = fr;
            }
        } else if fr < vals[d - 1] {
            pts[d] = xr;
            vals[d] = fr;
        } else {
            let xc = if fr < vals[d] {
                along(0.5)
            } else {
                along(-0.5)
            };
            let fc = f(&xc);
            evals += 1;
            if fc < vals[d].min(fr) {
                pts[d] = xc;
                vals[d] = fc;
            } else {
                for i in 1..=d {
                    let p: Vec<f64> = pts[i]
                        .iter()
                        .zip(&pts[0])
                        .map(|(a, b)| b + 0.5 * (a - b))
                        .collect();
                    vals[i] = f(&p);
                    pts[i] = p;
                    evals += 1;
                }
            }
        }
    }
    let best = (0..=d)
        .min_by(|&a, &b| vals[a].total_cmp(&vals[b]))
        .unwrap_or(0);
    pts[best].clone()
}

/// Hyperparameters for a fit: the user's `qc` and `pose_sigma` where given, estimated otherwise
/// on windows of at most `window_knots` knots in all.
pub fn choose(
    poses: &[PoseMeasurement],
    qc: Option<Vector6<f64>>,
    pose_sigma: Option<(f64, f64)>,
    window_knots: usize,
) -> Result<Hyper> {
    let all_have_cov = poses.iter().all(|p| p.cov.is_some());
    let sigma_known = pose_sigma.or(all_have_cov.then_some((1.0, 1.0)));
    if let Some(qc) = qc {
        let (sigma, est) = match sigma_known {
            Some(s) => (s, false),
            None => (noise_from_differences(poses), true),
        };
        return Ok(Hyper {
            qc,
            pose_sigma: sigma,
            qc_estimated: false,
            pose_sigma_estimated: est,
        });
    }
    let mut wins: Vec<Window> = windows(poses.len(), window_knots)
        .into_iter()
        .map(|(a, b)| {
            let ps = &poses[a..b];
            Window {
                poses: ps,
                times: ps.iter().map(|p| p.t).collect(),
                factors: PoseFactors::new(ps.iter().map(|p| p.pose).collect(), Vec::new()),
                knots: initial_knots(ps),
                converged_once: false,
                spare: None,
            }
        })
        .collect();
    let (s0p, s0r) = noise_from_differences(poses);
    let dt = (poses[poses.len() - 1].t - poses[0].t) / (poses.len() - 1) as f64;
    // Start from the jerk the differences suggest; the search moves in decades.
    let q0 = |s: f64| {
        (s * s * 20.0 / dt.powi(5))
            .clamp(Q_MIN * 10.0, Q_MAX / 10.0)
            .ln()
    };
    let mut x0 = vec![q0(s0p), q0(s0r)];
    if sigma_known.is_none() {
        x0.extend([
            s0p.clamp(SIGMA_MIN * 10.0, 0.1).ln(),
            s0r.clamp(SIGMA_MIN * 10.0, 0.1).ln(),
        ]);
    }
    let mut first_error = None;
    let mut objective = |p: &[f64]| -> f64 {
        // Bounds keep the search away from degenerate weights: a jerk density below 1e-10 (or a
        // pose noise below 1e-7) would make the normal equations numerically singular, and a
        // motion that smooth is indistinguishable from one at the bound.
        let q_ok = p[..2].iter().all(|v| (Q_MIN.ln()..=Q_MAX.ln()).contains(v));
        let s_ok = p[2..]
            .iter()
            .all(|v| (SIGMA_MIN.ln()..=SIGMA_MAX.ln()).contains(v));
        if !(q_ok && s_ok) {
            return f64::INFINITY;
        }
        let (qc, sigma) = unpack(p, sigma_known);
        // The windows on all cores, their terms summed in order (the same on any core count).
        let mut slots: Vec<(&mut Window, Option<Result<f64>>)> =
            wins.iter_mut().map(|w| (w, None)).collect();
        crate::parallel::for_each(&mut slots, |(w, ll)| {
            *ll = Some(window_log_likelihood(w, &qc, sigma));
        });
        let mut total = 0.0;
        for (_, ll) in slots {
            match ll.unwrap_or(Ok(f64::NAN)) {
                Ok(ll) if ll.is_finite() => total -= ll,
                Ok(_) => return f64::INFINITY,
                Err(e) => {
                    first_error.get_or_insert(e);
                    return f64::INFINITY;
                }
            }
        }
        total
    };
    // A tenth of a decade is finer than the likelihood can resolve Qc.
    let best = nelder_mead(&mut objective, &x0, 2.0, 80, 0.1);
    let best_value = objective(&best);
    if !best_value.is_finite() {
        return Err(first_error.unwrap_or_else(|| {
            crate::error::Error::Numerical("marginal likelihood search found no usable Qc".into())
        }));
    }
    let (qc, sigma) = unpack(&best, sigma_known);
    Ok(Hyper {
        qc,
        pose_sigma: sigma,
        qc_estimated: true,
        pose_sigma_estimated: sigma_known.is_none(),
    })
}
