//! Options a run would not use: each check takes the flags written on the command line
//! (`--init`, `--dvl-topic`, ...; not those left at their defaults) and what the run reads, and
//! refuses an option that would be accepted and then ignored with
//! [`Error::UnusedOption`]: why it does nothing here, and what to use instead.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::bag::is_bag;
use crate::io::dataset::DatasetFiles;

use super::dataset::Dataset;

fn has(given: &[&str], flag: &str) -> bool {
    given.contains(&flag)
}

fn refuse(msg: String) -> Result<()> {
    Err(Error::UnusedOption(msg))
}

/// The options `calibrate --method METHOD` (`uic`, `bcd` or `fixed`) would not use: `--init`
/// with uic, `--biased` without it, `--estimate-offset` without fixed, priors on what fixed
/// holds, `--offset-range` when fixed estimates nothing, `--default-lever-arm-sigma` beside
/// `--lever-arm-prior`.
pub fn method_options(method: &str, given: &[&str]) -> Result<()> {
    let fixed = method == "fixed";
    if has(given, "--lever-arm-prior") && has(given, "--default-lever-arm-sigma") {
        return refuse(
            "--default-lever-arm-sigma sets the broad prior used when no --lever-arm-prior is \
             given; --lever-arm-prior replaces it: drop one of the two"
                .into(),
        );
    }
    if method == "uic" && has(given, "--init") {
        return refuse(
            "--init is the guess of --method bcd (refined from) and --method fixed (its rotation \
             and lever arm held); --method uic, the default, starts from the data alone and \
             would not read it: add --method bcd or --method fixed, or drop --init (a measured \
             lever arm or rotation can be a prior: --lever-arm-prior, --rotation-prior)"
                .into(),
        );
    }
    if method != "uic" && has(given, "--biased") {
        return refuse(
            "--biased changes the closed-form initialisation of --method uic; --method bcd and \
             fixed start from --init and never compute it: drop --biased, or use --method uic"
                .into(),
        );
    }
    let estimate_offset = has(given, "--estimate-offset");
    if estimate_offset && !fixed {
        return refuse(
            "--estimate-offset belongs to --method fixed (the extrinsics of --init held, the \
             clock offset and scale estimated); --method uic and bcd estimate the clock offset \
             anyway: drop --estimate-offset, or add --method fixed"
                .into(),
        );
    }
    if !fixed {
        return Ok(());
    }
    for f in [
        "--lever-arm-prior",
        "--rotation-prior",
        "--default-lever-arm-sigma",
        "--offset-range",
    ] {
        let range = f == "--offset-range";
        if has(given, f) && !(range && estimate_offset) {
            let (what, or) = match range {
                true => (
                    "the clock offset of --init is held too (nothing is estimated without \
                     --estimate-offset)",
                    ", or add --estimate-offset",
                ),
                false => (
                    "the rotation and lever arm of --init are held, so a prior on them changes \
                     nothing",
                    "",
                ),
            };
            return refuse(format!(
                "{f} does nothing with --method fixed: {what}; drop {f}, or use --method bcd to \
                 refine from --init{or}"
            ));
        }
    }
    Ok(())
}

/// The options `evaluate` would not use: `--guess` and the estimator's settings apply to the
/// calibrations of the cross-validation, which `--calib` alone does not run.
pub fn evaluate_options(cross_validate: bool, given: &[&str], estimator: &[&str]) -> Result<()> {
    let unused = ["--guess"].iter().chain(estimator).find(|f| has(given, f));
    match (cross_validate, unused) {
        (false, Some(f)) => refuse(format!(
            "{f} applies to the calibrations of the cross-validation; with --calib alone the \
             calibration given is checked and nothing is calibrated: drop {f}, or add \
             --cross-validate (two or more datasets)"
        )),
        _ => Ok(()),
    }
}

/// The options of `calibrate` that only the DVL's calibration reads: refused in the camera +
/// IMU mode (no DVL log).
const DVL_ONLY: [&str; 14] = [
    "--method",
    "--dvl-sigma",
    "--offset-range",
    "--lever-arm-prior",
    "--rotation-prior",
    "--loss",
    "--default-lever-arm-sigma",
    "--model-covariance",
    "--clock-drift",
    "--dvl-sound-speed",
    "--init",
    "--estimate-offset",
    "--biased",
    "--strict",
];

/// The DVL's options that the DVL + IMU mode (no camera) reads too; the rest of [`DVL_ONLY`] it
/// does not read.
const READ_BY_DVL_IMU: [&str; 2] = ["--dvl-sigma", "--offset-range"];

/// The options a DVL + IMU run (no camera data) would not use: those only a calibration against
/// a camera reads. Checked before reading when the files show the mode, and after reading a bag
/// that turned out to hold no camera data.
pub fn dvl_imu_options(given: &[&str]) -> Result<()> {
    match DVL_ONLY
        .iter()
        .filter(|f| !READ_BY_DVL_IMU.contains(f))
        .find(|f| has(given, f))
    {
        Some(f) => refuse(format!(
            "{f} applies to a calibration against a camera; there is no camera data here, so \
             the DVL is calibrated against the IMU (DVL + IMU): drop {f}, or give the camera's \
             images, poses or bag"
        )),
        None => Ok(()),
    }
}

/// The options a dataset's inputs would not use: the bag options when no input is a bag
/// (`--dvl-topic` when the DVL log is not one), the camchain and board beside a pose file,
/// `--imu-noise` without an IMU stream, and the DVL's settings without a DVL log.
pub fn input_options(files: &DatasetFiles, given: &[&str]) -> Result<()> {
    let dvl = files
        .dvl
        .as_deref()
        .map_or("-".into(), |p| p.display().to_string());
    let dvl_bag = files.dvl.as_deref().is_some_and(is_bag);
    if has(given, "--dvl-topic") && !dvl_bag {
        return refuse(format!(
            "--dvl-topic chooses the DVL topic of a bag; the DVL log here is {dvl}, not a bag: \
             drop --dvl-topic, or give the bag as the dataset or with --dvl BAG"
        ));
    }
    let camera = match (&files.poses, &files.images) {
        (Some(p), _) => format!("the pose file {}", p.display()),
        (None, Some(d)) => format!("the image folder {}", d.display()),
        (None, None) => "no bag".into(),
    };
    let camera_bag = files.bag.is_some();
    for f in ["--image-topics", "--pose-topic", "--pose-frame"] {
        if has(given, f) && !camera_bag {
            return refuse(format!(
                "{f} chooses a topic of a bag that gives the camera data; the camera data come \
                 from {camera}: drop {f}, or give the bag as the dataset or with --bag BAG"
            ));
        }
    }
    if has(given, "--imu-topic") && !camera_bag && !dvl_bag {
        return refuse(format!(
            "--imu-topic chooses the sensor_msgs/Imu topic of a bag; no input here is a bag \
             (camera data from {camera}, DVL log {dvl}): drop --imu-topic"
        ));
    }
    if has(given, "--bag-time") && !camera_bag && !dvl_bag {
        return refuse(format!(
            "--bag-time chooses the times of a bag's messages; no input here is a bag (camera \
             data from {camera}, DVL log {dvl}): drop --bag-time (--dvl-time chooses the DVL \
             log's times)"
        ));
    }
    let bag_in = camera_bag || dvl_bag;
    if has(given, "--imu-noise") && files.imu.is_none() && !bag_in {
        return refuse(
            "--imu-noise gives the noise of an IMU stream; there is none here (no --imu FILE, \
             no imu0/data.csv in the dataset, no bag with a sensor_msgs/Imu topic): drop \
             --imu-noise, or give the IMU's stream with --imu FILE"
                .into(),
        );
    }
    if files.dvl.is_none()
        && let Some(f) = DVL_ONLY.iter().find(|f| has(given, f))
    {
        return refuse(format!(
            "{f} applies to the DVL's calibration; there is no DVL log here, so only the IMU is \
             calibrated against the camera (camera + IMU): drop {f}, or give the DVL log with \
             --dvl LOG"
        ));
    }
    let no_camera = files.poses.is_none() && files.images.is_none() && files.bag.is_none();
    if no_camera && files.imu.is_some() {
        dvl_imu_options(given)?;
    }
    if let Some(p) = &files.poses
        && let Some(f) = ["--camchain", "--target"].iter().find(|f| has(given, f))
    {
        return refuse(format!(
            "{f} is read with images; the camera poses come from the pose file {} and need \
             neither camchain nor board: drop {f}, or give the images with --images DIR instead \
             of the poses",
            p.display()
        ));
    }
    Ok(())
}

/// The image pipeline's options when the camera poses did not come from images (a pose file,
/// or a bag's pose topic).
pub fn image_options(data: &Dataset, given: &[&str]) -> Result<()> {
    let tuning = [
        "--decimate",
        "--pair-tolerance-ms",
        "--min-corners",
        "--pixel-sigma",
    ];
    match (&data.vision, tuning.iter().find(|f| has(given, f))) {
        (None, Some(f)) => refuse(format!(
            "{f} tunes the detection of the board in images; the camera poses come from {} \
             without images: drop {f}",
            data.camera_source.display()
        )),
        _ => Ok(()),
    }
}

/// The options the loaded `data` would not use: the image pipeline's ([`image_options`]), and
/// `--imu-noise` when no IMU stream was found (a bag without a sensor_msgs/Imu topic).
pub fn data_options(data: &Dataset, given: &[&str]) -> Result<()> {
    image_options(data, given)?;
    if has(given, "--imu-noise") && data.imu.is_none() {
        return refuse(format!(
            "--imu-noise gives the noise of an IMU stream; {} holds none that could be used \
             (no --imu FILE, no imu0/data.csv, no usable sensor_msgs/Imu topic): drop \
             --imu-noise, or give the IMU's stream with --imu FILE",
            data.files.root.display()
        ));
    }
    Ok(())
}

/// The bag options of a command that reads images (`detect`, `calibrate-cameras`) when the
/// images come from a folder.
pub fn image_bag_options(given: &[&str]) -> Result<()> {
    match ["--image-topics", "--bag-time"]
        .iter()
        .find(|f| has(given, f))
    {
        Some(f) => refuse(format!(
            "{f} applies to a bag's image topics; the images come from a folder (--images), \
             whose file names give the times: drop {f}, or give the bag with --bag BAG instead \
             of --images"
        )),
        None => Ok(()),
    }
}

/// `--dvl-topic` on a DVL log that is not a bag.
pub fn dvl_topic_option(log: &Path, given: &[&str]) -> Result<()> {
    match has(given, "--dvl-topic") && !is_bag(log) {
        true => refuse(format!(
            "--dvl-topic chooses the DVL topic of a bag; {} is not a bag: drop --dvl-topic",
            log.display()
        )),
        false => Ok(()),
    }
}

/// `--pose-sigma` when every pose of `poses` has its covariance from `table`.
pub fn pose_sigma_option(poses: &Path, table: Option<&Path>, given: &[&str]) -> Result<()> {
    match (has(given, "--pose-sigma"), table) {
        (true, Some(t)) => refuse(format!(
            "--pose-sigma sets the noise of poses without a covariance; every pose of {} has \
             one (from {}), which the fit uses instead: drop --pose-sigma, or move the table \
             away to fit with one noise for all poses",
            poses.display(),
            t.display()
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_options_refuse_what_the_method_ignores() {
        assert!(method_options("uic", &["--rotation-prior"]).is_ok());
        assert!(method_options("uic", &["--init"]).is_err());
        assert!(method_options("bcd", &["--init"]).is_ok());
        assert!(method_options("fixed", &["--init", "--estimate-offset"]).is_ok());
        assert!(method_options("fixed", &["--offset-range", "--estimate-offset"]).is_ok());
        assert!(method_options("fixed", &["--offset-range"]).is_err());
        let e = method_options("bcd", &["--biased"])
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--biased"), "{e}");
    }
}
