//! `dvlcal calibrate`: DVL extrinsics, clock offset and scale from camera poses and a DVL log.

use anyhow::{Context, Result, bail};
use clap::ValueEnum;
use std::path::PathBuf;

use crate::dataset::{DatasetArgs, find, read_files};
use crate::dvl_info::DvlInputArgs;

use dvlcal::calib::prior::{LeverArmPrior, Priors, RotationPrior, SigmaOrNone, VectorSigma};
use dvlcal::calib::robust::Loss;
use dvlcal::calib::{CalibOptions, Method, Setting, Status};
use dvlcal::error::Error;
use dvlcal::io::calib_yaml::{read_calibration_guess, rotation_from_rpy_deg};
use dvlcal::io::exports::FrameNames;
use dvlcal::io::provenance::this_command_line;
use dvlcal::pipeline::dvl_imu;
use dvlcal::pipeline::{
    CameraOutputs, OutputOptions, SEPARATE_CAMERA_RECORDING, VisionOptions,
    calibrate_camera_imu_dataset, calibrate_dataset, calibration_context, check_result_outputs,
    unused, write_camera_imu_results, write_failure_report, write_report, write_results,
    wrote_words,
};
use dvlcal::types::CalibrationParams;
use dvlcal::vision::detect::DetectionCache;

#[derive(Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// Initialise from the data alone, then refine (no guess needed).
    Uic,
    /// Refine from the guess given with --init.
    Bcd,
    /// Keep the extrinsics of --init; with --estimate-offset estimate clock offset and scale.
    Fixed,
}

/// Estimator settings shared by `calibrate` and `evaluate`.
#[derive(clap::Args)]
pub struct EstimatorArgs {
    /// Standard deviation of each DVL velocity component, m/s, replacing the reports'
    /// covariance in the calibration.
    #[arg(long = "dvl-sigma", value_name = "M_PER_S")]
    pub dvl_sigma: Option<f64>,
    /// Limit of the clock offset, `min,max` seconds (t_cam = t_dvl + offset); default: any
    /// offset at which the camera and DVL logs overlap, found by a global alignment.
    #[arg(long, value_delimiter = ',', value_name = "MIN,MAX")]
    pub offset_range: Option<Vec<f64>>,
    /// A measured lever arm, the DVL origin in the camera frame, `x,y,z` metres, with its
    /// standard deviation in metres after a colon (default 0.02 m): a prior of the calibration.
    #[arg(long, value_name = "X,Y,Z[:SIGMA_M]")]
    pub lever_arm_prior: Option<VectorSigma>,
    /// A known rotation R_cam_dvl as `roll,pitch,yaw` degrees (Rz(yaw) Ry(pitch) Rx(roll)),
    /// with its standard deviation in degrees after a colon (default 2 deg): a prior of the
    /// calibration.
    #[arg(long, value_name = "ROLL,PITCH,YAW[:SIGMA_DEG]")]
    pub rotation_prior: Option<VectorSigma>,
    /// Loss on the DVL and pose residuals: `cauchy` (outliers lose their pull), `huber`
    /// (outliers keep a bounded pull) or `l2` (least squares, every sample at full weight). The
    /// loss applies only when some residual is an outlier.
    #[arg(long, default_value = "cauchy", value_name = "cauchy|huber|l2")]
    pub loss: String,
    /// Standard deviation, metres, of the broad prior that keeps an unobserved lever arm near
    /// zero when no --lever-arm-prior is given; `none` turns it off.
    #[arg(long, default_value = "1", value_name = "SIGMA_M|none")]
    pub default_lever_arm_sigma: SigmaOrNone,
    /// Keep the standard deviations as the noise model states them: no inflation for
    /// correlated DVL residuals or for halves of the recording that disagree.
    #[arg(long)]
    pub model_covariance: bool,
    /// Estimate the DVL clock's drift (clock_drift_ppm, about the middle of the log: docs/method.md)
    #[arg(long)]
    pub clock_drift: bool,
}

impl EstimatorArgs {
    /// The long flags of these settings.
    pub fn flags() -> Vec<String> {
        let cmd = <Self as clap::Args>::augment_args(clap::Command::new("estimator"));
        cmd.get_arguments()
            .filter_map(|a| a.get_long().map(|l| format!("--{l}")))
            .collect()
    }

    fn priors(&self) -> Priors {
        Priors {
            lever_arm: self.lever_arm_prior.as_ref().map(|p| LeverArmPrior {
                lever_arm_cam_m: p.v.into(),
                sigma_m: p.sigma.unwrap_or(0.02),
            }),
            rotation: self.rotation_prior.as_ref().map(|p| RotationPrior {
                r_cam_dvl: rotation_from_rpy_deg(&p.v),
                sigma_deg: p.sigma.unwrap_or(2.0),
            }),
            ..Priors::default()
        }
    }
}

#[derive(clap::Args)]
pub struct CalibrateArgs {
    /// Dataset folder: cam0/ (+ cam1/) images or a TUM pose file, a Kalibr camchain YAML, a
    /// board YAML and a DVL log, recognised by their content (a bag may stand in for the
    /// images and the log); or a bag itself (ROS 1 .bag, ROS 2 .mcap / .db3 / bag folder).
    /// Options below override parts.
    /// Without a camchain the cameras are calibrated from the same images first (camchain.yaml
    /// beside --out, or RESULT-camchain.yaml to keep another's; --report R.html: R-cameras.html).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    #[command(flatten)]
    pub files: DatasetArgs,
    #[command(flatten)]
    pub vision: crate::detect::VisionTuning,
    #[command(flatten)]
    pub dvl_input: DvlInputArgs,
    #[command(flatten)]
    pub estimator: Box<EstimatorArgs>,
    /// The speed of sound the DVL was set to, m/s, when its log holds no configuration reply:
    /// the velocity scale is then also read as the water's sound speed.
    #[arg(long, value_name = "M_PER_S")]
    pub dvl_sound_speed: Option<f64>,
    /// Stop at the first malformed DVL line instead of skipping and counting it.
    #[arg(long)]
    pub strict: bool,
    /// Result YAML (written atomically; with a provenance section: version, command line, UTC
    /// time, each input's size and SHA-256); beside it RESULT-tf.txt (ROS 1 and ROS 2 static
    /// transform commands), RESULT-urdf.xml (a URDF robot: camera and DVL links, fixed joint) and
    /// RESULT-camchain-imucam.yaml (Kalibr's camchain-imucam with the DVL in the IMU's place:
    /// the camera chain, T_cam_imu = T_cam_dvl and timeshift_cam_imu per camera).
    #[arg(long, default_value = "calibration.yaml")]
    pub out: PathBuf,
    /// Parent (camera) and child (DVL) frame names of the ROS and URDF exports, `PARENT,CHILD`
    /// (names without spaces); default: the bag's cam0 image header.frame_id when it has one,
    /// else cam0, and dvl.
    #[arg(long, value_name = "PARENT,CHILD")]
    pub frames: Option<String>,
    #[arg(long, value_enum, default_value = "uic")]
    pub method: MethodArg,
    /// Initial guess or fixed extrinsics (result YAML schema), for --method bcd and fixed.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// With --method fixed: estimate clock offset and scale with the extrinsics held.
    #[arg(long)]
    pub estimate_offset: bool,
    /// Use the closed form without bias elimination (for comparison only).
    #[arg(long)]
    pub biased: bool,
    /// Write the ROS and Kalibr exports even when the calibration fails its sanity checks
    /// (the result file still says `status: failed`, and the exit status is still non-zero).
    #[arg(long)]
    pub force: bool,
    /// Self-contained HTML report with plots (written atomically; opens offline).
    #[arg(long, value_name = "REPORT.html")]
    pub report: Option<PathBuf>,
}

/// The calibration options of the command line; `guess` is the parsed `--init`.
pub fn options(
    method: MethodArg,
    guess: Option<CalibrationParams>,
    estimate_offset: bool,
    est: &EstimatorArgs,
    biased: bool,
) -> Result<CalibOptions> {
    let range = match est.offset_range.as_deref() {
        None => None,
        Some([lo, hi]) => Some((*lo, *hi)),
        Some(_) => bail!("--offset-range takes two values: min,max"),
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
        dvl_sigma: est.dvl_sigma,
        bias_corrected: !biased,
        priors: est.priors(),
        loss: Loss::parse(&est.loss).map_err(flagged)?,
        default_lever_arm_sigma_m: est.default_lever_arm_sigma.0,
        honest_covariance: !est.model_covariance,
        clock_drift: est.clock_drift,
        names: flag,
        ..CalibOptions::default()
    };
    opts.offset.range = range;
    opts.validate()?;
    Ok(opts)
}

/// The command line's words for the estimator's settings, in its messages and errors.
fn flag(s: Setting) -> &'static str {
    match s {
        Setting::DvlSigma => "--dvl-sigma",
        Setting::DefaultLeverArmSigma => "--default-lever-arm-sigma",
        Setting::LeverArmPrior => "--lever-arm-prior",
        Setting::RotationPrior => "--rotation-prior",
        Setting::OffsetRange => "--offset-range",
        Setting::Loss => "--loss",
        Setting::LeastSquares => "--loss l2",
        Setting::Uic => "--method uic",
        Setting::RefineGuess => "--method bcd --init",
        Setting::EstimateOffset => "--estimate-offset",
        Setting::Guess => "--init",
        Setting::ClockDrift => "--clock-drift",
        // Settings without a flag keep their field names.
        Setting::DefaultDvlSigma
        | Setting::OffsetWindow
        | Setting::OffsetCoarseStep
        | Setting::AlignStep => s.field(),
    }
}

/// A library error about a setting, naming the setting's flag instead of its field.
fn flagged(e: Error) -> Error {
    match e {
        Error::InvalidOption { option, msg } => Error::InvalidOption {
            option: Setting::from_field(option).map_or(option, flag),
            msg,
        },
        other => other,
    }
}

/// `cache`: detections of the images already made (`dvlcal watch`'s).
pub fn run(a: CalibrateArgs, cache: Option<DetectionCache>) -> Result<()> {
    let given = crate::given();
    let method = a
        .method
        .to_possible_value()
        .map(|v| v.get_name().to_owned());
    unused::method_options(method.as_deref().unwrap_or(""), &given)?;
    let guess = match &a.init {
        Some(p) => Some(read_calibration_guess(p)?),
        None => None,
    };
    let opts = options(a.method, guess, a.estimate_offset, &a.estimator, a.biased)?;
    let frames = a.frames.as_deref().map(FrameNames::parse).transpose()?;
    if let Some(c) = a.dvl_sound_speed
        && !(c.is_finite() && (1000.0..=2000.0).contains(&c))
    {
        bail!("--dvl-sound-speed must be between 1000 and 2000 m/s, got {c}");
    }
    check_result_outputs(&a.out, a.report.as_deref())?;
    let read = a.dvl_input.read_options(a.strict);
    let files = find(a.dataset.as_deref(), &a.files, &read)?;
    unused::input_options(&files, &given)?;
    // Without a camchain the cameras are calibrated first; where their camchain (and report)
    // will go is checked before the long run.
    let cameras_out = CameraOutputs::plan(&a.out, a.report.as_deref(), &files)?;
    let vision = VisionOptions {
        cache,
        ..a.vision.options()
    };
    let mut data = read_files(files, &vision, &read)?;
    unused::data_options(&data, &given)?;
    if let (Some(cams), Some(to)) = (&data.cameras, &cameras_out) {
        let command = this_command_line();
        for line in to.write(&a.out, cams, Some(command))? {
            println!("{line}");
        }
        if cams.is_weak() {
            eprintln!(
                "warning: the camera calibration from this recording is weak (see its warnings \
                 above). A recording made for the DVL rotates less than one made for the cameras: \
                 {SEPARATE_CAMERA_RECORDING}."
            );
        }
    }
    let output = OutputOptions {
        force: a.force,
        frames,
        command_line: Some(this_command_line()),
        extra_inputs: a.init.iter().map(|p| ("init".into(), p.clone())).collect(),
    };
    if data.log.is_none() {
        let run = calibrate_camera_imu_dataset(&data, &opts.weak, a.vision.detect.threads)?;
        let paths = write_camera_imu_results(&a.out, &run, &data, &output, a.report.as_deref())?;
        print!("{}", run.summary(&data));
        println!("{}", wrote_words(&paths));
        return Ok(());
    }
    if data.poses.is_empty() && data.vision.is_none() && data.imu.is_some() {
        unused::dvl_imu_options(&given)?; // a bag shows it holds no camera data once open
        let run = dvl_imu::calibrate_dvl_imu_dataset(&data, &opts)?;
        let paths =
            dvl_imu::write_dvl_imu_results(&a.out, &run, &data, &output, a.report.as_deref())?;
        println!("{}{}", run.summary(), wrote_words(&paths));
        if !run.ok() {
            bail!("the calibration failed: {}", run.file.failure.join("; "));
        }
        return Ok(());
    }
    if let Some(w) = data.give_sound_speed(a.dvl_sound_speed) {
        eprintln!("warning: {w}");
    }
    let run = match calibrate_dataset(&data, &opts, a.vision.detect.threads) {
        Ok(run) => run,
        Err(e) => {
            if let Some(path) = &a.report {
                match write_failure_report(path, &data, &e) {
                    Ok(()) => eprintln!("wrote {} (the report of the failure)", path.display()),
                    Err(w) => eprintln!("could not write the failure report: {w}"),
                }
            }
            return Err(e).context(calibration_context(&data));
        }
    };
    let paths = write_results(&a.out, &run, &data, &output)?;
    print!("{}", run.summary(data.dvl()?));
    println!("{}", wrote_words(&paths));
    if let Some(path) = &a.report {
        write_report(path, &run, &data, &paths.result).context("building the report")?;
        println!("wrote {}", path.display());
    }
    if let Status::Failed(reasons) = &run.outcome.status {
        bail!("the calibration failed: {}", reasons.join("; "));
    }
    Ok(())
}
