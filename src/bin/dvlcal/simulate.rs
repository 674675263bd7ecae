//! `dvlcal simulate`: a synthetic dataset with known truth, laid out as a dataset folder that
//! `dvlcal calibrate DIR` reads.
//!
//! The data: `dvl.jsonl` (A50 JSON lines) and `poses.txt` (noisy camera poses, TUM). With
//! `--images`, the stereo images of a board along the motion instead of the poses (see
//! `dvlcal::sim::image_dataset` for the frames): `cam0/<ns>.png`, `cam1/<ns>.png` (absolute Unix
//! nanoseconds of the camera pose times), `camchain.yaml`, `target.yaml`.
//!
//! The truth, in `truth/` (which dataset discovery never reads): `calibration.yaml`, `poses.txt`
//! (true `T_world_cam`), `twist.csv` (true camera twists at the pose times), `dvl_twist.csv` (at
//! the DVL samples' camera times); with images `poses_board.txt` (`T_board_cam0`),
//! `board_in_world.txt` (`T_world_board`) and `poses_noisy.txt` (the poses a pose-only run would
//! have had).

use anyhow::{Context, Result};
use clap::ValueEnum;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

use dvlcal::io::calib_yaml::{CalibrationFile, CalibrationInfo, read_calib_yaml, write_calib_yaml};
use dvlcal::io::dvl::a50::{A50Transducer, A50VelocityReport, write_a50_jsonl};
use dvlcal::io::tum::write_tum;
use dvlcal::io::twist_csv::{TwistRow, write_twist_csv};
use dvlcal::lie::Se3;
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::sim::image_dataset::{
    DEFAULT_BOARD_DISTANCE_M, FrameSpec, ImageSimSettings, board_facing, default_board,
    default_stereo_camchain, write_image_dataset,
};
use dvlcal::sim::motion::MotionState;
use dvlcal::time::Epoch;
use dvlcal::types::DvlSample;
use dvlcal::vision::board::Board;
use dvlcal::vision::camera::Camchain;

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
    #[arg(long, default_value_t = 10.0)]
    pub camera_rate: f64,
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
    /// Override the velocity scale of the truth.
    #[arg(long)]
    pub velocity_scale: Option<f64>,
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
    /// Worker threads for the images (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

fn truth_rows(states: &[MotionState], times: impl Iterator<Item = f64>) -> Vec<TwistRow> {
    states
        .iter()
        .zip(times)
        .map(|(s, t)| TwistRow {
            t,
            v: s.twist.fixed_rows::<3>(0).into_owned(),
            w: s.twist.fixed_rows::<3>(3).into_owned(),
            std_v: Vector3::zeros(),
            std_w: Vector3::zeros(),
            dv: s.twist_rate.fixed_rows::<3>(0).into_owned(),
            dw: s.twist_rate.fixed_rows::<3>(3).into_owned(),
        })
        .collect()
}

/// An A50 json_v3.1 velocity report carrying a simulated sample. Beam readings are not
/// simulated; the beams are reported valid at a nominal 1.5 m distance.
fn a50_report(
    s: &DvlSample,
    epoch: Epoch,
    prev_t: Option<f64>,
    altitude: f64,
) -> A50VelocityReport {
    let us = epoch.sec * 1_000_000 + (s.t * 1e6).round() as i64;
    let cov = s.cov.unwrap_or_else(nalgebra::Matrix3::zeros);
    let beam = |id: i64| A50Transducer {
        id,
        velocity: 0.0,
        distance: altitude,
        rssi: -40.0,
        nsd: -95.0,
        beam_valid: s.valid,
    };
    A50VelocityReport {
        time: prev_t.map(|p| (s.t - p) * 1e3).unwrap_or(100.0),
        vx: s.v.x,
        vy: s.v.y,
        vz: s.v.z,
        fom: cov.diagonal().max().max(0.0).sqrt(),
        covariance: [
            [cov[(0, 0)], cov[(0, 1)], cov[(0, 2)]],
            [cov[(1, 0)], cov[(1, 1)], cov[(1, 2)]],
            [cov[(2, 0)], cov[(2, 1)], cov[(2, 2)]],
        ],
        altitude,
        transducers: [beam(0), beam(1), beam(2), beam(3)],
        velocity_valid: s.valid,
        status: 0,
        format: "json_v3.1".into(),
        report_type: "velocity".into(),
        time_of_validity: us,
        // The report leaves the DVL a few tens of milliseconds after mid-ping.
        time_of_transmission: us + 40_000,
    }
}

pub fn run(a: SimulateArgs) -> Result<()> {
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
    // Read the image inputs before writing anything.
    let image_inputs = if a.images {
        let board = match &a.target {
            Some(p) => Board::load(p)?,
            None => default_board(),
        };
        let chain = match &a.camchain {
            Some(p) => Camchain::load(p)?,
            None => default_stereo_camchain(),
        };
        if !(a.board_distance.is_finite() && a.board_distance > 0.0) {
            anyhow::bail!(
                "--board-distance must be positive, got {}",
                a.board_distance
            );
        }
        Some((board, chain))
    } else {
        None
    };
    let ds: SimDataset = simulate(&cfg)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let truth_dir = a.out.join("truth");
    std::fs::create_dir_all(&truth_dir)
        .with_context(|| format!("creating {}", truth_dir.display()))?;
    let out = |name: &str| a.out.join(name);
    let truth_out = |name: &str| truth_dir.join(name);
    let noisy = if image_inputs.is_some() {
        truth_out("poses_noisy.txt")
    } else {
        out("poses.txt")
    };
    write_tum(&noisy, ds.epoch, &ds.poses)?;
    let truth_poses = ds.true_poses_in(&Se3::identity());
    write_tum(&truth_out("poses.txt"), ds.epoch, &truth_poses)?;
    write_twist_csv(
        &truth_out("twist.csv"),
        ds.epoch,
        &truth_rows(&ds.truth_poses, ds.poses.iter().map(|p| p.t)),
    )?;
    let offset = ds.truth.time_offset_s;
    write_twist_csv(
        &truth_out("dvl_twist.csv"),
        ds.epoch,
        &truth_rows(&ds.dvl_truth, ds.dvl.iter().map(|s| s.t + offset)),
    )?;
    let reports: Vec<A50VelocityReport> = ds
        .dvl
        .iter()
        .enumerate()
        .map(|(i, s)| a50_report(s, ds.epoch, i.checked_sub(1).map(|j| ds.dvl[j].t), 1.5))
        .collect();
    write_a50_jsonl(&out("dvl.jsonl"), &reports)?;
    let mut truth = CalibrationFile::from_params(&ds.truth);
    truth.info = Some(CalibrationInfo {
        method: Some("simulation truth".into()),
        notes: vec![format!(
            "dvlcal simulate --seed {} --duration {} --motion {}",
            a.seed,
            a.duration,
            motion
                .to_possible_value()
                .map(|v| v.get_name().to_owned())
                .unwrap_or_default()
        )],
        ..CalibrationInfo::default()
    });
    write_calib_yaml(&truth_out("calibration.yaml"), &truth)?;
    println!(
        "wrote {}: {} poses, {} DVL reports over {:.1} s (seed {})",
        a.out.display(),
        ds.poses.len(),
        ds.dvl.len(),
        a.duration,
        a.seed
    );
    if let Some((board, chain)) = image_inputs {
        write_images(&a, &ds, &board, &chain)?;
    }
    Ok(())
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// The image part of the dataset: the board faces the starting camera (`T_world_board`), each
/// camera pose time gets one stereo frame rendered from the true pose.
fn write_images(a: &SimulateArgs, ds: &SimDataset, board: &Board, chain: &Camchain) -> Result<()> {
    let first = ds
        .truth_poses
        .first()
        .context("the simulation produced no camera pose")?;
    let t_world_board = board_facing(&first.pose, board, a.board_distance);
    let t_board_world = t_world_board.inverse();
    let board_poses = ds.true_poses_in(&t_board_world);
    let frames: Vec<FrameSpec> = board_poses
        .iter()
        .map(|p| FrameSpec {
            t_ns: ds.unix_ns(p.t),
            t_board_cam0: p.pose,
        })
        .collect();
    let out = |name: &str| a.out.join(name);
    let truth_out = |name: &str| a.out.join("truth").join(name);
    write_tum(&truth_out("poses_board.txt"), ds.epoch, &board_poses)?;
    write_text(
        &truth_out("board_in_world.txt"),
        &board_in_world_text(&t_world_board),
    )?;
    write_text(&out("camchain.yaml"), &chain.to_kalibr_yaml())?;
    write_text(&out("target.yaml"), &board.to_yaml())?;
    let mut settings = ImageSimSettings {
        seed: a.seed,
        threads: a.threads,
        jpeg_quality: a.jpeg_quality,
        ..ImageSimSettings::default()
    };
    settings.render.supersample = a.supersample;
    let total = frames.len();
    let step = (total / 10).max(1);
    let progress = |done: usize, total: usize| {
        if done % step == 0 || done == total {
            eprintln!("rendered {done}/{total} stereo frames");
        }
    };
    let stats = write_image_dataset(&a.out, board, chain, &frames, &settings, &progress)?;
    let visible = stats
        .board_fully_visible
        .iter()
        .enumerate()
        .map(|(i, n)| format!("cam{i} {n}"))
        .collect::<Vec<_>>()
        .join(", ");
    println!(
        "wrote {} images of {} ({} frames x {} cameras) in {:.1} s ({:.0} ms per frame); whole board in view: {}",
        stats.images,
        board.description,
        stats.frames,
        chain.cams.len(),
        stats.seconds,
        1e3 * stats.seconds / stats.frames.max(1) as f64,
        visible
    );
    Ok(())
}

fn board_in_world_text(t: &Se3) -> String {
    let q = t.quaternion_xyzw();
    format!(
        "# T_world_board: the board's pose in the world frame of truth/poses.txt (tx ty tz qx qy \
         qz qw)\n\
         # truth/poses_board.txt = T_world_board^-1 * truth/poses.txt\n\
         {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}\n",
        t.trans.x, t.trans.y, t.trans.z, q[0], q[1], q[2], q[3]
    )
}
