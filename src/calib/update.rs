//! Calibration update with the trajectory held fixed: Levenberg-Marquardt on rotation, lever arm,
//! scale and clock offset (the offset's derivative comes from the GP's twist rate).

use nalgebra::{Matrix3, SMatrix, SVector};

use super::model::{NPARAM, d_predict_d_params, difference, predict};
use super::offset::DvlObs;
use super::prior::Priors;
use crate::error::Result;
use crate::trajectory::Trajectory;
use crate::types::CalibrationParams;

/// A vector in the parameters' coordinates.
pub type ParamVec = SVector<f64, NPARAM>;
/// A matrix in the parameters' coordinates.
pub type ParamMat = SMatrix<f64, NPARAM, NPARAM>;

/// Which parameters the update may change (`true` = free).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FreeParams {
    pub rotation: bool,
    pub lever_arm: bool,
    pub scale: bool,
    pub time_offset: bool,
}

impl FreeParams {
    pub const ALL: FreeParams = FreeParams {
        rotation: true,
        lever_arm: true,
        scale: true,
        time_offset: true,
    };

    /// Per-parameter flags in the order `[rotation x3, lever arm x3, scale, offset]`.
    pub fn mask(&self) -> [bool; NPARAM] {
        let (r, p, s, t) = (self.rotation, self.lever_arm, self.scale, self.time_offset);
        [r, r, r, p, p, p, s, t]
    }
}

/// Sum of weighted squared DVL residuals at `p`, with the normal equations of the update.
pub struct Linearized {
    pub cost: f64,
    pub hessian: ParamMat,
    pub gradient: ParamVec,
}

/// Samples per unit of work of [`linearize`]. The sums are formed per piece and then over the
/// pieces in order, so they do not depend on the number of threads.
const LINEARIZE_PIECE: usize = 1024;

/// Linearises the DVL term at `p` on the samples `idx` (pieces of samples on all cores).
pub fn linearize(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    p: &CalibrationParams,
) -> Result<Linearized> {
    DvlTerm::new(traj, obs, idx)?.linearize(p)
}

/// The DVL term on a fixed trajectory, with each sample's information matrix formed once for
/// every linearisation (a calibration update linearises at a dozen calibrations).
struct DvlTerm<'a> {
    traj: &'a Trajectory,
    obs: &'a [DvlObs],
    idx: &'a [usize],
    /// Information matrix of `obs[idx[j]]`, at `j`.
    info: Vec<Matrix3<f64>>,
}

impl<'a> DvlTerm<'a> {
    fn new(traj: &'a Trajectory, obs: &'a [DvlObs], idx: &'a [usize]) -> Result<Self> {
        let info = idx
            .iter()
            .map(|&i| obs[i].information())
            .collect::<Result<_>>()?;
        Ok(DvlTerm {
            traj,
            obs,
            idx,
            info,
        })
    }

    /// The cost and normal equations at `p`.
    fn linearize(&self, p: &CalibrationParams) -> Result<Linearized> {
        let pieces = crate::parallel::map_pieces(self.idx.len(), LINEARIZE_PIECE, |r| {
            let mut hessian = ParamMat::zeros();
            let mut gradient = ParamVec::zeros();
            let mut cost = 0.0;
            for j in r {
                let o = &self.obs[self.idx[j]];
                let s = self.traj.motion(o.t + p.time_offset_s)?;
                let r = o.v - predict(p, &s.twist);
                let jac = d_predict_d_params(p, &s.twist, &s.rate);
                let w = &self.info[j];
                let wj = w * jac;
                hessian += jac.transpose() * wj;
                gradient += wj.transpose() * r;
                cost += (r.transpose() * w * r)[0];
            }
            Ok((hessian, gradient, cost))
        });
        let mut out = Linearized {
            cost: 0.0,
            hessian: ParamMat::zeros(),
            gradient: ParamVec::zeros(),
        };
        for piece in pieces {
            let (h, g, c): (ParamMat, ParamVec, f64) = piece?;
            out.hessian += h;
            out.gradient += g;
            out.cost += c;
        }
        Ok(out)
    }
}

/// Outcome of a calibration update.
#[derive(Clone, Debug)]
pub struct UpdateResult {
    pub params: CalibrationParams,
    /// Information matrix of the DVL term at `params` (trajectory held fixed).
    pub hessian: ParamMat,
}

/// Levenberg-Marquardt on the free parameters, trajectory fixed.
#[allow(clippy::too_many_arguments)]
pub fn calibration_update(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    start: &CalibrationParams,
    free: FreeParams,
    priors: &Priors,
    max_iterations: usize,
) -> Result<UpdateResult> {
    let mask = free.mask();
    let mut p = *start;
    let term = DvlTerm::new(traj, obs, idx)?;
    // The DVL term with the priors' factors added.
    let linearize = |p: &CalibrationParams| -> Result<Linearized> {
        let mut lin = term.linearize(p)?;
        if priors.any() {
            let t = priors.terms(p);
            lin.cost += t.cost;
            lin.hessian += t.information;
            lin.gradient += t.gradient;
        }
        Ok(lin)
    };
    let mut lin = linearize(&p)?;
    // Offsets at which every sample's camera time stays inside the trajectory: a step beyond
    // them is too long (rejected like one that raises the cost), never an error.
    let (a, b) = traj.span();
    let (tmin, tmax) = idx
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &i| {
            (lo.min(obs[i].t), hi.max(obs[i].t))
        });
    let allowed = (a - tmin)..=(b - tmax);
    let mut lambda = 1e-4;
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        let mut h = lin.hessian;
        let mut g = lin.gradient;
        pin_fixed(&mut h, &mask);
        for k in 0..NPARAM {
            if !mask[k] {
                g[k] = 0.0;
            }
        }
        // Converged when the undamped step would move no parameter by more than a hundredth
        // of its standard deviation (trials that small only compare rounding noise).
        if let Some(c) = h.cholesky()
            && g.dot(&c.solve(&g)) < crate::trajectory::solver::STEP_DECREMENT
        {
            break;
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut hd = h;
            for k in 0..NPARAM {
                hd[(k, k)] += lambda * h[(k, k)].max(1e-12);
            }
            let Some(d) = hd.cholesky().map(|c| c.solve(&g)) else {
                lambda *= 10.0;
                continue;
            };
            let trial = p.updated(&d);
            if !allowed.contains(&trial.time_offset_s) {
                lambda *= 10.0;
                continue;
            }
            let tl = linearize(&trial)?;
            if tl.cost <= lin.cost {
                let rel = (lin.cost - tl.cost) / lin.cost.max(1e-300);
                let step = d.abs().max();
                p = trial;
                lin = tl;
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                if rel < 1e-10 || step < 1e-10 {
                    return Ok(UpdateResult {
                        params: p,
                        hessian: lin.hessian,
                    });
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Ok(UpdateResult {
        params: p,
        hessian: lin.hessian,
    })
}

/// Largest parameter change between `a` and `b` in units of the standard deviations implied by
/// `hessian` (free parameters only; rotation as the left perturbation of `R_dvl_cam`).
pub fn change_in_std(
    a: &CalibrationParams,
    b: &CalibrationParams,
    hessian: &ParamMat,
    free: &[bool; NPARAM],
) -> f64 {
    let d = difference(b, a);
    let mut h = *hessian;
    pin_fixed(&mut h, free);
    let Some(cov) = h.try_inverse() else {
        return f64::INFINITY;
    };
    (0..NPARAM)
        .filter(|&k| free[k])
        .map(|k| d[k].abs() / cov[(k, k)].max(1e-300).sqrt())
        .fold(0.0, f64::max)
}

/// Decouples the fixed parameters in an information matrix: their rows and columns become those
/// of the identity, so the free block can be solved or inverted on its own.
pub fn pin_fixed(h: &mut ParamMat, free: &[bool; NPARAM]) {
    for k in 0..NPARAM {
        if !free[k] {
            h.row_mut(k).fill(0.0);
            h.column_mut(k).fill(0.0);
            h[(k, k)] = 1.0;
        }
    }
}
