//! The Gauss-Newton solver of trajectory problems, and the seam the calibration plugs into.
//!
//! A trajectory problem has one 18-dimensional state per knot (pose perturbation, twist, twist
//! rate), and its normal equations are block tridiagonal: every factor involves one knot or two
//! consecutive knots. [`NormalEquations`] is the interface: anything that can linearise its cost
//! at a set of knots into a [`BlockTridiagonal`] system can be solved by [`gauss_newton`].
//!
//! - [`Problem`] is the pose-only fit: one pose factor per knot and the GP prior between knots.
//!   `Trajectory::fit` and the hyperparameter search solve it.
//! - The calibration's joint problem (`calib::state`) adds the DVL velocity factors to the same
//!   system by implementing [`NormalEquations`] with [`Problem`]'s blocks plus its own; it
//!   assembles in the same chunks ([`assembly_chunks`]) so that sums never depend on the
//!   number of threads.
//!
//! Steps are applied with [`step`]: poses are perturbed on the right (`T <- T exp(d)`), twists
//! and rates additively.

use nalgebra::{Matrix6, Vector6};

use super::blocktri::{BlockTridiagonal, Factored, M18, V18};
use super::gp::{
    Knot, LocalState, PriorNormal, apply_scalar, first_local_state, kron_diag_mul, local_gamma,
    phi_scalar, prior_factor, prior_gradient, prior_normal, q_scalar_inv,
};
use crate::error::{Error, Result};
use crate::lie::{Se3, se3_right_jacobian_inv};
use crate::types::PoseMeasurement;

/// Information matrices of the pose measurements.
pub(crate) fn measurement_information(
    poses: &[PoseMeasurement],
    sigma: (f64, f64),
) -> Result<Vec<Matrix6<f64>>> {
    let default = Matrix6::from_diagonal(&Vector6::new(
        sigma.0.powi(-2),
        sigma.0.powi(-2),
        sigma.0.powi(-2),
        sigma.1.powi(-2),
        sigma.1.powi(-2),
        sigma.1.powi(-2),
    ));
    poses
        .iter()
        .enumerate()
        .map(|(i, p)| match &p.cov {
            None => Ok(default),
            Some(c) => c
                .try_inverse()
                .filter(|w| w.iter().all(|v| v.is_finite()))
                .ok_or_else(|| {
                    Error::Input(format!(
                        "pose {} (t = {}): covariance is not invertible",
                        i + 1,
                        p.t
                    ))
                }),
        })
        .collect()
}

/// Knots initialised from the measurements: poses as measured, twists from central differences.
pub(crate) fn initial_knots(poses: &[PoseMeasurement]) -> Vec<Knot> {
    let n = poses.len();
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            let twist = (poses[a].pose.inverse() * poses[b].pose).log() / (poses[b].t - poses[a].t);
            Knot {
                pose: poses[k].pose,
                twist,
                rate: Vector6::zeros(),
            }
        })
        .collect()
}

/// The Gauss-Newton problem of a pose-only fit.
pub(crate) struct Problem<'a> {
    pub times: &'a [f64],
    pub meas: &'a [Se3],
    pub info: &'a [Matrix6<f64>],
    pub qc_inv: Vector6<f64>,
}

/// Knots per unit of work of the parallel assembly. The cost is summed per chunk and then over
/// chunks in order, so the result does not depend on the number of threads.
pub(crate) const ASSEMBLY_CHUNK: usize = 256;

/// The blocks of the normal equations of the knots `first..first + diag.len()` (and the upper
/// blocks between them and the next knot), with the cost of the terms the chunk owns.
pub(crate) struct AssemblyChunk<'s> {
    pub first: usize,
    pub diag: &'s mut [M18],
    pub upper: &'s mut [M18],
    pub rhs: &'s mut [V18],
    pub cost: f64,
}

/// `sys` cut into chunks of [`ASSEMBLY_CHUNK`] knots.
pub(crate) fn assembly_chunks(sys: &mut BlockTridiagonal) -> Vec<AssemblyChunk<'_>> {
    let n = sys.len();
    let mut chunks = Vec::with_capacity(n.div_ceil(ASSEMBLY_CHUNK));
    let (mut diag, mut upper, mut rhs) = (&mut sys.diag[..], &mut sys.upper[..], &mut sys.rhs[..]);
    let mut first = 0;
    while first < n {
        let len = ASSEMBLY_CHUNK.min(n - first);
        let (d, d_rest) = std::mem::take(&mut diag).split_at_mut(len);
        let (u, u_rest) = std::mem::take(&mut upper).split_at_mut(len.min(n - 1 - first));
        let (r, r_rest) = std::mem::take(&mut rhs).split_at_mut(len);
        (diag, upper, rhs) = (d_rest, u_rest, r_rest);
        chunks.push(AssemblyChunk {
            first,
            diag: d,
            upper: u,
            rhs: r,
            cost: 0.0,
        });
        first += len;
    }
    chunks
}

impl Problem<'_> {
    /// Normal equations linearised at `knots`, and the cost there.
    pub fn assemble(&self, knots: &[Knot]) -> (BlockTridiagonal, f64) {
        let mut sys = BlockTridiagonal::zeros(knots.len());
        let cost = self.assemble_into(knots, &mut sys);
        (sys, cost)
    }

    /// As [`Problem::assemble`], overwriting every block of `sys` (which must have `knots.len()`
    /// blocks). Chunks of knots are assembled on all available cores.
    pub fn assemble_into(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> f64 {
        assert_eq!(
            sys.len(),
            knots.len(),
            "system size does not match the knots"
        );
        let mut chunks = assembly_chunks(sys);
        crate::parallel::for_each(&mut chunks, |c| self.assemble_chunk(knots, c));
        chunks.iter().map(|c| c.cost).sum()
    }

    /// The cost at `knots` without the normal equations: the same terms, summed in the same
    /// order as by [`Problem::assemble_into`], so the two agree to the last bit.
    pub fn cost(&self, knots: &[Knot]) -> f64 {
        let n = knots.len();
        crate::parallel::map_pieces(n, ASSEMBLY_CHUNK, |r| {
            let mut cost = 0.0;
            for k in r {
                cost += self.pose_cost(knots, k);
                if k + 1 < n {
                    cost += self.prior_cost(knots, k).0;
                }
            }
            cost
        })
        .into_iter()
        .sum()
    }

    /// The right-hand side of the normal equations at `knots` alone (the same sums, in the same
    /// order, as [`Problem::assemble_into`] forms), and the cost.
    pub fn gradient_into(&self, knots: &[Knot], rhs: &mut [V18]) -> f64 {
        let n = knots.len();
        assert_eq!(
            rhs.len(),
            n,
            "right-hand side size does not match the knots"
        );
        let mut chunks: Vec<(usize, &mut [V18], f64)> = rhs
            .chunks_mut(ASSEMBLY_CHUNK)
            .enumerate()
            .map(|(c, r)| (c * ASSEMBLY_CHUNK, r, 0.0))
            .collect();
        crate::parallel::for_each(&mut chunks, |(first, rhs, cost)| {
            let first = *first;
            let len = rhs.len();
            let prior = |k: usize| {
                let dt = self.times[k + 1] - self.times[k];
                prior_gradient(
                    &prior_factor(&knots[k], &knots[k + 1], dt),
                    &q_scalar_inv(dt),
                    &self.qc_inv,
                )
            };
            let mut pose_cost = self.pose_rhs(knots, first, &mut rhs[0]);
            if first > 0 {
                rhs[0] += prior(first - 1).1;
            }
            *cost = 0.0;
            for i in 0..len {
                let k = first + i;
                *cost += pose_cost;
                if i + 1 < len {
                    pose_cost = self.pose_rhs(knots, k + 1, &mut rhs[i + 1]);
                }
                if k + 1 < n {
                    let (r1, r2, c) = prior(k);
                    rhs[i] += r1;
                    *cost += c;
                    if i + 1 < len {
                        rhs[i + 1] += r2;
                    }
                }
            }
        });
        chunks.iter().map(|c| c.2).sum()
    }

    /// Overwrites `rhs` with the pose term's right-hand side of knot `k` (as
    /// [`Problem::pose_terms`] forms it); returns its cost.
    fn pose_rhs(&self, knots: &[Knot], k: usize, rhs: &mut V18) -> f64 {
        *rhs = V18::zeros();
        let e = (self.meas[k].inverse() * knots[k].pose).log();
        let j = se3_right_jacobian_inv(&e);
        let wj = self.info[k] * j;
        rhs.fixed_rows_mut::<6>(0).copy_from(&-(wj.transpose() * e));
        (e.transpose() * self.info[k] * e)[0]
    }

    /// Fills one chunk: for each knot the pose term, then the prior terms of the intervals
    /// before and after it (the interval before the chunk is recomputed here). Each prior term
    /// is added to both of its knots as soon as it is formed (the next knot's pose term is
    /// written first), so no term is kept or copied from one knot to the next.
    fn assemble_chunk(&self, knots: &[Knot], chunk: &mut AssemblyChunk) {
        let n = knots.len();
        let len = chunk.diag.len();
        let (first, diag, rhs, upper) = (
            chunk.first,
            &mut *chunk.diag,
            &mut *chunk.rhs,
            &mut *chunk.upper,
        );
        let mut pose_cost = self.pose_terms(knots, first, &mut diag[0], &mut rhs[0]);
        if first > 0 {
            let t = self.prior_terms(knots, first - 1).0;
            diag[0] += t.d2;
            rhs[0] += t.r2;
        }
        chunk.cost = 0.0;
        for i in 0..len {
            let k = first + i;
            chunk.cost += pose_cost;
            if i + 1 < len {
                pose_cost = self.pose_terms(knots, k + 1, &mut diag[i + 1], &mut rhs[i + 1]);
            }
            if k + 1 < n {
                let t = self.prior_terms(knots, k).0;
                diag[i] += t.d1;
                rhs[i] += t.r1;
                upper[i] = t.upper;
                chunk.cost += t.cost;
                if i + 1 < len {
                    diag[i + 1] += t.d2;
                    rhs[i + 1] += t.r2;
                }
            }
        }
    }

    /// Overwrites `diag` and `rhs` with the pose term of knot `k`; returns its cost.
    pub(crate) fn pose_terms(
        &self,
        knots: &[Knot],
        k: usize,
        diag: &mut M18,
        rhs: &mut V18,
    ) -> f64 {
        *diag = M18::zeros();
        *rhs = V18::zeros();
        let e = (self.meas[k].inverse() * knots[k].pose).log();
        let j = se3_right_jacobian_inv(&e);
        let wj = self.info[k] * j;
        diag.fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&(j.transpose() * wj));
        rhs.fixed_rows_mut::<6>(0).copy_from(&-(wj.transpose() * e));
        (e.transpose() * self.info[k] * e)[0]
    }

    /// The cost of the pose term of knot `k` (as [`Problem::pose_terms`] returns it).
    pub(crate) fn pose_cost(&self, knots: &[Knot], k: usize) -> f64 {
        let e = (self.meas[k].inverse() * knots[k].pose).log();
        (e.transpose() * self.info[k] * e)[0]
    }

    /// The normal-equation blocks of the prior factor between knots `k` and `k + 1`, and the
    /// local state of knot `k + 1` relative to knot `k` with its Jacobians.
    pub(crate) fn prior_terms(&self, knots: &[Knot], k: usize) -> (PriorNormal, LocalState) {
        let dt = self.times[k + 1] - self.times[k];
        let f = prior_factor(&knots[k], &knots[k + 1], dt);
        let normal = prior_normal(&f, &q_scalar_inv(dt), &self.qc_inv);
        (normal, f.local)
    }

    /// The cost of the prior factor between knots `k` and `k + 1` (as
    /// [`Problem::prior_terms`] gives it), and the local state `gamma_2` of knot `k + 1`.
    pub(crate) fn prior_cost(&self, knots: &[Knot], k: usize) -> (f64, V18) {
        let dt = self.times[k + 1] - self.times[k];
        let (k1, k2) = (&knots[k], &knots[k + 1]);
        let gamma = local_gamma(k1, k2);
        let e = gamma - apply_scalar(&phi_scalar(dt), &first_local_state(k1));
        let we = kron_diag_mul(&q_scalar_inv(dt), &self.qc_inv, &e);
        (e.dot(&we), gamma)
    }
}

/// Knots per unit of work when a step is applied.
const STEP_CHUNK: usize = 2048;

/// Applies a step to the knots (on all cores; each knot on its own, so the result does not
/// depend on the number of threads).
pub(crate) fn step(knots: &[Knot], dx: &[V18], scale: f64) -> Vec<Knot> {
    crate::parallel::map_indices(knots.len().min(dx.len()), STEP_CHUNK, |i| {
        let (k, d) = (&knots[i], &dx[i]);
        Knot {
            pose: k.pose.retract(&(d.fixed_rows::<6>(0) * scale).into_owned()),
            twist: k.twist + d.fixed_rows::<6>(6) * scale,
            rate: k.rate + d.fixed_rows::<6>(12) * scale,
        }
    })
}

/// Result of a Gauss-Newton run.
pub(crate) struct Solved {
    pub knots: Vec<Knot>,
    pub iterations: usize,
    pub converged: bool,
    pub cost: f64,
    /// Factorisation of the information matrix at the final knots, when asked for.
    pub factor: Option<Factored>,
    /// Storage of a system of the problem's size that the run no longer needs (for the next
    /// run); `None` when it holds the factorisation.
    pub spare: Option<BlockTridiagonal>,
}

/// Something that linearises a trajectory cost: the pose-only fit, or the fit with further
/// factors (the calibration adds DVL velocities).
pub(crate) trait NormalEquations {
    /// Overwrites every block of `sys` (sized for `knots`) with the normal equations linearised
    /// at `knots` and returns the cost there.
    fn normal_equations(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> Result<f64>;

    /// The cost at `knots` alone, equal to what [`NormalEquations::normal_equations`] returns.
    fn cost(&self, knots: &[Knot]) -> Result<f64>;

    /// The right-hand side alone into `rhs` (sized for `knots`) and the cost, equal to what
    /// [`NormalEquations::normal_equations`] forms; `None` when the problem does not provide it
    /// (the solver then forms the whole system).
    fn gradient(&self, _knots: &[Knot], _rhs: &mut [V18]) -> Result<Option<f64>> {
        Ok(None)
    }
}

impl NormalEquations for Problem<'_> {
    fn normal_equations(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> Result<f64> {
        Ok(self.assemble_into(knots, sys))
    }

    fn cost(&self, knots: &[Knot]) -> Result<f64> {
        Ok(Problem::cost(self, knots))
    }

    fn gradient(&self, knots: &[Knot], rhs: &mut [V18]) -> Result<Option<f64>> {
        Ok(Some(self.gradient_into(knots, rhs)))
    }
}

/// How a Gauss-Newton run ends and what storage it may use.
pub(crate) struct GaussNewtonOptions {
    pub max_iterations: usize,
    /// Factorise the information matrix at the solution (for the log-determinant or the
    /// covariance). Without it the last step is checked with the cost alone.
    pub factor: bool,
    /// Storage for the system (any contents; sized for the knots or it is not used).
    pub storage: Option<BlockTridiagonal>,
}

/// A Gauss-Newton run stops when the step's squared length in the metric of the information
/// matrix ([`crate::trajectory::blocktri::Factored::decrement`]) is below this: the step moves
/// no quantity by more than 0.01 of its standard deviation. (The pose-only fit of 3 h of poses
/// at 10 Hz reaches 4e-5 after two steps, where its cost changes by 1e-10 relative; the
/// sum grows with the number of knots while each knot's share of the step shrinks.)
pub(crate) const STEP_DECREMENT: f64 = 1e-4;

/// Below this decrement a Gauss-Newton run that delivers a factorisation checks the end of its
/// next step with the right-hand side alone ([`check_by_gradient`]). The pose-only fit converges
/// about quadratically (3 h of poses at 10 Hz: decrements 3e7, 2e2, 2e-5), so from a few hundred
/// the next point is usually the solution; when it is not, one right-hand side (about half an
/// assembly) was formed in vain.
const CHECK_BY_GRADIENT_BELOW: f64 = 1e3;

/// The outcome of [`check_by_gradient`].
enum Checked {
    /// The step's end (its knots and cost) is the solution; the factor is the one it came from.
    Converged(Vec<Knot>, f64, Factored),
    /// Not shown to be: the factor, for the ordinary step.
    NotYet(Factored),
}

/// Takes the full step `dx` from `knots` (at `cost`, factorised in `factor`) and forms only the
/// right-hand side at its end; converged when the cost did not rise and the decrement there,
/// `g^T A^-1 g` with `A` this factorisation, is below [`STEP_DECREMENT`]. The information matrix
/// of a point one short step away differs from the end's by the step's size relative to the
/// variables' spread, so the decrement is measured to that accuracy and the factor serves as the
/// end's covariance.
fn check_by_gradient(
    problem: &dyn NormalEquations,
    knots: &[Knot],
    dx: &[V18],
    cost: f64,
    factor: Factored,
) -> Result<Checked> {
    let trial = step(knots, dx, 1.0);
    let mut rhs = vec![V18::zeros(); trial.len()];
    let Some(tcost) = problem.gradient(&trial, &mut rhs)? else {
        return Ok(Checked::NotYet(factor));
    };
    if !(tcost.is_finite() && tcost <= cost * (1.0 + 1e-12) + 1e-300) {
        return Ok(Checked::NotYet(factor));
    }
    let (decrement, _) = factor.quadratic_forms(&rhs);
    Ok(if decrement[(0, 0)] < STEP_DECREMENT {
        Checked::Converged(trial, tcost, factor)
    } else {
        Checked::NotYet(factor)
    })
}

/// Gauss-Newton with step halving; returns the factorisation at the solution when asked for.
pub(crate) fn gauss_newton(
    problem: &dyn NormalEquations,
    mut knots: Vec<Knot>,
    opts: GaussNewtonOptions,
) -> Result<Solved> {
    let n = knots.len();
    let mut sys = opts
        .storage
        .filter(|s| s.len() == n)
        .unwrap_or_else(|| BlockTridiagonal::zeros(n));
    let mut cost = problem.normal_equations(&knots, &mut sys)?;
    let mut iterations = 0;
    let mut converged = false;
    loop {
        if !opts.factor && (converged || iterations >= opts.max_iterations) {
            return Ok(Solved {
                knots,
                iterations,
                converged,
                cost,
                factor: None,
                spare: Some(sys),
            });
        }
        let factor = sys.factor()?;
        // A step that would move every quantity by less than a hundredth of its posterior
        // standard deviation is not worth taking, nor the system at its end worth forming: the
        // current point is the solution, and this factorisation the one at it.
        converged = converged || factor.decrement() < STEP_DECREMENT;
        if converged || iterations >= opts.max_iterations {
            let (factor, spare) = if opts.factor {
                (Some(factor), None)
            } else {
                (None, Some(factor.into_system()))
            };
            return Ok(Solved {
                knots,
                iterations,
                converged,
                cost,
                factor,
                spare,
            });
        }
        let dx = factor.solve();
        // Close to the solution, the full step's end is checked with its right-hand side alone,
        // in the metric of this factorisation: when that decrement is below the threshold, the
        // end point is the solution and this factor (one short step away) serves as its
        // information matrix, which saves forming and factorising the system once more.
        let factor = if opts.factor && factor.decrement() < CHECK_BY_GRADIENT_BELOW {
            match check_by_gradient(problem, &knots, &dx, cost, factor)? {
                Checked::Converged(trial, tcost, factor) => {
                    return Ok(Solved {
                        knots: trial,
                        iterations: iterations + 1,
                        converged: true,
                        cost: tcost,
                        factor: Some(factor),
                        spare: None,
                    });
                }
                Checked::NotYet(factor) => factor,
            }
        } else {
            factor
        };
        // The factor is not needed once the step is known: trial systems are assembled into its
        // storage, so a run holds one system however many steps it takes.
        sys = factor.into_system();
        // Without a factorisation to deliver, the last step needs the cost at the trial points
        // only, not their normal equations.
        let last = !opts.factor && iterations + 1 >= opts.max_iterations;
        let mut scale = 1.0;
        let mut accepted = None;
        for _ in 0..12 {
            let trial = step(&knots, &dx, scale);
            let tcost = if last {
                problem.cost(&trial)?
            } else {
                problem.normal_equations(&trial, &mut sys)?
            };
            if tcost.is_finite() && tcost <= cost * (1.0 + 1e-12) + 1e-300 {
                accepted = Some((trial, tcost));
                break;
            }
            scale *= 0.5;
        }
        iterations += 1;
        let max_step = dx.iter().map(|d| d.abs().max()).fold(0.0, f64::max) * scale;
        match accepted {
            Some((trial, tcost)) => {
                let rel = (cost - tcost).abs() / cost.max(1e-300);
                knots = trial;
                cost = tcost;
                // The pose-only problem is nearly linear: once a full step changes the cost by
                // less than a part in 1e9, the next step is far below the posterior spread.
                converged = max_step < 1e-9 || (scale == 1.0 && rel < 1e-9);
            }
            None => {
                // No decrease along the step: the current point is as good as we can do.
                if !last {
                    problem.normal_equations(&knots, &mut sys)?;
                }
                converged = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Noisy poses along a smooth motion, 0.1 s apart, with their information matrices.
    fn poses(n: usize) -> (Vec<f64>, Vec<Se3>, Vec<Matrix6<f64>>) {
        let mut pose = Se3::exp(&Vector6::new(0.1, -0.2, 0.3, 0.2, 0.1, -0.3));
        let (mut times, mut meas) = (Vec::new(), Vec::new());
        for k in 0..n {
            let t = 0.1 * k as f64;
            let twist = Vector6::new(
                0.3 * t.sin(),
                0.2,
                -0.1 * t.cos(),
                0.4 * (0.7 * t).cos(),
                0.1,
                0.2,
            );
            // A deterministic wobble of a few millimetres and milliradians as the noise.
            let noise = Vector6::from_fn(|i, _| 3e-3 * ((k * 7 + i * 13) as f64).sin());
            times.push(t);
            meas.push(pose * Se3::exp(&noise));
            pose = pose * Se3::exp(&(twist * 0.1));
        }
        let info = vec![Matrix6::from_diagonal(&Vector6::new(1e5, 1e5, 1e5, 3e5, 3e5, 3e5)); n];
        (times, meas, info)
    }

    #[test]
    fn right_hand_side_alone_is_the_assemblys_to_the_bit() {
        let n = 2 * ASSEMBLY_CHUNK + 37;
        let (times, meas, info) = poses(n);
        let problem = Problem {
            times: &times,
            meas: &meas,
            info: &info,
            qc_inv: Vector6::repeat(50.0),
        };
        let mut knots = initial_knots(
            &times
                .iter()
                .zip(&meas)
                .map(|(&t, &pose)| PoseMeasurement { t, pose, cov: None })
                .collect::<Vec<_>>(),
        );
        knots[5].rate = Vector6::new(0.1, -0.2, 0.3, 0.0, 0.5, -0.1);
        let (sys, cost) = problem.assemble(&knots);
        let mut rhs = vec![V18::repeat(f64::NAN); n];
        let gcost = problem.gradient_into(&knots, &mut rhs);
        assert_eq!(gcost, cost);
        for (k, (a, b)) in rhs.iter().zip(&sys.rhs).enumerate() {
            assert_eq!(a, b, "knot {k}");
        }
    }

    #[test]
    fn solution_checked_by_its_gradient_is_the_map_with_its_information() {
        // The fit stops on the right-hand side at the step's end and hands back the previous
        // factorisation: the point must be the solution to the stop rule's accuracy when
        // checked with its own system, and the covariance that of its own system to well under
        // a percent.
        let n = 2 * ASSEMBLY_CHUNK + 37;
        let (times, meas, info) = poses(n);
        let problem = Problem {
            times: &times,
            meas: &meas,
            info: &info,
            qc_inv: Vector6::repeat(50.0),
        };
        let start = initial_knots(
            &times
                .iter()
                .zip(&meas)
                .map(|(&t, &pose)| PoseMeasurement { t, pose, cov: None })
                .collect::<Vec<_>>(),
        );
        let opts = GaussNewtonOptions {
            max_iterations: 30,
            factor: true,
            storage: None,
        };
        let solved = gauss_newton(&problem, start, opts).unwrap();
        assert!(solved.converged);
        let (own, _) = problem.assemble(&solved.knots);
        let own = own.factor().unwrap();
        assert!(own.decrement() < STEP_DECREMENT, "{:e}", own.decrement());
        let handed = solved.factor.unwrap();
        // The check was taken: the factor handed back is not the end point's own.
        assert_ne!(handed.log_det(), own.log_det());
        let (a, b) = (handed.banded_inverse(), own.banded_inverse());
        let worst = a
            .diag
            .iter()
            .zip(&b.diag)
            .flat_map(|(x, y)| (0..18).map(move |i| (x[(i, i)] / y[(i, i)] - 1.0).abs()))
            .fold(0.0, f64::max);
        assert!(worst < 1e-3, "variances differ by {worst:e} relative");
        // The check itself: a point that is not the solution (the start, with no step) is not
        // taken; the solution with its own tiny step is.
        let start = initial_knots(
            &times
                .iter()
                .zip(&meas)
                .map(|(&t, &pose)| PoseMeasurement { t, pose, cov: None })
                .collect::<Vec<_>>(),
        );
        let (sys, cost) = problem.assemble(&start);
        let factor = sys.factor().unwrap();
        assert!(factor.decrement() > 1.0);
        let none = vec![V18::zeros(); n];
        let checked = check_by_gradient(&problem, &start, &none, cost, factor).unwrap();
        assert!(matches!(checked, Checked::NotYet(_)));
        let (sys, cost) = problem.assemble(&solved.knots);
        let factor = sys.factor().unwrap();
        let dx = factor.solve();
        let checked = check_by_gradient(&problem, &solved.knots, &dx, cost, factor).unwrap();
        assert!(matches!(checked, Checked::Converged(..)));
    }
}
