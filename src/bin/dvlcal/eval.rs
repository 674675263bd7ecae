//! `dvlcal eval-twist`: twist accuracy against a truth file.

use anyhow::{Context, Result};
use nalgebra::Vector6;
use std::path::{Path, PathBuf};

use dvlcal::eval::{TwistSample, twist_errors};
use dvlcal::io::twist_csv::read_twist_csv;
use dvlcal::time::Epoch;

#[derive(clap::Args)]
pub struct EvalTwistArgs {
    /// Twist CSV to check (from fit-trajectory).
    #[arg(long)]
    pub estimate: PathBuf,
    /// Truth twist CSV at the same times (from simulate).
    #[arg(long)]
    pub truth: PathBuf,
}

fn samples_from_csv(path: &Path) -> Result<(Epoch, Vec<TwistSample>)> {
    // The epoch only shifts times; take the first row's whole second.
    let first = std::fs::read_to_string(path)
        .with_context(|| format!("reading {}", path.display()))?
        .lines()
        .nth(1)
        .and_then(|l| l.split(',').next().map(str::to_owned))
        .and_then(|s| dvlcal::time::RawTime::parse(&s))
        .map(Epoch::at)
        .with_context(|| format!("{}: no data row", path.display()))?;
    let rows = read_twist_csv(path, first)?;
    Ok((
        first,
        rows.iter()
            .map(|r| TwistSample {
                t: r.t,
                twist: Vector6::new(r.v.x, r.v.y, r.v.z, r.w.x, r.w.y, r.w.z),
                std: Vector6::new(
                    r.std_v.x, r.std_v.y, r.std_v.z, r.std_w.x, r.std_w.y, r.std_w.z,
                ),
            })
            .collect(),
    ))
}

pub fn run(a: EvalTwistArgs) -> Result<()> {
    let (ee, est) = samples_from_csv(&a.estimate)?;
    let (et, mut truth) = samples_from_csv(&a.truth)?;
    let shift = (et.sec - ee.sec) as f64;
    truth.iter_mut().for_each(|s| s.t += shift);
    let e = twist_errors(&est, &truth).with_context(|| {
        format!(
            "comparing {} with {}",
            a.estimate.display(),
            a.truth.display()
        )
    })?;
    println!("samples                 {}", e.count);
    println!(
        "RMS error v  [m/s]      {:.5} {:.5} {:.5}  (norm {:.5})",
        e.rms[0], e.rms[1], e.rms[2], e.rms_v
    );
    println!(
        "RMS error w  [rad/s]    {:.5} {:.5} {:.5}  (norm {:.5})",
        e.rms[3], e.rms[4], e.rms[5], e.rms_w
    );
    println!(
        "mean (err/std)^2        {:.2} {:.2} {:.2} | {:.2} {:.2} {:.2}  (1 = honest std)",
        e.mean_normalized_sq[0],
        e.mean_normalized_sq[1],
        e.mean_normalized_sq[2],
        e.mean_normalized_sq[3],
        e.mean_normalized_sq[4],
        e.mean_normalized_sq[5]
    );
    Ok(())
}
