//! `dvlcal calibrate-cameras`: intrinsics, distortion and stereo extrinsics of every camera from
//! images of a board, written as a Kalibr camchain (with an HTML report).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use dvlcal::camcal::{CamCalOptions, CameraModel};
use dvlcal::io::bag::frames::plan_frames;
use dvlcal::io::bag::open::OpenBag;
use dvlcal::pipeline::{
    CameraCalOptions, calibrate_cameras_from_bag, calibrate_cameras_from_images,
};

use crate::detect::DetectTuning;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["images", "bag"])))]
pub struct CalibrateCamerasArgs {
    /// Image folder: DIR/cam0/<t_ns>.png (+ DIR/cam1/...) or EuRoC's DIR/mav0/camN/data.csv; every
    /// camN folder present is calibrated.
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// A bag (ROS 1 .bag, ROS 2 .mcap / .db3 or bag folder) whose image topics are calibrated
    /// (streamed; one pass per detection pass).
    #[arg(long, value_name = "BAG")]
    pub bag: Option<PathBuf>,
    #[command(flatten)]
    pub bag_args: crate::bag::ImageBagArgs,
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
    if a.images.is_some() {
        dvlcal::pipeline::unused::image_bag_options(&crate::given())?;
    }
    let Some(model) = CameraModel::from_name(&a.model) else {
        bail!("--model {}: use pinhole-radtan or pinhole-equi", a.model);
    };
    dvlcal::files::refuse_input("--out", &a.out, [a.target.as_path()])?;
    dvlcal::files::prepare_output("--out", &a.out)?;
    if let Some(r) = &a.report {
        dvlcal::files::refuse_input("--report", r, [a.target.as_path(), a.out.as_path()])?;
        dvlcal::files::prepare_output("--report", r)?;
    }
    let opts = CameraCalOptions {
        vision: a.tuning.options(),
        camcal: CamCalOptions {
            model,
            ..CamCalOptions::default()
        },
        second_pass: !a.single_pass,
    };
    let run = match (&a.images, &a.bag) {
        (Some(dir), _) => calibrate_cameras_from_images(dir, &a.target, &opts)
            .with_context(|| format!("calibrating the cameras of {}", dir.display()))?,
        (None, Some(bag)) => {
            let ob = OpenBag::open(bag, &a.bag_args.options())?;
            let tol_ns = (opts.vision.pair_tolerance_ms * 1e6).round() as i64;
            let plan = plan_frames(&ob, tol_ns)?;
            calibrate_cameras_from_bag(&ob, &plan, &a.target, &opts)
                .with_context(|| format!("calibrating the cameras of {}", bag.display()))?
        }
        (None, None) => bail!("give --images DIR or --bag BAG"),
    };
    print!("{}", run.summary());
    run.write_camchain(&a.out)?;
    println!("wrote {}", a.out.display());
    if let Some(r) = &a.report {
        let command = dvlcal::io::provenance::this_command_line();
        run.write_report(r, &a.out, Some(command))?;
        println!("wrote {}", r.display());
    }
    Ok(())
}
