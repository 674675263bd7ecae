//! Checking calibrations on data: the odometry check (DVL velocities integrated with the
//! camera's orientation against the camera's positions) and the cross-validation over several
//! datasets (calibrate on one, check on the others), with their Markdown tables.

use std::fmt::Write as _;

use crate::calib::{CalibOptions, Method, calibrate};
use crate::error::{Error, Result};
use crate::eval::odometry::{Odometry, OdometryOptions, dvl_odometry};
use crate::types::CalibrationParams;

use super::dataset::Dataset;

/// The odometry check of `calib` on one dataset.
pub fn odometry_check(
    data: &Dataset,
    calib: &CalibrationParams,
    opts: &OdometryOptions,
) -> Result<Odometry> {
    dvl_odometry(&data.poses, &data.dvl()?.samples, calib, opts)
}

/// The odometry table of one calibration over datasets (Markdown): ATE, RPE, path length, ATE
/// per path length, and dead-reckoning restarts per dataset.
pub fn odometry_table(
    title: &str,
    data: &[Dataset],
    calib: &CalibrationParams,
    opts: &OdometryOptions,
) -> Result<String> {
    let mut s = String::new();
    let _ = writeln!(s, "## Odometry check of {title}\n");
    let _ = writeln!(
        s,
        "| dataset | ATE (m) | RPE over {} s (m) | path (m) | ATE / path | restarts |",
        opts.rpe_delta_s
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for d in data {
        let r = odometry_check(d, calib, opts).map_err(|e| in_dataset(d, "odometry check", e))?;
        let _ = writeln!(
            s,
            "| {} | {:.4} | {:.4} | {:.2} | {:.2}% | {} |",
            d.short_name(),
            r.ate_m,
            r.rpe_m,
            r.path_length_m,
            100.0 * r.ate_m / r.path_length_m.max(1e-12),
            r.gaps
        );
    }
    s.push('\n');
    Ok(s)
}

/// An error of a step on one dataset, naming the step and the dataset.
fn in_dataset(d: &Dataset, step: &str, e: Error) -> Error {
    e.during(format!("{step} on {}", d.files.root.display()))
}

/// One method of the cross-validation.
#[derive(Clone, Debug)]
pub struct Baseline {
    /// Its name in the table.
    pub name: &'static str,
    /// How it calibrates.
    pub method: Method,
}

/// The methods compared: UIC, and with a user's guess of the extrinsics, BCD from the guess and
/// the guess held fixed with and without an estimated clock offset.
pub fn baselines(guess: Option<CalibrationParams>) -> Vec<Baseline> {
    let mut b = vec![Baseline {
        name: "UIC",
        method: Method::Uic,
    }];
    if let Some(g) = guess {
        b.push(Baseline {
            name: "BCD (from guess)",
            method: Method::Bcd(g),
        });
        b.push(Baseline {
            name: "Guess, estimated offset",
            method: Method::Fixed {
                guess: g,
                estimate_offset: true,
            },
        });
        b.push(Baseline {
            name: "Guess, its own offset",
            method: Method::Fixed {
                guess: g,
                estimate_offset: false,
            },
        });
    }
    b
}

/// The cross-validation's results: `results[m][i][j]` is method `m` calibrated on dataset `i`
/// and checked on dataset `j` (`None` on the diagonal).
#[derive(Clone, Debug)]
pub struct CrossValidation {
    /// The datasets' names.
    pub names: Vec<String>,
    /// The methods.
    pub baselines: Vec<Baseline>,
    /// The odometry checks.
    pub results: Vec<Vec<Vec<Option<Odometry>>>>,
    /// The RPE interval of the checks, s.
    pub rpe_delta_s: f64,
}

/// Calibrates every dataset with every method (`base` with the method replaced) on a pool of
/// `threads` workers and checks each calibration on every other dataset. `progress` is told each
/// calibration's result in a line. Needs two datasets or more.
pub fn cross_validate(
    data: &[Dataset],
    baselines: Vec<Baseline>,
    base: &CalibOptions,
    odo: &OdometryOptions,
    threads: Option<usize>,
    progress: &mut dyn FnMut(&str),
) -> Result<CrossValidation> {
    if data.len() < 2 {
        return Err(Error::Input(
            "cross-validation needs two or more datasets; give --calib FILE to check one".into(),
        ));
    }
    let workers = crate::parallel::worker_pool(threads)?;
    let n = data.len();
    let mut results = Vec::with_capacity(baselines.len());
    for b in &baselines {
        let mut per_cal = Vec::with_capacity(n);
        for (i, di) in data.iter().enumerate() {
            let opts = CalibOptions {
                method: b.method.clone(),
                ..base.clone()
            };
            let log = di.dvl()?;
            let o = workers
                .install(|| calibrate(&di.poses, &log.samples, &opts))
                .map_err(|e| in_dataset(di, b.name, e))?;
            let c = o.params;
            progress(&format!(
                "{} on {}: offset {:.4} s, scale {:.4}, lever arm [{:.3}, {:.3}, {:.3}] m",
                b.name,
                di.short_name(),
                c.time_offset_s,
                c.velocity_scale,
                c.t_cam_dvl.trans.x,
                c.t_cam_dvl.trans.y,
                c.t_cam_dvl.trans.z
            ));
            let mut row = Vec::with_capacity(n);
            for (j, dj) in data.iter().enumerate() {
                row.push(if i == j {
                    None
                } else {
                    Some(
                        odometry_check(dj, &c, odo)
                            .map_err(|e| in_dataset(dj, "odometry check", e))?,
                    )
                });
            }
            per_cal.push(row);
        }
        results.push(per_cal);
    }
    Ok(CrossValidation {
        names: data.iter().map(Dataset::short_name).collect(),
        baselines,
        results,
        rpe_delta_s: odo.rpe_delta_s,
    })
}

impl CrossValidation {
    /// The table (Markdown): one row per method, ATE and RPE per ordered pair of datasets and
    /// their means, with each method's figures in per cent of UIC's.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let names = &self.names;
        let n = names.len();
        let _ = writeln!(
            s,
            "## Cross-validation: calibrated on one dataset, checked on another\n\n\
             ATE and RPE (over {} s) in metres; in brackets, per cent of UIC's.\n",
            self.rpe_delta_s
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
        let results = &self.results;
        let mean = |m: usize, f: &dyn Fn(&Odometry) -> f64| -> f64 {
            let v: Vec<f64> = results[m].iter().flatten().flatten().map(f).collect();
            v.iter().sum::<f64>() / v.len().max(1) as f64
        };
        for (m, b) in self.baselines.iter().enumerate() {
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
                        cell(&mut s, r.ate_m, u.ate_m);
                        cell(&mut s, r.rpe_m, u.rpe_m);
                    }
                }
            }
            cell(&mut s, mean(m, &|r| r.ate_m), mean(0, &|r| r.ate_m));
            cell(&mut s, mean(m, &|r| r.rpe_m), mean(0, &|r| r.rpe_m));
            s.push('\n');
        }
        s
    }
}
