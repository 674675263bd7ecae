//! `dvlcal calibrate`: DVL extrinsics, clock offset and scale from camera poses and a DVL log.

use anyhow::{Context, Result, bail};
use clap::ValueEnum;
use std::path::PathBuf;

use crate::dataset::{DatasetArgs, load};
use crate::dvl_info::DvlInputArgs;

use dvlcal::calib::{CalibOptions, Method};
use dvlcal::io::calib_yaml::read_calib_yaml;
use dvlcal::pipeline::{calibrate_dataset, write_report, write_results};
use dvlcal::types::CalibrationParams;

#[derive(Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// Initialise from the data alone, then refine (no guess needed).
    Uic,
    /// Refine from the guess given with --init.
    Bcd,
    /// Keep the extrinsics of --init; with --estimate-offset estimate clock offset and scale.
    Fixed,
}

#[derive(clap::Args)]
pub struct CalibrateArgs {
    /// Dataset folder: cam0/ (+ cam1/) images or a TUM pose file, a Kalibr camchain YAML, a
    /// board YAML and a DVL log, recognised by their content. Options below override parts.
    #[arg(value_name = "DATASET_DIR")]
    pub dataset: Option<PathBuf>,
    #[command(flatten)]
    pub files: DatasetArgs,
    #[command(flatten)]
    pub vision: crate::detect::VisionTuning,
    #[command(flatten)]
    pub dvl_input: DvlInputArgs,
    /// Standard deviation of each DVL velocity component, m/s, replacing the reports'
    /// covariance in the calibration.
    #[arg(long = "dvl-sigma", value_name = "M_PER_S")]
    pub dvl_sigma: Option<f64>,
    /// Stop at the first malformed DVL line instead of skipping and counting it.
    #[arg(long)]
    pub strict: bool,
    /// Result YAML (written atomically); beside it RESULT-tf.txt (ROS static transform) and
    /// RESULT-camchain-dvl.yaml (Kalibr-style block).
    #[arg(long, default_value = "calibration.yaml")]
    pub out: PathBuf,
    #[arg(long, value_enum, default_value = "uic")]
    pub method: MethodArg,
    /// Initial guess or fixed extrinsics (result YAML schema), for --method bcd and fixed.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// Clock offsets searched, `min,max` seconds (t_cam = t_dvl + offset).
    #[arg(long, value_delimiter = ',', default_values_t = [-1.0, 1.0])]
    pub offset_range: Vec<f64>,
    /// With --method fixed: estimate clock offset and scale with the extrinsics held.
    #[arg(long)]
    pub estimate_offset: bool,
    /// Use the closed form without bias elimination (for comparison only).
    #[arg(long)]
    pub biased: bool,
    /// Self-contained HTML report with plots (written atomically; opens offline).
    #[arg(long, value_name = "REPORT.html")]
    pub report: Option<PathBuf>,
}

/// The calibration options of the command line; `guess` is the parsed `--init`.
pub fn options(
    method: MethodArg,
    guess: Option<CalibrationParams>,
    estimate_offset: bool,
    dvl_sigma: Option<f64>,
    offset_range: &[f64],
    biased: bool,
) -> Result<CalibOptions> {
    let [lo, hi] = offset_range else {
        bail!("--offset-range takes two increasing values: min,max");
    };
    let method = match (method, guess) {
        (MethodArg::Uic, _) => Method::Uic,
        (MethodArg::Bcd, Some(g)) => Method::Bcd(g),
        (MethodArg::Fixed, Some(g)) => Method::Fixed {
            guess: g,
            estimate_offset,
        },
        (_, None) => bail!("--method bcd and fixed need --init FILE"),
    };
    let mut opts = CalibOptions {
        method,
        dvl_sigma,
        bias_corrected: !biased,
        ..CalibOptions::default()
    };
    opts.offset.range = (*lo, *hi);
    opts.validate()?;
    Ok(opts)
}

pub fn run(a: CalibrateArgs) -> Result<()> {
    let guess = match &a.init {
        Some(p) => Some(read_calib_yaml(p)?.to_params()?),
        None => None,
    };
    let opts = options(
        a.method,
        guess,
        a.estimate_offset,
        a.dvl_sigma,
        &a.offset_range,
        a.biased,
    )?;
    let data = load(
        a.dataset.as_deref(),
        &a.files,
        &a.vision.options(),
        &a.dvl_input.read_options(a.strict),
    )?;
    let run = calibrate_dataset(&data, &opts, a.vision.threads).with_context(|| {
        format!(
            "calibrating {} against {}",
            data.dvl_path.display(),
            data.camera_source.display()
        )
    })?;
    let paths = write_results(&a.out, &run, &data)?;
    print!("{}", run.summary(&data.log));
    println!(
        "wrote {}, {} and {}",
        paths.result.display(),
        paths.tf.display(),
        paths.camchain_block.display()
    );
    if let Some(path) = &a.report {
        write_report(path, &run, &data, &paths.result).context("building the report")?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
