//! The dataset arguments `calibrate` and `evaluate` share, and loading with progress printed.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;

use dvlcal::io::dataset::{DatasetFiles, DatasetOverrides};
use dvlcal::io::dvl::DvlReadOptions;
use dvlcal::pipeline::{Dataset, VisionOptions, VisionRun, dataset_files_checked, describe_files};

/// The parts of a dataset that can be named on the command line.
#[derive(Args, Debug, Clone, Default)]
pub struct DatasetArgs {
    /// TUM file of T_world_cam (camera clock), instead of images; covariances from
    /// POSES.frames.csv beside it when there is one (as `dvlcal detect` writes it).
    #[arg(long, conflicts_with = "images")]
    pub poses: Option<PathBuf>,
    /// Image folder (DIR/cam0, DIR/cam1 or EuRoC's DIR/mav0/camN): poses and their covariances
    /// come from `dvlcal detect`'s pipeline (needs a target; without a camchain the cameras are
    /// calibrated from the same images first).
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// Kalibr camchain YAML, with images (default: calibrate the cameras from the images).
    #[arg(long, value_name = "FILE")]
    pub camchain: Option<PathBuf>,
    /// Board YAML (dvlcal grid or list, or a Kalibr aprilgrid), with images.
    #[arg(long, value_name = "FILE")]
    pub target: Option<PathBuf>,
    /// Water Linked A50 log: JSON lines (any json_v1..v3 version), serial capture, or a ROS
    /// bag (ROS 1, or ROS 2 MCAP / sqlite3).
    #[arg(long)]
    pub dvl: Option<PathBuf>,
    /// A bag (ROS 1 .bag, ROS 2 .mcap / .db3 or bag folder) giving the images or poses, and the
    /// DVL data unless --dvl names a log.
    #[arg(long, value_name = "BAG")]
    pub bag: Option<PathBuf>,
    /// IMU stream, EuRoC's IMU CSV (ns, rad/s, m/s^2); wins over imu0/data.csv and a bag's
    /// Imu topic. Without a DVL log: camera + IMU (T_cam_imu, imu_time_offset_s alone).
    #[arg(long, value_name = "FILE")]
    pub imu: Option<PathBuf>,
    /// The IMU's noise, Kalibr's imu.yaml (for --imu, imu0/data.csv or a bag's Imu topic).
    #[arg(long, value_name = "FILE")]
    pub imu_noise: Option<PathBuf>,
    #[command(flatten)]
    pub bag_args: crate::bag::BagArgs,
}

impl DatasetArgs {
    pub fn overrides(&self, read: &DvlReadOptions) -> DatasetOverrides {
        DatasetOverrides {
            images: self.images.clone(),
            camchain: self.camchain.clone(),
            target: self.target.clone(),
            dvl: self.dvl.clone(),
            poses: self.poses.clone(),
            bag: self.bag.clone(),
            bag_options: self.bag_args.options(read.topic.clone()),
            imu: self.imu.clone(),
            imu_noise: self.imu_noise.clone(),
        }
    }
}

/// Finds a dataset's files, printing what was found (for a folder).
pub fn find(dir: Option<&Path>, args: &DatasetArgs, read: &DvlReadOptions) -> Result<DatasetFiles> {
    let files = dataset_files_checked(dir, &args.overrides(read))?;
    if dir.is_some() {
        print!("{}", describe_files(&files));
    }
    Ok(files)
}

/// Reads the dataset `files` name, printing the camera calibration (images without a
/// camchain), the image pipeline's summary and warnings, and the DVL log's skipped lines.
pub fn read_files(
    files: DatasetFiles,
    vision: &VisionOptions,
    read: &DvlReadOptions,
) -> Result<Dataset> {
    if files.calibrates_cameras() {
        println!("no camchain: calibrating the cameras from the same images first");
    }
    let data = Dataset::load_observed(
        files,
        vision,
        read,
        &mut |c| print!("{}", c.summary()),
        &mut print_vision,
    )?;
    for n in &data.notes {
        eprintln!("note: {n}");
    }
    if let Some(st) = data.log.as_ref().map(|l| &l.stats)
        && st.rejected_lines > 0
    {
        eprintln!(
            "{}: {} malformed lines skipped (dvlcal dvl-info lists them)",
            st.path.display(),
            st.rejected_lines
        );
    }
    Ok(data)
}

/// Prints an image run's warnings and skipped images (stderr) and its summary (stdout).
pub fn print_vision(run: &VisionRun) {
    for w in &run.scan.warnings {
        eprintln!("warning: {w}");
    }
    const SHOWN: usize = 10;
    let problems = &run.stats.problems;
    for p in problems.iter().take(SHOWN) {
        eprintln!("skipped: {p}");
    }
    if problems.len() > SHOWN {
        eprintln!("skipped: ... and {} more images", problems.len() - SHOWN);
    }
    print!("{}", run.summary());
}
