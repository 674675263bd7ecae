//! MAP fit of the WNOJ trajectory to time-stamped poses, and queries at any time in its span.
//!
//! Knots sit at the pose measurement times. The cost is the sum of the GP prior terms between
//! consecutive knots and one pose term per knot; Gauss-Newton on the right perturbations of the
//! knot poses (and additive updates of twists and rates) solves it. Every step solves a
//! block-tridiagonal system, so a fit takes O(N) time and memory.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector6};

use super::blocktri::{BandedInverse, BlockTridiagonal, Factored, M18, V18};
use super::gp::{
    Knot, LocalState, PriorNormal, apply_scalar, d_jr_times, first_local_state,
    interpolation_weights, knot_from_local, kron_diag_mul, local_gamma, local_state, phi_scalar,
    prior_factor, prior_normal, q_scalar_inv,
};
use super::hyper;
use crate::error::{Error, Result};
use crate::lie::{Se3, se3_right_jacobian, se3_right_jacobian_inv};
use crate::types::PoseMeasurement;

/// How to fit.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Power spectral density of jerk, `[v; w]` order ((m/s^3)^2 s and (rad/s^3)^2 s). `None`:
    /// chosen by maximising the marginal likelihood of the poses.
    pub qc: Option<Vector6<f64>>,
    /// Standard deviations (m, rad) of poses that carry no covariance. `None`: estimated together
    /// with `qc` by marginal likelihood (or, when `qc` is given, from the data's third differences).
    pub pose_sigma: Option<(f64, f64)>,
    /// Gauss-Newton iteration limit.
    pub max_iterations: usize,
    /// Knots used for the marginal-likelihood search (several windows spread over the data).
    pub hyper_knots: usize,
    /// Compute the posterior covariance (needed for twist standard deviations).
    pub covariance: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            qc: None,
            pose_sigma: None,
            max_iterations: 30,
            hyper_knots: 400,
            covariance: true,
        }
    }
}

/// What the fit found about its own inputs and convergence.
#[derive(Clone, Debug)]
pub struct FitReport {
    pub iterations: usize,
    pub converged: bool,
    /// Final value of the (doubled negative log-posterior) cost.
    pub cost: f64,
    pub qc: Vector6<f64>,
    pub qc_estimated: bool,
    /// Default pose standard deviations (m, rad) used for poses without covariance.
    pub pose_sigma: (f64, f64),
    pub pose_sigma_estimated: bool,
    /// Root-mean-square pose residuals (m, rad) of the measurements against the fit.
    pub residual_rms_pos: f64,
    pub residual_rms_rot: f64,
}

/// A fitted continuous-time trajectory.
#[derive(Clone, Debug)]
pub struct Trajectory {
    times: Vec<f64>,
    knots: Vec<Knot>,
    qc: Vector6<f64>,
    cov: Option<BandedInverse>,
    report: FitReport,
}

/// The trajectory at one time.
#[derive(Clone, Debug)]
pub struct TrajectoryState {
    pub t: f64,
    /// `T_world_cam`.
    pub pose: Se3,
    /// Body twist `[v; w]` (m/s, rad/s, camera frame).
    pub twist: Vector6<f64>,
    /// Its time derivative.
    pub rate: Vector6<f64>,
    /// Posterior covariance of `twist`, when the fit computed covariances.
    pub twist_cov: Option<Matrix6<f64>>,
}

/// Interpolated twist with its Jacobian with respect to the variables of the two knots that
/// bracket the query time (for factors that involve the twist, e.g. DVL velocities).
pub struct TwistJacobian {
    /// Index of the first knot.
    pub knot: usize,
    pub state: Knot,
    /// d twist / d [x_k; x_{k+1}], each `x = [dT; dw; ddw]`.
    pub jacobian: SMatrix<f64, 6, 36>,
    /// d twist / d local state (6x18), for the conditional covariance term.
    pub d_local: SMatrix<f64, 6, 18>,
    /// Scalar conditional covariance of the local state at the query time (times `Qc`).
    pub cond: Matrix3<f64>,
}

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

/// Checks the inputs every fit needs.
fn check_poses(poses: &[PoseMeasurement]) -> Result<()> {
    if poses.len() < 3 {
        return Err(Error::Input(format!(
            "a trajectory needs at least 3 poses, got {}",
            poses.len()
        )));
    }
    for (i, w) in poses.windows(2).enumerate() {
        if w[1].t.partial_cmp(&w[0].t) != Some(std::cmp::Ordering::Greater) {
            return Err(Error::Input(format!(
                "pose times must increase: pose {} (t = {}) follows pose {} (t = {})",
                i + 2,
                w[1].t,
                i + 1,
                w[0].t
            )));
        }
    }
    Ok(())
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
    /// Factorise the information matrix at the solution (for the log-determinant or the
    /// covariance). Without it the last step is checked with the cost alone.
    pub factor: bool,
    /// Storage for the system (any contents; sized for the knots or it is not used).
    pub storage: Option<BlockTridiagonal>,
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
        if converged || iterations >= opts.max_iterations {
            return Ok(Solved {
                knots,
                iterations,
                converged,
                cost,
                factor: Some(factor),
                spare: None,
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

impl Trajectory {
    /// The same trajectory model (knot times, `Qc`, fit report) with other knot states, and
    /// optionally their posterior covariance.
    pub fn with_knots(&self, knots: Vec<Knot>, cov: Option<BandedInverse>) -> Trajectory {
        Trajectory {
            times: self.times.clone(),
            knots,
            qc: self.qc,
            cov,
            report: self.report.clone(),
        }
    }

    /// Fits a trajectory to at least three poses with strictly increasing times.
    pub fn fit(poses: &[PoseMeasurement], opts: &FitOptions) -> Result<Trajectory> {
        check_poses(poses)?;
        for (i, p) in poses.iter().enumerate() {
            if !p.t.is_finite()
                || !p
                    .pose
                    .trans
                    .iter()
                    .chain(p.pose.rot.iter())
                    .all(|v| v.is_finite())
            {
                return Err(Error::Input(format!(
                    "pose {} has non-finite values",
                    i + 1
                )));
            }
        }
        let hyp = hyper::choose(poses, opts)?;
        let times: Vec<f64> = poses.iter().map(|p| p.t).collect();
        let meas: Vec<Se3> = poses.iter().map(|p| p.pose).collect();
        let info = measurement_information(poses, hyp.pose_sigma)?;
        let problem = Problem {
            times: &times,
            meas: &meas,
            info: &info,
            qc_inv: hyp.qc.map(|q| 1.0 / q),
        };
        let solved = gauss_newton(
            &problem,
            initial_knots(poses),
            GaussNewtonOptions {
                max_iterations: opts.max_iterations,
                factor: opts.covariance,
                storage: None,
            },
        )?;
        let cov = solved.factor.map(Factored::banded_inverse);
        let (mut sp, mut sr) = (0.0, 0.0);
        for (k, m) in solved.knots.iter().zip(&meas) {
            let e = (m.inverse() * k.pose).log();
            sp += e.fixed_rows::<3>(0).norm_squared();
            sr += e.fixed_rows::<3>(3).norm_squared();
        }
        let n = poses.len() as f64;
        let report = FitReport {
            iterations: solved.iterations,
            converged: solved.converged,
            cost: solved.cost,
            qc: hyp.qc,
            qc_estimated: hyp.qc_estimated,
            pose_sigma: hyp.pose_sigma,
            pose_sigma_estimated: hyp.pose_sigma_estimated,
            residual_rms_pos: (sp / n).sqrt(),
            residual_rms_rot: (sr / n).sqrt(),
        };
        Ok(Trajectory {
            times,
            knots: solved.knots,
            qc: hyp.qc,
            cov,
            report,
        })
    }

    /// Removes the posterior covariance (queries then give no twist covariance) and returns its
    /// storage as a system of the same size, for a later fit to assemble into.
    pub(crate) fn take_covariance_storage(&mut self) -> Option<BlockTridiagonal> {
        self.cov.take().map(|c| BlockTridiagonal {
            rhs: vec![V18::zeros(); c.diag.len()],
            diag: c.diag,
            upper: c.upper,
        })
    }

    /// Knot times.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// Knot states.
    pub fn knots(&self) -> &[Knot] {
        &self.knots
    }

    pub fn qc(&self) -> Vector6<f64> {
        self.qc
    }

    pub fn report(&self) -> &FitReport {
        &self.report
    }

    /// The knots as a borrowed view (interpolation without the covariance).
    pub fn view(&self) -> KnotView<'_> {
        KnotView {
            times: &self.times,
            knots: &self.knots,
        }
    }

    /// First and last knot times.
    pub fn span(&self) -> (f64, f64) {
        self.view().span()
    }

    /// Index `k` of the interval `[t_k, t_{k+1}]` holding `t`, or `None` outside the span.
    pub fn interval(&self, t: f64) -> Option<usize> {
        self.view().interval(t)
    }

    /// Pose, twist and twist rate at `t`, without covariance or Jacobians (the cheap query).
    pub fn state(&self, t: f64) -> Result<TrajectoryState> {
        self.view().state(t)
    }

    /// The interpolated state at `t` with the twist's Jacobian with respect to the two knots.
    pub fn twist_jacobian(&self, t: f64) -> Result<TwistJacobian> {
        self.view().twist_jacobian(t)
    }

    /// Pose, twist, twist rate and (if computed) the twist covariance at `t`.
    pub fn query(&self, t: f64) -> Result<TrajectoryState> {
        let tj = self.twist_jacobian(t)?;
        let twist_cov = self.cov.as_ref().map(|cov| {
            let k = tj.knot;
            // J Sigma J^T over the two knots' blocks, without forming the 36x36 joint.
            let j1 = tj.jacobian.fixed_view::<6, 18>(0, 0);
            let j2 = tj.jacobian.fixed_view::<6, 18>(0, 18);
            let cross = j1 * cov.upper[k] * j2.transpose();
            let c = j1 * cov.diag[k] * j1.transpose()
                + cross
                + cross.transpose()
                + j2 * cov.diag[k + 1] * j2.transpose()
                + tj.d_local * kron_diag_mul(&tj.cond, &self.qc, &tj.d_local.transpose());
            (c + c.transpose()) * 0.5
        });
        Ok(TrajectoryState {
            t,
            pose: tj.state.pose,
            twist: tj.state.twist,
            rate: tj.state.rate,
            twist_cov,
        })
    }
}

/// Knot times and states borrowed from a trajectory or from a Gauss-Newton iterate: GP
/// interpolation and its Jacobians without copying the knots. Needs at least two knots.
#[derive(Clone, Copy, Debug)]
pub struct KnotView<'a> {
    pub times: &'a [f64],
    pub knots: &'a [Knot],
}

impl KnotView<'_> {
    /// First and last knot times.
    pub fn span(&self) -> (f64, f64) {
        (self.times[0], self.times[self.times.len() - 1])
    }

    /// Index `k` of the interval `[t_k, t_{k+1}]` holding `t`, or `None` outside the span.
    pub fn interval(&self, t: f64) -> Option<usize> {
        let (a, b) = self.span();
        let tol = 1e-9 * (1.0 + a.abs().max(b.abs()));
        if !(t >= a - tol && t <= b + tol) {
            return None;
        }
        let i = self.times.partition_point(|&x| x <= t);
        Some(i.saturating_sub(1).min(self.times.len() - 2))
    }

    /// The interval holding `t`, or an error naming the span.
    pub(crate) fn locate(&self, t: f64) -> Result<usize> {
        self.interval(t).ok_or_else(|| {
            let (a, b) = self.span();
            Error::Input(format!(
                "time {t} is outside the trajectory span [{a}, {b}]"
            ))
        })
    }

    /// Pose, twist and twist rate at `t`, without covariance or Jacobians (the cheap query).
    pub fn state(&self, t: f64) -> Result<TrajectoryState> {
        let k = self.locate(t)?;
        let s = self.state_in(k, t, &local_gamma(&self.knots[k], &self.knots[k + 1]));
        Ok(TrajectoryState {
            t,
            pose: s.pose,
            twist: s.twist,
            rate: s.rate,
            twist_cov: None,
        })
    }

    /// The time since knot `k` (clamped to the interval) and the interval's length.
    fn offset_in(&self, k: usize, t: f64) -> (f64, f64) {
        let dt = self.times[k + 1] - self.times[k];
        ((t - self.times[k]).clamp(0.0, dt), dt)
    }

    /// The state at `t` in the interval `k`, given the local state `gamma_2` of knot `k + 1`
    /// relative to knot `k` ([`local_gamma`]).
    pub(crate) fn state_in(&self, k: usize, t: f64, gamma2: &V18) -> Knot {
        let (s, dt) = self.offset_in(k, t);
        let (lambda, omega, _) = interpolation_weights(s, dt);
        let gamma = apply_scalar(&lambda, &first_local_state(&self.knots[k]))
            + apply_scalar(&omega, gamma2);
        knot_from_local(&self.knots[k].pose, &gamma)
    }

    /// The interpolated state at `t` with the twist's Jacobian with respect to the two knots.
    pub fn twist_jacobian(&self, t: f64) -> Result<TwistJacobian> {
        let k = self.locate(t)?;
        let ls = local_state(&self.knots[k], &self.knots[k + 1]);
        Ok(self.twist_jacobian_in(k, t, &ls))
    }

    /// The interpolated state at `t` in the interval `k` and the Jacobians of `m twist` with
    /// respect to the variables of the two knots (3 x 18 each), for a fixed 3 x 6 map `m` (a DVL
    /// velocity's dependence on the twist). The same derivative as `m` times
    /// [`KnotView::twist_jacobian_in`], formed in the three rows from the 6 x 6 pieces of the
    /// local state's Jacobians, without the 6 x 36 intermediate.
    pub(crate) fn projected_twist_jacobian_in(
        &self,
        k: usize,
        t: f64,
        ls: &LocalState,
        m: &SMatrix<f64, 3, 6>,
    ) -> (Knot, SMatrix<f64, 3, 18>, SMatrix<f64, 3, 18>) {
        type M36 = SMatrix<f64, 3, 6>;
        let (s, dt) = self.offset_in(k, t);
        let k1 = &self.knots[k];
        let (lambda, omega, _) = interpolation_weights(s, dt);
        let gamma = apply_scalar(&lambda, &first_local_state(k1)) + apply_scalar(&omega, &ls.gamma);
        let state = knot_from_local(&k1.pose, &gamma);
        let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
        let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
        // m d twist / d gamma = [p0, p1, 0] (the twist does not depend on xi'').
        let p0: M36 = m * d_jr_times(&xi, &[&xid])[0];
        let p1: M36 = m * se3_right_jacobian(&xi);
        // Through Lambda (x) I6 and Omega (x) I6: block j is p0 s[0][j] + p1 s[1][j].
        let through = |s: &Matrix3<f64>, j: usize| -> M36 { p0 * s[(0, j)] + p1 * s[(1, j)] };
        let (a0, a1, a2) = (through(&omega, 0), through(&omega, 1), through(&omega, 2));
        // gamma_2's Jacobians: d/dT_1 = -[I; du; da] J_l^-1 and d/dx_2 block lower triangular
        // (see LocalState::d_pose1 and LocalState::d_knot2).
        let pose = a0 + a1 * ls.du_dxi + a2 * ls.da_dxi;
        let mut j1 = SMatrix::<f64, 3, 18>::zeros();
        j1.fixed_view_mut::<3, 6>(0, 0).copy_from(&-(pose * ls.jli));
        j1.fixed_view_mut::<3, 6>(0, 6)
            .copy_from(&through(&lambda, 1));
        j1.fixed_view_mut::<3, 6>(0, 12)
            .copy_from(&through(&lambda, 2));
        let mut j2 = SMatrix::<f64, 3, 18>::zeros();
        j2.fixed_view_mut::<3, 6>(0, 0).copy_from(&(pose * ls.jri));
        j2.fixed_view_mut::<3, 6>(0, 6)
            .copy_from(&(a1 * ls.jri + a2 * ls.da_dw2));
        j2.fixed_view_mut::<3, 6>(0, 12).copy_from(&(a2 * ls.jri));
        (state, j1, j2)
    }

    /// [`KnotView::twist_jacobian`] at `t` in the interval `k`, given the local state of knot
    /// `k + 1` relative to knot `k` with its Jacobians ([`local_state`]).
    pub(crate) fn twist_jacobian_in(&self, k: usize, t: f64, ls: &LocalState) -> TwistJacobian {
        let (s, dt) = self.offset_in(k, t);
        let k1 = &self.knots[k];
        let (lambda, omega, cond) = interpolation_weights(s, dt);
        let gamma = apply_scalar(&lambda, &first_local_state(k1)) + apply_scalar(&omega, &ls.gamma);
        let state = knot_from_local(&k1.pose, &gamma);

        let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
        let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
        let mut d_local = SMatrix::<f64, 6, 18>::zeros();
        d_local
            .fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&d_jr_times(&xi, &[&xid])[0]);
        d_local
            .fixed_view_mut::<6, 6>(0, 6)
            .copy_from(&se3_right_jacobian(&xi));

        // The twist depends on gamma_1 through Lambda (x) I6 and on gamma_2 through
        // Omega (x) I6; fold those into d_local first (6x18 each, from 6x6 blocks).
        let through = |s: &Matrix3<f64>| {
            let mut m = SMatrix::<f64, 6, 18>::zeros();
            for j in 0..3 {
                let block: Matrix6<f64> = (0..3)
                    .map(|i| d_local.fixed_view::<6, 6>(0, 6 * i) * s[(i, j)])
                    .sum();
                m.fixed_view_mut::<6, 6>(0, 6 * j).copy_from(&block);
            }
            m
        };
        let (via_gamma1, via_gamma2) = (through(&lambda), through(&omega));
        let mut jacobian = SMatrix::<f64, 6, 36>::zeros();
        // gamma_1 = [0; w_1; dw_1] does not depend on T_1; gamma_2 does.
        jacobian
            .fixed_view_mut::<6, 18>(0, 0)
            .copy_from(&via_gamma1);
        jacobian
            .fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&(via_gamma2 * ls.d_pose1()));
        jacobian
            .fixed_view_mut::<6, 18>(0, 18)
            .copy_from(&(via_gamma2 * ls.d_knot2()));
        TwistJacobian {
            knot: k,
            state,
            jacobian,
            d_local,
            cond,
        }
    }
}
