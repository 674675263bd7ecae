//! The paper's dense GP regression (eqs. (8)-(10), with `K_1^-1`) against the block-tridiagonal
//! fit, in the case where the two are the same model: pure translation with identity rotation.
//!
//! With `R = I` the SE(3) local variable between knots is `xi = [p(t) - p_k; 0]`, so the
//! white-noise-on-jerk GP on SE(3) becomes, per axis, a linear triple integrator with state
//! `[p, p', p'']`. Its kernel, started at the first pose time `t0` with `x(t0) ~ N(0, P0)`, is
//! `K(a, b) = (Phi(a - t0) P0 Phi(a - t0)^T + Qc Q(a - t0)) Phi(b - a)^T` for `a <= b`. A broad
//! `P0` stands in for the sparse fit's flat prior on its first knot.
//!
//! Tolerances: twists agree to 3e-4 of the largest twist and twist covariances to 1e-3 of their
//! largest variance (the differences are about 1e-5 inside the span and reach 1e-4 at the last
//! knot). What is left comes from two places: the sparse fit linearises the SE(3) maps, whose
//! translation-rotation coupling (`1/2 rho^ w` in `J_r^-1`) adds a covariance term that grows with
//! the speed and is absent from the linear model; and `K_1` is badly conditioned (eigenvalues from
//! `Qc dt^5 / 20` to `P0 T^4`), so its explicit inverse loses digits as `P0` grows. `P0 = 1e2`
//! (10 m, 10 m/s, 10 m/s^2 standard deviations) is flat next to the data, which pin the first
//! knot to millimetres and centimetres per second; with `P0 = 1e4` the covariances still agree to
//! 3e-2, with `P0 = 1e6` only to 0.7 (loss of precision in `K_1^-1`, not a model difference).
//!
//! `cargo test --release --test dense_gp` checks agreement; the timing table (dense is O(N^3)) is
//! `cargo test --release --test dense_gp -- --ignored --nocapture`.

use std::time::Instant;

use dvlcal::calib::closed_form::{ClosedFormRow, closed_form};
use dvlcal::calib::model::predict;
use dvlcal::lie::{Se3, so3};
use dvlcal::rng::Rng;
use dvlcal::trajectory::gp::{phi_scalar, q_scalar};
use dvlcal::trajectory::{FitOptions, Trajectory};
use dvlcal::types::CalibrationParams;
use dvlcal::types::PoseMeasurement;
use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3, Vector6};

const P0: f64 = 1e2;
const QC_T: f64 = 0.5;
const QC_R: f64 = 1e-2;
const SIGMA_T: f64 = 0.003;
const SIGMA_R: f64 = 1e-3;

/// Pure translation: a few sinusoids per axis, identity rotation.
fn position(t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let a = Vector3::new(0.4, 0.3, 0.2);
    let f = Vector3::new(0.11, 0.07, 0.13) * std::f64::consts::TAU;
    let ph = Vector3::new(0.3, 1.1, 2.0);
    let p = Vector3::from_fn(|i, _| a[i] * (f[i] * t + ph[i]).sin() + 0.05 * t);
    let v = Vector3::from_fn(|i, _| a[i] * f[i] * (f[i] * t + ph[i]).cos() + 0.05);
    (p, v)
}

fn poses(n: usize, seed: u64) -> Vec<PoseMeasurement> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|k| {
            let t = k as f64 * 0.1;
            let p = position(t).0 + rng.normal_vec3() * SIGMA_T;
            PoseMeasurement {
                t,
                pose: Se3::new(Matrix3::identity(), p),
                cov: None,
            }
        })
        .collect()
}

/// Prior covariance of the scalar triple integrator at `t` (started at `t0`).
fn marginal(t: f64, t0: f64, qc: f64) -> Matrix3<f64> {
    let ph = phi_scalar(t - t0);
    ph * Matrix3::identity() * P0 * ph.transpose() + q_scalar(t - t0) * qc
}

/// `Cov(x(a), x(b))`.
fn kernel(a: f64, b: f64, t0: f64, qc: f64) -> Matrix3<f64> {
    if a <= b {
        marginal(a, t0, qc) * phi_scalar(b - a).transpose()
    } else {
        phi_scalar(a - b) * marginal(b, t0, qc)
    }
}

fn kernel_matrix(ta: &[f64], tb: &[f64], t0: f64, qc: f64) -> DMatrix<f64> {
    let mut k = DMatrix::zeros(3 * ta.len(), 3 * tb.len());
    for (i, &a) in ta.iter().enumerate() {
        for (j, &b) in tb.iter().enumerate() {
            k.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                .copy_from(&kernel(a, b, t0, qc));
        }
    }
    k
}

/// Dense GP regression of one scalar channel (all channels share the times).
struct DenseGp {
    times: Vec<f64>,
    t0: f64,
    qc: f64,
    /// LU factors of `K_1` (too ill-conditioned for a Cholesky factorisation beyond a few
    /// seconds of data: its eigenvalues range from `Qc dt^5 / 20` to `P0 T^4`).
    k1: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
    /// `K_1 - Sigma_Xb`.
    k1_minus_sigma: DMatrix<f64>,
    /// Posterior means `X_b` of each channel (columns).
    xb: DMatrix<f64>,
}

impl DenseGp {
    /// `y`: one column per channel, one row per time; noise `sigma`.
    fn fit(times: &[f64], y: &DMatrix<f64>, qc: f64, sigma: f64) -> DenseGp {
        let n = times.len();
        let t0 = times[0];
        let k1 = kernel_matrix(times, times, t0, qc);
        // H picks the position of each state.
        let h = DMatrix::from_fn(n, 3 * n, |i, j| if j == 3 * i { 1.0 } else { 0.0 });
        let k1ht = &k1 * h.transpose();
        let s = &h * &k1ht + DMatrix::identity(n, n) * (sigma * sigma);
        let s = s.lu();
        // X_b = mu + K1 H^T (R + H K1 H^T)^-1 (M - H mu), mu = 0.
        let xb = &k1ht * s.solve(y).expect("R + H K1 H^T is invertible");
        // K1 - Sigma_Xb = K1 H^T (R + H K1 H^T)^-1 H K1.
        let k1_minus_sigma = &k1ht
            * s.solve(&k1ht.transpose())
                .expect("R + H K1 H^T is invertible");
        DenseGp {
            times: times.to_vec(),
            t0,
            qc,
            k1: k1.lu(),
            k1_minus_sigma,
            xb,
        }
    }

    /// Posterior means (3 states x channels per time) and covariances (3x3 per time) at `tq`:
    /// `X_d = mu_2 - K3 K1^-1 (mu_1 - X_b)`,
    /// `Sigma_Xd = K4 - K3 K1^-1 (K1 - Sigma_Xb) K1^-1 K2`.
    fn query(&self, tq: &[f64]) -> (DMatrix<f64>, Vec<Matrix3<f64>>) {
        let k2 = kernel_matrix(&self.times, tq, self.t0, self.qc);
        // A^T = K1^-1 K2, A = K3 K1^-1 (K3 = K2^T).
        let at = self.k1.solve(&k2).expect("K1 is invertible");
        let xd = at.transpose() * &self.xb;
        let b = &self.k1_minus_sigma * &at;
        let covs = (0..tq.len())
            .map(|i| {
                let k4 = marginal(tq[i], self.t0, self.qc);
                let ai = at.columns(3 * i, 3);
                let bi = b.columns(3 * i, 3);
                let c: Matrix3<f64> =
                    k4 - Matrix3::from_iterator((ai.transpose() * bi).iter().copied());
                (c + c.transpose()) * 0.5
            })
            .collect();
        (xd, covs)
    }
}

/// Twists `[v; w]` and their 6x6 covariances from the dense GP (rotation channels measured at 0).
fn dense_twists(p: &[PoseMeasurement], tq: &[f64]) -> Vec<(Vector6<f64>, Matrix6<f64>)> {
    let times: Vec<f64> = p.iter().map(|m| m.t).collect();
    let y = DMatrix::from_fn(p.len(), 3, |i, j| p[i].pose.trans[j]);
    let trans = DenseGp::fit(&times, &y, QC_T, SIGMA_T);
    let rot = DenseGp::fit(&times, &DMatrix::zeros(p.len(), 1), QC_R, SIGMA_R);
    let (mt, ct) = trans.query(tq);
    let (_, cr) = rot.query(tq);
    (0..tq.len())
        .map(|i| {
            let v = Vector3::new(mt[(3 * i + 1, 0)], mt[(3 * i + 1, 1)], mt[(3 * i + 1, 2)]);
            let mut cov = Matrix6::zeros();
            for a in 0..3 {
                cov[(a, a)] = ct[i][(1, 1)];
                cov[(a + 3, a + 3)] = cr[i][(1, 1)];
            }
            (Vector6::new(v.x, v.y, v.z, 0.0, 0.0, 0.0), cov)
        })
        .collect()
}

fn fit_options() -> FitOptions {
    FitOptions {
        qc: Some(Vector6::new(QC_T, QC_T, QC_T, QC_R, QC_R, QC_R)),
        pose_sigma: Some((SIGMA_T, SIGMA_R)),
        ..FitOptions::default()
    }
}

fn sparse_twists(p: &[PoseMeasurement], tq: &[f64]) -> Vec<(Vector6<f64>, Matrix6<f64>)> {
    let traj = Trajectory::fit(p, &fit_options()).expect("fit");
    tq.iter()
        .map(|&t| {
            let q = traj.query(t).expect("query");
            (q.twist, q.twist_cov.expect("covariance"))
        })
        .collect()
}

fn query_times(p: &[PoseMeasurement], m: usize, seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let (a, b) = (p[0].t, p[p.len() - 1].t);
    (0..m).map(|_| rng.uniform_in(a, b)).collect()
}

/// Largest difference of twists relative to the largest twist, and of covariances relative to
/// the largest twist variance of the same block.
fn differences(
    d: &[(Vector6<f64>, Matrix6<f64>)],
    s: &[(Vector6<f64>, Matrix6<f64>)],
) -> (f64, f64) {
    let tw_scale = d.iter().map(|x| x.0.amax()).fold(0.0, f64::max);
    let mut dt: f64 = 0.0;
    let mut dc: f64 = 0.0;
    for (a, b) in d.iter().zip(s) {
        dt = dt.max((a.0 - b.0).amax() / tw_scale);
        for blk in [0, 3] {
            let ca = a.1.fixed_view::<3, 3>(blk, blk);
            let cb = b.1.fixed_view::<3, 3>(blk, blk);
            dc = dc.max((ca - cb).amax() / ca.diagonal().max());
        }
    }
    (dt, dc)
}

const TOL_TWIST: f64 = 3e-4;
const TOL_COV: f64 = 1e-3;
const TOL_CALIB: f64 = 1e-4;

#[test]
fn dense_and_block_tridiagonal_posteriors_agree() {
    let p = poses(60, 1);
    let tq = query_times(&p, 40, 2);
    let d = dense_twists(&p, &tq);
    let s = sparse_twists(&p, &tq);
    let (dt, dc) = differences(&d, &s);
    println!("twist max rel diff {dt:.2e}, twist covariance max rel diff {dc:.2e}");
    assert!(dt < TOL_TWIST, "twists differ by {dt:e} (relative)");
    assert!(
        dc < TOL_COV,
        "twist covariances differ by {dc:e} (relative)"
    );
    // The translational velocity is well inside the truth's reach too.
    for (t, x) in tq.iter().zip(&s) {
        let v = position(*t).1;
        assert!((x.0.fixed_rows::<3>(0) - v).amax() < 0.1);
    }
}

#[test]
fn closed_form_from_dense_and_sparse_twists_agrees() {
    let p = poses(60, 3);
    let truth = CalibrationParams::from_r_dvl_cam(
        so3::exp(&Vector3::new(-1.5, 0.04, 0.03)),
        Vector3::zeros(),
        1.01,
        0.0,
    );
    let tq = query_times(&p, 50, 4);
    let mut rng = Rng::new(5);
    let v_dvl: Vec<Vector3<f64>> = tq
        .iter()
        .map(|&t| {
            let v = position(t).1;
            predict(&truth, &Vector6::new(v.x, v.y, v.z, 0.0, 0.0, 0.0)) + rng.normal_vec3() * 0.01
        })
        .collect();
    let rows = |tw: &[(Vector6<f64>, Matrix6<f64>)]| -> Vec<ClosedFormRow> {
        tw.iter()
            .zip(&v_dvl)
            .map(|(x, v)| ClosedFormRow {
                v_dvl: *v,
                twist: x.0,
                twist_cov: x.1,
            })
            .collect()
    };
    let d = closed_form(&rows(&dense_twists(&p, &tq)), true).expect("dense");
    let s = closed_form(&rows(&sparse_twists(&p, &tq)), true).expect("sparse");
    // Pure translation does not excite the lever arm: both leave it unsolved.
    assert!(!d.lever_arm_solved && !s.lever_arm_solved);
    let rot = so3::log(&(d.params.r_dvl_cam() * s.params.r_dvl_cam().transpose())).norm();
    let scale = (d.params.velocity_scale - s.params.velocity_scale).abs();
    println!("closed form dense vs sparse: rotation {rot:.2e} rad, scale {scale:.2e}");
    assert!(
        rot < TOL_CALIB && scale < TOL_CALIB,
        "rotation {rot:e} rad, scale {scale:e}"
    );
}

#[test]
#[ignore = "timing table; run with --ignored --nocapture"]
fn dense_vs_sparse_timing() {
    println!(
        "| poses | dense fit + N queries | block-tridiagonal fit + N queries | dense / sparse | \
         twist max rel diff | covariance max rel diff |"
    );
    println!("|---|---|---|---|---|---|");
    for n in [50, 100, 200, 400, 800] {
        let p = poses(n, 7);
        let tq = query_times(&p, n, 8);
        let t0 = Instant::now();
        let d = dense_twists(&p, &tq);
        let td = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let s = sparse_twists(&p, &tq);
        let ts = t0.elapsed().as_secs_f64();
        let (dt, dc) = differences(&d, &s);
        println!(
            "| {n} | {td:.4} s | {ts:.4} s | {:.0} | {dt:.1e} | {dc:.1e} |",
            td / ts
        );
    }
}
