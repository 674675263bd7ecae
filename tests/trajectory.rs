//! Tests of the continuous-time trajectory fit against motions with known twists.
//!
//! Bounds on errors are statistical wherever the fit reports a covariance: the normalised
//! estimation error squared `NEES = e^T Sigma^-1 e` of the 6-dim twist error `e` has expectation 6
//! when the reported covariance `Sigma` is honest. Seeds are independent, so the spread of the
//! per-seed mean NEES gives the standard error of the across-seed mean.

use dvlcal::lie::{Se3, curly, se3_right_jacobian_inv, so3};
use dvlcal::rng::Rng;
use dvlcal::sim::motion::{Motion, SampledMotion, ScrewMotion, SinusoidMotion};
use dvlcal::sim::{SimConfig, simulate_with};
use dvlcal::trajectory::{FitOptions, Trajectory};
use dvlcal::types::PoseMeasurement;
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Vector3, Vector6};

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// Camera rate of every dataset here, Hz.
const RATE_HZ: f64 = 10.0;

/// Poses of `motion` on `[0, duration]` at [`RATE_HZ`] with right-perturbation noise of standard
/// deviations `(sp, sr)` drawn from `seed`. `with_cov`: the poses carry their true covariance;
/// otherwise they carry none (the fit then uses or estimates a default).
fn noisy_poses(
    motion: &dyn Motion,
    duration: f64,
    seed: u64,
    sigma: (f64, f64),
    with_cov: bool,
) -> Vec<PoseMeasurement> {
    let cfg = SimConfig {
        duration_s: duration,
        seed,
        camera_rate_hz: RATE_HZ,
        pose_sigma_pos_m: sigma.0,
        pose_sigma_rot_rad: sigma.1,
        ..SimConfig::default()
    };
    let mut poses = simulate_with(&cfg, motion).expect("simulation").poses;
    if !with_cov {
        poses.iter_mut().for_each(|p| p.cov = None);
    }
    poses
}

/// Exact poses of `motion` at [`RATE_HZ`] on `[0, duration]`, without covariance.
fn exact_poses(motion: &dyn Motion, duration: f64) -> Vec<PoseMeasurement> {
    let n = (duration * RATE_HZ + 1e-9).floor() as usize + 1;
    (0..n)
        .map(|k| {
            let t = k as f64 / RATE_HZ;
            PoseMeasurement {
                t,
                pose: motion.state(t).pose,
                cov: None,
            }
        })
        .collect()
}

/// The lively sinusoid: rotation rates up to about 2 rad/s.
fn lively(duration: f64) -> SinusoidMotion {
    SinusoidMotion::lively(duration).expect("motion")
}

/// A screw motion with |v| = 0.62 m/s and |w| = 1.56 rad/s.
fn screw(duration: f64) -> ScrewMotion {
    let start = Se3::exp(&Vector6::new(0.4, -0.3, 1.2, 0.3, -0.5, 0.2));
    let twist = Vector6::new(0.3, -0.2, 0.5, 1.2, -0.8, 0.6);
    ScrewMotion::new(start, twist, duration).expect("motion")
}

/// Rotation angle between two rotations, radians.
fn rot_dist(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    so3::log(&(a.transpose() * b)).norm()
}

/// `e^T c^-1 e`.
fn nees(e: &Vector6<f64>, c: &Matrix6<f64>) -> f64 {
    let chol = c
        .cholesky()
        .expect("twist covariance must be positive definite");
    e.dot(&chol.solve(e))
}

/// `count` query times uniform in the open span of `traj`, from `seed`.
fn random_times(traj: &Trajectory, count: usize, seed: u64) -> Vec<f64> {
    let (a, b) = traj.span();
    let mut rng = Rng::stream(seed, 99);
    (0..count).map(|_| rng.uniform_in(a, b)).collect()
}

/// Twist errors at `times`: per-component mean squared error and the mean NEES.
struct TwistStats {
    mse: Vector6<f64>,
    /// Mean reported variance per component.
    mean_var: Vector6<f64>,
    nees: f64,
}

impl TwistStats {
    fn rms_v(&self) -> f64 {
        self.mse.fixed_rows::<3>(0).sum().sqrt()
    }
    fn rms_w(&self) -> f64 {
        self.mse.fixed_rows::<3>(3).sum().sqrt()
    }
}

fn twist_stats(traj: &Trajectory, motion: &dyn Motion, times: &[f64]) -> TwistStats {
    let mut mse = Vector6::zeros();
    let mut mean_var = Vector6::zeros();
    let mut total = 0.0;
    for &t in times {
        let s = traj.query(t).expect("query inside the span");
        let c = s.twist_cov.expect("covariance requested");
        let e = s.twist - motion.state(t).twist;
        mse += e.component_mul(&e);
        mean_var += c.diagonal();
        total += nees(&e, &c);
    }
    let n = times.len() as f64;
    TwistStats {
        mse: mse / n,
        mean_var: mean_var / n,
        nees: total / n,
    }
}

/// Mean and standard error of independent values.
fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

// ---------------------------------------------------------------------------------------------
// Conventions against analytic motions
// ---------------------------------------------------------------------------------------------

/// Knot times, interval midpoints and random times of `traj`.
fn probe_times(traj: &Trajectory, seed: u64) -> Vec<f64> {
    let mut times: Vec<f64> = traj.times().to_vec();
    times.extend(traj.times().windows(2).map(|w| 0.5 * (w[0] + w[1])));
    times.extend(random_times(traj, 50, seed));
    times
}

#[test]
fn screw_motion_twist_pose_and_rate_are_exact() {
    // Constant body twist with |w| = 1.56 rad/s; poses with 1e-8 noise so that Gauss-Newton has
    // work to do. A constant twist lies in the null space of the WNOJ prior, so the fit must
    // reproduce it up to the noise: twist errors of order 1e-8 / 0.1 s.
    let m = screw(6.0);
    let poses = noisy_poses(&m, 6.0, 7, (1e-8, 1e-8), true);
    let traj = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
    assert!(traj.report().converged);
    let (mut tw, mut rate, mut pos, mut rot) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for t in probe_times(&traj, 1) {
        let s = traj.query(t).expect("query");
        let truth = m.state(t);
        tw = tw.max((s.twist - m.twist).abs().max());
        rate = rate.max(s.rate.abs().max());
        pos = pos.max((s.pose.trans - truth.pose.trans).norm());
        rot = rot.max(rot_dist(&s.pose.rot, &truth.pose.rot));
    }
    assert!(tw < 1e-6, "twist error {tw}");
    assert!(rate < 1e-4, "twist rate {rate} (truth 0)");
    assert!(pos < 1e-7, "position error {pos}");
    assert!(rot < 1e-7, "rotation error {rot}");
}

#[test]
fn sinusoid_twist_matches_truth_between_knots() {
    // Exact poses of the lively motion (|w| up to 2 rad/s, components up to 1.7 Hz, i.e. six
    // samples per period at 10 Hz). The WNOJ interpolant cannot represent sinusoids exactly; the
    // bounds are about four times the interpolation errors this motion shows (relative RMS twist
    // error 0.25 % for v, 0.6 % for w; rates 3 % and 5 %; poses 0.5 mm, 3 mrad), so they catch a
    // sign or frame error (relative error ~ 1) and a loss of interpolation order.
    let m = lively(20.0);
    let poses = exact_poses(&m, 20.0);
    let traj = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
    let (mut e2, mut t2) = (Vector6::<f64>::zeros(), Vector6::<f64>::zeros());
    let (mut r2, mut rt2) = (Vector6::<f64>::zeros(), Vector6::<f64>::zeros());
    let (mut pos, mut rot) = (0.0f64, 0.0f64);
    for t in random_times(&traj, 400, 2) {
        let s = traj.query(t).expect("query");
        let truth = m.state(t);
        let e = s.twist - truth.twist;
        e2 += e.component_mul(&e);
        t2 += truth.twist.component_mul(&truth.twist);
        let er = s.rate - truth.twist_rate;
        r2 += er.component_mul(&er);
        rt2 += truth.twist_rate.component_mul(&truth.twist_rate);
        pos = pos.max((s.pose.trans - truth.pose.trans).norm());
        rot = rot.max(rot_dist(&s.pose.rot, &truth.pose.rot));
    }
    let rel = |a: &Vector6<f64>, b: &Vector6<f64>, o: usize| {
        (a.fixed_rows::<3>(o).sum() / b.fixed_rows::<3>(o).sum()).sqrt()
    };
    let (rv, rw, rdv, rdw) = (
        rel(&e2, &t2, 0),
        rel(&e2, &t2, 3),
        rel(&r2, &rt2, 0),
        rel(&r2, &rt2, 3),
    );
    assert!(rv < 0.01, "relative v error {rv}");
    assert!(rw < 0.025, "relative w error {rw}");
    assert!(rdv < 0.12, "relative dv error {rdv}");
    assert!(rdw < 0.2, "relative dw error {rdw}");
    assert!(pos < 2e-3, "position error {pos}");
    assert!(rot < 1.3e-2, "rotation error {rot}");
}

// ---------------------------------------------------------------------------------------------
// Accuracy with noise
// ---------------------------------------------------------------------------------------------

/// Per-seed twist statistics of `motion` over `seeds`, 30 s at 10 Hz, 2 mm / 2 mrad noise.
fn noisy_runs(
    motion: &dyn Motion,
    seeds: std::ops::RangeInclusive<u64>,
    with_cov: bool,
) -> Vec<TwistStats> {
    seeds
        .map(|seed| {
            let poses = noisy_poses(motion, 30.0, seed, (0.002, 0.002), with_cov);
            let traj = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
            twist_stats(&traj, motion, &random_times(&traj, 200, seed))
        })
        .collect()
}

/// Bounds that follow from the reported covariance: a covariance that is not overconfident
/// gives a mean NEES of at most 6 (exactly 6 when it is honest), so the across-seed mean must
/// not exceed 6 by more than four standard errors; and each component's mean squared error must
/// stay below four times its mean reported variance (RMS error below two reported standard
/// deviations). `abs`: absolute RMS bounds (m/s, rad/s) for the record.
fn check_accuracy(name: &str, runs: &[TwistStats], abs: (f64, f64)) {
    let nees: Vec<f64> = runs.iter().map(|r| r.nees).collect();
    let (m, se) = mean_se(&nees);
    assert!(
        m < 6.0 + 4.0 * se.max(0.25),
        "{name}: mean NEES {m} (se {se})"
    );
    for (i, r) in runs.iter().enumerate() {
        for c in 0..6 {
            assert!(
                r.mse[c] < 4.0 * r.mean_var[c],
                "{name} run {i} component {c}: MSE {} vs reported variance {}",
                r.mse[c],
                r.mean_var[c]
            );
        }
        assert!(
            r.rms_v() < abs.0,
            "{name} run {i}: RMS v error {}",
            r.rms_v()
        );
        assert!(
            r.rms_w() < abs.1,
            "{name} run {i}: RMS w error {}",
            r.rms_w()
        );
    }
}

#[test]
fn screw_motion_with_noise_meets_covariance_bounds() {
    // Absolute bounds: three times the RMS norm errors seen over these seeds (3-6e-4).
    let m = screw(30.0);
    check_accuracy(
        "screw, true covariance",
        &noisy_runs(&m, 1..=5, true),
        (1.5e-3, 1.5e-3),
    );
    check_accuracy(
        "screw, noise estimated",
        &noisy_runs(&m, 1..=5, false),
        (1.5e-3, 1.5e-3),
    );
}

#[test]
fn sinusoid_with_noise_meets_covariance_bounds() {
    // Absolute bounds: about 1.5 times the RMS norm errors seen over these seeds (v 0.025-0.028
    // m/s, w 0.046-0.060 rad/s). For scale: a central difference of 2 mm position noise over
    // 0.2 s has an RMS norm error of sqrt(3/2) 0.002 / 0.1 = 0.024 m/s.
    let m = lively(30.0);
    check_accuracy(
        "sinusoid, true covariance",
        &noisy_runs(&m, 1..=5, true),
        (0.04, 0.09),
    );
    check_accuracy(
        "sinusoid, noise estimated",
        &noisy_runs(&m, 1..=5, false),
        (0.04, 0.09),
    );
}

// ---------------------------------------------------------------------------------------------
// Interpolation at knots and the posterior covariance
// ---------------------------------------------------------------------------------------------

#[test]
fn queries_at_knots_reproduce_the_knots_and_are_continuous() {
    let m = lively(10.0);
    let poses = noisy_poses(&m, 10.0, 4, (0.002, 0.002), true);
    let traj = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
    let n = traj.times().len();
    for k in 0..n {
        let t = traj.times()[k];
        let kn = traj.knots()[k];
        let s = traj.query(t).expect("query at a knot");
        assert!((s.twist - kn.twist).abs().max() < 1e-10, "knot {k} twist");
        assert!((s.rate - kn.rate).abs().max() < 1e-9, "knot {k} rate");
        assert!(
            (s.pose.trans - kn.pose.trans).norm() < 1e-12,
            "knot {k} position"
        );
        assert!(
            rot_dist(&s.pose.rot, &kn.pose.rot) < 1e-12,
            "knot {k} rotation"
        );
        if k == 0 || k == n - 1 {
            continue;
        }
        // Either side of the knot: the difference shrinks in proportion to the gap.
        let c0 = s.twist_cov.expect("covariance");
        for gap in [1e-3, 1e-5, 1e-7] {
            let a = traj.query(t - gap).expect("left");
            let b = traj.query(t + gap).expect("right");
            let dtw = (a.twist - b.twist).abs().max();
            let dp = (a.pose.trans - b.pose.trans).norm() + rot_dist(&a.pose.rot, &b.pose.rot);
            // |twist rate| < 20 and |twist| < 3 on this motion.
            assert!(dtw < 50.0 * gap, "knot {k} gap {gap}: twist jump {dtw}");
            assert!(dp < 10.0 * gap, "knot {k} gap {gap}: pose jump {dp}");
            for side in [&a, &b] {
                let c = side.twist_cov.expect("covariance");
                let rel = ((c - c0).abs().max()) / c0.diagonal().max();
                assert!(
                    rel < 1e-3 + 1e3 * gap,
                    "knot {k} gap {gap}: covariance jump {rel}"
                );
            }
        }
    }
}

#[test]
fn fit_is_the_map_and_knot_covariance_is_the_marginal() {
    // The dense reference builds the documented cost from scratch (its own residuals, numerical
    // Jacobians, dense inverse). At the fitted knots its Gauss-Newton step must be negligible
    // against the posterior spread (the fit is the MAP), and its inverse information must equal
    // the twist covariance queried at each knot (the knot's marginal block).
    let sigma = (0.002, 0.002);
    let qc = Vector6::new(1e-2, 1e-2, 1e-2, 1e-1, 1e-1, 1e-1);
    let m = lively(3.0);
    let poses = noisy_poses(&m, 3.0, 3, sigma, false);
    let opts = FitOptions {
        qc: Some(qc),
        pose_sigma: Some(sigma),
        ..FitOptions::default()
    };
    let traj = Trajectory::fit(&poses, &opts).expect("fit");
    let knots: Vec<RefKnot> = traj
        .knots()
        .iter()
        .map(|k| RefKnot {
            pose: k.pose,
            twist: k.twist,
            rate: k.rate,
        })
        .collect();
    let meas: Vec<Se3> = poses.iter().map(|p| p.pose).collect();
    let (step, cov) = reference_step_and_covariance(&knots, traj.times(), &meas, sigma, &qc);
    let worst_step = (0..step.len())
        .map(|i| (step[i] / cov[(i, i)].sqrt()).abs())
        .fold(0.0, f64::max);
    // Gauss-Newton stops once the next step would move no linear function of the knots by
    // more than 0.01 of its standard deviation (its decrement below 1e-4): what is left is
    // below that spread.
    assert!(worst_step < 1e-2, "MAP step / posterior std {worst_step}");
    for (k, &t) in traj.times().iter().enumerate() {
        let c = traj.query(t).expect("query").twist_cov.expect("covariance");
        let r = cov.view((18 * k + 6, 18 * k + 6), (6, 6));
        for i in 0..6 {
            for j in 0..6 {
                let d = (c[(i, j)] - r[(i, j)]).abs() / (c[(i, i)] * c[(j, j)]).sqrt();
                assert!(
                    d < 1e-5,
                    "knot {k} ({i},{j}): {} vs {}",
                    c[(i, j)],
                    r[(i, j)]
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Covariance consistency (NEES) on draws from the prior
// ---------------------------------------------------------------------------------------------

/// The WNOJ prior of the simulator's `MotionKind::Prior`: Qc 2e-6 (m/s^3)^2 s and 2e-5
/// (rad/s^3)^2 s, initial twist [0.1, 0, 0.05 | 0, 0, 0.05]; |w| stays below about 0.5 rad/s
/// over 20 s.
fn prior_qc() -> Vector6<f64> {
    Vector6::from(SimConfig::default().prior_qc)
}

/// Per-seed mean NEES over 50 random query times of WNOJ draws with `qc` and `initial_twist`,
/// 20 s at 10 Hz, 2 mm / 2 mrad noise, poses without covariance. `known`: fit with the true Qc
/// and noise; otherwise both are estimated by marginal likelihood.
fn wnoj_nees(
    qc: Vector6<f64>,
    initial_twist: Vector6<f64>,
    seeds: std::ops::RangeInclusive<u64>,
    known: bool,
) -> Vec<f64> {
    let sigma = (0.002, 0.002);
    seeds
        .map(|seed| {
            let m = SampledMotion::wnoj(seed, 20.0, qc.into(), initial_twist).expect("motion");
            let poses = noisy_poses(&m, 20.0, seed, sigma, false);
            let opts = if known {
                FitOptions {
                    qc: Some(qc),
                    pose_sigma: Some(sigma),
                    ..FitOptions::default()
                }
            } else {
                FitOptions::default()
            };
            let traj = Trajectory::fit(&poses, &opts).expect("fit");
            twist_stats(&traj, &m, &random_times(&traj, 50, seed)).nees
        })
        .collect()
}

fn prior_initial_twist() -> Vector6<f64> {
    Vector6::from(SimConfig::default().prior_initial_twist)
}

#[test]
fn nees_with_true_qc_matches_its_expectation() {
    // Seeds are independent, so the across-seed standard error is honest even though the 50
    // queries within one seed are correlated. With the true Qc and noise the posterior is exact
    // for this (nearly linear) problem: E[NEES] = 6.
    let per_seed = wnoj_nees(prior_qc(), prior_initial_twist(), 1..=40, true);
    let (m, se) = mean_se(&per_seed);
    eprintln!(
        "WNOJ prior, true Qc: mean NEES {m:.3} +- {se:.3} over {} seeds",
        per_seed.len()
    );
    assert!(
        (m - 6.0).abs() < 4.0 * se,
        "mean NEES {m}, standard error {se}"
    );
    assert!((5.0..7.0).contains(&m), "mean NEES {m}");
}

#[test]
fn nees_with_estimated_qc_is_near_its_expectation() {
    // Qc and pose noise from the marginal likelihood: the estimate scatters by a factor of a few
    // around the truth (see `ml_qc_estimate_is_near_the_truth`), which scales the reported
    // covariance; a band of [3.5, 9] (NEES 6 with the reported variances off by up to 1.5x either
    // way) is what such an estimate can promise.
    let per_seed = wnoj_nees(prior_qc(), prior_initial_twist(), 1..=12, false);
    let (m, se) = mean_se(&per_seed);
    eprintln!(
        "WNOJ prior, estimated Qc: mean NEES {m:.3} +- {se:.3} over {} seeds",
        per_seed.len()
    );
    assert!(
        (3.5..9.0).contains(&m),
        "mean NEES {m}, standard error {se}"
    );
}

#[test]
#[ignore = "known failure: the reported twist covariance is overconfident under fast rotation"]
fn nees_with_true_qc_under_fast_rotation() {
    // A nearly constant screw (|w| = 1.5 rad/s) perturbed by WNOJ with Qc 1e-6: with the true Qc
    // the mean NEES is about 13.6 +- 0.7 over 60 seeds (expectation 6), against 6.2 +- 0.1 for the
    // same Qc started at rest.
    let w0 = Vector6::new(0.0, 0.0, 0.0, 1.2, -0.8, 0.4);
    let per_seed = wnoj_nees(Vector6::repeat(1e-6), w0, 1..=40, true);
    let (m, se) = mean_se(&per_seed);
    eprintln!("WNOJ fast rotation, true Qc: mean NEES {m:.3} +- {se:.3}");
    assert!(
        (m - 6.0).abs() < 4.0 * se,
        "mean NEES {m}, standard error {se}"
    );
}

#[test]
fn sinusoid_nees_with_estimated_qc() {
    // The sinusoid is not a draw from the prior, so NEES 6 is not promised; it is reported, and
    // bounded only against gross overconfidence.
    let m = lively(30.0);
    let runs = noisy_runs(&m, 1..=5, false);
    let nees: Vec<f64> = runs.iter().map(|r| r.nees).collect();
    let (mean, se) = mean_se(&nees);
    eprintln!("lively sinusoid, estimated Qc and noise: mean NEES {mean:.3} +- {se:.3}");
    assert!(mean < 12.0, "mean NEES {mean}");
}

// ---------------------------------------------------------------------------------------------
// Hyperparameters and measurement covariance
// ---------------------------------------------------------------------------------------------

#[test]
fn qc_override_is_honoured() {
    let m = lively(5.0);
    let poses = noisy_poses(&m, 5.0, 1, (0.002, 0.002), false);
    let qc = Vector6::new(0.5, 0.6, 0.7, 3.0, 4.0, 5.0);
    let traj = Trajectory::fit(
        &poses,
        &FitOptions {
            qc: Some(qc),
            pose_sigma: Some((0.003, 0.004)),
            ..FitOptions::default()
        },
    )
    .expect("fit");
    let r = traj.report();
    assert_eq!(r.qc, qc);
    assert_eq!(traj.qc(), qc);
    assert!(!r.qc_estimated);
    assert_eq!(r.pose_sigma, (0.003, 0.004));
    assert!(!r.pose_sigma_estimated);
    let est = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
    assert!(est.report().qc_estimated && est.report().pose_sigma_estimated);
}

#[test]
fn a_looser_stop_saves_a_pass_and_moves_the_twists_by_a_fraction_of_their_spread() {
    // The calibration's fit stops at a decrement of 0.01 per knot. On 5 min of lively motion
    // that ends the fit one factorisation earlier, and the twists it gives differ from the fully
    // converged fit's by well under a tenth of their posterior standard deviation.
    let m = lively(300.0);
    let poses = noisy_poses(&m, 300.0, 4, (0.002, 0.002), false);
    let tight = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
    let loose = Trajectory::fit(
        &poses,
        &FitOptions {
            decrement_per_knot: 0.01,
            ..FitOptions::default()
        },
    )
    .expect("fit");
    let (it, il) = (tight.report().iterations, loose.report().iterations);
    assert!(il < it, "loose stop took {il} steps, the tight one {it}");
    assert!(loose.report().converged);
    let mut worst: f64 = 0.0;
    for &t in tight.times().iter().step_by(7) {
        let q = tight.query(t).expect("query");
        let cov = q.twist_cov.expect("covariance");
        let d = loose.twist(t).expect("twist") - q.twist;
        for a in 0..6 {
            worst = worst.max(d[a].abs() / cov[(a, a)].sqrt());
        }
    }
    assert!(worst < 0.1, "twists moved by {worst} standard deviations");
    assert!(
        worst > 0.0,
        "the two stops gave the same fit: the test shows nothing"
    );
}

#[test]
fn ml_qc_estimate_is_near_the_truth() {
    // WNOJ draws with the simulator's prior Qc, 20 s at 10 Hz (201 poses), 2 mm / 2 mrad noise,
    // seeds 1..=12, Qc and noise estimated. The geometric mean over the seeds of the estimated /
    // true ratio must lie within a factor of 3 for each part; the noise within 20 %.
    let qc = prior_qc();
    let (mut lv, mut lw) = (Vec::new(), Vec::new());
    for seed in 1..=12 {
        let m = SampledMotion::wnoj(seed, 20.0, qc.into(), prior_initial_twist()).expect("motion");
        let poses = noisy_poses(&m, 20.0, seed, (0.002, 0.002), false);
        let traj = Trajectory::fit(&poses, &FitOptions::default()).expect("fit");
        let r = traj.report();
        lv.push((r.qc[0] / qc[0]).ln());
        lw.push((r.qc[3] / qc[3]).ln());
        assert!(
            (r.pose_sigma.0 / 0.002 - 1.0).abs() < 0.2,
            "seed {seed}: {:?}",
            r.pose_sigma
        );
        assert!(
            (r.pose_sigma.1 / 0.002 - 1.0).abs() < 0.2,
            "seed {seed}: {:?}",
            r.pose_sigma
        );
    }
    let gv = mean_se(&lv).0.exp();
    let gw = mean_se(&lw).0.exp();
    eprintln!("ML Qc / true Qc, geometric mean over 12 seeds: trans {gv:.2}, rot {gw:.2}");
    assert!((1.0 / 3.0..3.0).contains(&gw), "rotational Qc ratio {gw}");
    assert!(
        (1.0 / 3.0..3.0).contains(&gv),
        "translational Qc ratio {gv}"
    );
}

#[test]
fn per_measurement_covariance_is_used() {
    let m = lively(6.0);
    let sigma = (0.002, 0.002);
    let qc = Vector6::new(10.0, 10.0, 10.0, 200.0, 200.0, 200.0);
    let with_cov = noisy_poses(&m, 6.0, 5, sigma, true);
    let mut without: Vec<PoseMeasurement> = with_cov.clone();
    without.iter_mut().for_each(|p| p.cov = None);
    let opts = |s: Option<(f64, f64)>| FitOptions {
        qc: Some(qc),
        pose_sigma: s,
        ..FitOptions::default()
    };
    // The covariance each pose carries and the same value as the default give the same fit.
    let a = Trajectory::fit(&with_cov, &opts(None)).expect("fit");
    let b = Trajectory::fit(&without, &opts(Some(sigma))).expect("fit");
    for t in random_times(&a, 20, 5) {
        let (sa, sb) = (a.query(t).expect("a"), b.query(t).expect("b"));
        assert!((sa.twist - sb.twist).abs().max() < 1e-9);
    }
    // A pose 0.5 m off whose covariance says so barely moves the fit; with the default it does.
    let k = 30;
    let mut bad = with_cov.clone();
    bad[k].pose = bad[k].pose * Se3::exp(&Vector6::new(0.5, 0.0, 0.0, 0.0, 0.0, 0.0));
    bad[k].cov = Some(Matrix6::identity() * 1e4);
    let c = Trajectory::fit(&bad, &opts(None)).expect("fit");
    let t = bad[k].t;
    let d_good = (c.query(t).unwrap().pose.trans - a.query(t).unwrap().pose.trans).norm();
    bad[k].cov = None;
    let d = Trajectory::fit(&bad, &opts(Some(sigma))).expect("fit");
    let d_bad = (d.query(t).unwrap().pose.trans - a.query(t).unwrap().pose.trans).norm();
    assert!(
        d_good < 1e-3,
        "down-weighted outlier moved the fit by {d_good} m"
    );
    assert!(
        d_bad > 0.05,
        "an outlier at full weight moved the fit by only {d_bad} m"
    );
}

// ---------------------------------------------------------------------------------------------
// Errors, never panics
// ---------------------------------------------------------------------------------------------

#[test]
fn bad_inputs_are_errors() {
    let m = lively(2.0);
    let poses = exact_poses(&m, 2.0);
    let opts = FitOptions::default();
    assert!(Trajectory::fit(&poses[..2], &opts).is_err());
    assert!(Trajectory::fit(&[], &opts).is_err());
    let mut dup = poses.clone();
    dup[5].t = dup[4].t;
    assert!(Trajectory::fit(&dup, &opts).is_err());
    let mut back = poses.clone();
    back[5].t = back[3].t;
    assert!(Trajectory::fit(&back, &opts).is_err());
    let mut nan = poses.clone();
    nan[6].pose.trans.x = f64::NAN;
    assert!(Trajectory::fit(&nan, &opts).is_err());
    let mut nan_t = poses.clone();
    nan_t[6].t = f64::NAN;
    assert!(Trajectory::fit(&nan_t, &opts).is_err());

    let traj = Trajectory::fit(&poses, &opts).expect("fit");
    let (a, b) = traj.span();
    assert!(traj.query(a).is_ok() && traj.query(b).is_ok());
    for t in [
        a - 0.01,
        b + 0.01,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ] {
        assert!(traj.query(t).is_err(), "query at {t}");
    }
}

// ---------------------------------------------------------------------------------------------
// Independent dense reference of the MAP problem
// ---------------------------------------------------------------------------------------------

/// Scalar covariance of a triple integrator over `dt` (times `Qc`).
fn q_scalar(dt: f64) -> Matrix3<f64> {
    let (d2, d3) = (dt * dt, dt * dt * dt);
    Matrix3::new(
        d3 * d2 / 20.0,
        d2 * d2 / 8.0,
        d3 / 6.0,
        d2 * d2 / 8.0,
        d3 / 3.0,
        d2 / 2.0,
        d3 / 6.0,
        d2 / 2.0,
        dt,
    )
}

/// Knot variables of the reference: pose, twist, twist rate.
#[derive(Clone, Copy)]
struct RefKnot {
    pose: Se3,
    twist: Vector6<f64>,
    rate: Vector6<f64>,
}

/// The whitened residual vector of the MAP problem, written from the documented model only
/// (docs/conventions.md "GP trajectory"): pose terms `L_R (log(T_meas^-1 T_k))` and prior terms
/// `L_Q (gamma_2 - Phi gamma_1)` with `gamma = [xi; J_r^-1(xi) w; J_r^-1(xi) dw + 1/2
/// curly(J_r^-1(xi) w) w]`, where `L^T L` is the inverse covariance.
fn reference_residuals(
    knots: &[RefKnot],
    times: &[f64],
    meas: &[Se3],
    sigma: (f64, f64),
    qc: &Vector6<f64>,
) -> DVector<f64> {
    let n = knots.len();
    let mut r = DVector::zeros(6 * n + 18 * (n - 1));
    for k in 0..n {
        let e = (meas[k].inverse() * knots[k].pose).log();
        for i in 0..6 {
            r[6 * k + i] = e[i] / if i < 3 { sigma.0 } else { sigma.1 };
        }
    }
    for k in 0..n - 1 {
        let dt = times[k + 1] - times[k];
        let (k1, k2) = (&knots[k], &knots[k + 1]);
        let xi = (k1.pose.inverse() * k2.pose).log();
        let jri = se3_right_jacobian_inv(&xi);
        let u = jri * k2.twist;
        let a = jri * k2.rate + curly(&u) * k2.twist * 0.5;
        let g2 = [xi, u, a];
        let g1 = [Vector6::zeros(), k1.twist, k1.rate];
        let phi = Matrix3::new(1.0, dt, 0.5 * dt * dt, 0.0, 1.0, dt, 0.0, 0.0, 1.0);
        // Whitening of Q(dt) (x) diag(qc): per component c, L_c = chol(Q(dt) qc_c)^-1.
        let lq = q_scalar(dt)
            .cholesky()
            .expect("Q(dt) is positive definite")
            .l();
        let lq_inv = lq.try_inverse().expect("invertible");
        for c in 0..6 {
            let mut ec = Vector3::zeros();
            for i in 0..3 {
                let pred: f64 = (0..3).map(|j| phi[(i, j)] * g1[j][c]).sum();
                ec[i] = g2[i][c] - pred;
            }
            let w = lq_inv * ec / qc[c].sqrt();
            for i in 0..3 {
                r[6 * n + 18 * k + 6 * i + c] = w[i];
            }
        }
    }
    r
}

/// Knots perturbed by `d` (18 per knot: right pose perturbation, twist, rate).
fn perturb_knots(knots: &[RefKnot], d: &DVector<f64>) -> Vec<RefKnot> {
    knots
        .iter()
        .enumerate()
        .map(|(k, kn)| {
            let v = |o: usize| Vector6::from_fn(|i, _| d[18 * k + o + i]);
            RefKnot {
                pose: kn.pose * Se3::exp(&v(0)),
                twist: kn.twist + v(6),
                rate: kn.rate + v(12),
            }
        })
        .collect()
}

/// Gradient-descent step `A^-1 g` and covariance `A^-1` of the dense reference at `knots`
/// (Gauss-Newton information from central-difference Jacobians).
fn reference_step_and_covariance(
    knots: &[RefKnot],
    times: &[f64],
    meas: &[Se3],
    sigma: (f64, f64),
    qc: &Vector6<f64>,
) -> (DVector<f64>, DMatrix<f64>) {
    let nv = 18 * knots.len();
    let r0 = reference_residuals(knots, times, meas, sigma, qc);
    let mut jac = DMatrix::zeros(r0.len(), nv);
    let h = 1e-6;
    for j in 0..nv {
        let mut d = DVector::zeros(nv);
        d[j] = h;
        let rp = reference_residuals(&perturb_knots(knots, &d), times, meas, sigma, qc);
        let rm = reference_residuals(&perturb_knots(knots, &-d), times, meas, sigma, qc);
        jac.set_column(j, &((rp - rm) / (2.0 * h)));
    }
    let a = jac.transpose() * &jac;
    let cov = a.clone().try_inverse().expect("information is invertible");
    let step = -(&cov * (jac.transpose() * r0));
    (step, cov)
}

// ---------------------------------------------------------------------------------------------
// The accuracy table of docs/accuracy.md
// ---------------------------------------------------------------------------------------------

/// Prints the "Trajectory (twist) accuracy" table:
/// `cargo test --release --test trajectory accuracy_table -- --ignored --nocapture`.
#[test]
#[ignore = "prints the table of docs/accuracy.md"]
fn accuracy_table() {
    println!(
        "| motion | Qc, noise | seeds | RMS v error (m/s) | RMS w error (rad/s) | mean NEES (expect 6) |"
    );
    println!("|---|---|---|---|---|---|");
    let sigma = (0.002, 0.002);
    let row = |name: &str, how: &str, stats: Vec<TwistStats>| {
        let n = stats.len();
        let v = (stats.iter().map(|s| s.rms_v().powi(2)).sum::<f64>() / n as f64).sqrt();
        let w = (stats.iter().map(|s| s.rms_w().powi(2)).sum::<f64>() / n as f64).sqrt();
        let (m, se) = mean_se(&stats.iter().map(|s| s.nees).collect::<Vec<_>>());
        println!("| {name} | {how} | {n} | {v:.5} | {w:.5} | {m:.2} +- {se:.2} |");
    };
    let screw30 = screw(30.0);
    let lively30 = lively(30.0);
    for (name, m) in [
        ("screw, 1.56 rad/s, 30 s", &screw30 as &dyn Motion),
        ("lively sinusoid, to 2 rad/s, 30 s", &lively30),
    ] {
        row(
            name,
            "Qc estimated, noise given",
            noisy_runs(m, 1..=10, true),
        );
        row(name, "both estimated", noisy_runs(m, 1..=10, false));
    }
    let wnoj = |qc: Vector6<f64>, w0: Vector6<f64>, seeds: u64, known: bool| -> Vec<TwistStats> {
        (1..=seeds)
            .map(|seed| {
                let m = SampledMotion::wnoj(seed, 20.0, qc.into(), w0).expect("motion");
                let poses = noisy_poses(&m, 20.0, seed, sigma, false);
                let opts = if known {
                    FitOptions {
                        qc: Some(qc),
                        pose_sigma: Some(sigma),
                        ..FitOptions::default()
                    }
                } else {
                    FitOptions::default()
                };
                let traj = Trajectory::fit(&poses, &opts).expect("fit");
                twist_stats(&traj, &m, &random_times(&traj, 50, seed))
            })
            .collect()
    };
    let fast = Vector6::new(0.0, 0.0, 0.0, 1.2, -0.8, 0.4);
    row(
        "WNOJ prior draw (sim Prior), 20 s",
        "both given (true)",
        wnoj(prior_qc(), prior_initial_twist(), 40, true),
    );
    row(
        "WNOJ prior draw (sim Prior), 20 s",
        "both estimated",
        wnoj(prior_qc(), prior_initial_twist(), 20, false),
    );
    row(
        "WNOJ Qc 1e-6 from rest, 20 s",
        "both given (true)",
        wnoj(Vector6::repeat(1e-6), Vector6::zeros(), 40, true),
    );
    row(
        "WNOJ Qc 1e-6 about w0 = 1.5 rad/s, 20 s",
        "both given (true)",
        wnoj(Vector6::repeat(1e-6), fast, 40, true),
    );
    row(
        "WNOJ Qc 1e-6 about w0 = 1.5 rad/s, 20 s",
        "both estimated",
        wnoj(Vector6::repeat(1e-6), fast, 20, false),
    );
}
