//! `dvlcal simulate`: a synthetic dataset with known truth.

use anyhow::{Context, Result};
use clap::ValueEnum;
use nalgebra::Vector3;
use std::path::PathBuf;

use dvlcal::io::a50_json::{A50Transducer, A50VelocityReport, write_a50_jsonl};
use dvlcal::io::calib_yaml::{CalibrationFile, CalibrationInfo, read_calib_yaml, write_calib_yaml};
use dvlcal::io::tum::write_tum;
use dvlcal::io::twist_csv::{TwistRow, write_twist_csv};
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::sim::motion::MotionState;
use dvlcal::time::Epoch;
use dvlcal::types::{DvlSample, PoseMeasurement};

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
    #[arg(long, value_enum, default_value = "calm-then-rotate")]
    pub motion: MotionArg,
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
    let mut cfg = SimConfig {
        duration_s: a.duration,
        seed: a.seed,
        camera_rate_hz: a.camera_rate,
        dvl_rate_hz: a.dvl_rate,
        pose_sigma_pos_m: a.pose_sigma_pos,
        pose_sigma_rot_rad: a.pose_sigma_rot,
        dvl_sigma: a.dvl_sigma,
        motion: match a.motion {
            MotionArg::Prior => MotionKind::Prior,
            MotionArg::CalmThenRotate => MotionKind::CalmThenRotate,
            MotionArg::WeakRotation => MotionKind::WeakRotation,
            MotionArg::Sinusoid => MotionKind::Sinusoid,
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
    let ds: SimDataset = simulate(&cfg)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let out = |name: &str| a.out.join(name);
    write_tum(&out("poses.txt"), ds.epoch, &ds.poses)?;
    let truth_poses: Vec<PoseMeasurement> = ds
        .poses
        .iter()
        .zip(&ds.truth_poses)
        .map(|(p, s)| PoseMeasurement {
            t: p.t,
            pose: s.pose,
            cov: None,
        })
        .collect();
    write_tum(&out("poses_truth.txt"), ds.epoch, &truth_poses)?;
    write_twist_csv(
        &out("truth_twist.csv"),
        ds.epoch,
        &truth_rows(&ds.truth_poses, ds.poses.iter().map(|p| p.t)),
    )?;
    let offset = ds.truth.time_offset_s;
    write_twist_csv(
        &out("dvl_truth_twist.csv"),
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
            a.motion
                .to_possible_value()
                .map(|v| v.get_name().to_owned())
                .unwrap_or_default()
        )],
        ..CalibrationInfo::default()
    });
    write_calib_yaml(&out("truth.yaml"), &truth)?;
    println!(
        "wrote {}: {} poses, {} DVL reports over {:.1} s (seed {})",
        a.out.display(),
        ds.poses.len(),
        ds.dvl.len(),
        a.duration,
        a.seed
    );
    Ok(())
}
