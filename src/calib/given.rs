//! The values a user gives: a guess to start from, extrinsics to hold, priors. They are checked
//! for units and plausibility before they are used ([`check_given`]: a lever arm of a hundred
//! metres is millimetres given as metres), and extrinsics held fixed are checked against the
//! data afterwards ([`contradicted`]: freed on their own, do the data move them far and explain
//! the residuals?).

use nalgebra::Vector3;

use super::model::{DvlObs, NPARAM, PARAM_NAMES};
use super::options::{CalibOptions, Method};
use super::prior::Priors;
use super::setting::Setting;
use super::update::{FreeParams, calibration_update, linearize, pin_fixed};
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;
use crate::types::CalibrationParams;

/// A given lever arm longer than this, metres, is no lever arm on a rig: millimetres given as
/// metres.
pub const MILLIMETRES_AS_METRES_M: f64 = 20.0;
/// A given lever arm longer than this, metres, is unusual for a DVL and a camera on one vehicle
/// and draws a warning.
pub const LONG_LEVER_ARM_M: f64 = 3.0;
/// A given velocity scale outside this range is not a ratio of sound speeds in water.
pub const GIVEN_SCALE_RANGE: (f64, f64) = (0.5, 2.0);
/// A lever-arm prior broader than this, metres, constrains nothing on a rig.
pub const BROAD_LEVER_ARM_SIGMA_M: f64 = 1.0;
/// A rotation prior broader than this, degrees, constrains nothing.
pub const BROAD_ROTATION_SIGMA_DEG: f64 = 45.0;
/// A held parameter whose freed estimate lies further than this many standard deviations from
/// the given value is contradicted by the data.
pub const CONTRADICTED_STD: f64 = 5.0;

/// Checks the values `opts` gives before anything is estimated: an error for values no rig can
/// have (naming the setting and the likely slip of units), warnings for unusual ones.
pub(crate) fn check_given(opts: &CalibOptions, warnings: &mut Vec<String>) -> Result<()> {
    let guess = match &opts.method {
        Method::Uic => None,
        Method::Bcd(g) | Method::Fixed { guess: g, .. } => Some(g),
    };
    if let Some(g) = guess {
        lever_arm(&g.lever_arm_cam_m(), opts.name(Setting::Guess), warnings)?;
        let (lo, hi) = GIVEN_SCALE_RANGE;
        let s = g.velocity_scale;
        // A negative scale is a half-turn in the guessed rotation (a flipped axis), which the
        // refinement mirrors back; only its size says whether the units are right.
        if !(s.abs() >= lo && s.abs() <= hi) {
            return Err(Error::option(
                opts.name(Setting::Guess),
                format!(
                    "has a velocity scale of {s}: a DVL's scale is the ratio of the sound speed it \
                     assumes to the water's, near 1 (0.9 to 1.1 from fresh to salt water); give 1 \
                     when it is not known"
                ),
            ));
        }
        let (lo, hi) = opts.sanity.scale_range;
        if s < 0.0 {
            warnings.push(format!(
                "the velocity scale {s} of {} is negative: read as a rotation half a turn away                  from the one given (an axis flipped in the measurement)",
                opts.name(Setting::Guess)
            ));
        } else if !(s >= lo && s <= hi) {
            warnings.push(format!(
                "the velocity scale {s} of {} is outside the range water allows ({lo} to {hi})",
                opts.name(Setting::Guess)
            ));
        }
    }
    check_priors(&opts.priors, opts, warnings)
}

fn check_priors(priors: &Priors, opts: &CalibOptions, warnings: &mut Vec<String>) -> Result<()> {
    if let Some(l) = &priors.lever_arm {
        let name = opts.name(Setting::LeverArmPrior);
        lever_arm(&l.lever_arm_cam_m, name, warnings)?;
        if l.sigma_m > BROAD_LEVER_ARM_SIGMA_M {
            warnings.push(format!(
                "{name} has a standard deviation of {} m, broader than any rig: it constrains \
                 nothing (were millimetres given as metres?)",
                l.sigma_m
            ));
        }
    }
    if let Some(r) = &priors.rotation
        && r.sigma_deg > BROAD_ROTATION_SIGMA_DEG
    {
        warnings.push(format!(
            "{} has a standard deviation of {} deg: it constrains next to nothing (radians \
             given as degrees are the other way round; were arc minutes meant?)",
            opts.name(Setting::RotationPrior),
            r.sigma_deg
        ));
    }
    Ok(())
}

/// A given lever arm `p` (named `what`) checked for its length.
fn lever_arm(p: &Vector3<f64>, what: &'static str, warnings: &mut Vec<String>) -> Result<()> {
    let n = p.norm();
    if n > MILLIMETRES_AS_METRES_M {
        let mm = p / 1000.0;
        return Err(Error::option(
            what,
            format!(
                "has a lever arm [{:.3}, {:.3}, {:.3}] m, {n:.1} m long: no rig holds a DVL that \
                 far from its camera. Were millimetres given as metres? In millimetres it is \
                 [{:.3}, {:.3}, {:.3}] m",
                p.x, p.y, p.z, mm.x, mm.y, mm.z
            ),
        ));
    }
    if n > LONG_LEVER_ARM_M {
        warnings.push(format!(
            "{what} has a lever arm {n:.2} m long, unusual for a DVL and a camera on one vehicle: \
             check its units and its frame (the DVL's origin in the camera frame)"
        ));
    }
    Ok(())
}

/// A held parameter group the data contradict.
#[derive(Clone, Debug, PartialEq)]
pub struct Contradiction {
    /// The group: `rotation`, `lever arm`, `velocity scale` or `clock offset`.
    pub what: &'static str,
    /// Where the data put it, minus the given value, in the covariance's coordinates and display
    /// units (deg, mm, -, ms), component by component.
    pub moved: Vec<f64>,
    /// The display unit of `moved`.
    pub unit: &'static str,
    /// The largest move in the freed estimate's standard deviations.
    pub z: f64,
    /// The DVL cost per degree of freedom before and after freeing the group.
    pub cost_before: f64,
    /// See `cost_before`.
    pub cost_after: f64,
}

impl Contradiction {
    /// The failure reason, in words.
    pub fn reason(&self) -> String {
        let moved: Vec<String> = self.moved.iter().map(|m| format!("{m:+.2}")).collect();
        format!(
            "the data contradict the given {}: freed, it moves by [{}] {} ({:.0} standard \
             deviations) and the DVL residuals drop from {:.1} to {:.1} times the stated noise; \
             the given {} does not belong to this rig or recording",
            self.what,
            moved.join(", "),
            self.unit,
            self.z,
            self.cost_before,
            self.cost_after,
            self.what
        )
    }
}

/// The groups of parameters held at the given values whose freed estimates the data put more
/// than [`CONTRADICTED_STD`] standard deviations away, most explaining first. Each group is
/// freed on its own (with the parameters the run estimated), the trajectory `traj` held.
pub(crate) fn contradicted(
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    params: &CalibrationParams,
    free: FreeParams,
) -> Result<Vec<Contradiction>> {
    let dof = (3 * idx.len()).saturating_sub(NPARAM).max(1) as f64;
    let before = linearize(traj, obs, idx, params)?.cost / dof;
    let groups: [(&'static str, std::ops::Range<usize>, bool); 4] = [
        ("rotation", 0..3, free.rotation),
        ("lever arm", 3..6, free.lever_arm),
        ("velocity scale", 6..7, free.scale),
        ("clock offset", 7..8, free.time_offset),
    ];
    let mut found = Vec::new();
    for (what, range, estimated) in groups.iter().cloned() {
        if estimated {
            continue;
        }
        let mut trial = free;
        match what {
            "rotation" => trial.rotation = true,
            "lever arm" => trial.lever_arm = true,
            "velocity scale" => trial.scale = true,
            _ => trial.time_offset = true,
        }
        let up = calibration_update(traj, obs, idx, params, trial, &Priors::default(), 30)?;
        let mut h = up.hessian;
        let mask = trial.mask();
        pin_fixed(&mut h, &mask);
        let Some(cov) = h.try_inverse() else {
            continue;
        };
        let d = super::model::difference(&up.params, params);
        let z = range
            .clone()
            .map(|k| d[k].abs() / cov[(k, k)].max(1e-300).sqrt())
            .fold(0.0, f64::max);
        // (a NaN z, no information, contradicts nothing)
        if z.is_nan() || z <= CONTRADICTED_STD {
            continue;
        }
        let after = linearize(traj, obs, idx, &up.params)?.cost / dof;
        let (_, factor, unit) = PARAM_NAMES[range.start];
        found.push(Contradiction {
            what,
            moved: range.map(|k| d[k] * factor).collect(),
            unit: if unit.is_empty() { "(no unit)" } else { unit },
            z,
            cost_before: before,
            cost_after: after,
        });
    }
    found.sort_by(|a, b| a.cost_after.total_cmp(&b.cost_after));
    Ok(found)
}
