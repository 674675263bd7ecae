//! `dvlcal simulate`: a synthetic dataset with known truth, laid out as a dataset folder that
//! `dvlcal calibrate DIR` reads.
//!
//! What is written: see `dvlcal::pipeline::write_simulated_dataset`.

use anyhow::Result;
use clap::ValueEnum;
use std::path::PathBuf;

use dvlcal::io::calib_yaml::read_calib_yaml;
use dvlcal::io::camchain::read_camchain;
use dvlcal::io::target::read_board;
use dvlcal::pipeline::{
    ImageRequest, SimulateRequest, simulated_imu_config, write_simulated_dataset,
    write_simulated_imu,
};
use dvlcal::sim::dataset::{MotionKind, SimConfig};
use dvlcal::sim::image_dataset::{
    DEFAULT_BOARD_DISTANCE_M, ImageSimSettings, default_board, default_stereo_camchain,
};

#[derive(Clone, Copy, ValueEnum)]
pub enum MotionArg {
    /// A draw from the white-noise-on-jerk prior.
    Prior,
    /// Calm first half (for the clock offset), strong rotation in the second.
    CalmThenRotate,
    /// Little rotation throughout (the lever arm is then weakly observable).
    WeakRotation,
    /// Sums of sinusoids with rotation rates past 1 rad/s.
    Sinusoid,
    /// Translation only in the first half, then rotations of about 1 rad/s that keep a board
    /// 2 m ahead of the starting camera in view (the default with --images).
    BoardView,
}

#[derive(clap::Args)]
pub struct SimulateArgs {
    /// Output folder (created).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Length of the recording, seconds.
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Default: calm-then-rotate, or board-view with --images.
    #[arg(long, value_enum)]
    pub motion: Option<MotionArg>,
    /// Camera poses (or stereo frames) per second, Hz.
    #[arg(long, default_value_t = 10.0)]
    pub camera_rate: f64,
    /// DVL velocity reports per second, Hz.
    #[arg(long, default_value_t = 10.0)]
    pub dvl_rate: f64,
    /// Pose noise, translation, metres (per axis).
    #[arg(long, default_value_t = 0.002)]
    pub pose_sigma_pos: f64,
    /// Pose noise, rotation, radians (per axis).
    #[arg(long, default_value_t = 0.002)]
    pub pose_sigma_rot: f64,
    /// DVL velocity noise, m/s (per axis).
    #[arg(long, default_value_t = 0.01)]
    pub dvl_sigma: f64,
    /// Calibration to simulate with (result YAML); default: a downward-looking DVL below a
    /// forward-looking camera.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Override the clock offset of the truth (t_cam = t_dvl + offset), seconds.
    #[arg(long)]
    pub time_offset: Option<f64>,
    /// Override the velocity scale of the truth (no unit; 1: the DVL's speeds are right).
    #[arg(long)]
    pub velocity_scale: Option<f64>,
    /// Drift of the DVL clock, ppm, from the first pose on (clock_drift_ppm in the truth)
    #[arg(long, default_value_t = 0.0, value_name = "PPM")]
    pub clock_drift: f64,
    /// Also render the stereo images of a board at every camera pose time.
    #[arg(long)]
    pub images: bool,
    /// Board of the images (board YAML or Kalibr aprilgrid); default: Kalibr's 6x6 tag36h11
    /// aprilgrid geometry (88 mm tags).
    #[arg(long, requires = "images")]
    pub target: Option<PathBuf>,
    /// Cameras of the images (Kalibr camchain); default: a 752x480 radtan stereo pair with a
    /// 0.11 m baseline.
    #[arg(long, requires = "images")]
    pub camchain: Option<PathBuf>,
    /// Distance from the starting camera to the board centre, metres.
    #[arg(long, requires = "images", default_value_t = DEFAULT_BOARD_DISTANCE_M)]
    pub board_distance: f64,
    /// Samples per pixel along each axis of the rendered images.
    #[arg(long, requires = "images", default_value_t = 4)]
    pub supersample: u32,
    /// Write the images as JPEG of this quality (1-100) instead of PNG (smaller datasets).
    #[arg(long, requires = "images", value_name = "Q", value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg_quality: Option<u8>,
    /// Write into an output folder that already holds files (they may be overwritten).
    #[arg(long)]
    pub force: bool,
    /// Worker threads for the images (0: one per core; at most 4 per core, 256 in all).
    #[arg(long, requires = "images", default_value_t = 0)]
    pub threads: usize,
    /// Also simulate an IMU: imu0/data.csv and imu.yaml, its truth in truth/imu.yaml.
    #[arg(long)]
    pub imu: bool,
    /// IMU samples per second, Hz.
    #[arg(long, requires = "imu", default_value_t = 200.0, value_name = "HZ")]
    pub imu_rate: f64,
}

pub fn run(a: SimulateArgs) -> Result<()> {
    if !a.force
        && let Ok(mut entries) = std::fs::read_dir(&a.out)
        && entries.next().is_some()
    {
        anyhow::bail!(
            "{} already holds files (a dataset?): simulate writes into an empty or new folder; \
             --force writes into it anyway",
            a.out.display()
        );
    }
    let motion = a.motion.unwrap_or(if a.images {
        MotionArg::BoardView
    } else {
        MotionArg::CalmThenRotate
    });
    let mut cfg = SimConfig {
        duration_s: a.duration,
        seed: a.seed,
        camera_rate_hz: a.camera_rate,
        dvl_rate_hz: a.dvl_rate,
        pose_sigma_pos_m: a.pose_sigma_pos,
        pose_sigma_rot_rad: a.pose_sigma_rot,
        dvl_sigma: a.dvl_sigma,
        clock_drift_ppm: a.clock_drift,
        motion: match motion {
            MotionArg::Prior => MotionKind::Prior,
            MotionArg::CalmThenRotate => MotionKind::CalmThenRotate,
            MotionArg::WeakRotation => MotionKind::WeakRotation,
            MotionArg::Sinusoid => MotionKind::Sinusoid,
            MotionArg::BoardView => MotionKind::BoardView,
        },
        ..SimConfig::default()
    };
    if let Some(p) = &a.truth {
        cfg.truth = read_calib_yaml(p)?.to_params()?;
    }
    if let Some(o) = a.time_offset {
        cfg.truth.time_offset_s = o;
    }
    if let Some(k) = a.velocity_scale {
        cfg.truth.velocity_scale = k;
    }
    // Read the image inputs and check the IMU's before writing anything.
    let imu = a
        .imu
        .then(|| simulated_imu_config(a.imu_rate, a.duration))
        .transpose()?;
    let images = if a.images {
        let mut settings = ImageSimSettings {
            seed: a.seed,
            threads: a.threads,
            jpeg_quality: a.jpeg_quality,
            ..ImageSimSettings::default()
        };
        settings.render.supersample = a.supersample;
        Some(ImageRequest {
            board: match &a.target {
                Some(p) => read_board(p)?,
                None => default_board(),
            },
            chain: match &a.camchain {
                Some(p) => read_camchain(p)?,
                None => default_stereo_camchain(),
            },
            board_distance_m: a.board_distance,
            settings,
        })
    } else {
        None
    };
    let req = SimulateRequest {
        config: cfg,
        images,
        note: format!(
            "dvlcal simulate --seed {} --duration {} --motion {}",
            a.seed,
            a.duration,
            motion
                .to_possible_value()
                .map(|v| v.get_name().to_owned())
                .unwrap_or_default()
        ),
    };
    let progress = |done: usize, total: usize| {
        if done % (total / 10).max(1) == 0 || done == total {
            eprintln!("rendered {done}/{total} stereo frames");
        }
    };
    let rec = write_simulated_dataset(&a.out, &req, &progress)?;
    rec.describe(&a.out, &req)
        .iter()
        .for_each(|l| println!("{l}"));
    if let Some(cfg) = &imu {
        let sim = write_simulated_imu(&a.out, &req.config, &rec, cfg)?;
        println!(
            "wrote {} IMU samples at {} Hz to imu0/data.csv, noise in imu.yaml, truth in \
             truth/imu.yaml",
            sim.samples.len(),
            cfg.noise.update_rate
        );
    }
    Ok(())
}
