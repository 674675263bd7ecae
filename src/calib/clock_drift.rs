//! A drifting DVL clock: the drift estimated with the calibration.
//!
//! The model is `t_cam = t_dvl + time_offset_s + 1e-6 ppm (t_dvl - t_ref)`, the reference the
//! middle of the valid reports (where the offset and the drift are least correlated). A run
//! maps the DVL times by the drift found so far and calibrates as usual; at its result the
//! drift is a ninth column of the joint system ([`super::joint::drift`]), whose Gauss-Newton
//! step corrects the drift and whose inverse gives every parameter's covariance with the drift
//! marginalised. The next run starts at the corrected drift; the model is linear in the drift
//! up to the trajectory's curvature over the time shift, so the second run usually settles it.

use super::joint::drift::{DriftAt, DriftSolution};
use super::model::NPARAM;
use super::outcome::{CalibrationOutcome, ClockDrift};
use crate::error::Result;
use crate::types::DvlSample;

/// Calibrations run at most.
pub const MAX_ROUNDS: usize = 4;

/// The drift has settled when its last correction is below this part of its standard deviation.
pub const SETTLED_STD: f64 = 0.05;

/// A drift beyond this, ppm, is not a clock's: a quartz clock drifts tens of ppm, an
/// undisciplined computer clock up to a few hundred.
pub const PLAUSIBLE_PPM: f64 = 1000.0;

/// Calibrates with the DVL clock's drift estimated (see the module documentation); `stages`
/// calibrates reports with their times mapped by a drift (`None`: by none).
pub(crate) fn calibrate_with_drift(
    dvl: &[DvlSample],
    stages: impl Fn(&[DvlSample], Option<DriftAt>) -> Result<CalibrationOutcome>,
) -> Result<CalibrationOutcome> {
    let Some(reference_t_s) = reference_time(dvl) else {
        // No valid report: the stages say so.
        return stages(dvl, None);
    };
    let mut ppm = 0.0;
    let mut round = 1;
    loop {
        let mapped = map_times(dvl, ppm, reference_t_s);
        let at = DriftAt { ppm, reference_t_s };
        let mut o = stages(&mapped, Some(at))?;
        let Some(d) = o.clock_drift.as_mut() else {
            return Ok(o);
        };
        d.rounds = round;
        let step = d.last_step_ppm;
        let settled = step.abs() <= SETTLED_STD * d.std_ppm;
        if !step.is_finite() || !d.std_ppm.is_finite() {
            o.warnings.push(
                "the clock drift could not be estimated: the motion does not tell a drift \
                 from a constant offset (its information is singular); the result assumes none"
                    .to_owned(),
            );
            o.clock_drift = None;
            return Ok(o);
        }
        if settled || round == MAX_ROUNDS {
            if !settled {
                o.warnings.push(format!(
                    "the clock drift did not settle in {MAX_ROUNDS} calibrations: its last \
                     correction was {step:+.1} ppm ({:.1} standard deviations)",
                    step.abs() / d.std_ppm
                ));
            }
            if d.ppm.abs() > PLAUSIBLE_PPM {
                o.warnings.push(format!(
                    "the clock drift, {:+.0} ppm, is beyond any clock's ({PLAUSIBLE_PPM:.0} \
                     ppm): look for a time base that is not seconds, or a clock that stepped",
                    d.ppm
                ));
            }
            return Ok(o);
        }
        ppm += step;
        round += 1;
    }
}

/// The middle of the valid reports' DVL times, `None` without one.
fn reference_time(dvl: &[DvlSample]) -> Option<f64> {
    let (lo, hi) = dvl
        .iter()
        .filter(|s| s.valid && s.t.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s.t), hi.max(s.t))
        });
    (lo <= hi).then_some(0.5 * (lo + hi))
}

/// The reports with their times mapped to `t + 1e-6 ppm (t - reference_t_s)`: on the clock
/// whose offset to the camera's is constant at that drift.
pub fn map_times(dvl: &[DvlSample], ppm: f64, reference_t_s: f64) -> Vec<DvlSample> {
    dvl.iter()
        .map(|s| DvlSample {
            t: s.t + 1e-6 * ppm * (s.t - reference_t_s),
            ..s.clone()
        })
        .collect()
}

/// The drift a run at `at` found: `at` corrected by the step of its nine-parameter system,
/// the standard deviation inflated by `inflation` (as the covariance is).
pub(crate) fn estimate(at: DriftAt, s: &DriftSolution, inflation: f64) -> ClockDrift {
    let step = s.step[NPARAM];
    ClockDrift {
        ppm: at.ppm + step,
        std_ppm: s.std_ppm() * inflation.sqrt(),
        reference_t_s: at.reference_t_s,
        last_step_ppm: step,
        rounds: 1,
    }
}
