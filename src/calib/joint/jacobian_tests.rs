//! Finite-difference checks of the DVL factor's Jacobians: the measurement model's
//! ([`d_predict_d_twist`], [`d_predict_d_params`]), the per-sample chain that
//! [`DvlFactors::interval_terms`] uses (residual `r = v - predict(p, twist(t_dvl + delta))`
//! against the two bracketing knots and the eight calibration parameters), and the assembled
//! joint normal equations of [`DvlFactors::assemble`] against `J^T W J`, `-J^T W r` built from a
//! numeric Jacobian.
//!
//! Perturbations are the estimator's own: knots through the solver's update
//! ([`crate::trajectory::solver::step`]: `T <- T exp(dT)`, additive twist and rate), parameters
//! through [`CalibrationParams::updated`] (rotation on the left, `R <- exp(dphi) R`, the rest additive).
//!
//! Tolerance. Central differences with step `h` err by about `h^2 / 6 |f'''|` (truncation) plus
//! `eps |f| / h` (rounding). For the knot variables and rotation, lever arm and scale,
//! `H = 1e-5` (the `eps^(1/3)` optimum of O(1) maps) measured errors below 1e-8. Along time (the
//! clock offset, and `d twist / dt`) the interpolated twist has third derivatives of order 1e3 to
//! 1e4 (an interval is 0.1 s), so truncation dominates there and `H_TIME = 1e-6` is used (1e-5
//! gave 1e-6 errors, 1e-6 gives 1e-8). Columns are compared relative to their norm, floored at
//! 1% of the largest column of the block, and normal-equation blocks relative to their largest
//! entry, all with `TOL = 1e-6`: a margin of about 60 over the largest error seen (1.6e-8), while
//! a wrong sign, frame or missing term is an O(1) error.
//!
//! The clock offset is special: its analytic column is `kappa R [I, -p^] rate(t)` with the GP's
//! interpolated twist *rate*, and that rate is not exactly the time derivative of the
//! interpolated twist away from the interval's first knot (`gp.rs` maps `xi''` to the rate with
//! the first-order expansion of `d J_r^-1 / dt`, exact where `xi = 0`). The tests therefore check
//! that column strictly against the model's claim (`dh * rate`), and against central
//! differences in time with a bound that grows with the distance from the first knot (see
//! `interpolated_rate_is_the_twist_derivative_only_at_the_first_knot`).

use nalgebra::{Matrix3, SMatrix, SVector, Vector3, Vector6};

use super::*;
use crate::calib::joint::covariance::{
    assemble_joint, finish, linear_estimate_of, part_linear_estimate,
};
use crate::calib::model::{DvlObs, NPARAM};
use crate::lie::{Se3, curly, se3_right_jacobian, so3};
use crate::trajectory::factors::{CoSensorFactors, PoseFactors};
use crate::trajectory::gp::{
    Motion, apply_scalar, d_jr_times, first_local_state, interpolation_weights, kron_diag,
    local_gamma, local_state, phi_scalar, q_scalar_inv,
};
use crate::trajectory::solver::step;
use nalgebra::Matrix6;

/// Finite-difference step of the knot variables and of rotation, lever arm and scale.
const H: f64 = 1e-5;
/// Finite-difference step in time (the clock offset, and `d twist / dt`).
const H_TIME: f64 = 1e-6;
/// Largest accepted relative column error (see the module documentation).
const TOL: f64 = 1e-6;

/// The project's deterministic generator, drawing uniformly in [-1, 1) for these tests.
struct Rng(crate::rng::Rng);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(crate::rng::Rng::new(seed))
    }

    /// Uniform in [-1, 1).
    fn next(&mut self) -> f64 {
        self.0.uniform_in(-1.0, 1.0)
    }

    fn vec3(&mut self, scale: f64) -> Vector3<f64> {
        Vector3::from_fn(|_, _| self.next() * scale)
    }

    fn vec6(&mut self, scale: f64) -> Vector6<f64> {
        Vector6::from_fn(|_, _| self.next() * scale)
    }

    /// A symmetric positive-definite matrix with eigenvalues around `scale`.
    fn spd<const D: usize>(&mut self, scale: f64) -> SMatrix<f64, D, D> {
        let a = SMatrix::<f64, D, D>::from_fn(|_, _| self.next());
        (a * a.transpose() * 0.5 + SMatrix::<f64, D, D>::identity()) * scale
    }
}

/// `n` knots at uneven times (0.08..0.14 s apart) with a random first pose and twists and rates
/// of order one, each knot roughly following its predecessor's twist and rate (a random walk in
/// the rate), so that the interpolated motion is smooth enough for central differences in time
/// (knots that contradict each other give an interpolant with third time derivatives of the
/// twist of order 1e6, whose truncation error would swamp the offset column's check).
fn test_knots(rng: &mut Rng, n: usize) -> (Vec<f64>, Vec<Knot>) {
    let mut times = vec![0.0];
    let mut knot = Knot {
        pose: Se3::exp(&rng.vec6(1.5)),
        twist: rng.vec6(1.5),
        rate: rng.vec6(1.5),
    };
    let mut knots = vec![knot];
    for k in 1..n {
        let dt = 0.11 + 0.03 * rng.next();
        times.push(times[k - 1] + dt);
        knot = Knot {
            pose: knot.pose
                * Se3::exp(&(knot.twist * dt + knot.rate * (0.5 * dt * dt) + rng.vec6(0.01))),
            twist: knot.twist + knot.rate * dt + rng.vec6(0.1),
            rate: (knot.rate + rng.vec6(1.0)).map(|v| v.clamp(-2.0, 2.0)),
        };
        knots.push(knot);
    }
    (times, knots)
}

/// Calibration parameters far from the identity.
fn test_params(rng: &mut Rng) -> CalibrationParams {
    CalibrationParams::from_r_dvl_cam(
        so3::exp(&rng.vec3(1.8)),
        rng.vec3(0.4),
        1.0 + 0.2 * rng.next(),
        0.04 * rng.next(),
    )
}

/// DVL samples whose camera times (`t + delta`) lie at the fractions `fractions` of every
/// interval (away from the knots, so that no perturbation moves a sample to another interval).
fn test_samples(
    rng: &mut Rng,
    times: &[f64],
    p: &CalibrationParams,
    fractions: &[f64],
) -> Vec<DvlObs> {
    let mut obs = Vec::new();
    for k in 0..times.len() - 1 {
        for f in fractions {
            let t_cam = times[k] + f * (times[k + 1] - times[k]);
            obs.push(DvlObs {
                t: t_cam - p.time_offset_s,
                v: rng.vec3(1.0),
                cov: rng.spd::<3>(1e-3),
            });
        }
    }
    obs
}

/// The DVL residual `v - predict(p, twist(t + delta))`, through the public query.
fn residual(times: &[f64], knots: &[Knot], p: &CalibrationParams, o: &DvlObs) -> Vector3<f64> {
    let view = KnotView { times, knots };
    o.v - predict(p, &view.state(o.t + p.time_offset_s).unwrap().twist)
}

/// Central differences of `f(knots)` with respect to the 18 variables of each of the knots
/// `first..first + B` (`C = 18 B`), perturbed by the solver's update.
fn numeric_knot_jacobian<const R: usize, const C: usize>(
    knots: &[Knot],
    first: usize,
    f: impl Fn(&[Knot]) -> SVector<f64, R>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for j in 0..C {
        let mut dx = vec![V18::zeros(); knots.len()];
        dx[first + j / 18][j % 18] = H;
        let plus = f(&step(knots, &dx, 1.0));
        let minus = f(&step(knots, &dx, -1.0));
        out.set_column(j, &((plus - minus) / (2.0 * H)));
    }
    out
}

/// Central differences of `f(params)` with respect to the update of [`CalibrationParams::updated`].
fn numeric_param_jacobian<const R: usize>(
    p: &CalibrationParams,
    f: impl Fn(&CalibrationParams) -> SVector<f64, R>,
) -> SMatrix<f64, R, NPARAM> {
    let mut out = SMatrix::<f64, R, NPARAM>::zeros();
    for j in 0..NPARAM {
        let h = if j == 7 { H_TIME } else { H };
        let mut d = ParamVec::zeros();
        d[j] = h;
        let col = (f(&p.updated(&d)) - f(&p.updated(&-d))) / (2.0 * h);
        out.set_column(j, &col);
    }
    out
}

/// Largest relative column error of `analytic` against `numeric`, each column relative to its
/// norm floored at 1% of the largest column norm of `numeric`.
fn column_error<const R: usize, const C: usize>(
    analytic: &SMatrix<f64, R, C>,
    numeric: &SMatrix<f64, R, C>,
) -> f64 {
    let largest = numeric.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
    let floor = (1e-2 * largest).max(1e-300);
    (0..C)
        .map(|j| {
            (analytic.column(j) - numeric.column(j)).norm() / numeric.column(j).norm().max(floor)
        })
        .fold(0.0, f64::max)
}

/// `|a - b|_max / |b|_max`.
fn rel<const R: usize, const C: usize>(a: &SMatrix<f64, R, C>, b: &SMatrix<f64, R, C>) -> f64 {
    (a - b).amax() / b.amax().max(1e-300)
}

#[test]
fn model_jacobians_match_central_differences_at_random_points() {
    // Beyond the existing single-point check in model.rs: many parameter sets (rotations far
    // from the identity, lever arms up to 0.4 m, scales 0.8..1.2) and a twist that is not linear
    // in time, so the offset column is checked as `dh * (d twist / dt)` for a curved twist.
    let mut rng = Rng::new(0x9E37_79B9_7F4A_7C15);
    let (mut worst_t, mut worst_p): (f64, f64) = (0.0, 0.0);
    for _ in 0..50 {
        let p = test_params(&mut rng);
        let (a, b, c) = (rng.vec6(2.0), rng.vec6(2.0), rng.vec6(2.0));
        // twist(tau) = a + b sin(tau) + c tau^2 around tau = 0: twist a, rate b.
        let twist_at = |tau: f64| a + b * tau.sin() + c * tau * tau;
        let jt = d_predict_d_twist(&p);
        let mut numeric = SMatrix::<f64, 3, 6>::zeros();
        for j in 0..6 {
            let mut d = Vector6::zeros();
            d[j] = H;
            numeric.set_column(
                j,
                &((predict(&p, &(a + d)) - predict(&p, &(a - d))) / (2.0 * H)),
            );
        }
        let e = column_error(&jt, &numeric);
        worst_t = worst_t.max(e);
        assert!(e < TOL, "d_predict_d_twist: {e:e}\n{jt}\n{numeric}");

        let jp = d_predict_d_params(&p, &a, &b);
        let numeric = numeric_param_jacobian(&p, |q| {
            predict(q, &twist_at(q.time_offset_s - p.time_offset_s))
        });
        let e = column_error(&jp, &numeric);
        worst_p = worst_p.max(e);
        assert!(e < TOL, "d_predict_d_params: {e:e}\n{jp}\n{numeric}");
    }
    eprintln!("model: max relative column error d/dtwist {worst_t:e}, d/dparams {worst_p:e}");
}

/// The per-sample Jacobians exactly as [`DvlFactors::interval_terms`] forms them: the
/// prediction's Jacobians `j1`, `j2` (knots) and `jt` (parameters), and the interpolated state.
fn analytic_sample(
    times: &[f64],
    knots: &[Knot],
    p: &CalibrationParams,
    o: &DvlObs,
) -> (usize, Motion, SMatrix<f64, 3, 36>, SMatrix<f64, 3, NPARAM>) {
    let view = KnotView { times, knots };
    let t = o.t + p.time_offset_s;
    let k = view.interval(t).unwrap();
    let ls = local_state(&knots[k], &knots[k + 1]);
    let (state, j1, j2) = view.projected_twist_jacobian_in(k, t, &ls, &d_predict_d_twist(p));
    let jt = d_predict_d_params(p, &state.twist, &state.rate);
    let mut jx = SMatrix::<f64, 3, 36>::zeros();
    jx.fixed_view_mut::<3, 18>(0, 0).copy_from(&j1);
    jx.fixed_view_mut::<3, 18>(0, 18).copy_from(&j2);
    (k, state, jx, jt)
}

/// The time derivative of the interpolated twist at `t`, by central differences in `t`.
fn twist_derivative(times: &[f64], knots: &[Knot], t: f64) -> Vector6<f64> {
    let view = KnotView { times, knots };
    (view.state(t + H_TIME).unwrap().twist - view.state(t - H_TIME).unwrap().twist) / (2.0 * H_TIME)
}

#[test]
fn dvl_residual_jacobians_match_central_differences() {
    // r = v - predict(p, twist(t + delta)) against [x_k; x_{k+1}] and the 8 parameters.
    let mut rng = Rng::new(0xD1B5_4A32_D192_ED03);
    let (mut worst_x, mut worst_p, mut worst_off, mut worst_start) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for _ in 0..3 {
        let (times, knots) = test_knots(&mut rng, 5);
        let p = test_params(&mut rng);
        let obs = test_samples(&mut rng, &times, &p, &[0.02, 0.3, 0.5, 0.77, 0.98]);
        for o in &obs {
            let (k, state, jx, jt) = analytic_sample(&times, &knots, &p, o);
            let numeric: SMatrix<f64, 3, 36> =
                numeric_knot_jacobian(&knots, k, |kn| residual(&times, kn, &p, o));
            let e = column_error(&-jx, &numeric);
            worst_x = worst_x.max(e);
            assert!(
                e < TOL,
                "knots, interval {k}, t {}: {e:e}\n{}\n{numeric}",
                o.t,
                -jx
            );

            let numeric = numeric_param_jacobian(&p, |q| residual(&times, &knots, q, o));
            // Rotation, lever arm and scale: strict.
            let a7 = -jt.fixed_columns::<7>(0);
            let n7 = numeric.fixed_columns::<7>(0);
            let e = column_error(&a7.into_owned(), &n7.into_owned());
            worst_p = worst_p.max(e);
            assert!(e < TOL, "parameters, t {}: {e:e}\n{}\n{numeric}", o.t, -jt);
            // Clock offset: exactly the model's claim, dh times the interpolated rate ...
            let dh = d_predict_d_twist(&p);
            let claim = dh * state.rate;
            assert!((jt.column(7) - claim).norm() <= 1e-12 * claim.norm());
            // ... which differs from d r / d delta only by the rate's approximation (see
            // `interpolated_rate_is_the_twist_derivative_only_at_the_first_knot`): the difference
            // is dh (rate - d twist/dt), bounded by |dh| |rate - d twist/dt|.
            let t = o.t + p.time_offset_s;
            let mismatch = (state.rate - twist_derivative(&times, &knots, t)).norm();
            let e = (-jt.column(7) - numeric.column(7)).norm();
            let bound = dh.norm() * mismatch + TOL * numeric.column(7).norm();
            worst_off = worst_off.max(e / numeric.column(7).norm());
            assert!(e <= bound, "offset column, t {}: {e:e} > {bound:e}", o.t);
        }
        // Just after an interval's first knot the rate is exact, and so is the offset column.
        for k in 0..times.len() - 1 {
            let o = DvlObs {
                t: times[k] + 3.0 * H_TIME - p.time_offset_s,
                v: rng.vec3(1.0),
                cov: Matrix3::identity(),
            };
            let (_, _, _, jt) = analytic_sample(&times, &knots, &p, &o);
            let numeric = numeric_param_jacobian(&p, |q| residual(&times, &knots, q, &o));
            let e = column_error(&-jt, &numeric);
            worst_start = worst_start.max(e);
            assert!(e < TOL, "parameters at knot {k}: {e:e}\n{}\n{numeric}", -jt);
        }
    }
    eprintln!(
        "DVL residual: max relative column error knots {worst_x:e}, rotation/lever/scale \
         {worst_p:e}, all 8 parameters next to a first knot {worst_start:e}; offset column vs \
         central differences inside intervals {worst_off:e} (the rate's approximation)"
    );
}

/// The premise of the clock offset's column: the interpolated twist rate against the time
/// derivative of the interpolated twist `J_r(xi) xi'`. The latter is formed exactly as
/// `J_r(xi) xi'' + (d/dxi [J_r(xi) xi']) xi'` from the interpolated local state and checked
/// against central differences in time (strict: the GP mean's `xi''` is the derivative of its
/// `xi'`). The interpolated rate equals it at an interval's first knot (`xi = 0`, strict) and
/// only approximately inside the interval (the first-order mapping documented in gp.rs): that
/// mismatch is reported, bounded loosely (5%, against about 0.5% measured for these motions of
/// 0.1-0.4 rad and m per interval), and checked to be the mapping's truncation: to leading order
/// in `xi` it is `(1/4 - 1/6) curly(xi') curly(xi) xi'` (the rate mapping's `-1/2 J_r curly(xi')
/// J_r xi'` gives 1/4, the exact derivative of `J_r(xi) xi'` 1/6).
#[test]
fn interpolated_rate_is_the_twist_derivative_only_at_the_first_knot() {
    let mut rng = Rng::new(0xBB67_AE85_84CA_A73B);
    let (mut worst_exact, mut worst_start, mut worst_inside, mut worst_beyond) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for _ in 0..3 {
        let (times, knots) = test_knots(&mut rng, 5);
        for k in 0..times.len() - 1 {
            let dt = times[k + 1] - times[k];
            let gamma2 = local_gamma(&knots[k], &knots[k + 1]);
            for f in [
                3.0 * H_TIME / dt,
                0.25,
                0.5,
                0.75,
                0.98,
                1.0 - 3.0 * H_TIME / dt,
            ] {
                let t = times[k] + f * dt;
                let (lambda, omega, _) = interpolation_weights(t - times[k], dt);
                let gamma = apply_scalar(&lambda, &first_local_state(&knots[k]))
                    + apply_scalar(&omega, &gamma2);
                let xi: Vector6<f64> = gamma.fixed_rows::<6>(0).into_owned();
                let xid: Vector6<f64> = gamma.fixed_rows::<6>(6).into_owned();
                let xidd: Vector6<f64> = gamma.fixed_rows::<6>(12).into_owned();
                let exact = se3_right_jacobian(&xi) * xidd + d_jr_times(&xi, [&xid])[0] * xid;
                let numeric = twist_derivative(&times, &knots, t);
                let e = (exact - numeric).norm() / numeric.norm();
                worst_exact = worst_exact.max(e);
                assert!(
                    e < TOL,
                    "interval {k}, t {t}: exact derivative off by {e:e}"
                );
                let rate = KnotView {
                    times: &times,
                    knots: &knots,
                }
                .state(t)
                .unwrap()
                .rate;
                let m = (rate - exact).norm() / exact.norm();
                if f < 0.1 {
                    worst_start = worst_start.max(m);
                } else {
                    worst_inside = worst_inside.max(m);
                    // The leading term of the mismatch, (1/4 - 1/6) curly(xi') curly(xi) xi'.
                    let lead = curly(&xid) * curly(&xi) * xid / 12.0;
                    let r = (rate - exact - lead).norm() / lead.norm();
                    worst_beyond = worst_beyond.max(r);
                }
            }
        }
    }
    eprintln!(
        "d twist/dt: exact form vs central differences {worst_exact:e}; \
         |rate - d twist/dt| / |d twist/dt| {worst_start:e} next to the first knots, up to \
         {worst_inside:e} inside the intervals; beyond its leading term {worst_beyond:e} of it"
    );
    // At s = 2e-5 of the interval, xi = O(1e-6): the mismatch is O(|xi|), far below 1e-6.
    assert!(worst_start < TOL, "{worst_start:e}");
    assert!(worst_inside < 5e-2, "{worst_inside:e}");
    // Inside, the mismatch is the documented truncation: its leading term explains it up to
    // terms one order higher in xi (|xi| up to about 0.4 here; 0.33 measured). A different
    // rate mapping (e.g. the curly term's sign flipped, leading term -5/12 instead of 1/12)
    // leaves a remainder several times the leading term.
    assert!(worst_beyond < 0.6, "{worst_beyond:e}");
}

/// Pose measurements near `knots` with their weights, and a `Qc^-1`, chosen so that pose, prior
/// and DVL terms are of similar size.
fn pose_terms(rng: &mut Rng, knots: &[Knot]) -> (Vec<Se3>, Vec<Matrix6<f64>>, Vector6<f64>) {
    let meas: Vec<Se3> = knots
        .iter()
        .map(|k| k.pose * Se3::exp(&rng.vec6(0.05)))
        .collect();
    let pose_info: Vec<Matrix6<f64>> = knots.iter().map(|_| rng.spd::<6>(2.5e5)).collect();
    let qc_inv = Vector6::from_fn(|_, _| 2e-3 * (1.5 + rng.next()));
    (meas, pose_info, qc_inv)
}

/// A joint problem over `times` with the given weights (set directly: `JointProblem::new`
/// needs a fitted trajectory).
fn joint_problem<'a>(
    times: &[f64],
    meas: Vec<Se3>,
    pose_info: Vec<Matrix6<f64>>,
    qc_inv: Vector6<f64>,
    obs: &'a [DvlObs],
    idx: &'a [usize],
) -> JointProblem<'a> {
    JointProblem::from_parts(
        obs,
        idx,
        obs.iter().map(|o| o.cov.try_inverse().unwrap()).collect(),
        times.to_vec(),
        Box::new(PoseFactors::new(meas, pose_info)),
        qc_inv,
    )
}

/// The joint normal equations from numeric Jacobians of the documented residuals: pose terms
/// `log(T_meas^-1 T_k)` (weight `pose_info`), prior terms `gamma_2 - Phi gamma_1` (weight
/// `Q(dt)^-1 (x) diag(qc_inv)`), DVL terms `v - predict` (weight `dvl_info`). The clock offset
/// column of the DVL terms is the model's `-dh * rate` (see the module documentation); every
/// other column is a central difference.
struct Reference {
    diag: Vec<M18>,
    upper: Vec<M18>,
    rhs: Vec<V18>,
    cross: Vec<CrossBlock>,
    theta: ParamMat,
    gradient: ParamVec,
    cost: f64,
    /// Largest entries of the pose, prior and DVL contributions to the diagonal blocks.
    scale: [f64; 3],
}

fn reference(
    jp: &JointProblem,
    (meas, pose_info): (&[Se3], &[Matrix6<f64>]),
    knots: &[Knot],
    p: &CalibrationParams,
) -> Reference {
    let n = knots.len();
    let mut out = Reference {
        diag: vec![M18::zeros(); n],
        upper: vec![M18::zeros(); n - 1],
        rhs: vec![V18::zeros(); n],
        cross: vec![CrossBlock::zeros(); n],
        theta: ParamMat::zeros(),
        gradient: ParamVec::zeros(),
        cost: 0.0,
        scale: [0.0; 3],
    };
    for k in 0..n {
        let e_of = |kn: &[Knot]| (meas[k].inverse() * kn[k].pose).log();
        let j: SMatrix<f64, 6, 18> = numeric_knot_jacobian(knots, k, e_of);
        let (w, e) = (&pose_info[k], e_of(knots));
        let d = j.transpose() * w * j;
        out.scale[0] = out.scale[0].max(d.amax());
        out.diag[k] += d;
        out.rhs[k] -= j.transpose() * w * e;
        out.cost += (e.transpose() * w * e)[0];
    }
    for k in 0..n - 1 {
        let dt = jp.times[k + 1] - jp.times[k];
        let e_of = |kn: &[Knot]| {
            local_gamma(&kn[k], &kn[k + 1])
                - apply_scalar(&phi_scalar(dt), &first_local_state(&kn[k]))
        };
        let j: SMatrix<f64, 18, 36> = numeric_knot_jacobian(knots, k, e_of);
        let w = kron_diag(&q_scalar_inv(dt), &jp.density.qc_inv(k));
        let e = e_of(knots);
        let (j1, j2) = (j.fixed_columns::<18>(0), j.fixed_columns::<18>(18));
        let d1 = j1.transpose() * w * j1;
        out.scale[1] = out.scale[1].max(d1.amax());
        out.diag[k] += d1;
        out.diag[k + 1] += j2.transpose() * w * j2;
        out.upper[k] += j1.transpose() * w * j2;
        out.rhs[k] -= j1.transpose() * w * e;
        out.rhs[k + 1] -= j2.transpose() * w * e;
        out.cost += (e.transpose() * w * e)[0];
    }
    let view = KnotView {
        times: &jp.times,
        knots,
    };
    for &i in jp.idx {
        let o = &jp.obs[i];
        let w = &jp.dvl_info[i];
        let k = view.interval(o.t + p.time_offset_s).unwrap();
        let r_of = |kn: &[Knot]| residual(&jp.times, kn, p, o);
        let j: SMatrix<f64, 3, 36> = numeric_knot_jacobian(knots, k, r_of);
        let mut jt = numeric_param_jacobian(p, |q| residual(&jp.times, knots, q, o));
        let rate = view.state(o.t + p.time_offset_s).unwrap().rate;
        jt.set_column(7, &-(d_predict_d_twist(p) * rate));
        let r = r_of(knots);
        let (j1, j2) = (j.fixed_columns::<18>(0), j.fixed_columns::<18>(18));
        let d1 = j1.transpose() * w * j1;
        out.scale[2] = out.scale[2].max(d1.amax());
        out.diag[k] += d1;
        out.diag[k + 1] += j2.transpose() * w * j2;
        out.upper[k] += j1.transpose() * w * j2;
        out.rhs[k] -= j1.transpose() * w * r;
        out.rhs[k + 1] -= j2.transpose() * w * r;
        out.cross[k] += j1.transpose() * w * jt;
        out.cross[k + 1] += j2.transpose() * w * jt;
        out.theta += jt.transpose() * w * jt;
        out.gradient -= jt.transpose() * w * r;
        out.cost += (r.transpose() * w * r)[0];
    }
    out
}

#[test]
fn assembled_normal_equations_match_numeric_jacobian() {
    // Enough knots for two assembly chunks (the second chunk recomputes the interval before
    // it), a few DVL samples per interval (some intervals empty, samples used out of order and
    // not all of them), weights chosen so that pose, prior and DVL terms are of similar size
    // (so an error in any one of them shows in the sums).
    let mut rng = Rng::new(0x510E_527F_ADE6_82D1);
    let n = ASSEMBLY_CHUNK + 6;
    let (times, knots) = test_knots(&mut rng, n);
    let p = test_params(&mut rng);
    let obs = test_samples(&mut rng, &times, &p, &[0.13, 0.64]);
    let idx: Vec<usize> = (0..obs.len())
        .rev()
        .filter(|i| i % 7 != 3 && !(40..44).contains(i))
        .collect();
    let (meas, pose_info, qc_inv) = pose_terms(&mut rng, &knots);
    let jp = joint_problem(&times, meas.clone(), pose_info.clone(), qc_inv, &obs, &idx);

    let factors = DvlFactors::new(&jp, &p).unwrap();
    let mut sys = BlockTridiagonal::zeros(n);
    let a = factors.assemble(&knots, &mut sys, true);
    let reference = reference(&jp, (&meas, &pose_info), &knots, &p);
    eprintln!(
        "largest diagonal contributions: pose {:e}, prior {:e}, DVL {:e}",
        reference.scale[0], reference.scale[1], reference.scale[2]
    );

    // Each block relative to its own largest entry. The numeric Jacobians are good to ~1e-8
    // relative (module documentation), so the products are too; 1e-6 leaves the same margin.
    let mut worst = [0.0f64; 6];
    for k in 0..n {
        worst[0] = worst[0].max(rel(&sys.diag[k], &reference.diag[k]));
        worst[2] = worst[2].max(rel(&sys.rhs[k], &reference.rhs[k]));
        worst[3] = worst[3].max(rel(&a.cross[k], &reference.cross[k]));
        if k + 1 < n {
            worst[1] = worst[1].max(rel(&sys.upper[k], &reference.upper[k]));
        }
    }
    worst[4] = rel(&a.theta, &reference.theta);
    worst[5] = rel(&a.gradient, &reference.gradient);
    eprintln!(
        "normal equations: max relative block error diag {:e}, upper {:e}, rhs {:e}, cross {:e}, \
         theta {:e}, gradient {:e}",
        worst[0], worst[1], worst[2], worst[3], worst[4], worst[5]
    );
    for (name, w) in ["diag", "upper", "rhs", "cross", "theta", "gradient"]
        .iter()
        .zip(worst)
    {
        assert!(w < TOL, "{name}: {w:e}");
    }
    assert!((a.cost - reference.cost).abs() <= 1e-12 * reference.cost);
    // The cost alone is the same sum.
    assert_eq!(factors.cost(&knots), a.cost);
}

#[test]
fn halves_from_the_whole_system_equal_their_own_assembly() {
    // The halves check takes each half's normal equations from the whole's assembled system
    // and assembles anew only the knots near the cut and at the ends of the half's span. Over
    // three assembly chunks, with samples of both halves in the interval of the cut, some
    // intervals empty, and spans that end inside the whole's trajectory, each half's linearised
    // estimate and covariance must be those of its own assembly and factorisation, to the bit,
    // for the full parameter set and for the offset held fixed.
    let mut rng = Rng::new(0x9B05_688C_2B3E_6C1F);
    let n = 3 * ASSEMBLY_CHUNK + 17;
    let (times, knots) = test_knots(&mut rng, n);
    let p = test_params(&mut rng);
    let obs = test_samples(&mut rng, &times, &p, &[0.13, 0.64]);
    // No samples in the first and last 60 intervals: the halves' spans end in knots that carry
    // only poses and the prior, where the whole has prior terms across the ends.
    let idx: Vec<usize> = (0..obs.len())
        .filter(|i| i % 5 != 2 && (120..obs.len() - 120).contains(i))
        .collect();
    let (meas, pose_info, qc_inv) = pose_terms(&mut rng, &knots);
    let whole_jp = joint_problem(&times, meas.clone(), pose_info.clone(), qc_inv, &obs, &idx);
    let whole = assemble_joint(&whole_jp, &knots, &p).unwrap();
    // The cut falls inside an interval: its first sample goes to the first half.
    let cut = idx
        .iter()
        .position(|&i| obs[i].t + p.time_offset_s > times[n / 2])
        .unwrap()
        + 1;
    let halves = [
        (&idx[..cut], 55..n / 2 + 90),
        (&idx[cut..], n / 2 - 75..n - 55),
    ];
    let mut checked = 0;
    for (part, range) in halves {
        let jh = joint_problem(
            &times[range.clone()],
            meas[range.clone()].to_vec(),
            pose_info[range.clone()].to_vec(),
            qc_inv,
            &obs,
            part,
        );
        let sub = &knots[range.clone()];
        for free in [
            [true; NPARAM],
            [true, true, true, true, true, true, true, false],
        ] {
            let (pe, ce) =
                part_linear_estimate(&whole_jp, &whole, &jh, sub, range.clone(), &free).unwrap();
            let own = assemble_joint(&jh, sub, &p).unwrap();
            let (po, co) =
                linear_estimate_of(&jh, finish(&jh, own, &free).unwrap(), &p, &free).unwrap();
            // The same blocks in the same elimination order: the same numbers to the bit.
            assert_eq!(pe, po, "{range:?}: estimate");
            assert_eq!(ce, co, "{range:?}: covariance");
            checked += 1;
        }
    }
    assert_eq!(checked, 4);
}

#[test]
fn lower_triangle_products_equal_nalgebras_to_the_bit() {
    // The DVL factors add `J^T W J` to the diagonal blocks on the lower triangle alone; there
    // it must be nalgebra's full product to the last bit, so that the factorisation (which
    // reads only the lower triangle) sees the same numbers.
    let mut rng = Rng::new(0x6A09_E667_F3BC_C908);
    for _ in 0..50 {
        let a = SMatrix::<f64, 3, 18>::from_fn(|_, _| rng.next() * 3.0);
        let w = rng.spd::<3>(2.0);
        let b = w * a;
        let start = M18::from_fn(|_, _| rng.next());
        let mut lower = start;
        add_lower_atb(&mut lower, &a, &b);
        let full = start + a.transpose() * b;
        for j in 0..18 {
            for i in j..18 {
                assert_eq!(lower[(i, j)], full[(i, j)], "({i}, {j})");
            }
        }
        mirror_lower(&mut lower);
        assert!(lower == lower.transpose());
    }
}

#[test]
fn the_joint_assembly_adds_a_co_sensors_interval_factors_as_the_trajectory_solver_does() {
    // A co-sensor with factors between knots: the joint system (without the calibration's
    // blocks) minus the trajectory problem's own system is the DVL factors' part alone, the same
    // as with poses that have no such factors.
    use crate::trajectory::factors::tests::setup;
    let (knots, cos) = setup(9);
    let mut rng = Rng::new(17);
    let p = test_params(&mut rng);
    let obs = test_samples(&mut rng, &cos.times, &p, &[0.3, 0.7]);
    let idx: Vec<usize> = (0..obs.len()).collect();
    let n = knots.len();
    let qc_inv = Vector6::from_element(20.0);
    let dvl_part = |factors: Box<dyn CoSensorFactors + '_>| {
        let jp = JointProblem::from_parts(
            &obs,
            &idx,
            obs.iter().map(|o| o.cov.try_inverse().unwrap()).collect(),
            cos.times.clone(),
            factors,
            qc_inv,
        );
        let mut joint = BlockTridiagonal::zeros(n);
        let cost = DvlFactors::new(&jp, &p)
            .unwrap()
            .assemble(&knots, &mut joint, false)
            .cost;
        let mut own = BlockTridiagonal::zeros(n);
        let own_cost = jp.trajectory_problem().assemble_into(&knots, &mut own);
        let d: Vec<M18> = joint
            .diag
            .iter()
            .zip(&own.diag)
            .map(|(a, b)| a - b)
            .collect();
        let u: Vec<M18> = joint
            .upper
            .iter()
            .zip(&own.upper)
            .map(|(a, b)| a - b)
            .collect();
        let r: Vec<V18> = joint.rhs.iter().zip(&own.rhs).map(|(a, b)| a - b).collect();
        (d, u, r, cost - own_cost)
    };
    let with = dvl_part(cos.restricted(0..n));
    let poses_only = dvl_part(Box::new(cos.poses.clone()));
    let scale = poses_only.0.iter().map(|m| m.amax()).fold(0.0, f64::max);
    for k in 0..n {
        assert!(
            (with.0[k] - poses_only.0[k]).amax() < 1e-9 * scale,
            "diagonal {k}"
        );
        assert!(
            (with.2[k] - poses_only.2[k]).amax() < 1e-9 * scale,
            "rhs {k}"
        );
        if k + 1 < n {
            assert!(
                (with.1[k] - poses_only.1[k]).amax() < 1e-9 * scale,
                "upper {k}"
            );
        }
    }
    assert!((with.3 - poses_only.3).abs() < 1e-9 * poses_only.3.abs().max(1.0));
}
