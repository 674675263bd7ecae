//! What a calibration is asked to do: how it starts ([`Method`]), its settings
//! ([`CalibOptions`], each checked by [`CalibOptions::validate`] before anything is computed),
//! the limits its verdicts and sanity checks apply, and the words its messages use for the
//! settings ([`Setting`]).

use nalgebra::Vector3;

use super::offset::OffsetOptions;
use super::prior::{self, Priors};
use super::robust::Loss;
use super::setting::{Setting, SettingNames};
use super::update::FreeParams;
use crate::error::{Error, Result};
use crate::trajectory::FitOptions;
use crate::types::CalibrationParams;

/// How the calibration starts.
#[derive(Clone, Debug)]
pub enum Method {
    /// UIC: initialisation from the data alone, then refinement.
    Uic,
    /// Block-coordinate refinement from a user guess.
    Bcd(CalibrationParams),
    /// The user's extrinsics kept fixed; with `estimate_offset` the clock offset (and scale)
    /// is estimated with the extrinsics held, otherwise the guess is only evaluated.
    Fixed {
        /// The user's calibration; its rotation and lever arm are held fixed.
        guess: CalibrationParams,
        /// Whether to estimate the clock offset and velocity scale (`false`: only evaluate the
        /// guess).
        estimate_offset: bool,
    },
}

impl Method {
    /// The parameters the method estimates: all of them, clock offset and scale only (fixed
    /// extrinsics with an estimated offset), or none (a fixed guess evaluated).
    pub fn free_parameters(&self) -> FreeParams {
        match self {
            Method::Fixed {
                estimate_offset: true,
                ..
            } => FreeParams {
                rotation: false,
                lever_arm: false,
                scale: true,
                time_offset: true,
            },
            Method::Fixed { .. } => FreeParams {
                rotation: false,
                lever_arm: false,
                scale: false,
                time_offset: false,
            },
            _ => FreeParams::ALL,
        }
    }
}

/// Standard deviations above which a parameter is reported as weakly observable.
#[derive(Clone, Debug)]
pub struct WeakThresholds {
    /// Limit on the rotation standard deviation about each axis, degrees.
    pub rotation_deg: f64,
    /// Limit on the lever-arm standard deviation along each axis, m.
    pub lever_arm_m: f64,
    /// Limit on the clock-offset standard deviation, s.
    pub time_offset_s: f64,
    /// Limit on the velocity-scale standard deviation (dimensionless).
    pub velocity_scale: f64,
}

impl Default for WeakThresholds {
    fn default() -> Self {
        WeakThresholds {
            rotation_deg: 0.5,
            lever_arm_m: 0.01,
            time_offset_s: 0.01,
            velocity_scale: 0.005,
        }
    }
}

impl WeakThresholds {
    /// The limits from four values, rotation (deg), lever arm (m), clock offset (s) and velocity
    /// scale, as `dvlcal watch --target-std` takes them; each must be a positive number.
    pub fn from_values(v: &[f64], option: &'static str) -> crate::error::Result<WeakThresholds> {
        match v {
            [r, l, o, s] if v.iter().all(|x| x.is_finite() && *x > 0.0) => Ok(WeakThresholds {
                rotation_deg: *r,
                lever_arm_m: *l,
                time_offset_s: *o,
                velocity_scale: *s,
            }),
            _ => Err(crate::error::Error::option(
                option,
                format!(
                    "takes four positive numbers, the std targets of the rotation (deg), lever \
                     arm (m), clock offset (s) and velocity scale, as 0.5,0.01,0.01,0.005; got \
                     {v:?}"
                ),
            )),
        }
    }
}

/// What a calibration must satisfy to be trusted; a result outside them is
/// [`Status::Failed`].
#[derive(Clone, Debug, PartialEq)]
pub struct SanityLimits {
    /// Largest DVL cost per degree of freedom (1 when the residuals match the stated noise).
    pub max_normalized_cost: f64,
    /// Largest ratio of the DVL's noise as its residuals show it to the noise stated (standard
    /// deviations). Within it a misstated noise is estimated and weighed by (`calib::noise`);
    /// beyond it the camera and the DVL do not describe the same motion.
    pub max_noise_ratio: f64,
    /// Physical range of the velocity scale: the ratio of the sound speed the DVL assumes to the
    /// water's (0.9..1.1 covers water from 0 to 35 C, fresh to salt).
    pub scale_range: (f64, f64),
    /// Largest share of the DVL reports that may be outliers (down-weighted by the robust loss,
    /// or only found under least squares). Beyond it the disagreement is not a few outliers but
    /// a model that does not fit (a drifting clock, poses of another body, a log of another
    /// recording), and the loss would only hide it.
    pub max_outlier_fraction: f64,
}

impl Default for SanityLimits {
    fn default() -> Self {
        SanityLimits {
            max_normalized_cost: 10.0,
            max_noise_ratio: 20.0,
            scale_range: (0.9, 1.1),
            max_outlier_fraction: 0.25,
        }
    }
}

/// Settings of a calibration.
#[derive(Clone, Debug)]
pub struct CalibOptions {
    /// How the calibration starts: UIC, BCD from a guess, or fixed extrinsics.
    pub method: Method,
    /// Per-axis DVL noise (m/s) replacing the reports' own covariance.
    pub dvl_sigma: Option<f64>,
    /// DVL noise used for reports without a covariance.
    pub default_dvl_sigma: f64,
    /// Settings of the clock-offset search. Its `range` bounds the offset everywhere: the
    /// search, and every step of the refinement (an offset that ends on a bound fails the
    /// sanity checks). The DVL samples kept are those inside the camera's span at every offset
    /// within `min(window_s, 0.5)` s of the starting one.
    pub offset: OffsetOptions,
    /// Use the bias-eliminated closed form (the paper's estimator); `false` gives the biased one.
    pub bias_corrected: bool,
    /// Outer block-coordinate iterations.
    pub max_outer_iterations: usize,
    /// Settings of the co-sensor's trajectory fit.
    pub fit: FitOptions,
    /// Standard deviations above which a parameter is reported as weak.
    pub weak: WeakThresholds,
    /// What a result must satisfy to be trusted.
    pub sanity: SanityLimits,
    /// Priors on the calibration (a measured lever arm, a known rotation); none by default.
    pub priors: prior::Priors,
    /// The loss on the DVL and pose residuals ([`super::robust`]); Cauchy by default.
    pub loss: Loss,
    /// Standard deviation of the broad prior (zero lever arm) applied when `priors` has no
    /// lever-arm prior, metres: it keeps a lever arm the motion does not observe from running
    /// to metres and corrupting the other parameters (1 m by default; `None`: no such prior).
    pub default_lever_arm_sigma_m: Option<f64>,
    /// Inflate the covariance for correlated DVL residuals and for halves of the recording that
    /// disagree (on by default).
    pub honest_covariance: bool,
    /// Estimate the DVL clock's drift with the calibration ([`super::clock_drift`]): `t_cam =
    /// t_dvl + time_offset_s + 1e-6 ppm (t_dvl - t_ref)`. Off by default (a constant offset).
    pub clock_drift: bool,
    /// Let the motion prior's jerk density vary along the recording, chosen by the evidence of
    /// poses and DVL ([`super::motion_prior`]); on by default.
    pub varying_motion_prior: bool,
    /// A solution of the same rig on overlapping data to start UIC from (a watched recording's
    /// last update; `None` by default). UIC's rules stay: the clock offset is still searched, in
    /// [`WARM_WINDOW_S`] around the solution's (the whole search again when it ends on that
    /// window's edge), and the closed form is still solved and still decides which directions of
    /// the lever arm the motion observes; the refinement starts from the solution, at the offset
    /// found, unless it fits the DVL velocities clearly worse than the closed form. Ignored by
    /// the other methods.
    pub warm_start: Option<CalibrationParams>,
    /// The words for the settings in warnings, verdicts and errors ([`Setting::field`] by
    /// default).
    pub names: SettingNames,
}

/// Half-width, seconds, of the clock-offset search around a warm start's offset
/// ([`CalibOptions::warm_start`]).
pub const WARM_WINDOW_S: f64 = 0.5;

impl Default for CalibOptions {
    fn default() -> Self {
        CalibOptions {
            method: Method::Uic,
            dvl_sigma: None,
            default_dvl_sigma: 0.01,
            offset: OffsetOptions::default(),
            bias_corrected: true,
            max_outer_iterations: 10,
            // The pose-only fit starts the joint refinement, whose state update moves every knot
            // again; a tenth of a standard deviation per knot is close enough to start from.
            fit: FitOptions {
                decrement_per_knot: 0.01,
                ..FitOptions::default()
            },
            weak: WeakThresholds::default(),
            sanity: SanityLimits::default(),
            priors: prior::Priors::default(),
            loss: Loss::default(),
            default_lever_arm_sigma_m: Some(1.0),
            honest_covariance: true,
            clock_drift: false,
            varying_motion_prior: true,
            warm_start: None,
            names: Setting::field,
        }
    }
}

impl CalibOptions {
    /// Checks every setting before anything is computed (each struct of settings checks its
    /// own); the error names the setting in [`CalibOptions::names`]'s words.
    pub fn validate(&self) -> Result<()> {
        self.offset.validate(self.names)?;
        self.priors.validate()?;
        if let Some(s) = self.default_lever_arm_sigma_m
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::option(
                self.name(Setting::DefaultLeverArmSigma),
                "must be a positive number of metres",
            ));
        }
        if let Some(s) = self.dvl_sigma
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::option(
                self.name(Setting::DvlSigma),
                "must be positive",
            ));
        }
        if !(self.default_dvl_sigma.is_finite() && self.default_dvl_sigma > 0.0) {
            return Err(Error::option(
                self.name(Setting::DefaultDvlSigma),
                "must be a positive number of m/s",
            ));
        }
        if let Some(w) = &self.warm_start {
            let m = w.t_cam_dvl.to_matrix();
            if !(m.iter().all(|x| x.is_finite())
                && w.time_offset_s.is_finite()
                && w.velocity_scale.is_finite()
                && w.velocity_scale > 0.0)
            {
                return Err(Error::option(
                    "warm_start",
                    "must be finite, with a positive velocity scale",
                ));
            }
        }
        Ok(())
    }

    /// The words for `setting` in messages.
    pub fn name(&self, setting: Setting) -> &'static str {
        (self.names)(setting)
    }

    /// The user's priors, with the broad default prior on the lever arm when none is given.
    pub fn effective_priors(&self) -> Priors {
        let mut p = self.priors;
        if p.lever_arm.is_none()
            && let Some(sigma_m) = self.default_lever_arm_sigma_m
        {
            p.lever_arm = Some(prior::LeverArmPrior {
                lever_arm_cam_m: Vector3::zeros(),
                sigma_m,
            });
        }
        p
    }

    /// What is done with outliers under the loss, in words.
    pub fn outliers_handled(&self) -> String {
        match self.loss {
            Loss::L2 => format!(
                "kept at full weight ({}): they pull the result",
                self.name(Setting::LeastSquares)
            ),
            l => format!("down-weighted by the {} loss", l.name()),
        }
    }

    /// The offset `t` moved inside the offsets allowed (`offset.range`), if any bound it.
    pub fn bounded_offset(&self, t: f64) -> f64 {
        match self.offset.range {
            Some((lo, hi)) => t.clamp(lo, hi),
            None => t,
        }
    }
}
