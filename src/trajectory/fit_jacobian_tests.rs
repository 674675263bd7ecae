//! Finite-difference checks of the Jacobians of the interpolated twist: `d_local`, the 6 x 36
//! `jacobian` of [`KnotView::twist_jacobian_in`] (and of the public
//! [`Trajectory::twist_jacobian`]), and the projected 3 x 18 pair of
//! [`KnotView::projected_twist_jacobian_in`].
//!
//! The knot variables are perturbed with the solver's own update, [`step`]: `T <- T exp(dT)`
//! (right perturbation, `dT = [rho; phi]`), `w <- w + dw`, `dw <- dw + ddw`.
//!
//! Tolerance. Central differences with step `H` err by about `H^2 / 6 |f'''|` (truncation) plus
//! `eps |f| / H` (rounding). The twist's derivatives with respect to the pose variables carry the
//! interpolation weights' `1 / dt` factors (tens here), so both terms are larger than for a
//! unit-scaled map; `H = 1e-5` (the usual `eps^(1/3)` optimum) measured ~1e-8 relative errors,
//! ten times smaller than `H = 1e-6` (rounding-dominated: the error scaled as `1 / H` between
//! 3e-7 and 1e-5). Columns are compared relative to their own norm, floored at 1% of the largest
//! column of the block (columns that vanish, e.g. the second knot's at the start of the interval,
//! are compared against that floor). `TOL = 1e-6` leaves a margin of about 60 over the largest
//! error seen (1.5e-8), while a wrong block (sign, transpose, missing term) is an O(1) error.

use nalgebra::{SMatrix, SVector, Vector6};

use super::{FitReport, KnotView, Trajectory};
use crate::lie::Se3;
use crate::trajectory::blocktri::V18;
use crate::trajectory::gp::{
    Knot, apply_scalar, first_local_state, interpolation_weights, knot_from_local, local_state,
};
use crate::trajectory::solver::step;

/// Finite-difference step (see the module documentation).
const H: f64 = 1e-5;
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

    fn vec6(&mut self, scale: f64) -> Vector6<f64> {
        Vector6::from_fn(|_, _| self.next() * scale)
    }
}

/// Knots at uneven times with random-ish poses, twists and rates of order one. Consecutive
/// poses follow the twist only roughly (the interpolation and its Jacobians hold for any knot
/// states); the relative rotation of interval 2 is made large (about 2.4 rad) to exercise the
/// series of `J_r` far from the identity.
fn test_knots(seed: u64) -> (Vec<f64>, Vec<Knot>) {
    let times = vec![0.0, 0.17, 0.29, 0.52, 0.61];
    let mut rng = Rng::new(seed);
    let mut pose = Se3::exp(&rng.vec6(1.5));
    let mut knots = Vec::new();
    for k in 0..times.len() {
        let knot = Knot {
            pose,
            twist: rng.vec6(1.5),
            rate: rng.vec6(1.5),
        };
        knots.push(knot);
        if k + 1 < times.len() {
            let dt = times[k + 1] - times[k];
            let mut xi = knot.twist * dt + rng.vec6(0.3);
            if k == 2 {
                let phi = xi.fixed_rows::<3>(3).normalize() * 2.4;
                xi.fixed_rows_mut::<3>(3).copy_from(&phi);
            }
            pose = pose * Se3::exp(&xi);
        }
    }
    (times, knots)
}

/// Query times in interval `k`: both ends, just inside both ends, and a few interior points.
fn times_in(times: &[f64], k: usize) -> Vec<f64> {
    let (a, dt) = (times[k], times[k + 1] - times[k]);
    [0.0, 1e-3, 0.1, 0.37, 0.5, 0.81, 0.999, 1.0]
        .iter()
        .map(|f| a + f * dt)
        .collect()
}

/// Central differences of `f(knots)` with respect to the 36 variables `[x_k; x_{k+1}]`, each knot
/// perturbed by the solver's update ([`step`]).
fn numeric_knot_jacobian<const R: usize>(
    knots: &[Knot],
    k: usize,
    f: impl Fn(&[Knot]) -> SVector<f64, R>,
) -> SMatrix<f64, R, 36> {
    let mut out = SMatrix::<f64, R, 36>::zeros();
    for j in 0..36 {
        let mut dx = vec![V18::zeros(); knots.len()];
        dx[k + j / 18][j % 18] = H;
        let plus = f(&step(knots, &dx, 1.0));
        let minus = f(&step(knots, &dx, -1.0));
        out.set_column(j, &((plus - minus) / (2.0 * H)));
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

/// The interpolated twist at `t` in interval `k` (the quantity the Jacobians differentiate).
fn twist_in(times: &[f64], knots: &[Knot], k: usize, t: f64) -> Vector6<f64> {
    let view = KnotView { times, knots };
    let ls = local_state(&knots[k], &knots[k + 1]);
    view.state_in(k, t, &ls.gamma).twist
}

#[test]
fn twist_jacobian_in_matches_central_differences() {
    let mut worst: f64 = 0.0;
    for seed in [
        0x9E37_79B9_7F4A_7C15,
        0xD1B5_4A32_D192_ED03,
        0x8CB9_2BA7_2F3D_8DD7,
    ] {
        let (times, knots) = test_knots(seed);
        let view = KnotView {
            times: &times,
            knots: &knots,
        };
        for k in 0..times.len() - 1 {
            let ls = local_state(&knots[k], &knots[k + 1]);
            for t in times_in(&times, k) {
                let tj = view.twist_jacobian_in(k, t, &ls);
                assert_eq!(tj.knot, k);
                let numeric = numeric_knot_jacobian(&knots, k, |kn| twist_in(&times, kn, k, t));
                let err = column_error(&tj.jacobian, &numeric);
                worst = worst.max(err);
                assert!(
                    err < TOL,
                    "seed {seed:x}, interval {k}, t {t}: relative error {err:e}\nanalytic {}\nnumeric {}",
                    tj.jacobian,
                    numeric
                );
                // The state it returns is the interpolated state.
                let s = view.state_in(k, t, &ls.gamma);
                assert!((tj.state.twist - s.twist).amax() <= 1e-12 * (1.0 + s.twist.amax()));
                assert!((tj.state.rate - s.rate).amax() <= 1e-12 * (1.0 + s.rate.amax()));
            }
        }
    }
    eprintln!("twist_jacobian_in: max relative column error {worst:e}");
}

#[test]
fn d_local_matches_central_differences() {
    // `d_local` is d twist / d gamma at the interpolated local state gamma(t) (6 x 18; the twist
    // does not depend on xi'', so its last six columns vanish).
    let mut worst: f64 = 0.0;
    for seed in [0x9E37_79B9_7F4A_7C15, 0x6A09_E667_F3BC_C908] {
        let (times, knots) = test_knots(seed);
        let view = KnotView {
            times: &times,
            knots: &knots,
        };
        for k in 0..times.len() - 1 {
            let ls = local_state(&knots[k], &knots[k + 1]);
            let dt = times[k + 1] - times[k];
            for t in times_in(&times, k) {
                let tj = view.twist_jacobian_in(k, t, &ls);
                let (lambda, omega, cond) = interpolation_weights(t - times[k], dt);
                let gamma = apply_scalar(&lambda, &first_local_state(&knots[k]))
                    + apply_scalar(&omega, &ls.gamma);
                // This gamma is the one the query used.
                let at = knot_from_local(&knots[k].pose, &gamma);
                assert!((at.twist - tj.state.twist).amax() <= 1e-12 * (1.0 + at.twist.amax()));
                assert!((cond - tj.cond).amax() <= 1e-12 * cond.amax().max(1e-300));
                let mut numeric = SMatrix::<f64, 6, 18>::zeros();
                for j in 0..18 {
                    let (mut gp, mut gm) = (gamma, gamma);
                    gp[j] += H;
                    gm[j] -= H;
                    let d = knot_from_local(&knots[k].pose, &gp).twist
                        - knot_from_local(&knots[k].pose, &gm).twist;
                    numeric.set_column(j, &(d / (2.0 * H)));
                }
                let err = column_error(&tj.d_local, &numeric);
                worst = worst.max(err);
                assert!(
                    err < TOL,
                    "seed {seed:x}, interval {k}, t {t}: relative error {err:e}\nanalytic {}\nnumeric {}",
                    tj.d_local,
                    numeric
                );
                assert!(tj.d_local.fixed_view::<6, 6>(0, 12).amax() == 0.0);
            }
        }
    }
    eprintln!("d_local: max relative column error {worst:e}");
}

#[test]
fn projected_twist_jacobian_matches_central_differences() {
    // `projected_twist_jacobian_in` claims `(state, m J[:, 0..18], m J[:, 18..36])` with `J` the
    // twist's Jacobian: checked against central differences of `m twist` and against `m` times
    // `twist_jacobian_in`'s blocks (the same algebra regrouped: agreement to round-off).
    let mut rng = Rng::new(0x2545_F491_4F6C_DD1D);
    let (mut worst_fd, mut worst_alg): (f64, f64) = (0.0, 0.0);
    for seed in [0x9E37_79B9_7F4A_7C15, 0xBB67_AE85_84CA_A73B] {
        let (times, knots) = test_knots(seed);
        let view = KnotView {
            times: &times,
            knots: &knots,
        };
        for k in 0..times.len() - 1 {
            let ls = local_state(&knots[k], &knots[k + 1]);
            for t in times_in(&times, k) {
                let m = SMatrix::<f64, 3, 6>::from_fn(|_, _| rng.next() * 2.0);
                let (state, j1, j2) = view.projected_twist_jacobian_in(k, t, &ls, &m);
                let tj = view.twist_jacobian_in(k, t, &ls);
                assert!(
                    (state.twist - tj.state.twist).amax() <= 1e-12 * (1.0 + state.twist.amax())
                );
                assert!((state.rate - tj.state.rate).amax() <= 1e-12 * (1.0 + state.rate.amax()));
                let mut both = SMatrix::<f64, 3, 36>::zeros();
                both.fixed_view_mut::<3, 18>(0, 0).copy_from(&j1);
                both.fixed_view_mut::<3, 18>(0, 18).copy_from(&j2);
                let numeric = numeric_knot_jacobian(&knots, k, |kn| m * twist_in(&times, kn, k, t));
                let err = column_error(&both, &numeric);
                worst_fd = worst_fd.max(err);
                assert!(
                    err < TOL,
                    "seed {seed:x}, interval {k}, t {t}: relative error {err:e}\nanalytic {both}\nnumeric {numeric}"
                );
                let mj = m * tj.jacobian;
                let alg = (both - mj).amax() / mj.amax().max(1e-300);
                worst_alg = worst_alg.max(alg);
                assert!(alg < 1e-12, "interval {k}, t {t}: {alg:e} from m J");
            }
        }
    }
    eprintln!(
        "projected_twist_jacobian_in: max relative column error {worst_fd:e}, {worst_alg:e} from m J"
    );
}

/// A trajectory over the test knots (no covariance; the report is not used by queries).
fn trajectory(times: Vec<f64>, knots: Vec<Knot>) -> Trajectory {
    Trajectory {
        times,
        knots,
        density: crate::trajectory::JerkDensity::constant(Vector6::repeat(1.0)),
        cov: None,
        report: FitReport {
            iterations: 0,
            converged: true,
            cost: 0.0,
            qc: Vector6::repeat(1.0),
            qc_estimated: false,
            pose_sigma: (0.01, 0.01),
            pose_sigma_estimated: false,
            residual_rms_pos: 0.0,
            residual_rms_rot: 0.0,
        },
        local: std::sync::OnceLock::new(),
    }
}

#[test]
fn public_twist_jacobian_matches_central_differences_of_state() {
    // Through the public API only: the interval is located from t, and the reference is
    // `Trajectory::state` of the trajectory with updated knots. Knots other than the bracketing
    // two must not move the twist at all.
    let (times, knots) = test_knots(0x510E_527F_ADE6_82D1);
    let traj = trajectory(times.clone(), knots.clone());
    let (a, b) = traj.span();
    assert!(traj.twist_jacobian(a - 0.1).is_err());
    assert!(traj.twist_jacobian(b + 0.1).is_err());
    let mut worst: f64 = 0.0;
    let mut queries: Vec<f64> = (0..times.len() - 1)
        .flat_map(|k| times_in(&times, k))
        .collect();
    queries.extend([0.5 * (a + b), times[2]]);
    for t in queries {
        let tj = traj.twist_jacobian(t).unwrap();
        let k = tj.knot;
        assert_eq!(Some(k), traj.interval(t));
        let twist_at = |kn: &[Knot]| traj.with_knots(kn.to_vec(), None).state(t).unwrap().twist;
        let numeric = numeric_knot_jacobian(&knots, k, twist_at);
        let err = column_error(&tj.jacobian, &numeric);
        worst = worst.max(err);
        assert!(
            err < TOL,
            "t {t} (interval {k}): relative error {err:e}\nanalytic {}\nnumeric {}",
            tj.jacobian,
            numeric
        );
        let s = traj.state(t).unwrap();
        assert!((tj.state.twist - s.twist).amax() <= 1e-12 * (1.0 + s.twist.amax()));
        // `step` re-normalises every rotation, so the baseline is a zero step.
        let base = twist_at(&step(&knots, &vec![V18::zeros(); knots.len()], 1.0));
        for other in (0..knots.len()).filter(|&o| o != k && o != k + 1) {
            for j in 0..18 {
                let mut dx = vec![V18::zeros(); knots.len()];
                dx[other][j] = 1e-3;
                assert_eq!(twist_at(&step(&knots, &dx, 1.0)), base, "knot {other}");
            }
        }
    }
    eprintln!("Trajectory::twist_jacobian: max relative column error {worst:e}");
}

#[test]
fn the_twist_alone_is_the_states_twist() {
    // `KnotView::twist` skips the pose and the rate, and `KnotView::motion` and the DVL
    // factors' `projected_twist_jacobian_in` the pose, not any step of what they give: the same
    // values to the last bit, in every interval (one with a 2.4 rad rotation) and outside the
    // span.
    for seed in 1..4 {
        let (times, knots) = test_knots(seed);
        let view = KnotView {
            times: &times,
            knots: &knots,
        };
        let m = SMatrix::<f64, 3, 6>::from_fn(|r, c| (r * 6 + c) as f64 * 0.1 - 0.7);
        for k in 0..times.len() - 1 {
            let ls = local_state(&knots[k], &knots[k + 1]);
            for t in times_in(&times, k) {
                let state = view.state(t).unwrap();
                assert_eq!(view.twist(t).unwrap(), state.twist, "t = {t}");
                let motion = view.motion(t).unwrap();
                assert_eq!((motion.twist, motion.rate), (state.twist, state.rate));
                // With the local state as the DVL factors form it (with its Jacobians).
                let (projected, _, _) = view.projected_twist_jacobian_in(k, t, &ls, &m);
                let in_interval = view.state_in(k, t, &ls.gamma);
                assert_eq!(projected.twist, in_interval.twist, "t = {t}");
                assert_eq!(projected.rate, in_interval.rate, "t = {t}");
                assert_eq!(view.motion_in(k, t, &ls.gamma), projected);
            }
        }
        let after = times[times.len() - 1] + 1.0;
        assert!(view.twist(after).is_err() && view.state(after).is_err());
        assert!(view.motion(after).is_err());
        // A trajectory forms each interval's local state once and keeps it: the same values
        // as the view's, which forms it for every query, on the first query and later ones.
        let traj = trajectory(times.clone(), knots.clone());
        for k in 0..times.len() - 1 {
            for t in times_in(&times, k) {
                let (state, own) = (traj.state(t).unwrap(), view.state(t).unwrap());
                assert_eq!((state.twist, state.rate), (own.twist, own.rate), "t = {t}");
                assert_eq!(
                    (state.pose.rot, state.pose.trans),
                    (own.pose.rot, own.pose.trans)
                );
                assert_eq!(traj.twist(t).unwrap(), own.twist);
                assert_eq!(traj.motion(t).unwrap(), view.motion(t).unwrap());
            }
        }
        assert!(traj.twist(after).is_err() && traj.motion(after).is_err());
    }
}
