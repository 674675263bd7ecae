//! The IMU as a co-sensor of the camera: its rotation, lever arm and clock offset relative to
//! the camera, its biases and the direction of gravity, estimated jointly with the camera's
//! trajectory.
//!
//! - [`state`]: what is estimated besides the trajectory, and how a step moves it.
//! - [`bins`]: the IMU's samples averaged in short bins, once.
//! - [`init`]: a first estimate from the camera trajectory alone.
//! - [`factors`]: each bin's prediction and Jacobians; camera poses on some of the knots.
//! - [`solve`]: Gauss-Newton on knots and calibration together, and the calibration's
//!   covariance with the trajectory marginalised.
//! - [`dvl`] (with `dvl_init`): a DVL calibrated against the IMU alone, no camera.
//! - `dvl_factors`: the DVL's velocities as factors of the joint problem (with a camera or
//!   without).
//!
//! The trajectory is the camera's white-noise-on-jerk GP with knots between the pose times as
//! well (the IMU measures the motion between poses, which the knots at pose times alone would
//! smooth over).

pub(crate) mod bins;
pub(crate) mod block;
pub(crate) mod coupling;
pub mod dvl;
pub(crate) mod dvl_factors;
pub(crate) mod dvl_init;
pub(crate) mod factors;
pub(crate) mod init;
pub(crate) mod preint;
pub(crate) mod solve;
pub mod state;
pub(crate) mod walks;

use nalgebra::{DMatrix, Matrix3, Vector3};

use crate::calib::model::{DvlObs, NPARAM};
use crate::calib::noise::COST_INFLATION_FROM;
use crate::calib::options::CalibOptions;
use crate::calib::outcome::CalibrationOutcome;
use crate::error::{Error, Result};
use crate::trajectory::solver::measurement_information;
use crate::trajectory::{FitOptions, JerkDensity, Knot, Trajectory};
use crate::types::imu::{ImuNoise, ImuSample, STANDARD_GRAVITY};
use crate::types::{CalibrationParams, DvlSample, PoseMeasurement};
use factors::{SparsePoseFactors, bin_information};
pub use state::{BiasNodes, ImuState};

/// How the camera-IMU calibration runs.
#[derive(Clone, Debug)]
pub struct ImuOptions {
    /// `|g|`, m/s^2.
    pub gravity_magnitude: f64,
    /// Knots per interval between poses (1: knots at the pose times only); `None`: as many as
    /// put knots about 25 ms apart (4 for poses at 10 Hz, 1 for motion capture at 100 Hz).
    pub knots_per_pose: Option<usize>,
    /// Estimate the factors by which the stated gyro and accelerometer noise are too small from
    /// the residuals (their chi-square over their redundancy) and use them (`false`: as
    /// stated). The factors are at least 1.
    pub estimate_noise: bool,
    /// The longest span of IMU samples averaged into one bin, s.
    pub bin_width_s: f64,
    /// The spacing of the first estimate's bias nodes, s (at least: see `max_bias_nodes`). The
    /// DVL + IMU start estimates the gyro's bias on them; the joint problem then carries one
    /// bias per knot, started from them.
    pub bias_spacing_s: f64,
    /// The most bias nodes of the first estimate: a longer recording spaces them further apart.
    pub max_bias_nodes: usize,
    /// The largest clock offset searched, s.
    pub max_offset_s: f64,
    /// Gauss-Newton iterations at most.
    pub max_iterations: usize,
    /// The motion prior's jerk density is the pose-only fit's times this.
    pub density_factor: f64,
    /// Integrate the IMU's samples between the knots at the pose times once ([`preint`])
    /// rather than compare short bins with the trajectory between knots about 25 ms apart
    /// (`knots_per_pose` then does not apply); `None`: for recordings whose poses span more
    /// than [`PREINTEGRATE_FROM_S`]. The windows cost a fifth of the bins and match or beat
    /// them in simulation, but on a real IMU they see less of its vibration, and their
    /// estimate of its noise (from far fewer redundant residuals) gives std two to three times
    /// smaller than the bins' (docs/accuracy.md): the bins stay where their cost is bearable.
    pub preintegrate: Option<bool>,
    /// With the IMU preintegrated: the poses per interval between knots (1: a knot at every
    /// pose; `m`: knots at every `m`-th pose, the poses between them compared with the
    /// trajectory the GP interpolates there); `None`: as many as the pose-only fit's trajectory
    /// allows without straying from the poses between ([`knot_stride`]).
    pub poses_per_knot: Option<usize>,
    /// DVL + IMU with the IMU preintegrated: start the first solve from the same problem on
    /// every fifth knot, solved; `None`: from [`dvl::COARSE_FROM_KNOTS`] knots on.
    pub coarse_start: Option<bool>,
}

impl Default for ImuOptions {
    fn default() -> Self {
        ImuOptions {
            gravity_magnitude: STANDARD_GRAVITY,
            knots_per_pose: None,
            estimate_noise: true,
            bin_width_s: 0.02,
            bias_spacing_s: 10.0,
            max_bias_nodes: 8,
            max_offset_s: 0.5,
            max_iterations: 30,
            density_factor: 1.0,
            preintegrate: None,
            poses_per_knot: None,
            coarse_start: None,
        }
    }
}

/// The span of the poses beyond which the IMU is preintegrated unless the options say (s).
pub const PREINTEGRATE_FROM_S: f64 = 600.0;

/// The camera-IMU calibration.
#[derive(Clone, Debug)]
pub struct ImuEstimate {
    /// The estimate.
    pub state: ImuState,
    /// Covariance of the parameter vector (see [`state`] for its layout); on the IMU's
    /// columns it includes the motion prior's share ([`ImuEstimate::prior_shift`]).
    pub covariance: DMatrix<f64>,
    /// Gauss-Newton iterations of the last solution.
    pub iterations: usize,
    /// Whether it converged.
    pub converged: bool,
    /// IMU bins used (inside the camera's span; preintegrated, inside a window).
    pub bins_used: usize,
    /// IMU bins in all.
    pub bins_total: usize,
    /// The trajectory's knot times.
    pub times: Vec<f64>,
    /// The trajectory's knot states at the solution.
    pub knots: Vec<Knot>,
    /// The cost at the solution.
    pub cost: f64,
    /// The factors the stated gyro and accelerometer noise densities were multiplied by (the
    /// square roots of their chi-square over redundancy; 1 when not estimated).
    pub noise_factor: (f64, f64),
    /// With a DVL in the problem: the factor its stated noise was multiplied by (else 1).
    pub dvl_noise_factor: f64,
    /// Other clock offsets (`t_cam = t_imu + offset`, s, to 10 ms) at which the gyro's rate
    /// magnitudes match the camera's about as well as at the one found (within half its
    /// misfit again): the motion repeats, and the offset is ambiguous among them. Of those that
    /// match as well (within a tenth), the one kept is the one the two recordings overlap most
    /// at. Empty when the offset is unique.
    pub offset_alternatives_s: Vec<f64>,
    /// How far the calibration moves when the motion prior's jerk density is
    /// [`PRIOR_SHIFT_FACTOR`] times looser; its outer product is part of `covariance`. `None`
    /// when the noise is not estimated (the covariance is then the data's alone).
    pub prior_shift: Option<PriorShift>,
}

/// The calibration's move under a looser motion prior, in the coordinates of
/// [`ImuEstimate::std`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PriorShift {
    /// Rotation, rad, per axis (IMU frame).
    pub rotation: Vector3<f64>,
    /// Lever arm, m.
    pub lever_arm: Vector3<f64>,
    /// Clock offset, s.
    pub time_offset_s: f64,
}

impl PriorShift {
    /// The shift of each of the seven quantities of [`ImuEstimate::std`] over the std the
    /// data alone give it ([`ImuEstimate::data_std`]): above 1 where the motion prior, not the
    /// sensors' noise, limits what is known of it.
    pub fn over_data_std(&self, est: &ImuEstimate) -> [f64; 7] {
        let (r, l, o) = est.data_std();
        let std = [r.x, r.y, r.z, l.x, l.y, l.z, o];
        let shift = self.as_array();
        std::array::from_fn(|i| {
            if std[i] > 0.0 {
                shift[i].abs() / std[i]
            } else {
                f64::INFINITY
            }
        })
    }

    /// Rotation x, y, z, lever arm x, y, z, clock offset.
    fn as_array(&self) -> [f64; 7] {
        [
            self.rotation.x,
            self.rotation.y,
            self.rotation.z,
            self.lever_arm.x,
            self.lever_arm.y,
            self.lever_arm.z,
            self.time_offset_s,
        ]
    }
}

impl ImuEstimate {
    /// Standard deviations of the rotation (rad, per axis, IMU frame), the lever arm (m, per
    /// axis) and the clock offset (s).
    pub fn std(&self) -> (Vector3<f64>, Vector3<f64>, f64) {
        let s = |i: usize| self.covariance[(i, i)].max(0.0).sqrt();
        (
            Vector3::new(s(0), s(1), s(2)),
            Vector3::new(s(3), s(4), s(5)),
            s(6),
        )
    }

    /// [`ImuEstimate::std`] without the motion prior's share ([`ImuEstimate::prior_shift`]):
    /// what the sensors' noise alone leaves unknown.
    pub fn data_std(&self) -> (Vector3<f64>, Vector3<f64>, f64) {
        let shift = self.prior_shift.map_or([0.0; 7], |p| p.as_array());
        let s = |i: usize| {
            (self.covariance[(i, i)] - shift[i] * shift[i])
                .max(0.0)
                .sqrt()
        };
        (
            Vector3::new(s(0), s(1), s(2)),
            Vector3::new(s(3), s(4), s(5)),
            s(6),
        )
    }

    /// With a DVL in the problem: the standard deviations of its parameters in
    /// `calib::model`'s coordinates (rotation rad, lever arm m, scale, offset s).
    pub fn dvl_std(&self) -> Option<[f64; NPARAM]> {
        let c0 = self.state.dvl.map(|_| self.state.dvl_start())?;
        Some(std::array::from_fn(|i| {
            self.covariance[(c0 + i, c0 + i)].max(0.0).sqrt()
        }))
    }
}

/// Calibrates the IMU of `samples` (with `noise`) against the camera poses `poses`.
pub fn calibrate_camera_imu(
    poses: &[PoseMeasurement],
    samples: &[ImuSample],
    noise: &ImuNoise,
    opts: &ImuOptions,
) -> Result<ImuEstimate> {
    camera_imu(poses, samples, noise, opts, None)
}

/// Calibrates the IMU and the DVL against the camera in one problem: the camera's poses, the
/// IMU's bins and the DVL's velocities on one trajectory, the IMU's and the DVL's parameters
/// estimated together (the DVL's from `dvl_start`, e.g. its camera-only calibration). The
/// DVL's result is the state's `dvl`, its covariance the last 8 rows and columns of the
/// estimate's. The DVL's noise is taken as `dvl_opts` says (each report at its stated noise and
/// full weight); [`calibrate_camera_imu_carried`] takes it as the camera-only run found it.
pub fn calibrate_camera_imu_dvl(
    poses: &[PoseMeasurement],
    samples: &[ImuSample],
    noise: &ImuNoise,
    dvl: &[DvlSample],
    dvl_start: &CalibrationParams,
    dvl_opts: &CalibOptions,
    opts: &ImuOptions,
) -> Result<ImuEstimate> {
    let carried = CarriedDvl {
        start: *dvl_start,
        observations: crate::calib::samples::observe(dvl, dvl_opts)?.obs,
        information_divided_by: 1.0,
        std_factor: [1.0; NPARAM],
        noise_factor_from: 1.0,
    };
    calibrate_camera_imu_carried(poses, samples, noise, &carried, opts)
}

/// The DVL's noise as its camera-only calibration found it, for the joint problem of the three
/// sensors, so that the DVL's std there rest on the same noise as the camera-only ones.
///
/// The camera-only std go beyond the stated noise in three ways, each of which the joint
/// problem would otherwise lack:
/// - each report's covariance is the stated one times the variance component the run applied
///   ([`CalibrationOutcome::noise`]), over the weight the robust loss left it (the camera-only
///   covariance is formed with those weights): [`CarriedDvl::observations`];
/// - correlated residuals ([`CalibrationOutcome::whiteness`]) carry the information of fewer
///   independent reports, so the DVL's information is divided by their integrated
///   autocorrelation time: [`CarriedDvl::information_divided_by`]. The IMU changes the
///   trajectory the reports are compared with, not the errors of the reports, so the time found
///   against the camera-only trajectory stands in the joint problem too (the joint problem's
///   DVL residuals are the same reports' errors, to the trajectory's error);
/// - a parameter whose halves of the recording disagree ([`CalibrationOutcome::halves`]) has its
///   std multiplied by the factor that covers the difference: [`CarriedDvl::std_factor`]. What
///   the halves show (a calibration that changed, motion the model does not capture) is in the
///   joint problem's data as well, and the IMU does not remove it.
///
/// The first two enter the joint problem's DVL factors, so the IMU's information combines with
/// the DVL's as it is; the third is a factor on the result's std, as in the camera-only run. The
/// joint problem's own estimate of the DVL's noise (the chi-square of its residuals over their
/// redundancy) applies on top of the first, before the second, by the camera-only run's rule
/// for its normalized cost: only beyond [`COST_INFLATION_FROM`] (the residuals that the
/// camera-only run took as the stated noise's are not inflated by a percent or two in the joint
/// one).
#[derive(Clone, Debug)]
pub struct CarriedDvl {
    /// Where the DVL's parameters start (the camera-only result).
    pub start: CalibrationParams,
    /// The valid DVL reports, each with the covariance the camera-only run weighed it by.
    pub observations: Vec<DvlObs>,
    /// The factor the DVL's information is divided by for correlated residuals (1: white).
    pub information_divided_by: f64,
    /// The factor each DVL parameter's std is multiplied by for disagreeing halves (1: none).
    pub std_factor: [f64; NPARAM],
    /// The chi-square of the DVL's residuals over their redundancy beyond which the joint
    /// problem inflates the DVL's noise by it (1: whenever it exceeds one).
    pub noise_factor_from: f64,
}

impl CarriedDvl {
    /// What the camera-only outcome `o` (run with `opts`) found about the DVL's noise: its
    /// observations (already scaled by the variance component applied) with the robust weights
    /// of its result, the whiteness inflation when it was applied (`honest_covariance`), and
    /// the halves' inflation.
    pub fn from_outcome(o: &CalibrationOutcome, opts: &CalibOptions) -> CarriedDvl {
        let observations = o
            .observations
            .iter()
            .enumerate()
            .map(|(i, x)| {
                let w = o.robust.dvl_weights.get(i).copied().unwrap_or(1.0);
                let cov = if w.is_finite() && w > 0.0 {
                    x.cov / w
                } else {
                    x.cov
                };
                DvlObs { cov, ..*x }
            })
            .collect();
        let tau = o.whiteness.inflation;
        let applied = opts.honest_covariance && o.whiteness.correlated && tau.is_finite();
        CarriedDvl {
            start: o.params,
            observations,
            information_divided_by: if applied { tau.max(1.0) } else { 1.0 },
            std_factor: o.halves.as_ref().map_or([1.0; NPARAM], |h| {
                h.inflation
                    .map(|f| if f.is_finite() { f.max(1.0) } else { 1.0 })
            }),
            noise_factor_from: COST_INFLATION_FROM,
        }
    }
}

/// [`calibrate_camera_imu_dvl`] with the DVL's reports, their noise and the inflations of its
/// std as `dvl` carries them from the camera-only run.
pub fn calibrate_camera_imu_carried(
    poses: &[PoseMeasurement],
    samples: &[ImuSample],
    noise: &ImuNoise,
    dvl: &CarriedDvl,
    opts: &ImuOptions,
) -> Result<ImuEstimate> {
    let mut est = camera_imu(
        poses,
        samples,
        noise,
        opts,
        Some(DvlPart {
            obs: &dvl.observations,
            start: &dvl.start,
            information_divided_by: dvl.information_divided_by,
            noise_factor_from: dvl.noise_factor_from,
        }),
    )?;
    let c0 = est.state.dvl_start();
    let n = est.covariance.nrows();
    for (k, f) in dvl.std_factor.iter().enumerate() {
        if c0 + k < n && *f != 1.0 {
            est.covariance.row_mut(c0 + k).scale_mut(*f);
            est.covariance.column_mut(c0 + k).scale_mut(*f);
        }
    }
    Ok(est)
}

/// The DVL's part of the joint problem: its reports (with their covariances), where its
/// parameters start, and how its noise is taken ([`CarriedDvl`]).
struct DvlPart<'a> {
    obs: &'a [DvlObs],
    start: &'a CalibrationParams,
    information_divided_by: f64,
    noise_factor_from: f64,
}

fn camera_imu(
    poses: &[PoseMeasurement],
    samples: &[ImuSample],
    noise: &ImuNoise,
    opts: &ImuOptions,
    dvl: Option<DvlPart>,
) -> Result<ImuEstimate> {
    if samples.len() < 100 {
        return Err(Error::Input(format!(
            "{} IMU samples: too few to calibrate with",
            samples.len()
        )));
    }
    // The pose-only fit only starts the joint problem, which moves every knot again (a tenth
    // of a standard deviation per knot is close enough), and its covariance is not used.
    let fit = FitOptions {
        covariance: false,
        decrement_per_knot: 0.01,
        ..FitOptions::default()
    };
    let traj = Trajectory::fit(poses, &fit)?;
    let bins = bins::make_bins(samples, opts.bin_width_s, noise.update_rate);
    let first = init::initial_state(
        &traj,
        &bins,
        bias_spacing(samples, opts),
        opts.max_offset_s,
        opts.gravity_magnitude,
    )?;
    let mut st = first.state;
    let preintegrate = opts.preintegrate.unwrap_or_else(|| {
        poses.last().map_or(0.0, |p| p.t) - poses.first().map_or(0.0, |p| p.t) > PREINTEGRATE_FROM_S
    });
    let per = if preintegrate {
        1
    } else {
        opts.knots_per_pose
            .unwrap_or_else(|| knots_per_pose(poses))
            .max(1)
    };
    let info = measurement_information(poses, traj.report().pose_sigma)?;
    let stride = match opts.poses_per_knot {
        _ if !preintegrate => 1,
        Some(m) => m.max(1),
        None => knot_stride(&traj, &info),
    };
    let (times, knots, pose_factors, density) = if stride > 1 {
        sparse_knots(&traj, poses, &info, stride)
    } else {
        let (times, knots, pose_at) = densify(&traj, per);
        let mut sparse = vec![None; times.len()];
        for (i, k) in pose_at.iter().enumerate() {
            sparse[*k] = Some((poses[i].pose, info[i]));
        }
        let density = density_on(&traj, |f| {
            f.iter()
                .flat_map(|x| std::iter::repeat_n(*x, per))
                .collect()
        });
        let factors = SparsePoseFactors {
            poses: sparse,
            between: Vec::new(),
        };
        (times, knots, factors, density)
    };
    let density = density.scaled(opts.density_factor);
    // One bias per knot, from the first estimate's nodes on the IMU's clock.
    st.bias = st.bias.resampled(&times, st.time_offset_s);
    let stated: Vec<_> = bins.iter().map(|b| bin_information(b, noise)).collect();
    let (dvl_obs, dvl_stated) = match &dvl {
        Some(d) => {
            st.dvl = Some(*d.start);
            let info: Vec<Matrix3<f64>> = d
                .obs
                .iter()
                .map(DvlObs::information)
                .collect::<Result<_>>()?;
            (d.obs, info)
        }
        None => (&[][..], Vec::new()),
    };
    let mut joint = solve::ImuJoint {
        times: times.clone(),
        poses: pose_factors,
        density,
        bins: &bins,
        info: stated.clone(),
        noise: *noise,
        held: Vec::new(),
        dvl: dvl_obs,
        dvl_info: dvl_stated.clone(),
        windows: None,
    };
    joint.windows = preintegrate.then(|| {
        preint::Windows::new(
            samples,
            &times,
            &st,
            noise,
            preint::Windows::stated_variances(noise),
        )
    });
    let mut sol = solve_placed(&mut joint, knots, st, opts.max_iterations, samples)?;
    let mut factor = (1.0, 1.0);
    let mut dvl_factor = 1.0;
    if opts.estimate_noise {
        // Two rounds: the first factor moves the solution a little, the second settles it.
        for _ in 0..2 {
            let before = (factor, dvl_factor);
            let r = joint.redundancy_of(&mut sol)?;
            let (chi_g, red_g, chi_a, red_a) = (r.gyro.0, r.gyro.1, r.accel.0, r.accel.1);
            if !dvl_obs.is_empty() {
                // The variance ratio the residuals show, applied beyond `noise_factor_from`.
                let v = (dvl_factor * solve::Redundancy::factor(r.dvl)).powi(2);
                let from = dvl.as_ref().map_or(1.0, |d| d.noise_factor_from);
                dvl_factor = if v > from { v.sqrt() } else { 1.0 };
                joint.dvl_info = dvl_stated
                    .iter()
                    .map(|w| w / (dvl_factor * dvl_factor))
                    .collect();
            }
            // Only ever inflated: a chi-square below its redundancy says more about the motion
            // prior (a smooth motion lets the knots absorb the residuals) than about the IMU,
            // whose stated noise is a floor.
            let (fg, fa) = (
                (factor.0 * (chi_g / red_g.max(1.0)).sqrt()).max(1.0),
                (factor.1 * (chi_a / red_a.max(1.0)).sqrt()).max(1.0),
            );
            factor = (fg, fa);
            if (factor, dvl_factor) == before {
                // The weights stay as they were: so does the solution.
                break;
            }
            joint.weigh_imu(&stated, factor);
            sol = solve_placed(
                &mut joint,
                sol.knots,
                sol.state,
                opts.max_iterations,
                samples,
            )?;
        }
    }
    // Correlated DVL residuals: the DVL's information divided by their autocorrelation time,
    // after its noise factor (estimated from white-noise redundancies, which the division would
    // hide), and the solution settled under it.
    if let Some(tau) = dvl
        .as_ref()
        .map(|d| d.information_divided_by)
        .filter(|t| *t > 1.0)
    {
        let f2 = dvl_factor * dvl_factor * tau;
        joint.dvl_info = dvl_stated.iter().map(|w| w / f2).collect();
        sol = solve_placed(
            &mut joint,
            sol.knots,
            sol.state,
            opts.max_iterations,
            samples,
        )?;
    }
    let mut covariance = sol.covariance;
    let prior_shift = if opts.estimate_noise {
        let step = joint.theta_step_at_density(&sol.knots, &sol.state, PRIOR_SHIFT_FACTOR)?;
        // The IMU's columns: the DVL's std come from its own noise model.
        let imu = sol.state.dvl_start();
        covariance.view_mut((0, 0), (imu, imu)).ger(
            1.0,
            &step.rows(0, imu),
            &step.rows(0, imu),
            1.0,
        );
        Some(PriorShift {
            rotation: step.fixed_rows::<3>(0).into_owned(),
            lever_arm: step.fixed_rows::<3>(3).into_owned(),
            time_offset_s: step[6],
        })
    } else {
        None
    };
    Ok(ImuEstimate {
        state: sol.state,
        covariance,
        iterations: sol.iterations,
        converged: sol.converged,
        bins_used: sol.bins_used,
        bins_total: bins.len(),
        times,
        knots: sol.knots,
        cost: sol.cost,
        noise_factor: factor,
        dvl_noise_factor: dvl_factor,
        offset_alternatives_s: first.offset_alternatives_s,
        prior_shift,
    })
}

/// The motion prior's share of the camera-IMU calibration's uncertainty is taken as its move
/// when the prior's jerk density is this many times looser: one Gauss-Newton step from the
/// solution (a minimum at its own density, so the step is the linear response to the looser
/// prior), whose outer product is added to the covariance of the IMU's columns.
///
/// The density the pose-only fit chooses describes the motion's jerk on average (in the joint
/// problem its terms' chi-square comes out at 0.86-1.19 of their redundancy), but no vehicle's
/// motion is a sample of the prior: the prior flattens the angular rates and accelerations
/// through which the accelerometer sees the lever arm, and nothing in the residuals shows it.
/// On 20-minute simulated recordings the lever arm came out biased by about twice its std from
/// the data alone, and this step points back at the truth by one to two of those std; on 60 s
/// it is below half a std. On real recordings it is larger: four to fifteen std on EuRoC's and
/// MoCap2GT's, whose lever arms differ from the published ones by about that much. Taking the
/// looser density itself instead is no cure: it moved MoCap2GT's lever arm from 7 to 27 mm
/// from the published one (docs/accuracy.md).
pub const PRIOR_SHIFT_FACTOR: f64 = 10.0;

/// The largest difference between the clock offset and the one the windows were integrated at
/// before they are integrated again, s (the windows' ends are extrapolated from the knots by
/// it).
const REPLACE_WINDOWS_S: f64 = 0.001;

/// Solves `joint` from `knots` and `st`; with windows, integrates them again at the solution's
/// clock offset and solves again while it moved further than [`REPLACE_WINDOWS_S`] from
/// theirs (a few times at most: each time the move is a fraction of the last).
fn solve_placed(
    joint: &mut solve::ImuJoint,
    knots: Vec<Knot>,
    st: ImuState,
    max_iterations: usize,
    samples: &[ImuSample],
) -> Result<solve::Solution> {
    let mut sol = joint.solve(knots, st, max_iterations)?;
    for _ in 0..4 {
        let Some(w) = &joint.windows else { break };
        if (sol.state.time_offset_s - w.offset0).abs() <= REPLACE_WINDOWS_S {
            break;
        }
        let var = w.var;
        joint.windows = Some(preint::Windows::new(
            samples,
            &joint.times,
            &sol.state,
            &joint.noise,
            var,
        ));
        sol = joint.solve(sol.knots, sol.state, max_iterations)?;
    }
    Ok(sol)
}

/// The first estimate's bias nodes' spacing: `bias_spacing_s`, or wider so that at most
/// `max_bias_nodes` span the samples.
pub(crate) fn bias_spacing(samples: &[ImuSample], opts: &ImuOptions) -> f64 {
    let span = match (samples.first(), samples.last()) {
        (Some(a), Some(b)) => b.t - a.t,
        _ => 0.0,
    };
    let most = opts.max_bias_nodes.max(2) - 1;
    opts.bias_spacing_s.max(span / most as f64 * (1.0 + 1e-9))
}

/// The indices `0, stride, 2 stride, ...` below `n`, and `n - 1` (none when `n` is 0): the
/// knots kept when thinning `n` of them.
pub(crate) fn every_nth(n: usize, stride: usize) -> Vec<usize> {
    let mut kept: Vec<usize> = (0..n).step_by(stride.max(1)).collect();
    if n > 0 && kept.last() != Some(&(n - 1)) {
        kept.push(n - 1);
    }
    kept
}

/// The pose-only fit's motion prior on other intervals: as it is when constant, else with the
/// per-interval factors `per_interval` makes of the fit's.
fn density_on(
    traj: &Trajectory,
    per_interval: impl FnOnce(&[[f64; 2]]) -> Vec<[f64; 2]>,
) -> JerkDensity {
    let d = traj.density();
    if d.is_constant() {
        d.clone()
    } else {
        JerkDensity::varying(d.base(), per_interval(d.factors()))
    }
}

/// The fit's knots thinned to every `stride`-th (and the last), the poses on them as factors
/// on those knots and the poses between them as factors on the pose the GP interpolates there;
/// the motion prior's varying density averaged over the intervals each new one spans.
fn sparse_knots(
    traj: &Trajectory,
    poses: &[PoseMeasurement],
    info: &[nalgebra::Matrix6<f64>],
    stride: usize,
) -> (Vec<f64>, Vec<Knot>, SparsePoseFactors, JerkDensity) {
    let (t, k) = (traj.times(), traj.knots());
    let n = t.len();
    let kept = every_nth(n, stride);
    let times: Vec<f64> = kept.iter().map(|&i| t[i]).collect();
    let knots: Vec<Knot> = kept.iter().map(|&i| k[i]).collect();
    let mut on = vec![None; kept.len()];
    let mut between = vec![Vec::new(); kept.len() - 1];
    // The fit has one knot per pose, at its time.
    let mut interval = 0;
    for (i, p) in poses.iter().enumerate().take(n) {
        while interval + 1 < kept.len() && kept[interval + 1] <= i {
            interval += 1;
        }
        if kept[interval] == i {
            on[interval] = Some((p.pose, info[i]));
        } else {
            between[interval].push(factors::BetweenPose {
                s: t[i] - times[interval],
                meas: p.pose,
                info: info[i],
            });
        }
    }
    let density = density_on(traj, |f| {
        kept.windows(2)
            .map(|w| {
                let m = (w[1] - w[0]) as f64;
                let part = |c: usize| f[w[0]..w[1]].iter().map(|x| x[c]).sum::<f64>() / m;
                [part(0), part(1)]
            })
            .collect()
    });
    let factors = SparsePoseFactors { poses: on, between };
    (times, knots, factors, density)
}

/// The most poses per interval between knots [`knot_stride`] considers.
pub const MAX_POSES_PER_KNOT: usize = 8;

/// The largest misfit [`knot_stride`] accepts (see [`interpolation_misfit`]): a ten-thousandth
/// of the poses' own variance. In simulation the std stay within 2 % of those with a knot at
/// every pose up to this, and grow beyond it (docs/accuracy.md).
pub const MAX_INTERPOLATION_MISFIT: f64 = 1e-4;

/// The poses per interval between knots with the IMU preintegrated: the largest stride, up to
/// [`MAX_POSES_PER_KNOT`], at which the pose-only fit's trajectory through every stride-th of
/// its knots still passes through the others (misfit at most [`MAX_INTERPOLATION_MISFIT`]).
/// Smooth motion gets knots several poses apart, fast motion one at every pose.
pub(crate) fn knot_stride(traj: &Trajectory, info: &[nalgebra::Matrix6<f64>]) -> usize {
    let mut stride = 1;
    while stride < MAX_POSES_PER_KNOT
        && interpolation_misfit(traj, info, stride + 1) <= MAX_INTERPOLATION_MISFIT
    {
        stride += 1;
    }
    stride
}

/// How far the GP through every `stride`-th knot of `traj` strays from its other knots' poses:
/// the mean of `e^T W e / 6` over those poses (`W` their information), `e` the dropped knot's
/// pose against the interpolated one.
fn interpolation_misfit(traj: &Trajectory, info: &[nalgebra::Matrix6<f64>], stride: usize) -> f64 {
    let (t, k) = (traj.times(), traj.knots());
    let mut sum = 0.0;
    let mut count = 0usize;
    for w in every_nth(t.len(), stride).windows(2) {
        let (a, b) = (w[0], w[1]);
        let g2 = crate::trajectory::gp::local_gamma(&k[a], &k[b]);
        for i in a + 1..b {
            let p = factors::BetweenPose {
                s: t[i] - t[a],
                meas: k[i].pose,
                info: info[i],
            };
            let e = factors::between_residual(&k[a], &g2, t[b] - t[a], &p);
            sum += (e.transpose() * info[i] * e)[0] / 6.0;
            count += 1;
        }
    }
    if count == 0 { 0.0 } else { sum / count as f64 }
}

/// Knots per interval between poses that put them about 25 ms apart.
fn knots_per_pose(poses: &[PoseMeasurement]) -> usize {
    let mut dt: Vec<f64> = poses.windows(2).map(|w| w[1].t - w[0].t).collect();
    dt.sort_by(f64::total_cmp);
    let median = dt.get(dt.len() / 2).copied().unwrap_or(0.1);
    ((median / 0.025).round() as usize).clamp(1, 8)
}

/// The trajectory's knots with `per - 1` more in each interval, evenly spaced, their states
/// interpolated; and the index of each original knot among them.
fn densify(traj: &Trajectory, per: usize) -> (Vec<f64>, Vec<Knot>, Vec<usize>) {
    let t = traj.times();
    let k = traj.knots();
    let mut times = Vec::with_capacity((t.len() - 1) * per + 1);
    let mut knots = Vec::with_capacity(times.capacity());
    let mut at = Vec::with_capacity(t.len());
    for i in 0..t.len() {
        at.push(times.len());
        times.push(t[i]);
        knots.push(k[i]);
        if i + 1 == t.len() {
            break;
        }
        for j in 1..per {
            let tj = t[i] + (t[i + 1] - t[i]) * j as f64 / per as f64;
            let s = traj.view().state(tj).map(|s| Knot {
                pose: s.pose,
                twist: s.twist,
                rate: s.rate,
            });
            if let Ok(s) = s {
                times.push(tj);
                knots.push(s);
            }
        }
    }
    (times, knots, at)
}
