//! A simulated recording written as a dataset folder that [`super::Dataset::load`] reads, with
//! its truth beside it.
//!
//! The data: `dvl.jsonl` (A50 json_v3.1 lines) and `poses.txt` (noisy camera poses, TUM); with
//! images, the stereo images of a board along the motion instead of the poses: `cam0/<ns>.png`,
//! `cam1/<ns>.png` (absolute Unix nanoseconds of the camera pose times), `camchain.yaml`,
//! `target.yaml`.
//!
//! The truth, in `truth/` (which dataset discovery never reads): `calibration.yaml`, `poses.txt`
//! (true `T_world_cam`), `twist.csv` (true camera twists at the pose times), `dvl_twist.csv` (at
//! the DVL samples' camera times); with images `poses_board.txt` (`T_board_cam0`),
//! `board_in_world.txt` (`T_world_board`) and `poses_noisy.txt` (the poses a pose-only run would
//! have had).
//!
//! With an IMU ([`write_simulated_imu`]): `imu0/data.csv` (EuRoC's IMU CSV, on the IMU clock)
//! and `imu.yaml` (Kalibr's noise file) beside the data; `truth/imu.yaml` (`T_cam_imu`, the IMU
//! clock offset, gravity, the first biases, the sample count and noise) and
//! `truth/imu_bias.csv` (the biases at every sample).

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::io::calib_yaml::{CalibrationFile, CalibrationInfo, write_calib_yaml};
use crate::io::camchain::camchain_yaml;
use crate::io::dvl::a50::write_a50_jsonl;
use crate::io::imu::noise::write_kalibr_imu_yaml;
use crate::io::imu::truth::{ImuTruth, write_imu_bias_csv, write_imu_truth};
use crate::io::imu::write_imu_csv;
use crate::io::target::board_yaml;
use crate::io::tum::write_tum;
use crate::io::twist_csv::{TwistRow, write_twist_csv};
use crate::io::write_atomic;
use crate::lie::Se3;
use crate::sim::a50::a50_reports;
use crate::sim::dataset::{SimConfig, SimDataset, build_motion, simulate};
use crate::sim::image_dataset::{
    FrameSpec, ImageSimSettings, ImageSimStats, board_facing, write_image_dataset,
};
use crate::sim::imu::{ImuSimConfig, SimImu, simulate_imu};
use crate::sim::motion::MotionState;
use crate::types::board::Board;
use crate::types::camera::Camchain;

/// The distance every simulated A50 beam reports, m.
const ALTITUDE_M: f64 = 1.5;

/// The images of a simulated recording.
#[derive(Clone, Debug)]
pub struct ImageRequest {
    /// The board in view.
    pub board: Board,
    /// The cameras.
    pub chain: Camchain,
    /// Distance from the starting camera to the board's centre, m (`--board-distance`).
    pub board_distance_m: f64,
    /// Image formation, threads and file format.
    pub settings: ImageSimSettings,
}

impl ImageRequest {
    /// Checks the values; the error names the option.
    pub fn validate(&self) -> Result<()> {
        if !(self.board_distance_m.is_finite() && self.board_distance_m > 0.0) {
            return Err(Error::option(
                "--board-distance",
                format!("must be positive, got {}", self.board_distance_m),
            ));
        }
        Ok(())
    }
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimulateRequest {
    /// The motion, rates, noise levels, truth and seed.
    pub config: SimConfig,
    /// Render stereo images of a board instead of writing the noisy poses as the camera data.
    pub images: Option<ImageRequest>,
    /// How the dataset was made, in a line (recorded in `truth/calibration.yaml`).
    pub note: String,
}

/// What [`write_simulated_dataset`] wrote.
#[derive(Clone, Debug)]
pub struct SimulatedRecording {
    /// The simulation itself (truth, noisy poses, DVL samples).
    pub dataset: SimDataset,
    /// The image part, when images were rendered.
    pub images: Option<ImageSimStats>,
}

impl SimulatedRecording {
    /// What was written to `out`, a line each: the poses and DVL reports, then the images.
    pub fn describe(&self, out: &Path, req: &SimulateRequest) -> Vec<String> {
        let ds = &self.dataset;
        let mut lines = vec![format!(
            "wrote {}: {} poses, {} DVL reports over {:.1} s (seed {})",
            out.display(),
            ds.poses.len(),
            ds.dvl.len(),
            req.config.duration_s,
            req.config.seed
        )];
        if let (Some(stats), Some(im)) = (&self.images, &req.images) {
            let visible = stats
                .board_fully_visible
                .iter()
                .enumerate()
                .map(|(i, n)| format!("cam{i} {n}"))
                .collect::<Vec<_>>()
                .join(", ");
            lines.push(format!(
                "wrote {} images of {} ({} frames x {} cameras) in {:.1} s ({:.0} ms per frame); \
                 whole board in view: {}",
                stats.images,
                im.board.description,
                stats.frames,
                im.chain.cams.len(),
                stats.seconds,
                1e3 * stats.seconds / stats.frames.max(1) as f64,
                visible
            ));
        }
        lines
    }
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

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))
}

/// Simulates `req.config` and writes the dataset folder `out` (created) with its truth.
/// `progress(done, total)` is told about rendered frames.
pub fn write_simulated_dataset(
    out: &Path,
    req: &SimulateRequest,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<SimulatedRecording> {
    if let Some(im) = &req.images {
        im.validate()?;
    }
    let ds = simulate(&req.config)?;
    create_dir(out)?;
    let truth_dir = out.join("truth");
    create_dir(&truth_dir)?;
    let data = |name: &str| out.join(name);
    let truth = |name: &str| truth_dir.join(name);
    let noisy = if req.images.is_some() {
        truth("poses_noisy.txt")
    } else {
        data("poses.txt")
    };
    write_tum(&noisy, ds.epoch, &ds.poses)?;
    let truth_poses = ds.true_poses_in(&Se3::identity());
    write_tum(&truth("poses.txt"), ds.epoch, &truth_poses)?;
    write_twist_csv(
        &truth("twist.csv"),
        ds.epoch,
        &truth_rows(&ds.truth_poses, ds.poses.iter().map(|p| p.t)),
    )?;
    let offset = ds.truth.time_offset_s;
    write_twist_csv(
        &truth("dvl_twist.csv"),
        ds.epoch,
        &truth_rows(&ds.dvl_truth, ds.dvl.iter().map(|s| s.t + offset)),
    )?;
    write_a50_jsonl(
        &data("dvl.jsonl"),
        &a50_reports(&ds.dvl, ds.epoch, ALTITUDE_M),
    )?;
    let mut file = CalibrationFile::from_params(&ds.truth);
    let ppm = req.config.clock_drift_ppm;
    if ppm != 0.0 {
        // The simulator's drift runs from the DVL time of the first pose (camera time 0).
        file.clock_drift_ppm = Some(ppm);
        file.clock_reference_t_dvl_s = Some(ds.epoch.sec as f64 - offset);
    }
    file.info = Some(CalibrationInfo {
        method: Some("simulation truth".into()),
        notes: vec![req.note.clone()],
        ..CalibrationInfo::default()
    });
    write_calib_yaml(&truth("calibration.yaml"), &file)?;
    let images = match &req.images {
        Some(im) => Some(write_images(out, &ds, im, progress)?),
        None => None,
    };
    Ok(SimulatedRecording {
        dataset: ds,
        images,
    })
}

/// The image part of the dataset: the board faces the starting camera (`T_world_board`), each
/// camera pose time gets one stereo frame rendered from the true pose.
fn write_images(
    out: &Path,
    ds: &SimDataset,
    im: &ImageRequest,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<ImageSimStats> {
    let first = ds
        .truth_poses
        .first()
        .ok_or_else(|| Error::Input("the simulation produced no camera pose".into()))?;
    let t_world_board = board_facing(&first.pose, &im.board, im.board_distance_m);
    let board_poses = ds.true_poses_in(&t_world_board.inverse());
    let frames: Vec<FrameSpec> = board_poses
        .iter()
        .map(|p| FrameSpec {
            t_ns: ds.unix_ns(p.t),
            t_board_cam0: p.pose,
        })
        .collect();
    let truth = |name: &str| -> PathBuf { out.join("truth").join(name) };
    write_tum(&truth("poses_board.txt"), ds.epoch, &board_poses)?;
    write_atomic(
        &truth("board_in_world.txt"),
        board_in_world_text(&t_world_board).as_bytes(),
    )?;
    write_atomic(
        &out.join("camchain.yaml"),
        camchain_yaml(&im.chain).as_bytes(),
    )?;
    write_atomic(&out.join("target.yaml"), board_yaml(&im.board).as_bytes())?;
    write_image_dataset(out, &im.board, &im.chain, &frames, &im.settings, progress)
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

/// The IMU of a dataset [`write_simulated_dataset`] wrote to `out` from `config`: the IMU `imu`
/// on the same motion (rebuilt from `config`), sampled on its own clock over the camera poses'
/// span, written as `imu0/data.csv` and `imu.yaml`, with `truth/imu.yaml` and
/// `truth/imu_bias.csv`. The IMU's noise and bias walk draw from streams of `config.seed` of
/// their own, so the rest of the dataset is the same with or without it.
pub fn write_simulated_imu(
    out: &Path,
    config: &SimConfig,
    rec: &SimulatedRecording,
    imu: &ImuSimConfig,
) -> Result<SimImu> {
    let ds = &rec.dataset;
    let (Some(first), Some(last)) = (ds.poses.first(), ds.poses.last()) else {
        return Err(Error::Input(
            "the simulation produced no camera pose".into(),
        ));
    };
    let motion = build_motion(config)?;
    let sim = simulate_imu(motion.as_ref(), imu, first.t, last.t, config.seed)?;
    create_dir(&out.join("imu0"))?;
    write_imu_csv(&out.join("imu0").join("data.csv"), ds.epoch, &sim.samples)?;
    write_kalibr_imu_yaml(&out.join("imu.yaml"), &imu.noise, "/imu0")?;
    let truth_dir = out.join("truth");
    create_dir(&truth_dir)?;
    let truth = ImuTruth {
        t_cam_imu: imu.t_cam_imu,
        imu_time_offset_s: imu.time_offset_s,
        gravity_world: imu.gravity_world,
        bias_start: sim.bias.first().copied().unwrap_or(imu.initial_bias),
        samples: sim.samples.len(),
        noise: imu.noise,
    };
    write_imu_truth(&truth_dir.join("imu.yaml"), &truth)?;
    let rows: Vec<_> = sim
        .samples
        .iter()
        .zip(&sim.bias)
        .map(|(s, b)| (s.t, *b))
        .collect();
    write_imu_bias_csv(&truth_dir.join("imu_bias.csv"), ds.epoch, &rows)?;
    Ok(sim)
}

/// The simulated IMU of `dvlcal simulate --imu`: [`ImuSimConfig::default_truth`] sampled at
/// `rate_hz` (`--imu-rate`), checked before anything is written: a rate that is not positive,
/// above 10 kHz, or that would make more than [`crate::sim::dataset::MAX_SAMPLES`] samples over
/// `duration_s` is refused, naming the option.
pub fn simulated_imu_config(rate_hz: f64, duration_s: f64) -> Result<ImuSimConfig> {
    if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 1e4) {
        return Err(Error::option(
            "--imu-rate",
            format!("must be a rate in Hz above 0 and at most 10000, got {rate_hz}"),
        ));
    }
    if rate_hz * duration_s > crate::sim::dataset::MAX_SAMPLES {
        return Err(Error::option(
            "--imu-rate",
            format!(
                "{rate_hz} Hz over {duration_s} s would make more than {} samples",
                crate::sim::dataset::MAX_SAMPLES
            ),
        ));
    }
    let mut cfg = ImuSimConfig::default_truth();
    cfg.noise.update_rate = rate_hz;
    Ok(cfg)
}
