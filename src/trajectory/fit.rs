//! MAP fit of the WNOJ trajectory to time-stamped poses, and queries at any time in its span.
//!
//! Knots sit at the pose measurement times. The cost is the sum of the GP prior terms between
//! consecutive knots and one pose term per knot; Gauss-Newton on the right perturbations of the
//! knot poses (and additive updates of twists and rates) solves it. Every step solves a
//! block-tridiagonal system, so a fit takes O(N) time and memory. The problem and the solver are
//! in `trajectory::solver`; the hyperparameters are chosen in `trajectory::hyper`.

use std::sync::OnceLock;

use nalgebra::Vector6;

use super::blocktri::{BandedInverse, BlockTridiagonal, Factored, V18};
use super::density::JerkDensity;
use super::factors::PoseFactors;
use super::gp::{Knot, Motion, kron_diag_mul, local_gamma};
use super::hyper;
use super::solver::{
    GaussNewtonOptions, Problem, STEP_DECREMENT, gauss_newton, initial_knots,
    measurement_information,
};
use super::view::{KnotView, TrajectoryState, TwistJacobian};
use crate::error::{Error, Result};
use crate::lie::Se3;
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
    /// Gauss-Newton stops once the step's squared length in the metric of the information
    /// matrix, per knot, is below this (or below the solver's absolute 1e-4, whichever is
    /// larger). Zero (the default) keeps the absolute threshold: the fit is converged to a
    /// hundredth of a standard deviation. A fit that only starts a joint refinement, which moves
    /// every knot again, can stop earlier (the calibration uses 0.01, a tenth of a standard
    /// deviation summed over a knot's 18 quantities).
    pub decrement_per_knot: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            qc: None,
            pose_sigma: None,
            max_iterations: 30,
            hyper_knots: 400,
            covariance: true,
            decrement_per_knot: 0.0,
        }
    }
}

/// What the fit found about its own inputs and convergence.
#[derive(Clone, Debug)]
pub struct FitReport {
    /// Gauss-Newton iterations run.
    pub iterations: usize,
    /// Whether Gauss-Newton converged within the iteration limit.
    pub converged: bool,
    /// Final value of the (doubled negative log-posterior) cost.
    pub cost: f64,
    /// Power spectral density of jerk used, `[v; w]` order ((m/s^3)^2 s and (rad/s^3)^2 s).
    pub qc: Vector6<f64>,
    /// Whether `qc` was chosen by marginal likelihood (`false`: given in the options).
    pub qc_estimated: bool,
    /// Default pose standard deviations (m, rad) used for poses without covariance.
    pub pose_sigma: (f64, f64),
    /// Whether `pose_sigma` was estimated from the poses (`false`: given, or every pose has a
    /// covariance).
    pub pose_sigma_estimated: bool,
    /// Root-mean-square pose residuals (m, rad) of the measurements against the fit.
    pub residual_rms_pos: f64,
    /// Root-mean-square rotation residual of the measurements against the fit, rad.
    pub residual_rms_rot: f64,
}

/// A fitted continuous-time trajectory.
#[derive(Clone, Debug)]
pub struct Trajectory {
    times: Vec<f64>,
    knots: Vec<Knot>,
    density: JerkDensity,
    cov: Option<BandedInverse>,
    report: FitReport,
    /// Each interval's local state `gamma_2` (knot `k + 1` relative to knot `k`), formed on
    /// the first query that needs it: a pass over many samples would otherwise form it again
    /// for every sample, and the calibration makes dozens of such passes over one trajectory.
    local: OnceLock<Vec<V18>>,
}

/// Checks the inputs every fit needs.
fn check_poses(poses: &[PoseMeasurement]) -> Result<()> {
    if poses.len() < 3 {
        return Err(Error::TooFewSamples {
            what: "camera poses for a trajectory".into(),
            found: poses.len(),
            needed: 3,
        });
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

impl Trajectory {
    /// The same trajectory model (knot times, `Qc`, fit report) with other knot states, and
    /// optionally their posterior covariance.
    pub fn with_knots(&self, knots: Vec<Knot>, cov: Option<BandedInverse>) -> Trajectory {
        Trajectory {
            times: self.times.clone(),
            knots,
            density: self.density.clone(),
            cov,
            report: self.report.clone(),
            local: OnceLock::new(),
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
        let hyp = hyper::choose(poses, opts.qc, opts.pose_sigma, opts.hyper_knots)?;
        let times: Vec<f64> = poses.iter().map(|p| p.t).collect();
        let meas: Vec<Se3> = poses.iter().map(|p| p.pose).collect();
        let factors = PoseFactors::new(meas, measurement_information(poses, hyp.pose_sigma)?);
        let density = JerkDensity::constant(hyp.qc);
        let problem = Problem {
            times: &times,
            cosensor: &factors,
            density: &density,
        };
        let solved = gauss_newton(
            &problem,
            initial_knots(poses),
            GaussNewtonOptions {
                max_iterations: opts.max_iterations,
                stop_decrement: STEP_DECREMENT.max(opts.decrement_per_knot * poses.len() as f64),
                factor: opts.covariance,
                storage: None,
            },
        )?;
        let cov = solved.factor.map(Factored::banded_inverse);
        let (mut sp, mut sr) = (0.0, 0.0);
        for (k, m) in solved.knots.iter().zip(factors.measurements()) {
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
            density,
            cov,
            report,
            local: OnceLock::new(),
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

    /// Power spectral density of jerk `Qc` of the GP prior, `[v; w]` order (the base of
    /// [`Trajectory::density`]).
    pub fn qc(&self) -> Vector6<f64> {
        self.density.base()
    }

    /// The GP prior's jerk density per interval.
    pub fn density(&self) -> &JerkDensity {
        &self.density
    }

    /// The same knots under the jerk density `density` (which must not change the knot
    /// times); the posterior covariance, which rests on the prior, is dropped.
    pub fn with_density(&self, density: JerkDensity) -> Trajectory {
        Trajectory {
            times: self.times.clone(),
            knots: self.knots.clone(),
            density,
            cov: None,
            report: self.report.clone(),
            local: OnceLock::new(),
        }
    }

    /// What the fit found about its inputs and convergence.
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

    /// The interval holding `t` and its local state `gamma_2` (the values [`KnotView`]'s
    /// queries form for each call).
    fn located(&self, t: f64) -> Result<(usize, &V18)> {
        let k = self.view().locate(t)?;
        let local = self.local.get_or_init(|| {
            let knots = &self.knots;
            crate::parallel::map_indices(knots.len().saturating_sub(1), 4096, |k| {
                local_gamma(&knots[k], &knots[k + 1])
            })
        });
        Ok((k, &local[k]))
    }

    /// Pose, twist and twist rate at `t`, without covariance or Jacobians (the cheap query).
    pub fn state(&self, t: f64) -> Result<TrajectoryState> {
        let (k, gamma2) = self.located(t)?;
        Ok(TrajectoryState::of_knot(
            t,
            self.view().state_in(k, t, gamma2),
        ))
    }

    /// The twist at `t` alone: the value [`Trajectory::state`] gives, without forming the pose
    /// and the rate.
    pub fn twist(&self, t: f64) -> Result<Vector6<f64>> {
        let (k, gamma2) = self.located(t)?;
        Ok(self.view().twist_in(k, t, gamma2))
    }

    /// The twist and the rate at `t`: the values [`Trajectory::state`] gives, without forming
    /// the pose.
    pub fn motion(&self, t: f64) -> Result<Motion> {
        let (k, gamma2) = self.located(t)?;
        Ok(self.view().motion_in(k, t, gamma2))
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
                + tj.d_local
                    * kron_diag_mul(&tj.cond, &self.density.qc(k), &tj.d_local.transpose());
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

#[cfg(test)]
#[path = "fit_jacobian_tests.rs"]
mod jacobian_tests;
