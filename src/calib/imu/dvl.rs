//! A DVL calibrated against an IMU without a camera: `T_imu_dvl`, the DVL's clock offset on
//! the IMU's clock (`t_imu = t_dvl + offset`) and its velocity scale, with the IMU's biases and
//! the direction of gravity.
//!
//! The trajectory is the IMU's own, on its clock, in a world frame that is the IMU's frame at
//! the first knot (a tight prior on that knot fixes the gauge; gravity's direction in it is
//! estimated). Its knots are about 25 ms apart; the IMU's bins drive it between the DVL's
//! reports, the DVL's velocities tie its speed. The problem is the camera-IMU one
//! ([`super::solve::ImuJoint`]) with the camera's poses replaced by that prior, the IMU's frame
//! and clock held as the trajectory's, and the DVL's velocities added with their parameters.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

use super::bins::{ImuBin, make_bins};
use super::dvl_init::{DeadReckoning, DvlImuStart, gyro_bias_from_gravity, initial_dvl_imu};
use super::factors::{SparsePoseFactors, bin_information};
use super::preint::Windows;
use super::solve::{ImuJoint, Redundancy};
use super::state::{BiasNodes, ImuState};
use super::{ImuOptions, bias_spacing};
use crate::calib::model::{DvlObs, NPARAM};
use crate::calib::options::CalibOptions;
use crate::calib::samples::observe;
use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::trajectory::{JerkDensity, Knot, KnotView};
use crate::types::imu::{ImuBias, ImuNoise, ImuSample};
use crate::types::{CalibrationParams, DvlSample};

/// A noise factor above this says the sensors do not describe one motion (another recording's
/// IMU, a wrong clock): the calibration fails rather than scale its std by it.
const MISFIT_FACTOR: f64 = 8.0;

/// Knot spacing of the IMU's trajectory, s.
const KNOT_SPACING_S: f64 = 0.025;

/// Knot spacing with the IMU preintegrated between knots, s (the camera modes' 10 Hz).
const WINDOW_SPACING_S: f64 = 0.1;

/// With the IMU preintegrated, the first solve may start from the solution of the same
/// problem on every `COARSE_STRIDE`-th knot (its windows that much longer, the DVL's velocities
/// interpolated between them).
const COARSE_STRIDE: usize = 5;

/// The knots (0.1 s apart) from which the coarse start is taken unless the options say: half
/// an hour. At 16 minutes the reckoned start converges in 4 iterations and the coarse solve
/// costs more than it saves; at an hour it took 16.
pub const COARSE_FROM_KNOTS: usize = 18_000;

/// The start for `joint` from its problem on every [`COARSE_STRIDE`]-th knot (and the last):
/// the reckoned trajectory's nonlinearity (a long chain fixed at its first knot, turning as
/// its attitude is corrected) is worked off there at about a fifth of the cost, and the full
/// problem starts near its minimum. The full problem, its windows and its minimum are the
/// same; only its first iterate moves. The coarse solution's knots are interpolated at the
/// full problem's times.
fn coarse_start(
    joint: &ImuJoint,
    samples: &[ImuSample],
    knots: Vec<Knot>,
    st: ImuState,
    max_iterations: usize,
) -> Result<(Vec<Knot>, ImuState)> {
    let kept = super::every_nth(joint.times.len(), COARSE_STRIDE);
    let times: Vec<f64> = kept.iter().map(|&i| joint.times[i]).collect();
    let coarse_knots: Vec<Knot> = kept.iter().map(|&i| knots[i]).collect();
    let poses = kept.iter().map(|&i| joint.poses.poses[i]).collect();
    let mut st = st;
    st.bias = BiasNodes {
        times: times.clone(),
        values: kept.iter().map(|&i| st.bias.values[i]).collect(),
    };
    let windows = Windows::new(
        samples,
        &times,
        &st,
        &joint.noise,
        Windows::stated_variances(&joint.noise),
    );
    let coarse = ImuJoint {
        times,
        poses: SparsePoseFactors {
            poses,
            between: Vec::new(),
        },
        density: joint.density.clone(),
        bins: joint.bins,
        info: joint.info.clone(),
        noise: joint.noise,
        held: joint.held.clone(),
        dvl: joint.dvl,
        dvl_info: joint.dvl_info.clone(),
        windows: Some(windows),
    };
    let mut sol = coarse.solve(coarse_knots, st, max_iterations)?;
    let view = KnotView {
        times: &coarse.times,
        knots: &sol.knots,
    };
    let knots = joint
        .times
        .iter()
        .map(|&t| {
            view.state(t).map(|s| Knot {
                pose: s.pose,
                twist: s.twist,
                rate: s.rate,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    // The biases linear between the coarse knots, as they are between the full problem's.
    sol.state.bias = sol.state.bias.resampled(&joint.times, 0.0);
    Ok((knots, sol.state))
}

/// The DVL's calibration against the IMU.
#[derive(Clone, Debug)]
pub struct DvlImuEstimate {
    /// `T_cam_dvl` holds `T_imu_dvl` (DVL points into the IMU frame); the clock offset is
    /// `t_imu = t_dvl + time_offset_s`.
    pub params: CalibrationParams,
    /// Covariance of `[dphi; dp; dkappa; ddelta]` (`calib::model`'s coordinates), the
    /// trajectory, biases and gravity marginalised, scaled by the noise factors.
    pub covariance: SMatrix<f64, NPARAM, NPARAM>,
    /// The IMU's biases and gravity at the solution.
    pub imu: ImuState,
    /// Factors by which the stated gyro, accelerometer and DVL noise were multiplied (at least
    /// 1; 1 when not estimated).
    pub noise_factor: (f64, f64, f64),
    /// Gauss-Newton iterations of the last solution.
    pub iterations: usize,
    /// Whether it converged.
    pub converged: bool,
    /// DVL reports used (inside the IMU's span at the solution's offset).
    pub dvl_used: usize,
    /// Valid DVL reports in all.
    pub dvl_total: usize,
    /// IMU bins used (inside the trajectory's span; preintegrated, inside a window).
    pub bins_used: usize,
    /// IMU bins in all.
    pub bins_total: usize,
    /// The trajectory's knot times (IMU clock).
    pub times: Vec<f64>,
    /// The trajectory's knot states at the solution (world: the IMU at the first knot).
    pub knots: Vec<Knot>,
    /// How far the DVL's parameters move (`calib::model`'s coordinates) when the motion
    /// prior's jerk density is [`super::PRIOR_SHIFT_FACTOR`] times looser; its outer product is
    /// part of `covariance` (`None`: the noise was not estimated).
    pub prior_shift: Option<SMatrix<f64, NPARAM, 1>>,
}

impl DvlImuEstimate {
    /// Standard deviations in `calib::model`'s coordinates: rotation (rad, per axis), lever arm
    /// (m, per axis), scale, clock offset (s).
    pub fn std(&self) -> [f64; NPARAM] {
        std::array::from_fn(|i| self.covariance[(i, i)].max(0.0).sqrt())
    }

    /// [`DvlImuEstimate::std`] without the motion prior's share: what the sensors' noise alone
    /// leaves unknown.
    pub fn data_std(&self) -> [f64; NPARAM] {
        let shift = self.prior_shift.unwrap_or_default();
        std::array::from_fn(|i| {
            (self.covariance[(i, i)] - shift[i] * shift[i])
                .max(0.0)
                .sqrt()
        })
    }
}

/// Calibrates the DVL of `dvl` against the IMU of `samples` (with `noise`), no camera. The
/// DVL's noise is taken as `dvl_opts` says (its reports' covariance or a default);
/// `dvl_opts.offset.window_s` bounds the clock offset searched.
pub fn calibrate_dvl_imu(
    dvl: &[DvlSample],
    samples: &[ImuSample],
    noise: &ImuNoise,
    dvl_opts: &CalibOptions,
    opts: &ImuOptions,
) -> Result<DvlImuEstimate> {
    if samples.len() < 100 {
        return Err(Error::Input(format!(
            "{} IMU samples: too few to calibrate with",
            samples.len()
        )));
    }
    let obs = observe(dvl, dvl_opts)?.obs;
    let bins = make_bins(samples, opts.bin_width_s, noise.update_rate);
    let max_offset = dvl_opts.offset.window_s.max(opts.max_offset_s);
    let g = opts.gravity_magnitude;
    let dr = DeadReckoning::new(&bins, Vector3::zeros());
    let start = initial_dvl_imu(&dr, &obs, max_offset, g)?;
    let params = CalibrationParams::from_r_dvl_cam(
        start.r_imu_dvl.transpose(),
        start.lever,
        start.scale,
        start.offset,
    );
    // Knots over the span both sensors cover.
    let (b0, b1) = (bins[0].t, bins[bins.len() - 1].t);
    let (d0, d1) = obs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), o| {
            (a.min(o.t + start.offset), b.max(o.t + start.offset))
        });
    let (t0, t1) = (b0.max(d0), b1.min(d1));
    if t1 - t0 <= 2.0 || t1.is_nan() || t0.is_nan() {
        return Err(Error::NoTimeOverlap(format!(
            "the DVL and the IMU overlap for {:.2} s at the clock offset found ({:.3} s)",
            (t1 - t0).max(0.0),
            start.offset
        )));
    }
    let preintegrate = opts
        .preintegrate
        .unwrap_or(t1 - t0 > super::PREINTEGRATE_FROM_S);
    let spacing = if preintegrate {
        WINDOW_SPACING_S
    } else {
        KNOT_SPACING_S
    };
    let n = ((t1 - t0) / spacing).ceil() as usize + 1;
    let times: Vec<f64> = (0..n)
        .map(|i| t0 + (t1 - t0) * i as f64 / (n - 1) as f64)
        .collect();
    let mut bias = BiasNodes::spanning(
        bins[0].t,
        bins[bins.len() - 1].t,
        bias_spacing(samples, opts),
        ImuBias {
            gyro: Vector3::zeros(),
            accel: start.accel_bias,
        },
    );
    // The gyro's bias from the windows' gravity, so that the knots' attitudes do not drift
    // from the start (over an hour a bias of a few tenths of a degree per second turns the
    // reckoning by radians, and Gauss-Newton would spend tens of iterations undoing it).
    let unbiased = unbias_gyro(&bins, &start, &mut bias, noise);
    let dr = DeadReckoning::new(&unbiased, Vector3::zeros());
    let gravity = gravity_in(&dr, &start, g);
    let knots = initial_knots(&dr, &times, &obs, &params, &start.accel_bias, &gravity)?;
    // World frame: the IMU at the first knot.
    let to_world = knots[0].pose.inverse();
    let knots: Vec<Knot> = knots
        .into_iter()
        .map(|k| Knot {
            pose: to_world * k.pose,
            ..k
        })
        .collect();
    let gravity_world = to_world.rot * gravity;
    let st = ImuState {
        t_cam_imu: Se3::identity(),
        time_offset_s: 0.0,
        gravity_rotation: ImuState::gravity_rotation_of(&gravity_world),
        gravity_magnitude: g,
        // One bias per knot; the IMU is the trajectory's clock.
        bias: bias.resampled(&times, 0.0),
        dvl: Some(params),
    };
    let mut gauge = vec![None; n];
    gauge[0] = Some((knots[0].pose, Matrix6::identity() * 1e10));
    let stated: Vec<_> = bins.iter().map(|b| bin_information(b, noise)).collect();
    let dvl_stated: Vec<Matrix3<f64>> =
        obs.iter().map(DvlObs::information).collect::<Result<_>>()?;
    let mut joint = ImuJoint {
        times: times.clone(),
        poses: SparsePoseFactors {
            poses: gauge,
            between: Vec::new(),
        },
        density: jerk_density(&bins, noise).scaled(opts.density_factor),
        bins: &bins,
        info: stated.clone(),
        noise: *noise,
        // The IMU is the body, on its own clock.
        held: (0..7).collect(),
        dvl: &obs,
        dvl_info: dvl_stated.clone(),
        windows: None,
    };
    // The offset is held at zero: the windows never move.
    joint.windows = preintegrate.then(|| {
        Windows::new(
            samples,
            &joint.times,
            &st,
            noise,
            Windows::stated_variances(noise),
        )
    });
    let coarse = opts
        .coarse_start
        .unwrap_or(times.len() >= COARSE_FROM_KNOTS);
    let (knots, st) = if preintegrate && coarse {
        coarse_start(&joint, samples, knots, st, opts.max_iterations)?
    } else {
        (knots, st)
    };
    let mut sol = joint.solve(knots, st, opts.max_iterations)?;
    let mut factor = (1.0, 1.0, 1.0);
    if opts.estimate_noise {
        for _ in 0..2 {
            let before = factor;
            let r = joint.redundancy_of(&mut sol)?;
            factor = (
                (factor.0 * Redundancy::factor(r.gyro)).max(1.0),
                (factor.1 * Redundancy::factor(r.accel)).max(1.0),
                (factor.2 * Redundancy::factor(r.dvl)).max(1.0),
            );
            if factor == before {
                // The weights stay as they were: so does the solution.
                break;
            }
            joint.weigh_imu(&stated, (factor.0, factor.1));
            joint.dvl_info = dvl_stated
                .iter()
                .map(|w| w / (factor.2 * factor.2))
                .collect();
            sol = joint.solve(sol.knots, sol.state, opts.max_iterations)?;
        }
    }
    // Velocities that miss the IMU's motion by many times their noise are not a calibration.
    if factor.2 > MISFIT_FACTOR || factor.1 > MISFIT_FACTOR {
        return Err(Error::Input(format!(
            "the DVL's velocities and the IMU's motion do not fit together: their residuals are \
             {:.0} (DVL) and {:.0} (accelerometer) times their stated noise. Is the IMU from \
             this recording, on this clock (offset searched within {max_offset} s), and are \
             the noise files right?",
            factor.2, factor.1
        )));
    }
    let c0 = sol.state.dvl_start();
    let mut covariance =
        SMatrix::<f64, NPARAM, NPARAM>::from_fn(|r, c| sol.covariance[(c0 + r, c0 + c)]);
    // The motion prior's share (as with a camera, `super::PRIOR_SHIFT_FACTOR`): the DVL's
    // parameters' move under a looser prior, added to their covariance.
    let prior_shift = if opts.estimate_noise {
        let step =
            joint.theta_step_at_density(&sol.knots, &sol.state, super::PRIOR_SHIFT_FACTOR)?;
        let shift = SMatrix::<f64, NPARAM, 1>::from_fn(|r, _| step[c0 + r]);
        covariance += shift * shift.transpose();
        Some(shift)
    } else {
        None
    };
    let params = sol.state.dvl.ok_or_else(|| {
        Error::Numerical("the DVL's parameters were lost from the joint problem".into())
    })?;
    let dvl_used = {
        let (a, b) = (times[0], times[times.len() - 1]);
        obs.iter()
            .filter(|o| (a..=b).contains(&(o.t + params.time_offset_s)))
            .count()
    };
    Ok(DvlImuEstimate {
        params,
        covariance,
        imu: sol.state,
        noise_factor: factor,
        iterations: sol.iterations,
        converged: sol.converged,
        dvl_used,
        dvl_total: obs.len(),
        bins_used: sol.bins_used,
        bins_total: bins.len(),
        times,
        knots: sol.knots,
        prior_shift,
    })
}

/// The bins with the gyro's bias at `bias` removed, its nodes' gyro biases estimated from the
/// windows' gravity of `start` (twice: the second pass reckons with the first's bias removed,
/// so that what it linearises is small). Where the windows say too little, the bias stays as
/// it was.
fn unbias_gyro(
    bins: &[ImuBin],
    start: &DvlImuStart,
    bias: &mut BiasNodes,
    noise: &ImuNoise,
) -> Vec<ImuBin> {
    let remove = |bias: &BiasNodes| -> Vec<ImuBin> {
        bins.iter()
            .map(|b| ImuBin {
                gyro: b.gyro - bias.at(b.t).gyro,
                ..*b
            })
            .collect()
    };
    let mut unbiased = remove(bias);
    for _ in 0..2 {
        let dr = DeadReckoning::new(&unbiased, Vector3::zeros());
        let Some(db) =
            gyro_bias_from_gravity(&dr, &start.windows, bias, noise.gyroscope_random_walk)
        else {
            break;
        };
        for (v, d) in bias.values.iter_mut().zip(db) {
            v.gyro += d;
        }
        unbiased = remove(bias);
    }
    unbiased
}

/// Gravity (magnitude `g`) in the frame of the reckoning `dr`: the mean direction of the
/// windows' gravity of `start` rotated by it (`start.gravity` if they cancel).
fn gravity_in(dr: &DeadReckoning, start: &DvlImuStart, g: f64) -> Vector3<f64> {
    let sum: Vector3<f64> = start
        .windows
        .iter()
        .filter_map(|w| dr.at(w.t).map(|s| s.rot * w.body))
        .sum();
    sum.try_normalize(1e-9).map_or(start.gravity, |d| d * g)
}

/// The trajectory at `times` from the dead reckoning and the first estimate: attitude from the
/// gyro, velocity from the DVL (`v = R_imu_dvl u / kappa - w x p`), position its integral,
/// the rates from the accelerometer and the gyro's differences. In the dead reckoning's
/// reference frame.
fn initial_knots(
    dr: &DeadReckoning,
    times: &[f64],
    obs: &[DvlObs],
    p: &CalibrationParams,
    accel_bias: &Vector3<f64>,
    gravity: &Vector3<f64>,
) -> Result<Vec<Knot>> {
    let r_imu_dvl = p.t_cam_dvl.rot;
    let lever = p.lever_arm_cam_m();
    // DVL velocity at trajectory time tau, linear between reports.
    let u_at = |tau: f64| -> Vector3<f64> {
        let t = tau - p.time_offset_s;
        let j = obs.partition_point(|o| o.t <= t);
        match (j.checked_sub(1).map(|i| &obs[i]), obs.get(j)) {
            (Some(a), Some(b)) if b.t > a.t => {
                let u = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
                a.v * (1.0 - u) + b.v * u
            }
            (Some(a), _) => a.v,
            (None, Some(b)) => b.v,
            (None, None) => Vector3::zeros(),
        }
    };
    let h = 0.5 * KNOT_SPACING_S;
    let mut out = Vec::with_capacity(times.len());
    let mut pos = Vector3::zeros();
    let mut last: Option<(f64, Vector3<f64>)> = None;
    for &tau in times {
        let s = dr.at(tau).ok_or_else(|| {
            Error::NoTimeOverlap(format!("time {tau:.3} s lies outside the IMU's samples"))
        })?;
        let w = s.w;
        let v = r_imu_dvl * u_at(tau) / p.velocity_scale - w.cross(&lever);
        let world_v = s.rot * v;
        if let Some((t_prev, v_prev)) = last {
            pos += (world_v + v_prev) * (0.5 * (tau - t_prev));
        }
        last = Some((tau, world_v));
        let dw = match (dr.at(tau - h), dr.at(tau + h)) {
            (Some(a), Some(b)) => (b.w - a.w) / (2.0 * h),
            _ => Vector3::zeros(),
        };
        let dv = s.f - accel_bias + s.rot.transpose() * gravity - w.cross(&v);
        out.push(Knot {
            pose: Se3::new(s.rot, pos),
            twist: Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z),
            rate: Vector6::new(dv.x, dv.y, dv.z, dw.x, dw.y, dw.z),
        });
    }
    Ok(out)
}

/// A jerk density from the IMU itself: the accelerometer's change between bins (its variance
/// grows as `Qc dt` for white jerk) and the gyro's second differences over 0.1 s blocks
/// (`2/3 Qc dt^3`), each less what the sensor's white noise explains, and at least a small
/// floor. Generous rather than tight: the IMU's bins, not the prior, should shape the motion.
fn jerk_density(bins: &[ImuBin], noise: &ImuNoise) -> JerkDensity {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let dt = {
        let mut d: Vec<f64> = bins.windows(2).map(|w| w[1].t - w[0].t).collect();
        d.sort_by(f64::total_cmp);
        d.get(d.len() / 2).copied().unwrap_or(0.02).max(1e-4)
    };
    let width = dt;
    let da: Vec<f64> = bins
        .windows(2)
        .map(|w| (w[1].accel - w[0].accel).norm_squared() / 3.0)
        .collect();
    let na = noise.accelerometer_noise_density.powi(2) / width;
    let q_trans = ((mean(&da) - 2.0 * na) / dt).max(1e-3);
    // Gyro means over blocks of about 0.1 s.
    let per = ((0.1 / dt).round() as usize).max(1);
    let blocks: Vec<Vector3<f64>> = bins
        .chunks(per)
        .filter(|c| c.len() == per)
        .map(|c| c.iter().map(|b| b.gyro).sum::<Vector3<f64>>() / per as f64)
        .collect();
    let bt = dt * per as f64;
    let d2: Vec<f64> = blocks
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).norm_squared() / 3.0)
        .collect();
    let ng = noise.gyroscope_noise_density.powi(2) / bt;
    let q_rot = ((mean(&d2) - 6.0 * ng) / (2.0 / 3.0 * bt.powi(3))).max(1e-3);
    JerkDensity::constant(Vector6::new(q_trans, q_trans, q_trans, q_rot, q_rot, q_rot))
}
