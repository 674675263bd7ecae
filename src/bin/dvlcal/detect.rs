//! `dvlcal detect`: camera poses `T_world_cam0` (board frame as world) from folders of stereo
//! images of an AprilTag board, with per-frame statistics and covariances.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use dvlcal::io::bag::frames::plan_frames;
use dvlcal::io::bag::open::OpenBag;
use dvlcal::io::camchain::read_camchain;
use dvlcal::io::tum::write_tum;
use dvlcal::io::write_atomic;
use dvlcal::pipeline::{VisionOptions, frames_csv_path, poses_from_bag, poses_from_images};

/// Detection settings shared by every command that reads images.
#[derive(Args, Debug, Clone)]
pub struct DetectTuning {
    /// Worker threads (one image pair per thread at a time; default: all cores; 4 per core max).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Decimation factor of the image for quad detection (no unit; corners are refined at full
    /// resolution).
    #[arg(long, value_name = "X", default_value_t = 2.0)]
    pub decimate: f32,
    /// Largest time difference between paired cam0 / cam1 images, milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 2.0)]
    pub pair_tolerance_ms: f64,
    /// No progress bar (it is shown only when stderr is a terminal anyway).
    #[arg(long)]
    pub no_progress: bool,
}

impl DetectTuning {
    /// The library's options for these arguments (the pose settings at their defaults).
    pub fn options(&self) -> VisionOptions {
        VisionOptions {
            threads: self.threads,
            decimate: self.decimate,
            pair_tolerance_ms: self.pair_tolerance_ms,
            progress: !self.no_progress,
            ..VisionOptions::default()
        }
    }
}

/// Detection and PnP settings shared by `detect` and `calibrate --images`.
#[derive(Args, Debug, Clone)]
pub struct VisionTuning {
    #[command(flatten)]
    pub detect: DetectTuning,
    /// Frames with fewer board corners (all cameras) get no pose.
    #[arg(long, value_name = "N", default_value_t = 8)]
    pub min_corners: usize,
    /// Corner noise (pixels) for the pose covariances (default: estimated per frame from the
    /// residuals).
    #[arg(long, value_name = "PX")]
    pub pixel_sigma: Option<f64>,
}

impl VisionTuning {
    /// The library's options for these arguments.
    pub fn options(&self) -> VisionOptions {
        VisionOptions {
            min_corners: self.min_corners,
            pixel_sigma: self.pixel_sigma,
            ..self.detect.options()
        }
    }
}

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["images", "bag"])))]
pub struct DetectArgs {
    /// Image folder: DIR/cam0/<t_ns>.png (+ DIR/cam1/...) or EuRoC's DIR/mav0/camN/data.csv.
    /// Without cam1 images the poses come from cam0 alone (with a warning); unreadable images
    /// and unpaired frames are counted and skipped.
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// A bag (ROS 1 .bag, ROS 2 .mcap / .db3 or bag folder) whose image topics are read instead
    /// of a folder, streamed.
    #[arg(long, value_name = "BAG")]
    pub bag: Option<PathBuf>,
    #[command(flatten)]
    pub bag_args: crate::bag::ImageBagArgs,
    /// Kalibr camchain YAML (intrinsics, distortion, T_cn_cnm1).
    #[arg(long, value_name = "FILE")]
    pub camchain: PathBuf,
    /// Board YAML (dvlcal grid or tag list, or Kalibr aprilgrid target).
    #[arg(long, value_name = "FILE")]
    pub target: PathBuf,
    /// TUM file of T_world_cam0 to write; per-frame statistics go to OUT.frames.csv.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    #[command(flatten)]
    pub tuning: VisionTuning,
}

pub fn run(a: DetectArgs) -> Result<()> {
    if a.images.is_some() {
        dvlcal::pipeline::unused::image_bag_options(&crate::given())?;
    }
    let frames = frames_csv_path(&a.out);
    for out in [&a.out, &frames] {
        dvlcal::files::refuse_input("--out", out, [a.camchain.as_path(), a.target.as_path()])?;
    }
    dvlcal::files::prepare_output("--out", &a.out)?;
    let opts = a.tuning.options();
    let run = match (&a.images, &a.bag) {
        (Some(dir), _) => poses_from_images(dir, &a.camchain, &a.target, &opts)?,
        (None, Some(bag)) => {
            let ob = OpenBag::open(bag, &a.bag_args.options())?;
            for n in &ob.roles.notes {
                eprintln!("note: {n}");
            }
            let tol_ns = (opts.pair_tolerance_ms * 1e6).round() as i64;
            let plan = plan_frames(&ob, tol_ns)?;
            let chain = read_camchain(&a.camchain)?;
            poses_from_bag(&ob, &plan, chain, &a.target, &opts)?
        }
        (None, None) => anyhow::bail!("give --images DIR or --bag BAG"),
    };
    crate::dataset::print_vision(&run);
    run.require_poses()?;
    write_tum(&a.out, run.epoch, &run.poses)?;
    write_atomic(&frames, run.frames_csv().as_bytes())?;
    println!("wrote {} and {}", a.out.display(), frames.display());
    Ok(())
}
