//! Each sensor's noise as the recording shows it, against the noise it states: variance
//! components of the DVL's reports and of the co-sensor's measurements, estimated with the
//! calibration.
//!
//! At the joint estimate, a group of measurements whose stated variances are `1/s^2` of the true
//! ones has a cost whose expectation is `s^2 r`, with `r` its redundancy: its dimension less the
//! degrees of freedom it takes in the problem (`calib::joint::redundancy`). So `s^2 = cost / r`
//! (Helmert's and Forstner's variance components). A DVL stated ten times too precise pulls the
//! trajectory away from the poses until its own residuals look right; the poses' cost then shows
//! what it did, and the redundancies share the misfit between the two groups correctly.
//!
//! When either scale is far from one (below 1/2 or above 2) and significantly so (or below 1/4
//! or above 4 at all), its group's
//! variances are multiplied by it, the calibration is refined again from where it ended, and the
//! scales are estimated again, until both are within 10 % of one (at most [`ROUNDS`] times).
//! The weights, and the standard deviations, then rest on the noise the data show. Data whose
//! noise is as stated are left exactly as they were.

use super::joint::problem::JointProblem;
use super::joint::redundancy::redundancy;
use super::model::DvlObs;
use crate::error::Result;
use crate::trajectory::Trajectory;
use crate::types::CalibrationParams;

/// A first estimate outside this range starts the rescaling...
pub const APPLIED_OUTSIDE: (f64, f64) = (0.5, 2.0);
/// ... when it is this many of its standard deviations from one, or outside the square of the
/// range whatever its spread (a group given far too much weight takes nearly all the degrees of
/// freedom, and its own redundancy is then too small to estimate its scale well).
pub const SIGNIFICANT_STD: f64 = 3.0;
/// The DVL's normalized cost beyond which its covariance is inflated by it (below, the
/// residuals are taken as the stated noise's).
pub const COST_INFLATION_FROM: f64 = 1.5;
/// Once started, the rescaling goes on until both scales are within this of one...
pub const CONVERGED: f64 = 0.1;
/// ... or this many refinements were run again.
pub const ROUNDS: usize = 4;

/// One variance component: the ratio of a group's variance as the data show it to the variance
/// stated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Component {
    /// `cost / redundancy` at the result (1: as stated, or as rescaled).
    pub scale: f64,
    /// Its standard deviation, `scale sqrt(2 / redundancy)` (Gaussian noise).
    pub std: f64,
    /// The group's redundancy.
    pub redundancy: f64,
    /// The factor the stated variances were multiplied by (1: as stated).
    pub applied: f64,
}

impl Component {
    fn of(cost: f64, redundancy: f64, applied: f64) -> Component {
        let r = redundancy.max(1.0);
        let scale = cost / r;
        Component {
            scale,
            std: scale * (2.0 / r).sqrt(),
            redundancy,
            applied,
        }
    }

    /// Whether the first estimate calls for rescaling.
    fn far(&self) -> bool {
        let (lo, hi) = APPLIED_OUTSIDE;
        let (far_lo, far_hi) = (lo * lo, hi * hi);
        (self.scale < lo || self.scale > hi)
            && ((self.scale - 1.0).abs() > SIGNIFICANT_STD * self.std
                || self.scale < far_lo
                || self.scale > far_hi)
            && self.scale.is_finite()
            && self.scale > 0.0
    }

    /// Whether a later estimate is close enough to one to stop.
    fn settled(&self) -> bool {
        !self.scale.is_finite() || self.scale <= 0.0 || (self.scale - 1.0).abs() <= CONVERGED
    }

    /// Whether the stated variances were replaced by ones more than [`CONVERGED`] away (a group
    /// rescaled in the first round and found right in a later one was not).
    pub fn rescaled(&self) -> bool {
        self.applied != 1.0 && (self.total() - 1.0).abs() > CONVERGED
    }

    /// The variance the data show over the variance stated.
    pub fn total(&self) -> f64 {
        self.scale * self.applied
    }
}

/// The variance components of a calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseCheck {
    /// The DVL's reports.
    pub dvl: Component,
    /// The co-sensor's measurements (camera poses).
    pub cosensor: Component,
    /// How many times the calibration was refined again with rescaled noise.
    pub rounds: usize,
}

impl NoiseCheck {
    /// Which groups the first estimate calls to rescale: `(dvl, cosensor)`. The co-sensor's
    /// variances are only ever raised: errors correlated from one measurement to the next (a
    /// board's corner pattern seen the same way in every frame) fit into a smooth trajectory and
    /// hide from its residuals, so a scale below one does not show that the stated noise is too
    /// large.
    pub(crate) fn far(&self) -> (bool, bool) {
        (
            self.dvl.far(),
            self.cosensor.far() && self.cosensor.scale > 1.0,
        )
    }

    /// Whether the rescaling of the groups `engaged` can stop.
    pub(crate) fn settled(&self, engaged: (bool, bool)) -> bool {
        (!engaged.0 || self.dvl.settled()) && (!engaged.1 || self.cosensor.settled())
    }

    /// The warnings of applied scales.
    pub(crate) fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        let words = |what: &str, c: &Component, too_small: &str, too_large: &str| {
            let ratio = c.total().sqrt();
            format!(
                "the {what} noise is {ratio:.2} times the noise {} (variance {:.3} times, the \
                 variance components of the joint estimate): {}; the calibration weighs them by \
                 the noise the recording shows, and the standard deviations rest on it",
                if what == "DVL's" {
                    "its reports state"
                } else {
                    "their covariances state"
                },
                c.total(),
                if ratio > 1.0 { too_small } else { too_large }
            )
        };
        if self.dvl.rescaled() {
            out.push(words(
                "DVL's",
                &self.dvl,
                "stated too small, it would bend the trajectory away from the poses",
                "stated too large, it would understate what the DVL measures",
            ));
        }
        if self.cosensor.rescaled() {
            out.push(words(
                "camera poses'",
                &self.cosensor,
                "stated too small, they would hold the trajectory to their noise",
                "stated too large, they would let the DVL bend the trajectory",
            ));
        }
        out
    }
}

/// The variance components at the joint estimate (`traj`, `p`) of the problem `jp` (its DVL
/// reports as weighed, its co-sensor's factors), of which `free_params` parameters were
/// estimated; `applied` holds the factors already applied to the DVL's and the co-sensor's
/// variances.
pub(crate) fn components(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    free_params: usize,
    applied: (f64, f64),
    rounds: usize,
) -> Result<NoiseCheck> {
    let r = redundancy(jp, traj.knots(), p, free_params)?;
    Ok(NoiseCheck {
        dvl: Component::of(r.dvl_cost, r.dvl_redundancy, applied.0),
        cosensor: Component::of(r.cosensor_cost, r.cosensor_redundancy, applied.1),
        rounds,
    })
}

/// The observations with their stated covariances multiplied by `factor`.
pub(crate) fn scaled(obs: &[DvlObs], factor: f64) -> Vec<DvlObs> {
    obs.iter()
        .map(|o| DvlObs {
            cov: o.cov * factor,
            ..o.clone()
        })
        .collect()
}
