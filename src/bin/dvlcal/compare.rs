//! `dvlcal compare-calib`: the difference between two calibrations (an estimate and a reference
//! such as a simulation's truth), in units and in the estimate's standard deviations. Parameters
//! the estimate held fixed are compared in units only: their difference is one of inputs.

use anyhow::Result;
use std::path::PathBuf;

use dvlcal::eval::{CalibrationError, calibration_error};
use dvlcal::io::calib_yaml::{Observability, read_calib_yaml};

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The calibration to check (result YAML, with its `std`).
    #[arg(long)]
    pub estimate: PathBuf,
    /// The reference calibration (e.g. a simulation's truth/calibration.yaml).
    #[arg(long)]
    pub truth: PathBuf,
}

/// The error of parameters `ks` in standard deviations, or what replaces it: held parameters
/// have none, and a parameter a prior determined is labelled so.
fn in_std(ce: &CalibrationError, ks: &[usize]) -> String {
    let k0 = ks[0];
    if ce.held(k0) {
        return "held fixed (from --init): a difference of inputs, not a measured error".into();
    }
    let z: Vec<String> = ks
        .iter()
        .map(|&k| match ce.std {
            Some(s) if s[k] > 0.0 => format!("{:+.1}", ce.error[k] / s[k]),
            _ => "-".into(),
        })
        .collect();
    let prior = if ce.state[k0] == Some(Observability::Prior) {
        ", from prior: the standard deviation is mostly the prior's"
    } else {
        ""
    };
    format!("in std: {}{prior}", z.join(" "))
}

pub fn run(a: CompareArgs) -> Result<()> {
    let truth = read_calib_yaml(&a.truth)?.to_params()?;
    let ce = calibration_error(&read_calib_yaml(&a.estimate)?, &truth)?;
    let d = ce.error;
    let rot = nalgebra::Vector3::new(d[0], d[1], d[2]);
    println!("{} against {}", a.estimate.display(), a.truth.display());
    if let Some(why) = &ce.failure {
        println!("FAILED calibration (status: failed), not a result to use: {why}");
    }
    println!(
        "rotation   {:.4} deg  (about DVL x, y, z: {:+.4} {:+.4} {:+.4} deg; {})",
        rot.norm().to_degrees(),
        d[0].to_degrees(),
        d[1].to_degrees(),
        d[2].to_degrees(),
        in_std(&ce, &[0, 1, 2])
    );
    println!(
        "lever arm  {:.2} mm  (x, y, z: {:+.2} {:+.2} {:+.2} mm; {})",
        1e3 * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]).sqrt(),
        1e3 * d[3],
        1e3 * d[4],
        1e3 * d[5],
        in_std(&ce, &[3, 4, 5])
    );
    println!("clock      {:+.2} ms  ({})", 1e3 * d[7], in_std(&ce, &[7]));
    println!("scale      {:+.5}  ({})", d[6], in_std(&ce, &[6]));
    let estimated: Vec<usize> = (0..8).filter(|&k| !ce.held(k)).collect();
    if let Some(s) = ce.std {
        if estimated.is_empty() {
            println!(
                "nothing was estimated: every parameter was held at the value given, so the \
                 differences above are in units only"
            );
        } else if ce.failure.is_none() {
            let worst = estimated
                .iter()
                .filter(|&&k| s[k] > 0.0)
                .map(|&k| (d[k] / s[k]).abs())
                .fold(0.0, f64::max);
            println!(
                "largest error of the estimated parameters {worst:.1} standard deviations ({}){}",
                if worst <= 3.0 {
                    "every estimated parameter within 3 std"
                } else {
                    "outside 3 std"
                },
                if estimated.len() < 8 {
                    "; the held parameters are compared in units only"
                } else {
                    ""
                }
            );
        }
    }
    ce.refuse_failed(&a.estimate)?;
    Ok(())
}
