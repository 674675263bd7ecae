//! `dvlcal evaluate`: the odometry check of calibrations (DVL velocities integrated with the
//! camera's orientation against the camera's positions), and the cross-validation table over
//! several datasets.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;

use dvlcal::eval::odometry::OdometryOptions;
use dvlcal::io::calib_yaml::read_calibration_guess;
use dvlcal::io::write_atomic;
use dvlcal::pipeline::{baselines, cross_validate, odometry_table, unused};

use crate::calibrate::{EstimatorArgs, MethodArg, options};
use crate::dataset::{DatasetArgs, find, read_files};
use crate::detect::VisionTuning;
use crate::dvl_info::DvlInputArgs;

#[derive(Args)]
pub struct EvaluateArgs {
    /// Dataset folders or bags (as for `calibrate`).
    #[arg(value_name = "DATASET", required = true)]
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
    #[command(flatten)]
    pub vision: VisionTuning,
    #[command(flatten)]
    pub dvl_input: DvlInputArgs,
    #[command(flatten)]
    pub bag_args: crate::bag::BagArgs,
    #[command(flatten)]
    pub estimator: EstimatorArgs,
}

pub fn run(a: EvaluateArgs) -> Result<()> {
    let odo = OdometryOptions {
        rpe_delta_s: a.rpe_delta,
        max_gap_s: a.max_gap,
    };
    odo.validate()?;
    if let Some(out) = &a.out {
        dvlcal::files::prepare_output("--out", out)?;
    }
    let cross = a.cross_validate || a.calib.is_none();
    if cross && a.datasets.len() < 2 {
        bail!("cross-validation needs two or more datasets; give --calib FILE to check one");
    }
    let given = crate::given();
    let estimator = EstimatorArgs::flags();
    let estimator: Vec<&str> = estimator.iter().map(String::as_str).collect();
    unused::evaluate_options(cross, &given, &estimator)?;
    let read = a.dvl_input.read_options(false);
    let vision = a.vision.options();
    let args = DatasetArgs {
        bag_args: a.bag_args.clone(),
        ..DatasetArgs::default()
    };
    let mut found = Vec::with_capacity(a.datasets.len());
    for d in &a.datasets {
        found.push(find(Some(d), &args, &read)?);
    }
    // An option that applies to some dataset is used; one that applies to none is refused.
    let checks = found.iter().map(|f| unused::input_options(f, &given));
    checks.reduce(|a, b| a.or(b)).transpose()?;
    let mut data = Vec::with_capacity(a.datasets.len());
    for files in found {
        data.push(read_files(files, &vision, &read)?);
    }
    let checks = data.iter().map(|d| unused::image_options(d, &given));
    checks.reduce(|a, b| a.or(b)).transpose()?;
    let mut report = String::new();
    if let Some(p) = &a.calib {
        let c = read_calibration_guess(p)?;
        report.push_str(&odometry_table(&p.display().to_string(), &data, &c, &odo)?);
    }
    if cross {
        let guess = match &a.guess {
            Some(p) => Some(read_calibration_guess(p)?),
            None => None,
        };
        let base = options(MethodArg::Uic, None, false, &a.estimator, false)?;
        let cv = cross_validate(
            &data,
            baselines(guess),
            &base,
            &odo,
            a.vision.detect.threads,
            &mut |line| eprintln!("{line}"),
        )?;
        report.push_str(&cv.markdown());
        if a.guess.is_none() {
            report.push_str(
                "\n(--guess FILE adds the baselines: BCD from the guess, and the guess held fixed \
                 with and without an estimated clock offset.)\n",
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
