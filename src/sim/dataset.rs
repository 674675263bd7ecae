//! Simulated camera poses and DVL velocities with known calibration.
//!
//! Camera poses are taken at `k / camera_rate_hz` on the camera clock, from 0 to the duration,
//! and perturbed on the right: `T_meas = T_true exp(n)`, `n = [rho; phi]`. DVL samples are taken
//! on the DVL clock at `j / dvl_rate_hz` plus a uniform jitter; a sample stamped `t_dvl` is
//! measured at camera time `t_cam = t_dvl + time_offset_s` and reads
//! `v_dvl = kappa R_dvl_cam (v_cam + w_cam x p_cam_dvl) + n`. Only samples whose camera time lies
//! inside the span of the camera poses are kept. The motion, the pose noise, the jitter and the
//! DVL noise draw from separate streams of the seed, so changing one noise level leaves the others
//! (and the motion) unchanged.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use super::motion::{
    BoardViewMotion, Motion, MotionState, SampledMotion, SinusoidMotion, check_rotation,
};
use crate::error::{Error, Result};
use crate::lie::{Se3, so3};
use crate::rng::Rng;
use crate::time::Epoch;
use crate::types::{CalibrationParams, DvlSample, PoseMeasurement};

const STREAM_POSE_NOISE: u64 = 11;
const STREAM_DVL_JITTER: u64 = 12;
const STREAM_DVL_NOISE: u64 = 13;

/// Largest number of camera poses or DVL samples a simulation may produce.
pub const MAX_SAMPLES: f64 = 1e7;

/// The camera motion a dataset is simulated from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MotionKind {
    /// A draw from the white-noise-on-jerk prior ([`SampledMotion::wnoj`]) with
    /// `SimConfig::prior_qc` and `SimConfig::prior_initial_twist`.
    Prior,
    /// [`SampledMotion::calm_then_rotate`]: calm first half, strong rotation in the second.
    #[default]
    CalmThenRotate,
    /// [`SampledMotion::weak_rotation`].
    WeakRotation,
    /// [`SinusoidMotion::lively`].
    Sinusoid,
    /// [`BoardViewMotion::new`]: keeps a board about 2 m ahead of the starting camera in view.
    BoardView,
}

/// Everything that defines a simulated dataset.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// Length of the recording on the camera clock, seconds (poses cover `[0, duration_s]`).
    pub duration_s: f64,
    /// Seed of the random streams (motion, pose noise, DVL jitter, DVL noise).
    pub seed: u64,
    /// Camera pose rate, Hz (poses at `k / camera_rate_hz`).
    pub camera_rate_hz: f64,
    /// DVL sample rate, Hz (nominal samples at `j / dvl_rate_hz` on the DVL clock).
    pub dvl_rate_hz: f64,
    /// Standard deviation of each translation component of the pose noise, metres.
    pub pose_sigma_pos_m: f64,
    /// Standard deviation of each rotation component of the pose noise, radians.
    pub pose_sigma_rot_rad: f64,
    /// Standard deviation of each DVL velocity component, m/s.
    pub dvl_sigma: f64,
    /// The calibration the DVL data are generated with.
    pub truth: CalibrationParams,
    /// Half-width of the uniform jitter of the DVL sampling instants around the regular DVL grid,
    /// seconds (less than half the DVL period).
    pub dvl_time_jitter_s: f64,
    /// Absolute time (Unix seconds) of camera time 0; the dataset's epoch.
    pub unix_start_s: i64,
    /// The camera motion simulated.
    pub motion: MotionKind,
    /// Jerk power spectral densities (`[v; w]`) of [`MotionKind::Prior`].
    pub prior_qc: [f64; 6],
    /// Initial twist (`[v; w]`) of [`MotionKind::Prior`].
    pub prior_initial_twist: [f64; 6],
    /// Drift of the DVL clock, ppm: `t_cam = t_dvl + time_offset_s + 1e-6 clock_drift_ppm
    /// (t_dvl - t_ref)`, with `t_ref` the DVL time at camera time 0 (0 by default: no drift).
    pub clock_drift_ppm: f64,
}

impl SimConfig {
    /// A plausible mount: the DVL (z axis along its beams' mean direction) looks down below a
    /// forward-looking camera (x right, y down, z forward): `R_cam_dvl` is -90 deg about camera x
    /// followed by a misalignment of a few degrees; lever arm `[0.05, 0.25, -0.10]` m (25 cm below,
    /// 10 cm behind); 70 ms clock offset; 1 % scale error.
    pub fn default_truth() -> CalibrationParams {
        let mount = so3::exp(&Vector3::new(-std::f64::consts::FRAC_PI_2, 0.0, 0.0));
        let misalignment = so3::exp(&Vector3::new(0.02, -0.035, 0.05));
        CalibrationParams {
            t_cam_dvl: Se3::new(mount * misalignment, Vector3::new(0.05, 0.25, -0.10)),
            time_offset_s: 0.07,
            velocity_scale: 1.01,
        }
    }

    fn validate(&self) -> Result<()> {
        let positive = |name: &str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(Error::Input(format!(
                    "{name} must be positive and finite, got {x}"
                )))
            }
        };
        let non_negative = |name: &str, x: f64| {
            if x.is_finite() && x >= 0.0 {
                Ok(())
            } else {
                Err(Error::Input(format!(
                    "{name} must be non-negative and finite, got {x}"
                )))
            }
        };
        positive("duration_s", self.duration_s)?;
        positive("camera_rate_hz", self.camera_rate_hz)?;
        positive("dvl_rate_hz", self.dvl_rate_hz)?;
        non_negative("pose_sigma_pos_m", self.pose_sigma_pos_m)?;
        non_negative("pose_sigma_rot_rad", self.pose_sigma_rot_rad)?;
        non_negative("dvl_sigma", self.dvl_sigma)?;
        non_negative("dvl_time_jitter_s", self.dvl_time_jitter_s)?;
        if !(self.clock_drift_ppm.is_finite() && self.clock_drift_ppm.abs() < 1e5) {
            return Err(Error::Input(format!(
                "clock_drift_ppm must be finite and below 1e5 ppm in size, got {}",
                self.clock_drift_ppm
            )));
        }
        if self.dvl_time_jitter_s >= 0.5 / self.dvl_rate_hz {
            return Err(Error::Input(format!(
                "dvl_time_jitter_s ({}) must be less than half the DVL period",
                self.dvl_time_jitter_s
            )));
        }
        check_rotation("truth T_cam_dvl", &self.truth.t_cam_dvl.rot)?;
        if !self.truth.t_cam_dvl.trans.iter().all(|x| x.is_finite()) {
            return Err(Error::Input("truth lever arm must be finite".into()));
        }
        if !self.truth.time_offset_s.is_finite() {
            return Err(Error::Input("truth time offset must be finite".into()));
        }
        positive("truth velocity_scale", self.truth.velocity_scale)?;
        if !self
            .prior_qc
            .iter()
            .chain(self.prior_initial_twist.iter())
            .all(|x| x.is_finite())
        {
            return Err(Error::Input(
                "prior Qc and initial twist must be finite".into(),
            ));
        }
        let too_many = |rate: f64| self.duration_s * rate + 3.0 > MAX_SAMPLES;
        if too_many(self.camera_rate_hz) || too_many(self.dvl_rate_hz) {
            return Err(Error::Input(format!(
                "simulation would produce more than {MAX_SAMPLES} samples"
            )));
        }
        Ok(())
    }
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            duration_s: 60.0,
            seed: 1,
            camera_rate_hz: 10.0,
            dvl_rate_hz: 10.0,
            pose_sigma_pos_m: 0.002,
            pose_sigma_rot_rad: 0.002,
            dvl_sigma: 0.01,
            truth: SimConfig::default_truth(),
            dvl_time_jitter_s: 0.002,
            unix_start_s: 1_700_000_000,
            motion: MotionKind::default(),
            prior_qc: [2e-6, 2e-6, 2e-6, 2e-5, 2e-5, 2e-5],
            prior_initial_twist: [0.1, 0.0, 0.05, 0.0, 0.0, 0.05],
            clock_drift_ppm: 0.0,
        }
    }
}

/// A simulated dataset and its truth.
#[derive(Clone, Debug)]
pub struct SimDataset {
    /// Camera time 0 is `epoch` (Unix seconds `unix_start_s`).
    pub epoch: Epoch,
    /// Noisy camera poses, camera clock, with their noise covariance.
    pub poses: Vec<PoseMeasurement>,
    /// True camera states at the pose times.
    pub truth_poses: Vec<MotionState>,
    /// DVL samples, DVL clock (`t = t_cam - time_offset_s`), covariance `dvl_sigma^2 I`.
    pub dvl: Vec<DvlSample>,
    /// True camera state at each DVL sample's camera time.
    pub dvl_truth: Vec<MotionState>,
    /// The calibration the DVL data were generated with.
    pub truth: CalibrationParams,
}

impl SimDataset {
    /// The true camera poses at the pose times, expressed in another fixed frame:
    /// `T_frame_world * T_world_cam` (the identity gives `T_world_cam`); no covariance.
    pub fn true_poses_in(&self, t_frame_world: &Se3) -> Vec<PoseMeasurement> {
        self.poses
            .iter()
            .zip(&self.truth_poses)
            .map(|(p, s)| PoseMeasurement {
                t: p.t,
                pose: t_frame_world * &s.pose,
                cov: None,
            })
            .collect()
    }

    /// Absolute Unix time in nanoseconds of camera time `t` (image file names).
    pub fn unix_ns(&self, t: f64) -> i64 {
        self.epoch.sec * 1_000_000_000 + (t * 1e9).round() as i64
    }
}

/// Builds the motion `cfg.motion` of `cfg` (the one [`simulate`] uses).
pub fn build_motion(cfg: &SimConfig) -> Result<Box<dyn Motion>> {
    Ok(match cfg.motion {
        MotionKind::Prior => Box::new(SampledMotion::wnoj(
            cfg.seed,
            cfg.duration_s,
            cfg.prior_qc,
            Vector6::from(cfg.prior_initial_twist),
        )?),
        MotionKind::CalmThenRotate => {
            Box::new(SampledMotion::calm_then_rotate(cfg.seed, cfg.duration_s)?)
        }
        MotionKind::WeakRotation => {
            Box::new(SampledMotion::weak_rotation(cfg.seed, cfg.duration_s)?)
        }
        MotionKind::Sinusoid => Box::new(SinusoidMotion::lively(cfg.duration_s)?),
        MotionKind::BoardView => Box::new(BoardViewMotion::new(cfg.duration_s)?),
    })
}

/// The noise-free DVL reading for the camera body twist `twist = [v; w]`:
/// `kappa R_dvl_cam (v + w x p_cam_dvl)`.
pub fn dvl_model(truth: &CalibrationParams, twist: &Vector6<f64>) -> Vector3<f64> {
    let v = twist.fixed_rows::<3>(0).into_owned();
    let w = twist.fixed_rows::<3>(3).into_owned();
    let lever = &truth.t_cam_dvl.trans;
    (truth.t_cam_dvl.rot.transpose() * (v + w.cross(lever))) * truth.velocity_scale
}

/// Simulates the dataset described by `cfg`. The same configuration always gives bit-identical
/// output.
pub fn simulate(cfg: &SimConfig) -> Result<SimDataset> {
    cfg.validate()?;
    let motion = build_motion(cfg)?;
    simulate_with(cfg, motion.as_ref())
}

/// Simulates measurements of `motion` with the rates, noise and truth of `cfg` (`cfg.motion` and
/// the prior fields are ignored). Camera poses cover `[0, cfg.duration_s]`.
pub fn simulate_with(cfg: &SimConfig, motion: &dyn Motion) -> Result<SimDataset> {
    cfg.validate()?;
    let truth = cfg.truth;

    // Camera poses.
    let n_cam = (cfg.duration_s * cfg.camera_rate_hz + 1e-9).floor() as usize + 1;
    let (sp, sr) = (cfg.pose_sigma_pos_m, cfg.pose_sigma_rot_rad);
    let pose_cov = Matrix6::from_diagonal(&Vector6::new(
        sp * sp,
        sp * sp,
        sp * sp,
        sr * sr,
        sr * sr,
        sr * sr,
    ));
    let mut pose_rng = Rng::stream(cfg.seed, STREAM_POSE_NOISE);
    let mut poses = Vec::with_capacity(n_cam);
    let mut truth_poses = Vec::with_capacity(n_cam);
    for k in 0..n_cam {
        let t = k as f64 / cfg.camera_rate_hz;
        let state = motion.state(t);
        let z = pose_rng.normal_vec6();
        let n = Vector6::new(
            sp * z[0],
            sp * z[1],
            sp * z[2],
            sr * z[3],
            sr * z[4],
            sr * z[5],
        );
        poses.push(PoseMeasurement {
            t,
            pose: state.pose.retract(&n),
            cov: Some(pose_cov),
        });
        truth_poses.push(state);
    }
    let t_first = 0.0;
    let t_last = poses.last().map_or(0.0, |p| p.t);

    // DVL samples.
    let offset = truth.time_offset_s;
    let jitter = cfg.dvl_time_jitter_s;
    let rate = cfg.dvl_rate_hz;
    let drift = 1e-6 * cfg.clock_drift_ppm;
    let t_ref = t_first - offset;
    let reach = jitter + drift.abs() * (t_last - t_first) * 2.0;
    let j_lo = ((t_first - offset - reach) * rate).floor() as i64 - 1;
    let j_hi = ((t_last - offset + reach) * rate).ceil() as i64 + 1;
    let dvl_cov = Matrix3::identity() * (cfg.dvl_sigma * cfg.dvl_sigma);
    let mut jitter_rng = Rng::stream(cfg.seed, STREAM_DVL_JITTER);
    let mut noise_rng = Rng::stream(cfg.seed, STREAM_DVL_NOISE);
    let mut dvl = Vec::new();
    let mut dvl_truth = Vec::new();
    for j in j_lo..=j_hi {
        let t_dvl = j as f64 / rate + jitter_rng.uniform_in(-jitter, jitter);
        let t_cam = t_dvl + offset + drift * (t_dvl - t_ref);
        if !(t_first..=t_last).contains(&t_cam) {
            continue;
        }
        let state = motion.state(t_cam);
        let v = dvl_model(&truth, &state.twist) + noise_rng.normal_vec3() * cfg.dvl_sigma;
        dvl.push(DvlSample {
            t: t_dvl,
            v,
            cov: Some(dvl_cov),
            valid: true,
        });
        dvl_truth.push(state);
    }
    if dvl.is_empty() {
        return Err(Error::Input(
            "no DVL sample falls inside the camera span (time offset too large?)".into(),
        ));
    }
    Ok(SimDataset {
        epoch: Epoch {
            sec: cfg.unix_start_s,
        },
        poses,
        truth_poses,
        dvl,
        dvl_truth,
        truth,
    })
}
