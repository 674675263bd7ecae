//! MAP fit of the WNOJ trajectory to time-stamped poses, and queries at any time in its span.
//!
//! Knots sit at the pose measurement times. The cost is the sum of the GP prior terms between
//! consecutive knots and one pose term per knot; Gauss-Newton on the right perturbations of the
//! knot poses (and additive updates of twists and rates) solves it. Every step solves a
//! block-tridiagonal system, so a fit takes O(N) time and memory.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector6};

use super::blocktri::{BandedInverse, BlockTridiagonal, Factored, M18, V18};
use super::gp::{
    Knot, PriorNormal, apply_scalar, d_jr_times, first_local_state, interpolation_weights,
    knot_from_local, kron_diag_mul, local_gamma, local_state, prior_factor, prior_normal,
    q_scalar_inv,
};
use super::hyper;
use super::lie::{Se3, se3_right_jacobian, se3_right_jacobian_inv};
use crate::error::{Error, Result};
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
const ASSEMBLY_CHUNK: usize = 256;

/// The blocks of the normal equations of the knots `first..first + diag.len()`.
struct AssemblyChunk<'s> {
    first: usize,
    diag: &'s mut [M18],
    upper: &'s mut [M18],
    rhs: &'s mut [V18],
    cost: f64,
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
        let n = knots.len();
        assert_eq!(sys.len(), n, "system size does not match the knots");
        let mut chunks = Vec::with_capacity(n.div_ceil(ASSEMBLY_CHUNK));
        let (mut diag, mut upper, mut rhs) =
            (&mut sys.diag[..], &mut sys.upper[..], &mut sys.rhs[..]);
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
        let threads = std::thread::available_parallelism()
            .map_or(1, |t| t.get())
            .min(chunks.len());
        if threads <= 1 {
            chunks
                .iter_mut()
                .for_each(|c| self.assemble_chunk(knots, c));
        } else {
            let per_thread = chunks.len().div_ceil(threads);
            std::thread::scope(|scope| {
                for group in chunks.chunks_mut(per_thread) {
                    scope.spawn(move || {
                        group.iter_mut().for_each(|c| self.assemble_chunk(knots, c))
                    });
                }
            });
        }
        chunks.iter().map(|c| c.cost).sum()
    }

    /// Fills one chunk: for each knot the pose term, then the prior terms of the intervals
    /// before and after it (the interval before the chunk is recomputed here).
    fn assemble_chunk(&self, knots: &[Knot], chunk: &mut AssemblyChunk) {
        let n = knots.len();
        let mut before = (chunk.first > 0).then(|| self.prior_terms(knots, chunk.first - 1));
        chunk.cost = 0.0;
        for (i, (diag, rhs)) in chunk.diag.iter_mut().zip(chunk.rhs.iter_mut()).enumerate() {
            let k = chunk.first + i;
            *diag = M18::zeros();
            *rhs = V18::zeros();
            let e = (self.meas[k].inverse() * knots[k].pose).log();
            let j = se3_right_jacobian_inv(&e);
            let wj = self.info[k] * j;
            diag.fixed_view_mut::<6, 6>(0, 0)
                .copy_from(&(j.transpose() * wj));
            rhs.fixed_rows_mut::<6>(0).copy_from(&-(wj.transpose() * e));
            chunk.cost += (e.transpose() * self.info[k] * e)[0];
            if let Some(t) = &before {
                *diag += t.d2;
                *rhs += t.r2;
            }
            if k + 1 < n {
                let t = self.prior_terms(knots, k);
                *diag += t.d1;
                *rhs += t.r1;
                chunk.upper[i] = t.upper;
                chunk.cost += t.cost;
                before = Some(t);
            }
        }
    }

    /// The normal-equation blocks of the prior factor between knots `k` and `k + 1`.
    fn prior_terms(&self, knots: &[Knot], k: usize) -> PriorNormal {
        let dt = self.times[k + 1] - self.times[k];
        let f = prior_factor(&knots[k], &knots[k + 1], dt);
        prior_normal(&f, &q_scalar_inv(dt), &self.qc_inv)
    }
}

/// Applies a step to the knots.
pub(crate) fn step(knots: &[Knot], dx: &[V18], scale: f64) -> Vec<Knot> {
    knots
        .iter()
        .zip(dx)
        .map(|(k, d)| Knot {
            pose: k.pose.retract(&(d.fixed_rows::<6>(0) * scale).into_owned()),
            twist: k.twist + d.fixed_rows::<6>(6) * scale,
            rate: k.rate + d.fixed_rows::<6>(12) * scale,
        })
        .collect()
}

/// Result of a Gauss-Newton run.
pub(crate) struct Solved {
    pub knots: Vec<Knot>,
    pub iterations: usize,
    pub converged: bool,
    pub cost: f64,
    /// Factorisation of the information matrix at the final knots.
    pub factor: Factored,
}

/// Gauss-Newton with step halving; returns the factorisation at the solution.
/// Something that linearises a trajectory cost: the pose-only fit, or the fit with further
/// factors (the calibration adds DVL velocities).
pub(crate) trait NormalEquations {
    /// Overwrites every block of `sys` (sized for `knots`) with the normal equations linearised
    /// at `knots` and returns the cost there.
    fn normal_equations(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> Result<f64>;
}

impl NormalEquations for Problem<'_> {
    fn normal_equations(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> Result<f64> {
        Ok(self.assemble_into(knots, sys))
    }
}

pub(crate) fn gauss_newton(
    problem: &dyn NormalEquations,
    mut knots: Vec<Knot>,
    max_iterations: usize,
) -> Result<Solved> {
    let mut sys = BlockTridiagonal::zeros(knots.len());
    let mut cost = problem.normal_equations(&knots, &mut sys)?;
    // Trial systems are assembled into storage recycled from the previous factorisation.
    let mut spare = None;
    let mut iterations = 0;
    let mut converged = false;
    loop {
        let factor = sys.factor()?;
        if converged || iterations >= max_iterations {
            return Ok(Solved {
                knots,
                iterations,
                converged,
                cost,
                factor,
            });
        }
        let dx = factor.solve();
        let mut trial_sys = spare
            .take()
            .unwrap_or_else(|| BlockTridiagonal::zeros(knots.len()));
        let mut scale = 1.0;
        let mut accepted = None;
        for _ in 0..12 {
            let trial = step(&knots, &dx, scale);
            let tcost = problem.normal_equations(&trial, &mut trial_sys)?;
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
                sys = trial_sys;
                spare = Some(factor.into_system());
                cost = tcost;
                // The pose-only problem is nearly linear: once a full step changes the cost by
                // less than a part in 1e9, the next step is far below the posterior spread.
                converged = max_step < 1e-9 || (scale == 1.0 && rel < 1e-9);
            }
            None => {
                // No decrease along the step: the current point is as good as we can do.
                problem.normal_equations(&knots, &mut trial_sys)?;
                sys = trial_sys;
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
        let solved = gauss_newton(&problem, initial_knots(poses), opts.max_iterations)?;
        let cov = opts.covariance.then(|| solved.factor.banded_inverse());
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

    /// The interval holding `t`, the time since its first knot and its length.
    fn locate(&self, t: f64) -> Result<(usize, f64, f64)> {
        let k = self.interval(t).ok_or_else(|| {
            let (a, b) = self.span();
            Error::Input(format!(
                "time {t} is outside the trajectory span [{a}, {b}]"
            ))
        })?;
        let dt = self.times[k + 1] - self.times[k];
        Ok((k, (t - self.times[k]).clamp(0.0, dt), dt))
    }

    /// Pose, twist and twist rate at `t`, without covariance or Jacobians (the cheap query).
    pub fn state(&self, t: f64) -> Result<TrajectoryState> {
        let (k, s, dt) = self.locate(t)?;
        let (k1, k2) = (&self.knots[k], &self.knots[k + 1]);
        let (lambda, omega, _) = interpolation_weights(s, dt);
        let gamma = apply_scalar(&lambda, &first_local_state(k1))
            + apply_scalar(&omega, &local_gamma(k1, k2));
        let s = knot_from_local(&k1.pose, &gamma);
        Ok(TrajectoryState {
            t,
            pose: s.pose,
            twist: s.twist,
            rate: s.rate,
            twist_cov: None,
        })
    }

    /// The interpolated state at `t` with the twist's Jacobian with respect to the two knots.
    pub fn twist_jacobian(&self, t: f64) -> Result<TwistJacobian> {
        let (k, s, dt) = self.locate(t)?;
        let (k1, k2) = (&self.knots[k], &self.knots[k + 1]);
        let (lambda, omega, cond) = interpolation_weights(s, dt);
        let ls = local_state(k1, k2);
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
        Ok(TwistJacobian {
            knot: k,
            state,
            jacobian,
            d_local,
            cond,
        })
    }
}
