//! The dataset arguments `calibrate` and `evaluate` share, and loading with progress printed.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;

use crate::detect::VisionTuning;
use crate::dvl_info::DvlInputArgs;

use dvlcal::io::bag::is_bag;
use dvlcal::io::dataset::{DatasetFiles, DatasetOverrides};
use dvlcal::io::dvl::DvlReadOptions;
use dvlcal::pipeline::{Dataset, VisionOptions, VisionRun, dataset_files, describe_files};

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
    #[command(flatten)]
    pub bag_args: crate::bag::BagArgs,
}

impl DatasetArgs {
    fn overrides(&self, read: &DvlReadOptions) -> DatasetOverrides {
        DatasetOverrides {
            images: self.images.clone(),
            camchain: self.camchain.clone(),
            target: self.target.clone(),
            dvl: self.dvl.clone(),
            poses: self.poses.clone(),
            bag: self.bag.clone(),
            bag_options: self.bag_args.options(read.topic.clone()),
        }
    }
}

/// Finds a dataset's files, printing what was found (for a folder).
pub fn find(dir: Option<&Path>, args: &DatasetArgs, read: &DvlReadOptions) -> Result<DatasetFiles> {
    let files = dataset_files(dir, &args.overrides(read))?;
    if dir.is_some() {
        print!("{}", describe_files(&files));
    }
    Ok(files)
}

/// Refuses the options a dataset's inputs would not use: the bag options when no input is a bag
/// (`--dvl-topic` when the DVL log is not one), and the camchain and board when the camera poses
/// come from a pose file. Says why, and what to use instead.
pub fn refuse_unused_inputs(
    files: &DatasetFiles,
    args: &DatasetArgs,
    dvl: &DvlInputArgs,
) -> Result<()> {
    let dvl_bag = files.dvl.as_deref().is_some_and(is_bag);
    if dvl.dvl_topic.is_some() && !dvl_bag {
        return crate::refuse(format!(
            "--dvl-topic chooses the DVL topic of a bag; the DVL log here is {}, not a bag: drop \
             --dvl-topic, or give the bag as the dataset or with --dvl BAG",
            files
                .dvl
                .as_deref()
                .map_or("-".into(), |p| p.display().to_string())
        ));
    }
    let camera_bag = files.bag.is_some();
    let camera = match (&files.poses, &files.images) {
        (Some(p), _) => format!("the pose file {}", p.display()),
        (None, Some(d)) => format!("the image folder {}", d.display()),
        (None, None) => "no bag".into(),
    };
    let bag_only = [
        (args.bag_args.image_topics.is_some(), "--image-topics"),
        (args.bag_args.pose_topic.is_some(), "--pose-topic"),
        (args.bag_args.pose_frame.is_some(), "--pose-frame"),
    ];
    if let (false, Some((_, f))) = (camera_bag, bag_only.iter().find(|(g, _)| *g)) {
        return crate::refuse(format!(
            "{f} chooses a topic of a bag that gives the camera data; the camera data come from \
             {camera}: drop {f}, or give the bag as the dataset or with --bag BAG"
        ));
    }
    if crate::given("bag_time") && !camera_bag && !dvl_bag {
        return crate::refuse(format!(
            "--bag-time chooses the times of a bag's messages; no input here is a bag (camera \
             data from {camera}, DVL log {}): drop --bag-time (--dvl-time chooses the DVL log's \
             times)",
            files
                .dvl
                .as_deref()
                .map_or("-".into(), |p| p.display().to_string())
        ));
    }
    if let Some(p) = &files.poses {
        for (g, f) in [
            (args.camchain.is_some(), "--camchain"),
            (args.target.is_some(), "--target"),
        ] {
            if g {
                return crate::refuse(format!(
                    "{f} is read with images; the camera poses come from the pose file {} and \
                     need neither camchain nor board: drop {f}, or give the images with --images \
                     DIR instead of the poses",
                    p.display()
                ));
            }
        }
    }
    Ok(())
}

/// Refuses the image pipeline's options when the camera poses did not come from images (a pose
/// file, or a bag's pose topic).
pub fn refuse_unused_image_options(data: &Dataset, vision: &VisionTuning) -> Result<()> {
    if data.vision.is_some() {
        return Ok(());
    }
    let options = [
        ("decimate", "--decimate"),
        ("pair_tolerance_ms", "--pair-tolerance-ms"),
        ("min_corners", "--min-corners"),
    ];
    let given = options
        .iter()
        .find(|(id, _)| crate::given(id))
        .map(|(_, f)| *f)
        .or(vision.pixel_sigma.map(|_| "--pixel-sigma"));
    match given {
        Some(f) => crate::refuse(format!(
            "{f} tunes the detection of the board in images; the camera poses come from {} \
             without images: drop {f}",
            data.camera_source.display()
        )),
        None => Ok(()),
    }
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
    let st = &data.log.stats;
    if st.rejected_lines > 0 {
        eprintln!(
            "{}: {} malformed lines skipped (dvlcal dvl-info lists them)",
            data.dvl_path.display(),
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
