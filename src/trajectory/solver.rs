//! The Gauss-Newton solver of trajectory problems, and the seam the calibration plugs into.
//!
//! A trajectory problem has one 18-dimensional state per knot (pose perturbation, twist, twist
//! rate), and its normal equations are block tridiagonal: every factor involves one knot or two
//! consecutive knots. [`NormalEquations`] is the interface: anything that can linearise its cost
//! at a set of knots into a [`BlockTridiagonal`] system can be solved by [`gauss_newton`].
//!
//! - [`Problem`] is the fit to the co-sensor alone: the GP prior between knots and the
//!   co-sensor's factors ([`super::factors::CoSensorFactors`]; camera poses: one per knot).
//!   `Trajectory::fit` and the hyperparameter search solve it.
//! - The calibration's joint problem (`calib::joint`) adds the DVL velocity factors to the same
//!   system by implementing [`NormalEquations`] with [`Problem`]'s blocks plus its own; it
//!   assembles in the same chunks ([`assembly_chunks`]) so that sums never depend on the
//!   number of threads.
//!
//! Steps are applied with [`step`]: poses are perturbed on the right (`T <- T exp(d)`), twists
//! and rates additively.

use nalgebra::{Matrix6, Vector6};

use super::blocktri::{BlockTridiagonal, Factored, M18, V18};
use super::density::JerkDensity;
use super::factors::{CoSensorFactors, IntervalNormal};
use super::gp::{
    Knot, LocalState, PriorNormal, apply_scalar, first_local_state, kron_diag_mul, local_gamma,
    phi_scalar, prior_factor, prior_normal, q_scalar_inv,
};
use super::view::KnotView;
use crate::error::{Error, Result};
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

/// The Gauss-Newton problem of a fit to the co-sensor alone: the GP prior and the co-sensor's
/// factors.
pub(crate) struct Problem<'a> {
    pub times: &'a [f64],
    pub cosensor: &'a dyn CoSensorFactors,
    /// The motion prior's jerk density per interval.
    pub density: &'a JerkDensity,
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
    /// The normal equations linearised at `knots` into `sys` (which must have `knots.len()`
    /// blocks; every block is overwritten, so its storage can be reused as it is), and the cost
    /// there. Chunks of knots are assembled on all available cores.
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
                cost += self.knot_cost(knots, k);
                if k + 1 < n {
                    let (c, gamma2) = self.prior_cost(knots, k);
                    cost += c;
                    if self.cosensor.has_interval_terms() {
                        cost += self.cosensor.interval_cost(self.view(knots), k, &gamma2);
                    }
                }
            }
            cost
        })
        .into_iter()
        .sum()
    }

    /// The knot times with the states `knots`.
    pub(crate) fn view<'k>(&'k self, knots: &'k [Knot]) -> KnotView<'k> {
        KnotView {
            times: self.times,
            knots,
        }
    }

    /// Fills one chunk: for each knot its co-sensor term, then the terms of the intervals
    /// before and after it (prior, then co-sensor; the interval before the chunk is recomputed
    /// here). Each interval's terms are added to both of its knots as soon as they are formed
    /// (the next knot's own term is written first), so no term is kept or copied from one knot
    /// to the next.
    fn assemble_chunk(&self, knots: &[Knot], chunk: &mut AssemblyChunk) {
        let n = knots.len();
        let len = chunk.diag.len();
        let (first, diag, rhs, upper) = (
            chunk.first,
            &mut *chunk.diag,
            &mut *chunk.rhs,
            &mut *chunk.upper,
        );
        let mut knot_cost = self.knot_terms(knots, first, &mut diag[0], &mut rhs[0]);
        let mut t = PriorNormal::zeros();
        let mut c = IntervalNormal::zeros();
        if first > 0 {
            // The off-diagonal block of this interval is the previous chunk's.
            let ls = self.prior_terms(knots, first - 1, &mut t, &mut M18::zeros());
            diag[0] += t.d2;
            rhs[0] += t.r2;
            if self.cosensor_interval(knots, first - 1, &ls, &mut c) {
                diag[0] += c.d2;
                rhs[0] += c.r2;
            }
        }
        chunk.cost = 0.0;
        for i in 0..len {
            let k = first + i;
            chunk.cost += knot_cost;
            if i + 1 < len {
                knot_cost = self.knot_terms(knots, k + 1, &mut diag[i + 1], &mut rhs[i + 1]);
            }
            if k + 1 < n {
                let ls = self.prior_terms(knots, k, &mut t, &mut upper[i]);
                diag[i] += t.d1;
                rhs[i] += t.r1;
                chunk.cost += t.cost;
                if i + 1 < len {
                    diag[i + 1] += t.d2;
                    rhs[i + 1] += t.r2;
                }
                if self.cosensor_interval(knots, k, &ls, &mut c) {
                    diag[i] += c.d1;
                    rhs[i] += c.r1;
                    upper[i] += c.upper;
                    chunk.cost += c.cost;
                    if i + 1 < len {
                        diag[i + 1] += c.d2;
                        rhs[i + 1] += c.r2;
                    }
                }
            }
        }
    }

    /// Overwrites `diag` and `rhs` with the co-sensor's terms on knot `k`; returns their cost.
    pub(crate) fn knot_terms(
        &self,
        knots: &[Knot],
        k: usize,
        diag: &mut M18,
        rhs: &mut V18,
    ) -> f64 {
        self.cosensor.knot_terms(knots, k, diag, rhs)
    }

    /// The cost of the co-sensor's terms on knot `k` (as [`Problem::knot_terms`] returns it).
    pub(crate) fn knot_cost(&self, knots: &[Knot], k: usize) -> f64 {
        self.cosensor.knot_cost(knots, k)
    }

    /// The co-sensor's terms on the interval after knot `k` into `out` (`ls`: the local state
    /// of knot `k + 1`); `false` when it has none there.
    pub(crate) fn cosensor_interval(
        &self,
        knots: &[Knot],
        k: usize,
        ls: &LocalState,
        out: &mut IntervalNormal,
    ) -> bool {
        self.cosensor.has_interval_terms()
            && self.cosensor.interval_terms(self.view(knots), k, ls, out)
    }

    /// The normal-equation blocks of the prior factor between knots `k` and `k + 1`, written
    /// into `out` and (the off-diagonal block) into `upper`; returns the local state of knot
    /// `k + 1` relative to knot `k` with its Jacobians.
    pub(crate) fn prior_terms(
        &self,
        knots: &[Knot],
        k: usize,
        out: &mut PriorNormal,
        upper: &mut M18,
    ) -> LocalState {
        self.prior_terms_weighted(knots, k, &self.density.qc_inv(k), out, upper)
    }

    /// [`Problem::prior_terms`] with `Qc^-1` replaced by `qc_inv` (a part of the prior: its
    /// translational or rotational terms alone).
    pub(crate) fn prior_terms_weighted(
        &self,
        knots: &[Knot],
        k: usize,
        qc_inv: &Vector6<f64>,
        out: &mut PriorNormal,
        upper: &mut M18,
    ) -> LocalState {
        let dt = self.times[k + 1] - self.times[k];
        let f = prior_factor(&knots[k], &knots[k + 1], dt);
        prior_normal(&f, &q_scalar_inv(dt), qc_inv, out, upper);
        f.local
    }

    /// The cost of the prior factor between knots `k` and `k + 1` (as
    /// [`Problem::prior_terms`] gives it), and the local state `gamma_2` of knot `k + 1`.
    pub(crate) fn prior_cost(&self, knots: &[Knot], k: usize) -> (f64, V18) {
        let dt = self.times[k + 1] - self.times[k];
        let (k1, k2) = (&knots[k], &knots[k + 1]);
        let gamma = local_gamma(k1, k2);
        let e = gamma - apply_scalar(&phi_scalar(dt), &first_local_state(k1));
        let we = kron_diag_mul(&q_scalar_inv(dt), &self.density.qc_inv(k), &e);
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
}

impl NormalEquations for Problem<'_> {
    fn normal_equations(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> Result<f64> {
        Ok(self.assemble_into(knots, sys))
    }

    fn cost(&self, knots: &[Knot]) -> Result<f64> {
        Ok(Problem::cost(self, knots))
    }
}

/// How a Gauss-Newton run ends and what storage it may use.
pub(crate) struct GaussNewtonOptions {
    pub max_iterations: usize,
    /// The run stops when the step's decrement is below this ([`STEP_DECREMENT`] unless the
    /// caller needs less).
    pub stop_decrement: f64,
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
        converged = converged || factor.decrement() < opts.stop_decrement;
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
