//! Stage 1: the trajectory from the co-sensor alone, its outlying measurements down-weighted.
//!
//! The co-sensor is the sensor whose motion the DVL is calibrated against. [`CoSensor`] names
//! the kinds of measurement the estimator takes; each kind knows three things, and the stages
//! ask for nothing else:
//!
//! - its trajectory fit, with the measurements the robust loss finds outlying down-weighted
//!   ([`CoSensor::fit`], which gives a [`CoSensorFit`]);
//! - its factors of the joint problem, on the knots of a trajectory fitted to it
//!   ([`CoSensorFit::factors`], a [`CoSensorFactors`]: the trajectory's solver, the joint
//!   assembly and the covariance take any kind through that seam);
//! - a fresh fit of the weighted measurements ([`CoSensorFit::fit_afresh`], for the mirrored
//!   solution's refinement).
//!
//! Camera poses are the one kind today. A new kind (an IMU's angular rate and specific force)
//! adds a variant here and its factors in `trajectory::factors`; the stages stay as they are.

use super::options::CalibOptions;
use super::robust::{self, Loss, RobustSummary};
use super::spacing::{SparsePoses, sparse_poses};
use crate::error::{Error, Result};
use crate::trajectory::factors::{CoSensorFactors, PoseFactors};
use crate::trajectory::solver::measurement_information;
use crate::trajectory::{FitOptions, Trajectory};
use crate::types::PoseMeasurement;

/// The co-sensor's measurements, the data the trajectory is fitted to.
#[derive(Clone, Copy, Debug)]
pub enum CoSensor<'a> {
    /// Camera poses `T_world_cam` on the camera clock (from images, motion capture or VIO),
    /// strictly increasing in time: the trajectory has a knot at each.
    Poses(&'a [PoseMeasurement]),
}

/// The co-sensor's measurements as the robust loss weighed them.
#[derive(Clone, Debug)]
pub(crate) enum Weighted {
    /// The poses with each covariance divided by its weight.
    Poses(Vec<PoseMeasurement>),
}

/// What stage 1 gives the later stages besides the trajectory.
pub(crate) struct CoSensorFit {
    /// The factor the measurements' variances are multiplied by in the joint problem (1: as
    /// stated; set by the noise estimate, `calib::noise`).
    pub variance_scale: f64,
    /// The measurements as weighted.
    pub measurements: Weighted,
    /// What the loss found.
    pub robust: RobustSummary,
    /// The weight of each measurement (1: full weight).
    pub weights: Vec<f64>,
    /// Poses too sparse for the trajectory to follow the motion (a warning says so, and the
    /// calibration fails with it as the first reason).
    pub sparse: Option<SparsePoses>,
}

impl CoSensor<'_> {
    /// How many measurements there are.
    pub fn len(&self) -> usize {
        match self {
            CoSensor::Poses(p) => p.len(),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The trajectory fitted to the measurements, the outlying ones down-weighted by the loss
    /// of `opts` (a warning names them), and the measurements as weighted.
    pub(crate) fn fit(
        &self,
        opts: &CalibOptions,
        warnings: &mut Vec<String>,
    ) -> Result<(Trajectory, CoSensorFit)> {
        let (trajectory, fit) = match self {
            CoSensor::Poses(poses) => {
                let (weighted, trajectory, robust, weights) = robust_pose_fit(poses, opts)?;
                let fit = CoSensorFit {
                    variance_scale: 1.0,
                    measurements: Weighted::Poses(weighted),
                    robust,
                    weights,
                    sparse: sparse_poses(poses),
                };
                (trajectory, fit)
            }
        };
        if let Some(s) = &fit.sparse {
            warnings.push(s.reason());
        }
        if fit.robust.outliers > 0 {
            warnings.push(format!(
                "{} of {} camera poses lie far from the trajectory the others describe (worst at \
                 t = {:.2} s, {:.0} times the stated variance): {} (a misdetected tag or a board \
                 seen at a grazing angle?)",
                fit.robust.outliers,
                fit.robust.factors,
                fit.robust.worst.first().map_or(f64::NAN, |o| o.t),
                fit.robust.worst.first().map_or(f64::NAN, |o| o.s),
                opts.outliers_handled()
            ));
        }
        Ok((trajectory, fit))
    }

    /// The measurements' factors, unweighted, on the knots of `traj` (fitted to them).
    pub(crate) fn factors(&self, traj: &Trajectory) -> Result<Box<dyn CoSensorFactors>> {
        match self {
            CoSensor::Poses(poses) => pose_factors(poses, traj),
        }
    }
}

impl CoSensorFit {
    /// The weighted measurements' factors on the knots of `traj` (a trajectory of the same
    /// knots: the fit's, or one the refinement moved), their variances times
    /// `variance_scale`.
    pub(crate) fn factors(&self, traj: &Trajectory) -> Result<Box<dyn CoSensorFactors>> {
        match &self.measurements {
            Weighted::Poses(poses) if self.variance_scale == 1.0 => pose_factors(poses, traj),
            Weighted::Poses(poses) => {
                let info = measurement_information(poses, traj.report().pose_sigma)?;
                Ok(Box::new(PoseFactors::new(
                    poses.iter().map(|m| m.pose).collect(),
                    info.into_iter().map(|w| w / self.variance_scale).collect(),
                )))
            }
        }
    }

    /// A trajectory fitted afresh to the weighted measurements.
    pub(crate) fn fit_afresh(&self, opts: &FitOptions) -> Result<Trajectory> {
        match &self.measurements {
            Weighted::Poses(poses) => Trajectory::fit(poses, opts),
        }
    }
}

/// Poses as factors, weighed with their covariance or, without one, with the pose noise that
/// the fit of `traj` used.
fn pose_factors(poses: &[PoseMeasurement], traj: &Trajectory) -> Result<Box<dyn CoSensorFactors>> {
    Ok(Box::new(PoseFactors::new(
        poses.iter().map(|m| m.pose).collect(),
        measurement_information(poses, traj.report().pose_sigma)?,
    )))
}

/// The trajectory fitted to the poses with the bad ones down-weighted: a fit, the poses'
/// residuals against it, and refits with the weights of the loss until the outliers found stop
/// changing (at most three fits). Returns the poses as weighted (their covariance divided by
/// the weight), the trajectory, what was done, and the weight of each pose.
fn robust_pose_fit(
    poses: &[PoseMeasurement],
    opts: &CalibOptions,
) -> Result<(Vec<PoseMeasurement>, Trajectory, RobustSummary, Vec<f64>)> {
    let mut traj = Trajectory::fit(poses, &opts.fit)?;
    let mut weighted = poses.to_vec();
    let mut weights = vec![1.0; poses.len()];
    let mut summary = RobustSummary::default();
    if opts.loss == Loss::L2 {
        return Ok((weighted, traj, summary, weights));
    }
    let t: Vec<f64> = poses.iter().map(|p| p.t).collect();
    // The stated noise: the poses' own covariance, or the first fit's estimate of it (later
    // fits see every pose with a covariance and estimate nothing).
    let info = measurement_information(poses, traj.report().pose_sigma)?;
    let refit = FitOptions {
        pose_sigma: Some(traj.report().pose_sigma),
        ..opts.fit.clone()
    };
    for fit in 1..=3 {
        let s: Vec<f64> = poses
            .iter()
            .zip(traj.knots())
            .zip(&info)
            .map(|((m, k), w)| {
                let e = (m.pose.inverse() * k.pose).log();
                (e.transpose() * w * e)[0]
            })
            .collect();
        let (w, sum) = robust::weigh(opts.loss, &s, &t, 6, 1.0);
        let change = w
            .iter()
            .zip(&weights)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        summary = sum;
        if change < 0.01 || fit == 3 {
            break;
        }
        for (k, p) in weighted.iter_mut().enumerate() {
            weights[k] = w[k];
            let cov = info[k].try_inverse().ok_or_else(|| {
                Error::Numerical(format!(
                    "pose {} (t = {}): information not invertible",
                    k + 1,
                    p.t
                ))
            })?;
            p.cov = if w[k] < 1.0 {
                Some(cov / w[k].max(1e-12))
            } else {
                poses[k].cov
            };
        }
        traj = Trajectory::fit(&weighted, &refit)?;
    }
    Ok((weighted, traj, summary, weights))
}
