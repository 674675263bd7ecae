//! `dvlcal evaluate`: the odometry check of calibrations (DVL velocities integrated with the
//! camera's orientation against the camera's positions), and the cross-validation table over
//! several datasets.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use dvlcal::calib::{CalibOptions, Method, calibrate};
use dvlcal::eval::odometry::{Odometry, OdometryOptions, dvl_odometry};
use dvlcal::io::calib_yaml::read_calib_yaml;
use dvlcal::io::write_atomic;
use dvlcal::types::CalibrationParams;

use crate::calibrate::{MethodArg, options};
use crate::dataset::{DatasetArgs, Loaded, load, resolve};
use crate::detect::{VisionTuning, worker_pool};
use crate::dvl_info::DvlInputArgs;

#[derive(Args)]
pub struct EvaluateArgs {
    /// Dataset folders (as for `calibrate`).
    #[arg(value_name = "DATASET_DIR", required = true)]
    pub datasets: Vec<PathBuf>,
    /// A calibration (result YAML) to check on every dataset.
    #[arg(long, value_name = "FILE")]
    pub calib: Option<PathBuf>,
    /// Cross-validate: calibrate on each dataset, check on every other one (needs two or more
    /// datasets; the default when no --calib is given).
    #[arg(long)]
    pub cross_validate: bool,
    /// A user's guess of the extrinsics (result YAML schema, e.g. measured by hand): adds the
    /// baselines BCD from the guess, and the guess held fixed with and without an estimated
    /// clock offset, to the cross-validation.
    #[arg(long, value_name = "FILE")]
    pub guess: Option<PathBuf>,
    /// Time between the poses of an RPE pair, seconds.
    #[arg(long, default_value_t = 1.0)]
    pub rpe_delta: f64,
    /// Longest stretch without DVL reports that dead reckoning bridges, seconds.
    #[arg(long, default_value_t = 0.5)]
    pub max_gap: f64,
    /// Write the tables (Markdown) here as well.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Clock offsets searched when calibrating, `min,max` seconds.
    #[arg(long, value_delimiter = ',', default_values_t = [-1.0, 1.0])]
    pub offset_range: Vec<f64>,
    #[command(flatten)]
    pub vision: VisionTuning,
    #[command(flatten)]
    pub dvl_input: DvlInputArgs,
    /// Standard deviation of each DVL velocity component, m/s, replacing the reports'
    /// covariance in the calibration.
    #[arg(long = "dvl-sigma", value_name = "M_PER_S")]
    pub dvl_sigma: Option<f64>,
}

/// The name of a dataset in tables: its folder's last component.
fn short_name(l: &Loaded) -> String {
    l.files
        .root
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| l.files.root.display().to_string())
}

fn check(l: &Loaded, c: &CalibrationParams, o: &OdometryOptions) -> Result<Odometry> {
    dvl_odometry(&l.poses, &l.log.samples, c, o)
        .with_context(|| format!("odometry check on {}", l.files.root.display()))
}

/// One row of methods in the cross-validation.
struct Baseline {
    name: &'static str,
    method: Method,
}

pub fn run(a: EvaluateArgs) -> Result<()> {
    if !(a.rpe_delta.is_finite() && a.rpe_delta > 0.0) {
        bail!("--rpe-delta must be positive");
    }
    if !(a.max_gap.is_finite() && a.max_gap > 0.0) {
        bail!("--max-gap must be positive");
    }
    let cross = a.cross_validate || a.calib.is_none();
    if cross && a.datasets.len() < 2 {
        bail!("cross-validation needs two or more datasets; give --calib FILE to check one");
    }
    let odo = OdometryOptions {
        rpe_delta_s: a.rpe_delta,
        max_gap_s: a.max_gap,
    };
    let read = a.dvl_input.read_options(false);
    let mut data = Vec::with_capacity(a.datasets.len());
    for d in &a.datasets {
        let files = resolve(Some(d), &DatasetArgs::default())?;
        data.push(load(files, &a.vision, &read)?);
    }
    let mut report = String::new();

    if let Some(p) = &a.calib {
        let c = read_calib_yaml(p)?.to_params()?;
        let _ = writeln!(report, "## Odometry check of {}\n", p.display());
        let _ = writeln!(
            report,
            "| dataset | ATE (m) | RPE over {} s (m) | path (m) | ATE / path | restarts |",
            a.rpe_delta
        );
        let _ = writeln!(report, "|---|---|---|---|---|---|");
        for l in &data {
            let r = check(l, &c, &odo)?;
            let _ = writeln!(
                report,
                "| {} | {:.4} | {:.4} | {:.2} | {:.2}% | {} |",
                short_name(l),
                r.ate_m,
                r.rpe_m,
                r.path_length_m,
                100.0 * r.ate_m / r.path_length_m.max(1e-12),
                r.gaps
            );
        }
        report.push('\n');
    }

    if cross {
        let guess = match &a.guess {
            Some(p) => Some(read_calib_yaml(p)?.to_params()?),
            None => None,
        };
        let mut baselines = vec![Baseline {
            name: "UIC",
            method: Method::Uic,
        }];
        if let Some(g) = guess {
            baselines.push(Baseline {
                name: "BCD (from guess)",
                method: Method::Bcd(g),
            });
            baselines.push(Baseline {
                name: "Guess, estimated offset",
                method: Method::Fixed {
                    guess: g,
                    estimate_offset: true,
                },
            });
            baselines.push(Baseline {
                name: "Guess, its own offset",
                method: Method::Fixed {
                    guess: g,
                    estimate_offset: false,
                },
            });
        }
        let base = options(
            MethodArg::Uic,
            None,
            false,
            a.dvl_sigma,
            &a.offset_range,
            false,
        )?;
        let workers = worker_pool(a.vision.threads)?;
        // results[m][i][j]: method m calibrated on i, checked on j (i != j).
        let n = data.len();
        let mut results: Vec<Vec<Vec<Option<Odometry>>>> = Vec::new();
        for b in &baselines {
            let mut per_cal = Vec::with_capacity(n);
            for (i, li) in data.iter().enumerate() {
                let opts = CalibOptions {
                    method: b.method.clone(),
                    ..base.clone()
                };
                let o = workers
                    .install(|| calibrate(&li.poses, &li.log.samples, &opts))
                    .with_context(|| format!("{} on {}", b.name, li.files.root.display()))?;
                let c = o.params;
                eprintln!(
                    "{} on {}: offset {:.4} s, scale {:.4}, lever arm [{:.3}, {:.3}, {:.3}] m",
                    b.name,
                    short_name(li),
                    c.time_offset_s,
                    c.velocity_scale,
                    c.t_cam_dvl.trans.x,
                    c.t_cam_dvl.trans.y,
                    c.t_cam_dvl.trans.z
                );
                let mut row = Vec::with_capacity(n);
                for (j, lj) in data.iter().enumerate() {
                    row.push(if i == j {
                        None
                    } else {
                        Some(check(lj, &c, &odo)?)
                    });
                }
                per_cal.push(row);
            }
            results.push(per_cal);
        }
        cross_table(&mut report, &data, &baselines, &results, a.rpe_delta);
        if a.guess.is_none() {
            let _ = writeln!(
                report,
                "\n(--guess FILE adds the baselines: BCD from the guess, and the guess held fixed \
                 with and without an estimated clock offset.)"
            );
        }
    }

    print!("{report}");
    if let Some(out) = &a.out {
        write_atomic(out, report.as_bytes())?;
        println!("wrote {}", out.display());
    }
    Ok(())
}

fn cross_table(
    s: &mut String,
    data: &[Loaded],
    baselines: &[Baseline],
    results: &[Vec<Vec<Option<Odometry>>>],
    rpe_delta: f64,
) {
    let n = data.len();
    let names: Vec<String> = data.iter().map(short_name).collect();
    let _ = writeln!(
        s,
        "## Cross-validation: calibrated on one dataset, checked on another\n\n\
         ATE and RPE (over {rpe_delta} s) in metres; in brackets, per cent of UIC's.\n"
    );
    let mut header = String::from("| method |");
    let mut rule = String::from("|---|");
    for i in 0..n {
        for j in 0..n {
            if i != j {
                let _ = write!(header, " {} → {} ATE | RPE |", names[i], names[j]);
                rule.push_str("---|---|");
            }
        }
    }
    header.push_str(" mean ATE | mean RPE |");
    rule.push_str("---|---|");
    let _ = writeln!(s, "{header}\n{rule}");
    let mean = |m: usize, f: &dyn Fn(&Odometry) -> f64| -> f64 {
        let v: Vec<f64> = results[m].iter().flatten().flatten().map(f).collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    for (m, b) in baselines.iter().enumerate() {
        let _ = write!(s, "| {} |", b.name);
        let cell = |s: &mut String, x: f64, reference: f64| {
            if m == 0 || reference.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                let _ = write!(s, " {x:.4} |");
            } else {
                let _ = write!(s, " {x:.4} ({:.0}%) |", 100.0 * x / reference);
            }
        };
        for (mine, uic) in results[m].iter().zip(&results[0]) {
            for (r, u) in mine.iter().zip(uic) {
                if let (Some(r), Some(u)) = (r, u) {
                    cell(s, r.ate_m, u.ate_m);
                    cell(s, r.rpe_m, u.rpe_m);
                }
            }
        }
        cell(s, mean(m, &|r| r.ate_m), mean(0, &|r| r.ate_m));
        cell(s, mean(m, &|r| r.rpe_m), mean(0, &|r| r.rpe_m));
        s.push('\n');
    }
}
