//! `dvlcal calibrate-cameras`: intrinsics, distortion and stereo extrinsics of every camera from
//! images of a board, written as a Kalibr camchain (with an HTML report).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use dvlcal::camcal::{CamCalOptions, CameraModel};
use dvlcal::pipeline::{CameraCalOptions, calibrate_cameras_from_images};

use crate::detect::DetectTuning;

#[derive(Args, Debug)]
pub struct CalibrateCamerasArgs {
    /// Image folder: DIR/cam0/<t_ns>.png (+ DIR/cam1/...) or EuRoC's DIR/mav0/camN/data.csv; every
    /// camN folder present is calibrated.
    #[arg(long, value_name = "DIR")]
    pub images: PathBuf,
    /// Board YAML (dvlcal grid or tag list, or Kalibr aprilgrid target); the board must be flat.
    #[arg(long, value_name = "FILE")]
    pub target: PathBuf,
    /// Kalibr camchain YAML to write (with each parameter's standard deviation).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Camera model: pinhole-radtan (most lenses) or pinhole-equi (wide-angle and fisheye).
    #[arg(long, value_name = "MODEL", default_value = "pinhole-radtan")]
    pub model: String,
    /// HTML report to write (residuals per camera, coverage of the images, per-frame RMS).
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// One detection pass only (corners fitted in the distorted image; faster, less accurate).
    #[arg(long)]
    pub single_pass: bool,
    #[command(flatten)]
    pub tuning: DetectTuning,
}

pub fn run(a: CalibrateCamerasArgs) -> Result<()> {
    let Some(model) = CameraModel::from_name(&a.model) else {
        bail!("--model {}: use pinhole-radtan or pinhole-equi", a.model);
    };
    dvlcal::files::refuse_input("--out", &a.out, [a.target.as_path()])?;
    if let Some(r) = &a.report {
        dvlcal::files::refuse_input("--report", r, [a.target.as_path(), a.out.as_path()])?;
    }
    let opts = CameraCalOptions {
        vision: a.tuning.options(),
        camcal: CamCalOptions {
            model,
            ..CamCalOptions::default()
        },
        second_pass: !a.single_pass,
    };
    let run = calibrate_cameras_from_images(&a.images, &a.target, &opts)
        .with_context(|| format!("calibrating the cameras of {}", a.images.display()))?;
    print!("{}", run.summary());
    run.write_camchain(&a.out)?;
    println!("wrote {}", a.out.display());
    if let Some(r) = &a.report {
        let command = std::env::args().collect::<Vec<_>>().join(" ");
        run.write_report(r, &a.out, Some(command))?;
        println!("wrote {}", r.display());
    }
    Ok(())
}
