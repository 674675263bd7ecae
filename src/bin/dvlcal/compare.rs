//! `dvlcal compare-calib`: the difference between two calibrations (an estimate and a reference
//! such as a simulation's truth), in units and in the estimate's standard deviations.

use anyhow::Result;
use std::path::PathBuf;

use dvlcal::eval::calibration_error;
use dvlcal::io::calib_yaml::read_calib_yaml;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The calibration to check (result YAML, with its `std`).
    #[arg(long)]
    pub estimate: PathBuf,
    /// The reference calibration (e.g. a simulation's truth/calibration.yaml).
    #[arg(long)]
    pub truth: PathBuf,
}

pub fn run(a: CompareArgs) -> Result<()> {
    let truth = read_calib_yaml(&a.truth)?.to_params()?;
    let ce = calibration_error(&read_calib_yaml(&a.estimate)?, &truth)?;
    let d = ce.error;
    let std = ce.std;
    let z = |k: usize| -> String {
        match std {
            Some(s) if s[k] > 0.0 => format!("{:+.1}", d[k] / s[k]),
            _ => "-".into(),
        }
    };
    let rot = nalgebra::Vector3::new(d[0], d[1], d[2]);
    println!("{} against {}", a.estimate.display(), a.truth.display());
    println!(
        "rotation   {:.4} deg  (about DVL x, y, z: {:+.4} {:+.4} {:+.4} deg; in std: {} {} {})",
        rot.norm().to_degrees(),
        d[0].to_degrees(),
        d[1].to_degrees(),
        d[2].to_degrees(),
        z(0),
        z(1),
        z(2)
    );
    println!(
        "lever arm  {:.2} mm  (x, y, z: {:+.2} {:+.2} {:+.2} mm; in std: {} {} {})",
        1e3 * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]).sqrt(),
        1e3 * d[3],
        1e3 * d[4],
        1e3 * d[5],
        z(3),
        z(4),
        z(5)
    );
    println!("clock      {:+.2} ms  (in std: {})", 1e3 * d[7], z(7));
    println!("scale      {:+.5}  (in std: {})", d[6], z(6));
    if let Some(s) = std {
        let worst = (0..8)
            .filter(|&k| s[k] > 0.0)
            .map(|k| (d[k] / s[k]).abs())
            .fold(0.0, f64::max);
        println!(
            "largest error {worst:.1} standard deviations ({})",
            if worst <= 3.0 {
                "every parameter within 3 std"
            } else {
                "outside 3 std"
            }
        );
    }
    Ok(())
}
