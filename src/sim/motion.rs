//! Continuous camera motions with exact poses, body twists and twist rates.
//!
//! Every motion gives, at any time `t`, the pose `T_world_cam(t)`, the body twist
//! `varpi = [v; w]` with `T' = T hat(varpi)` (so `v = R^T p'` and `w` is the body angular
//! velocity) and the twist rate `d(varpi)/dt`.

use std::f64::consts::PI;

/// sqrt(3).
const SQRT_3: f64 = 1.732_050_807_568_877_2;

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3, Vector6};

use crate::error::{Error, Result};
use crate::lie::{Se3, curly, so3};
use crate::rng::Rng;

/// Stream numbers of [`Rng::stream`] used by the motions (kept apart from the dataset noise).
const STREAM_MOTION_STEPS: u64 = 1;
const STREAM_MOTION_INIT: u64 = 2;

/// Pose, body twist and twist rate of a motion at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionState {
    /// `T_world_cam`.
    pub pose: Se3,
    /// Body twist `[v; w]`: velocity of the camera origin and angular velocity, camera frame.
    pub twist: Vector6<f64>,
    /// `d(twist)/dt`.
    pub twist_rate: Vector6<f64>,
}

/// A continuous camera motion.
pub trait Motion: Send + Sync {
    /// The time interval `(start, end)` the motion is meant to be used on, seconds.
    fn span(&self) -> (f64, f64);
    /// The state at time `t` (defined for every finite `t`; outside the span it is an
    /// extrapolation).
    fn state(&self, t: f64) -> MotionState;
}

fn input(msg: impl Into<String>) -> Error {
    Error::Input(msg.into())
}

fn check_duration(duration_s: f64) -> Result<()> {
    if duration_s.is_finite() && duration_s > 0.0 {
        Ok(())
    } else {
        Err(input(format!(
            "motion duration must be positive and finite, got {duration_s}"
        )))
    }
}

fn check_finite_vec<const N: usize>(name: &str, v: &nalgebra::SVector<f64, N>) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(input(format!("{name} must be finite")))
    }
}

/// Checks that `r` is a finite proper rotation matrix (to 1e-6).
pub(crate) fn check_rotation(name: &str, r: &Matrix3<f64>) -> Result<()> {
    if !r.iter().all(|x| x.is_finite()) {
        return Err(input(format!("{name}: rotation must be finite")));
    }
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err > 1e-6 || r.determinant() <= 0.0 {
        return Err(input(format!("{name}: not a rotation matrix")));
    }
    Ok(())
}

fn check_pose(name: &str, t: &Se3) -> Result<()> {
    check_rotation(name, &t.rot)?;
    check_finite_vec(name, &t.trans)
}

/// Exponential coordinates of the motion over `[0, s]` under the twist `f(tau)` (`s` may be
/// negative): fourth-order Magnus expansion with the two Gauss-Legendre points, so that
/// `T(s) = T(0) exp(result)` to `O(s^5)`.
fn magnus4(s: f64, f: impl Fn(f64) -> Vector6<f64>) -> Vector6<f64> {
    let c = SQRT_3 / 6.0;
    let a1 = f((0.5 - c) * s);
    let a2 = f((0.5 + c) * s);
    (a1 + a2) * (0.5 * s) + curly(&a1) * a2 * (SQRT_3 / 12.0 * s * s)
}

// ---------------------------------------------------------------------------------------------
// Screw motion
// ---------------------------------------------------------------------------------------------

/// Constant body twist: `T(t) = start * exp(t * twist)` on `[0, duration_s]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScrewMotion {
    /// `T_world_cam` at time 0.
    pub start: Se3,
    /// Constant body twist `[v; w]` (m/s, rad/s, camera frame).
    pub twist: Vector6<f64>,
    /// The motion is used on `[0, duration_s]`, seconds.
    pub duration_s: f64,
}

impl ScrewMotion {
    /// The screw motion, after checking the start pose, the twist and the duration.
    pub fn new(start: Se3, twist: Vector6<f64>, duration_s: f64) -> Result<ScrewMotion> {
        check_duration(duration_s)?;
        check_pose("screw motion start", &start)?;
        check_finite_vec("screw motion twist", &twist)?;
        Ok(ScrewMotion {
            start,
            twist,
            duration_s,
        })
    }
}

impl Motion for ScrewMotion {
    fn span(&self) -> (f64, f64) {
        (0.0, self.duration_s)
    }

    fn state(&self, t: f64) -> MotionState {
        MotionState {
            pose: self.start * Se3::exp(&(self.twist * t)),
            twist: self.twist,
            twist_rate: Vector6::zeros(),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Sinusoidal motion
// ---------------------------------------------------------------------------------------------

/// One sinusoid per axis: component `i` is `amplitude[i] * sin(2 pi freq_hz[i] t + phase_rad[i])`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SinusoidTerm {
    /// Amplitude per axis (m for position terms, rad for rotation terms).
    pub amplitude: Vector3<f64>,
    /// Frequency per axis, Hz.
    pub freq_hz: Vector3<f64>,
    /// Phase per axis at `t = 0`, rad.
    pub phase_rad: Vector3<f64>,
}

impl SinusoidTerm {
    /// A term from per-axis amplitudes, frequencies (Hz) and phases (rad).
    pub fn new(amplitude: [f64; 3], freq_hz: [f64; 3], phase_rad: [f64; 3]) -> SinusoidTerm {
        SinusoidTerm {
            amplitude: Vector3::from(amplitude),
            freq_hz: Vector3::from(freq_hz),
            phase_rad: Vector3::from(phase_rad),
        }
    }

    fn is_finite(&self) -> bool {
        self.amplitude
            .iter()
            .chain(self.freq_hz.iter())
            .chain(self.phase_rad.iter())
            .all(|x| x.is_finite())
    }
}

/// Value, first and second derivative of `offset + sum(terms)` at `t`.
fn sum_sinusoids(
    offset: &Vector3<f64>,
    terms: &[SinusoidTerm],
    t: f64,
) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let mut x = *offset;
    let mut dx = Vector3::zeros();
    let mut ddx = Vector3::zeros();
    for term in terms {
        for i in 0..3 {
            let om = 2.0 * PI * term.freq_hz[i];
            let (s, c) = (om * t + term.phase_rad[i]).sin_cos();
            let a = term.amplitude[i];
            x[i] += a * s;
            dx[i] += a * om * c;
            ddx[i] -= a * om * om * s;
        }
    }
    (x, dx, ddx)
}

/// Position and rotation vector as sums of sinusoids: `p(t) = p0 + sum`, `R(t) = exp(phi(t))`,
/// `phi(t) = phi0 + sum`, on `[0, duration_s]`.
///
/// Twist: `w = J_r(phi) phi'`, `v = R^T p'` (exact). Twist rate: `v' = R^T p'' - w x v`
/// (exact) and `w'` by a fourth-order central difference of the exact `w` (error ~1e-10).
#[derive(Clone, Debug, PartialEq)]
pub struct SinusoidMotion {
    /// The motion is used on `[0, duration_s]`, seconds.
    pub duration_s: f64,
    /// Constant part `p0` of the camera position in the world frame, m.
    pub position_offset: Vector3<f64>,
    /// Sinusoids added to the position, m.
    pub position: Vec<SinusoidTerm>,
    /// Constant part `phi0` of the rotation vector of `R_world_cam`, rad.
    pub rotation_offset: Vector3<f64>,
    /// Sinusoids added to the rotation vector, rad.
    pub rotation: Vec<SinusoidTerm>,
}

impl SinusoidMotion {
    /// Step of the central difference for `w'`, seconds.
    const RATE_STEP_S: f64 = 5e-4;

    /// Checks the fields (duration positive, everything finite).
    pub fn validate(&self) -> Result<()> {
        check_duration(self.duration_s)?;
        check_finite_vec("sinusoid position offset", &self.position_offset)?;
        check_finite_vec("sinusoid rotation offset", &self.rotation_offset)?;
        if self
            .position
            .iter()
            .chain(self.rotation.iter())
            .all(SinusoidTerm::is_finite)
        {
            Ok(())
        } else {
            Err(input("sinusoid terms must be finite"))
        }
    }

    /// A lively motion: rotation rates up to about 2 rad/s per axis (RMS of |w| about 1.6 rad/s)
    /// and speeds around 0.5 m/s, with incommensurate frequencies on every axis.
    pub fn lively(duration_s: f64) -> Result<SinusoidMotion> {
        let m = SinusoidMotion {
            duration_s,
            position_offset: Vector3::zeros(),
            position: vec![
                SinusoidTerm::new([0.25, 0.15, 0.20], [0.31, 0.23, 0.17], [0.0, 1.0, 2.0]),
                SinusoidTerm::new([0.05, 0.08, 0.04], [0.9, 0.7, 1.1], [0.5, 0.2, 1.3]),
            ],
            rotation_offset: Vector3::zeros(),
            rotation: vec![
                SinusoidTerm::new([0.35, 0.30, 0.40], [0.45, 0.60, 0.38], [0.3, 1.1, 2.0]),
                SinusoidTerm::new([0.10, 0.12, 0.08], [1.3, 1.1, 1.7], [0.9, 2.5, 0.4]),
            ],
        };
        m.validate()?;
        Ok(m)
    }

    /// Rotation and angular velocity at `t`.
    fn rotation_parts(&self, t: f64) -> (Matrix3<f64>, Vector3<f64>) {
        let (phi, dphi, _) = sum_sinusoids(&self.rotation_offset, &self.rotation, t);
        (so3::exp(&phi), so3::right_jacobian(&phi) * dphi)
    }

    fn angular_velocity(&self, t: f64) -> Vector3<f64> {
        self.rotation_parts(t).1
    }
}

impl Motion for SinusoidMotion {
    fn span(&self) -> (f64, f64) {
        (0.0, self.duration_s)
    }

    fn state(&self, t: f64) -> MotionState {
        let (r, w) = self.rotation_parts(t);
        let (p, dp, ddp) = sum_sinusoids(&self.position_offset, &self.position, t);
        let rt = r.transpose();
        let v = rt * dp;
        let dv = rt * ddp - w.cross(&v);
        let h = Self::RATE_STEP_S;
        let dw = (self.angular_velocity(t - 2.0 * h) - self.angular_velocity(t + 2.0 * h)
            + (self.angular_velocity(t + h) - self.angular_velocity(t - h)) * 8.0)
            / (12.0 * h);
        MotionState {
            pose: Se3::new(r, p),
            twist: Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z),
            twist_rate: Vector6::new(dv.x, dv.y, dv.z, dw.x, dw.y, dw.z),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Sampled white-noise-on-jerk motion
// ---------------------------------------------------------------------------------------------

/// Damping that pulls the twist towards zero: per component
/// `varpi'' = -omega0^2 varpi - 2 zeta omega0 varpi' + noise`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanReversion {
    /// Natural frequency, rad/s.
    pub omega0: f64,
    /// Damping ratio.
    pub zeta: f64,
}

impl MeanReversion {
    /// Stationary standard deviations of `(varpi, varpi')` of one component with noise density
    /// `qc`: `sqrt(qc / (4 zeta omega0^3))` and `sqrt(qc / (4 zeta omega0))`.
    pub fn stationary_std(&self, qc: f64) -> (f64, f64) {
        let w = self.omega0;
        (
            (qc / (4.0 * self.zeta * w * w * w)).sqrt(),
            (qc / (4.0 * self.zeta * w)).sqrt(),
        )
    }
}

/// Everything that defines a [`SampledMotion`].
#[derive(Clone, Debug, PartialEq)]
pub struct SampledConfig {
    /// Seed of the random stream of the jerk noise.
    pub seed: u64,
    /// The motion is used on `[0, duration_s]`.
    pub duration_s: f64,
    /// Grid step, seconds.
    pub dt_s: f64,
    /// `(start time, Qc)`: the power spectral density of the jerk of each twist component
    /// (`[v; w]` order) from that time on. Starts strictly increasing; before the first start the
    /// first phase applies.
    pub phases: Vec<(f64, [f64; 6])>,
    /// `None`: pure white noise on jerk.
    pub mean_reversion: Option<MeanReversion>,
    /// `T_world_cam` at time 0.
    pub initial_pose: Se3,
    /// Body twist `[v; w]` at time 0 (m/s, rad/s, camera frame).
    pub initial_twist: Vector6<f64>,
    /// Time derivative of the body twist at time 0 (m/s^2, rad/s^2).
    pub initial_twist_rate: Vector6<f64>,
}

impl SampledConfig {
    /// Pure white noise on jerk with one `Qc`, 1 ms grid, starting at rest at the identity.
    pub fn new(seed: u64, duration_s: f64, qc: [f64; 6]) -> SampledConfig {
        SampledConfig {
            seed,
            duration_s,
            dt_s: SampledMotion::DEFAULT_DT_S,
            phases: vec![(0.0, qc)],
            mean_reversion: None,
            initial_pose: Se3::identity(),
            initial_twist: Vector6::zeros(),
            initial_twist_rate: Vector6::zeros(),
        }
    }

    fn validate(&self) -> Result<usize> {
        check_duration(self.duration_s)?;
        if !(self.dt_s.is_finite() && self.dt_s > 0.0) {
            return Err(input(format!(
                "grid step must be positive and finite, got {}",
                self.dt_s
            )));
        }
        let steps = (self.duration_s / self.dt_s - 1e-9).ceil().max(1.0);
        if steps + 1.0 > SampledMotion::MAX_GRID_POINTS as f64 {
            return Err(input(format!(
                "sampled motion of {} s at {} s steps needs more than {} grid points",
                self.duration_s,
                self.dt_s,
                SampledMotion::MAX_GRID_POINTS
            )));
        }
        if self.phases.is_empty() {
            return Err(input("sampled motion needs at least one Qc phase"));
        }
        for (i, (start, qc)) in self.phases.iter().enumerate() {
            if !start.is_finite() {
                return Err(input("phase start times must be finite"));
            }
            if i > 0 && *start <= self.phases[i - 1].0 {
                return Err(input("phase start times must increase strictly"));
            }
            if !qc.iter().all(|q| q.is_finite() && *q >= 0.0) {
                return Err(input("Qc values must be finite and non-negative"));
            }
        }
        if let Some(mr) = &self.mean_reversion {
            if !(mr.omega0.is_finite() && mr.omega0 > 0.0 && mr.zeta.is_finite() && mr.zeta > 0.0) {
                return Err(input(
                    "mean reversion needs positive finite omega0 and zeta",
                ));
            }
        }
        check_pose("initial pose", &self.initial_pose)?;
        check_finite_vec("initial twist", &self.initial_twist)?;
        check_finite_vec("initial twist rate", &self.initial_twist_rate)?;
        Ok(steps as usize)
    }
}

/// A trajectory sampled on a fine grid from a white-noise-on-jerk model of the body twist.
///
/// Per twist component, `(varpi, varpi')` is propagated exactly over each step (transition
/// `[[1, dt], [0, 1]]`, or the exact damped transition with mean reversion) with noise covariance
/// `Qc [[dt^3/3, dt^2/2], [dt^2/2, dt]]`. Between grid points the twist is the cubic Hermite
/// interpolant of the grid values and rates; the pose is integrated along it with a fourth-order
/// Magnus step from the previous grid point (`T_{k+1} = T_k exp(Omega_k)`), so poses, twists and
/// twist rates at any time agree with `T' = T hat(varpi)` to about 1e-10.
/// Outside the grid the twist is extrapolated linearly from the end point's value and rate.
#[derive(Clone, Debug)]
pub struct SampledMotion {
    duration_s: f64,
    dt: f64,
    poses: Vec<Se3>,
    twists: Vec<Vector6<f64>>,
    rates: Vec<Vector6<f64>>,
}

impl SampledMotion {
    /// Default grid step, seconds.
    pub const DEFAULT_DT_S: f64 = 1e-3;
    /// Largest grid accepted (about 0.8 GB; 66 minutes at 1 ms).
    pub const MAX_GRID_POINTS: usize = 4_000_000;

    /// Mean reversion of the scripted motions.
    const SCRIPTED_REVERSION: MeanReversion = MeanReversion {
        omega0: 1.0,
        zeta: 0.7,
    };
    /// Translational jerk density of the scripted motions: stationary speed about 0.15 m/s per
    /// axis (0.26 m/s RMS).
    const SCRIPTED_QC_V: f64 = 0.063;

    /// Samples the motion defined by `cfg`.
    pub fn generate(cfg: &SampledConfig) -> Result<SampledMotion> {
        let steps = cfg.validate()?;
        let dt = cfg.dt_s;
        let phi = match &cfg.mean_reversion {
            None => Matrix2::new(1.0, dt, 0.0, 1.0),
            Some(mr) => {
                let a = Matrix2::new(0.0, 1.0, -mr.omega0 * mr.omega0, -2.0 * mr.zeta * mr.omega0);
                (a * dt).exp()
            }
        };
        // Cholesky factor of [[dt^3/3, dt^2/2], [dt^2/2, dt]].
        let l11 = (dt * dt * dt / 3.0).sqrt();
        let l21 = 0.5 * (3.0 * dt).sqrt();
        let l22 = 0.5 * dt.sqrt();

        let mut rng = Rng::stream(cfg.seed, STREAM_MOTION_STEPS);
        let mut twists = Vec::with_capacity(steps + 1);
        let mut rates = Vec::with_capacity(steps + 1);
        twists.push(cfg.initial_twist);
        rates.push(cfg.initial_twist_rate);
        let mut phase = 0;
        for k in 0..steps {
            let t = k as f64 * dt;
            while phase + 1 < cfg.phases.len() && cfg.phases[phase + 1].0 <= t {
                phase += 1;
            }
            let qc = &cfg.phases[phase].1;
            let (w0, r0) = (twists[k], rates[k]);
            let mut w1 = Vector6::zeros();
            let mut r1 = Vector6::zeros();
            for i in 0..6 {
                let z1 = rng.normal();
                let z2 = rng.normal();
                let sq = qc[i].sqrt();
                let x = phi * Vector2::new(w0[i], r0[i]);
                w1[i] = x[0] + sq * l11 * z1;
                r1[i] = x[1] + sq * (l21 * z1 + l22 * z2);
            }
            twists.push(w1);
            rates.push(r1);
        }
        let poses = integrate_twists(cfg.initial_pose, &twists, &rates, dt);
        Ok(SampledMotion {
            duration_s: cfg.duration_s,
            dt,
            poses,
            twists,
            rates,
        })
    }

    /// The motion whose body twist and twist rate at grid point `k` (time `k * dt`) are
    /// `twists[k]` and `rates[k]`, starting at `initial_pose`: the twist between grid points is
    /// their cubic Hermite interpolant and the poses are its exact integral, so poses, twists and
    /// rates agree at every time. Used to replay a recorded vehicle's twists
    /// ([`crate::sim::track`]). The span is `[0, duration_s]`; the grid must cover it.
    pub fn from_twists(
        initial_pose: Se3,
        twists: Vec<Vector6<f64>>,
        rates: Vec<Vector6<f64>>,
        dt: f64,
        duration_s: f64,
    ) -> Result<SampledMotion> {
        check_duration(duration_s)?;
        check_pose("initial pose", &initial_pose)?;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(input(format!("grid step must be positive, got {dt}")));
        }
        if twists.len() != rates.len() || twists.len() < 2 {
            return Err(input(format!(
                "need as many twists as rates, at least 2 (got {} and {})",
                twists.len(),
                rates.len()
            )));
        }
        if twists.len() > Self::MAX_GRID_POINTS {
            return Err(input(format!(
                "{} grid points exceed the limit of {}",
                twists.len(),
                Self::MAX_GRID_POINTS
            )));
        }
        if (twists.len() - 1) as f64 * dt < duration_s * (1.0 - 1e-12) {
            return Err(input(format!(
                "the grid ({} points of {dt} s) ends before the duration {duration_s} s",
                twists.len()
            )));
        }
        for (k, (w, r)) in twists.iter().zip(&rates).enumerate() {
            check_finite_vec(&format!("twist {k}"), w)?;
            check_finite_vec(&format!("twist rate {k}"), r)?;
        }
        let poses = integrate_twists(initial_pose, &twists, &rates, dt);
        Ok(SampledMotion {
            duration_s,
            dt,
            poses,
            twists,
            rates,
        })
    }

    /// Pure white noise on jerk with density `qc` (`[v; w]` order), starting at the identity with
    /// twist `initial_twist` and zero twist rate.
    pub fn wnoj(
        seed: u64,
        duration_s: f64,
        qc: [f64; 6],
        initial_twist: Vector6<f64>,
    ) -> Result<SampledMotion> {
        let mut cfg = SampledConfig::new(seed, duration_s, qc);
        cfg.initial_twist = initial_twist;
        Self::generate(&cfg)
    }

    /// Scripted motion: translation throughout (about 0.15 m/s per axis, kept bounded by mean
    /// reversion), almost no rotation in the first half (rotation Qc 1e-10, |w| ~ 1e-5 rad/s),
    /// strong rotation in the second half (about 0.6 rad/s per axis, |w| ~ 1 rad/s).
    pub fn calm_then_rotate(seed: u64, duration_s: f64) -> Result<SampledMotion> {
        let qv = Self::SCRIPTED_QC_V;
        let calm = [qv, qv, qv, 1e-10, 1e-10, 1e-10];
        let strong = [qv, qv, qv, 1.0, 1.0, 1.0];
        Self::scripted(
            seed,
            duration_s,
            vec![(0.0, calm), (0.5 * duration_s, strong)],
        )
    }

    /// Scripted motion with weak rotation throughout (about 0.02 rad/s per axis, |w| ~ 0.035
    /// rad/s) and the same translation as [`SampledMotion::calm_then_rotate`].
    pub fn weak_rotation(seed: u64, duration_s: f64) -> Result<SampledMotion> {
        let qv = Self::SCRIPTED_QC_V;
        let q = [qv, qv, qv, 1.12e-3, 1.12e-3, 1.12e-3];
        Self::scripted(seed, duration_s, vec![(0.0, q)])
    }

    /// Mean-reverting motion whose initial twist and rate are drawn from the stationary
    /// distribution of the first phase.
    fn scripted(seed: u64, duration_s: f64, phases: Vec<(f64, [f64; 6])>) -> Result<SampledMotion> {
        check_duration(duration_s)?;
        let mr = Self::SCRIPTED_REVERSION;
        let mut rng = Rng::stream(seed, STREAM_MOTION_INIT);
        let z_twist = rng.normal_vec6();
        let z_rate = rng.normal_vec6();
        let mut twist = Vector6::zeros();
        let mut rate = Vector6::zeros();
        for i in 0..6 {
            let (sw, sr) = mr.stationary_std(phases[0].1[i]);
            twist[i] = sw * z_twist[i];
            rate[i] = sr * z_rate[i];
        }
        Self::generate(&SampledConfig {
            seed,
            duration_s,
            dt_s: Self::DEFAULT_DT_S,
            phases,
            mean_reversion: Some(mr),
            initial_pose: Se3::identity(),
            initial_twist: twist,
            initial_twist_rate: rate,
        })
    }

    /// Grid step, seconds.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Number of grid points (the grid covers at least the span).
    pub fn grid_len(&self) -> usize {
        self.poses.len()
    }

    /// Time of grid point `k`: `k * dt`.
    pub fn grid_time(&self, k: usize) -> f64 {
        k as f64 * self.dt
    }

    /// The stored state at grid point `k`.
    pub fn grid_state(&self, k: usize) -> Option<MotionState> {
        Some(MotionState {
            pose: *self.poses.get(k)?,
            twist: *self.twists.get(k)?,
            twist_rate: *self.rates.get(k)?,
        })
    }

    /// State at `s` after grid point `k` with the twist extrapolated linearly.
    fn extrapolate(&self, k: usize, s: f64) -> MotionState {
        let (w, r) = (self.twists[k], self.rates[k]);
        let omega = magnus4(s, |tau| w + r * tau);
        MotionState {
            pose: self.poses[k] * Se3::exp(&omega),
            twist: w + r * s,
            twist_rate: r,
        }
    }
}

/// Poses at every grid point from the first one: each step multiplies by the exponential of the
/// Magnus expansion of the Hermite-interpolated twist.
fn integrate_twists(
    initial_pose: Se3,
    twists: &[Vector6<f64>],
    rates: &[Vector6<f64>],
    dt: f64,
) -> Vec<Se3> {
    let mut poses = Vec::with_capacity(twists.len());
    poses.push(initial_pose);
    for k in 0..twists.len().saturating_sub(1) {
        let (w0, r0, w1, r1) = (&twists[k], &rates[k], &twists[k + 1], &rates[k + 1]);
        let omega = magnus4(dt, |s| hermite(w0, r0, w1, r1, dt, s).0);
        poses.push((poses[k] * Se3::exp(&omega)).renormalized());
    }
    poses
}

/// Cubic Hermite interpolant on `[0, dt]` of values `w0, w1` and slopes `r0, r1`: value and
/// derivative at `s`.
fn hermite(
    w0: &Vector6<f64>,
    r0: &Vector6<f64>,
    w1: &Vector6<f64>,
    r1: &Vector6<f64>,
    dt: f64,
    s: f64,
) -> (Vector6<f64>, Vector6<f64>) {
    let u = s / dt;
    let u2 = u * u;
    let u3 = u2 * u;
    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
    let h10 = u3 - 2.0 * u2 + u;
    let h01 = -2.0 * u3 + 3.0 * u2;
    let h11 = u3 - u2;
    let value = w0 * h00 + r0 * (h10 * dt) + w1 * h01 + r1 * (h11 * dt);
    let rate = (w0 - w1) * ((6.0 * u2 - 6.0 * u) / dt)
        + r0 * (3.0 * u2 - 4.0 * u + 1.0)
        + r1 * (3.0 * u2 - 2.0 * u);
    (value, rate)
}

impl Motion for SampledMotion {
    fn span(&self) -> (f64, f64) {
        (0.0, self.duration_s)
    }

    fn state(&self, t: f64) -> MotionState {
        let n = self.poses.len() - 1;
        let t_end = self.grid_time(n);
        if t.is_nan() || t <= 0.0 {
            return self.extrapolate(0, t);
        }
        if t >= t_end {
            return self.extrapolate(n, t - t_end);
        }
        let mut k = ((t / self.dt).floor() as usize).min(n - 1);
        while k + 1 < n && self.grid_time(k + 1) <= t {
            k += 1;
        }
        while k > 0 && self.grid_time(k) > t {
            k -= 1;
        }
        let s = t - self.grid_time(k);
        let (w0, r0, w1, r1) = (
            &self.twists[k],
            &self.rates[k],
            &self.twists[k + 1],
            &self.rates[k + 1],
        );
        let (twist, twist_rate) = hermite(w0, r0, w1, r1, self.dt, s);
        let omega = magnus4(s, |tau| hermite(w0, r0, w1, r1, self.dt, tau).0);
        MotionState {
            pose: self.poses[k] * Se3::exp(&omega),
            twist,
            twist_rate,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Motion in front of a calibration board
// ---------------------------------------------------------------------------------------------

/// A camera moving in front of a board it keeps in view: a calm first part with translation only
/// (about 0.2 m/s per axis, no rotation), then rotations that oscillate about the initial
/// orientation with per-axis rates up to about 1 rad/s but amplitudes of only 0.12-0.26 rad, so
/// that a board 1.5-2.5 m ahead of the starting camera stays in a 752x480 field of view.
///
/// Position: `p(t)` from [`BoardViewMotion::sinusoids`]' position terms (world frame = the
/// starting camera's orientation: x right, y down, z forward). Rotation: `R(t) = exp(e(t) s(t))`
/// where `s(t)` is the sum of the rotation terms and `e(t)` a quintic smooth step from 0 at
/// `rotation_start_s` to 1 at `rotation_start_s + ramp_s` (so the twist and its rate stay
/// continuous). Twist: `w = J_r(phi) phi'`, `v = R^T p'`; twist rate as for [`SinusoidMotion`].
#[derive(Clone, Debug, PartialEq)]
pub struct BoardViewMotion {
    /// Position terms and (envelope-free) rotation terms; its duration is the motion's.
    pub sinusoids: SinusoidMotion,
    /// End of the calm part, seconds.
    pub rotation_start_s: f64,
    /// Length of the ramp from no rotation to full rotation, seconds (may be 0).
    pub ramp_s: f64,
}

impl BoardViewMotion {
    /// The standard motion of `duration_s` seconds: calm first half, rotation ramped in over
    /// `min(4 s, duration / 10)`. The camera starts at the world origin and stays within about
    /// 0.25 m of it along x, 0.13 m along y and 0.23 m along z (the depth of a board ahead).
    pub fn new(duration_s: f64) -> Result<BoardViewMotion> {
        check_duration(duration_s)?;
        let sinusoids = SinusoidMotion {
            duration_s,
            position_offset: Vector3::zeros(),
            position: vec![
                SinusoidTerm::new([0.22, 0.10, 0.20], [0.15, 0.19, 0.13], [0.0, 0.0, 0.0]),
                SinusoidTerm::new([0.03, 0.03, 0.03], [0.7, 0.8, 0.55], [0.0, PI, PI]),
            ],
            rotation_offset: Vector3::zeros(),
            // x: pitch (moves the board vertically), y: yaw (horizontally), z: roll.
            rotation: vec![
                SinusoidTerm::new([0.09, 0.16, 0.20], [0.70, 0.55, 0.60], [0.3, 1.1, 2.0]),
                SinusoidTerm::new([0.035, 0.05, 0.06], [1.9, 1.7, 1.5], [0.9, 2.5, 0.4]),
            ],
        };
        let m = BoardViewMotion {
            sinusoids,
            rotation_start_s: 0.5 * duration_s,
            ramp_s: (0.1 * duration_s).min(4.0),
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks the fields.
    pub fn validate(&self) -> Result<()> {
        self.sinusoids.validate()?;
        if !self.rotation_start_s.is_finite() || !self.ramp_s.is_finite() || self.ramp_s < 0.0 {
            return Err(input(
                "board-view motion: rotation start must be finite and ramp non-negative",
            ));
        }
        Ok(())
    }

    /// Envelope and its derivative at `t`.
    fn envelope(&self, t: f64) -> (f64, f64) {
        let t0 = self.rotation_start_s;
        if t <= t0 {
            return (0.0, 0.0);
        }
        if t >= t0 + self.ramp_s {
            return (1.0, 0.0);
        }
        let u = (t - t0) / self.ramp_s;
        let e = u * u * u * (10.0 + u * (-15.0 + 6.0 * u));
        let de = 30.0 * u * u * (1.0 - u) * (1.0 - u) / self.ramp_s;
        (e, de)
    }

    fn rotation_parts(&self, t: f64) -> (Matrix3<f64>, Vector3<f64>) {
        let s = &self.sinusoids;
        let (sum, dsum, _) = sum_sinusoids(&Vector3::zeros(), &s.rotation, t);
        let (e, de) = self.envelope(t);
        let phi = s.rotation_offset + sum * e;
        let dphi = dsum * e + sum * de;
        (so3::exp(&phi), so3::right_jacobian(&phi) * dphi)
    }
}

impl Motion for BoardViewMotion {
    fn span(&self) -> (f64, f64) {
        (0.0, self.sinusoids.duration_s)
    }

    fn state(&self, t: f64) -> MotionState {
        let (r, w) = self.rotation_parts(t);
        let s = &self.sinusoids;
        let (p, dp, ddp) = sum_sinusoids(&s.position_offset, &s.position, t);
        let rt = r.transpose();
        let v = rt * dp;
        let dv = rt * ddp - w.cross(&v);
        let h = SinusoidMotion::RATE_STEP_S;
        let ang = |t: f64| self.rotation_parts(t).1;
        let dw =
            (ang(t - 2.0 * h) - ang(t + 2.0 * h) + (ang(t + h) - ang(t - h)) * 8.0) / (12.0 * h);
        MotionState {
            pose: Se3::new(r, p),
            twist: Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z),
            twist_rate: Vector6::new(dv.x, dv.y, dv.z, dw.x, dw.y, dw.z),
        }
    }
}
