//! The joint problem's normal equations against differences of its whole cost: the gradient
//! `-J^T W e` of every knot variable (the trajectory's and the biases') and every calibration
//! column (the IMU's and the DVL's) is half the cost's derivative, and held columns carry none.

use nalgebra::{DVector, Matrix3, Matrix6, Vector3, Vector6};

use super::*;
use crate::calib::imu::bins::ImuBin;
use crate::calib::imu::state::BiasNodes;
use crate::lie::{Se3, so3};
use crate::trajectory::blocktri::BlockTridiagonal;
use crate::types::CalibrationParams;
use crate::types::imu::{ImuBias, STANDARD_GRAVITY};

fn knots(n: usize) -> (Vec<f64>, Vec<Knot>) {
    let times: Vec<f64> = (0..n).map(|i| 0.025 * i as f64).collect();
    let knots = times
        .iter()
        .map(|&t| Knot {
            pose: Se3::exp(&Vector6::new(
                0.3 * t,
                -0.1,
                0.2 * t,
                0.4 * t,
                -0.3 + t,
                0.2,
            )),
            twist: Vector6::new(0.3, 0.1 - t, -0.2, 0.5 * t, -0.4, 0.3 + t),
            rate: Vector6::new(-0.1, 0.3 * t, 0.05, 0.2, 0.1 * t, -0.4),
        })
        .collect();
    (times, knots)
}

fn state(dvl: bool) -> ImuState {
    let mut bias = BiasNodes::spanning(
        0.0,
        0.15,
        0.1,
        ImuBias {
            gyro: Vector3::new(0.01, 0.02, -0.01),
            accel: Vector3::new(0.1, -0.2, 0.05),
        },
    );
    bias.values[1].accel.y = -0.1;
    // One bias per knot of [`knots`], linear between the nodes above (0.025 s apart, walking).
    let times: Vec<f64> = (0..7).map(|i| 0.025 * i as f64).collect();
    let bias = bias.resampled(&times, 0.0);
    ImuState {
        t_cam_imu: Se3::new(
            so3::exp(&Vector3::new(0.4, 1.1, -0.3)),
            Vector3::new(0.1, -0.05, 0.2),
        ),
        time_offset_s: 0.004,
        gravity_rotation: so3::exp(&Vector3::new(0.2, -0.1, 0.4)),
        gravity_magnitude: STANDARD_GRAVITY,
        bias,
        dvl: dvl.then(|| {
            CalibrationParams::from_r_dvl_cam(
                so3::exp(&Vector3::new(1.2, -0.3, 0.4)),
                Vector3::new(0.05, 0.25, -0.1),
                1.02,
                0.007,
            )
        }),
    }
}

fn bins() -> Vec<ImuBin> {
    (0..14)
        .map(|j| ImuBin {
            t: 0.003 + 0.011 * j as f64,
            gyro: Vector3::new(0.1, -0.3 + 0.01 * j as f64, 0.2),
            accel: Vector3::new(0.5, 9.0, -2.0 + 0.1 * j as f64),
            n: 2,
        })
        .collect()
}

fn dvl_obs() -> Vec<DvlObs> {
    (0..5)
        .map(|j| DvlObs {
            t: 0.01 + 0.03 * j as f64,
            v: Vector3::new(0.2, -0.1 * j as f64, 0.3),
            cov: Matrix3::identity() * 1e-4,
        })
        .collect()
}

/// The problem on `ks`: a pose on the first knot, the bins, the DVL's velocities, the lever
/// arm's x and the clock offset held.
fn joint<'a>(times: &[f64], ks: &[Knot], bins: &'a [ImuBin], dvl: &'a [DvlObs]) -> ImuJoint<'a> {
    let mut poses = vec![None; times.len()];
    poses[0] = Some((
        ks[0].pose * Se3::exp(&Vector6::from_element(0.01)),
        Matrix6::identity() * 1e3,
    ));
    ImuJoint {
        times: times.to_vec(),
        poses: SparsePoseFactors {
            poses,
            between: Vec::new(),
        },
        density: JerkDensity::constant(Vector6::from_element(1e5)),
        bins,
        info: vec![Vector6::from_element(50.0); bins.len()],
        noise: ImuNoise {
            accelerometer_noise_density: 4e-3,
            accelerometer_random_walk: 1e-3,
            gyroscope_noise_density: 3e-4,
            gyroscope_random_walk: 4e-5,
            update_rate: 200.0,
        },
        held: vec![3, 6],
        dvl,
        dvl_info: dvl.iter().map(|o| o.information().expect("info")).collect(),
        windows: None,
    }
}

#[test]
fn the_gradient_matches_differences_of_the_cost_with_a_dvl_and_held_columns() {
    let (times, ks) = knots(7);
    let (bins, dvl) = (bins(), dvl_obs());
    let joint = joint(&times, &ks, &bins, &dvl);
    let st = state(true);
    let mut sys = BlockTridiagonal::<KB>::zeros(ks.len());
    let lin = joint.linearise(&ks, &st, &mut sys);
    assert!((lin.cost - joint.cost(&ks, &st)).abs() < 1e-9 * lin.cost.max(1.0));
    // Round-off in the differences: about the cost times 1e-16 over the step.
    let noise = |h: f64| lin.cost * 1e-15 / h;
    assert!(
        noise(1e-5) < 1e-3,
        "cost {} too large for the differences",
        lin.cost
    );
    // Calibration columns.
    for c in 0..st.dim() {
        let h = 1e-5;
        let mut d = DVector::zeros(st.dim());
        d[c] = h;
        let num =
            -(joint.cost(&ks, &st.retract(&d)) - joint.cost(&ks, &st.retract(&-d))) / (4.0 * h);
        if joint.held.contains(&c) {
            assert_eq!(lin.gth[c], 0.0, "held column {c}");
            assert!(lin.cross.dense().column(c).iter().all(|x| *x == 0.0));
            continue;
        }
        assert!(
            (num - lin.gth[c]).abs() < 1e-4 * num.abs() + noise(h),
            "column {c}: numeric {num} vs {}",
            lin.gth[c]
        );
    }
    // Knot variables: the trajectory's, then the biases'.
    for k in 0..ks.len() {
        for i in 0..KB {
            let h = 1e-5;
            let (up, down) = if i < 18 {
                let mut dx = vec![V18::zeros(); ks.len()];
                dx[k][i] = h;
                (
                    joint.cost(&step(&ks, &dx, 1.0), &st),
                    joint.cost(&step(&ks, &dx, -1.0), &st),
                )
            } else {
                let mut db = vec![Vector6::zeros(); ks.len()];
                db[k][i - 18] = h;
                (
                    joint.cost(&ks, &st.clone().with_bias_step(&db, 1.0)),
                    joint.cost(&ks, &st.clone().with_bias_step(&db, -1.0)),
                )
            };
            let num = -(up - down) / (4.0 * h);
            let ana = sys.rhs[k][i];
            assert!(
                (num - ana).abs() < 1e-4 * num.abs() + noise(h),
                "knot {k} variable {i}: numeric {num} vs {ana}"
            );
        }
    }
}

/// The whole problem's information matrix (knots, then `theta`) and right-hand side, dense.
fn dense_system(
    sys: &BlockTridiagonal<KB>,
    lin: &Linear,
    n: usize,
) -> (nalgebra::DMatrix<f64>, DVector<f64>) {
    let (nx, p) = (KB * n, lin.hth.nrows());
    let mut h = nalgebra::DMatrix::zeros(nx + p, nx + p);
    let mut g = DVector::zeros(nx + p);
    for k in 0..n {
        h.view_mut((KB * k, KB * k), (KB, KB))
            .copy_from(&sys.diag[k]);
        g.rows_mut(KB * k, KB).copy_from(&sys.rhs[k]);
        if k + 1 < n {
            h.view_mut((KB * k, KB * (k + 1)), (KB, KB))
                .copy_from(&sys.upper[k]);
            h.view_mut((KB * (k + 1), KB * k), (KB, KB))
                .copy_from(&sys.upper[k].transpose());
        }
    }
    let cross = lin.cross.dense();
    h.view_mut((0, nx), (nx, p)).copy_from(&cross);
    h.view_mut((nx, 0), (p, nx)).copy_from(&cross.transpose());
    h.view_mut((nx, nx), (p, p)).copy_from(&lin.hth);
    g.rows_mut(nx, p).copy_from(&lin.gth);
    (h, g)
}

#[test]
fn the_streamed_schur_and_the_chunked_redundancy_match_the_dense_problem() {
    let (times, ks) = knots(7);
    let (bins, dvl) = (bins(), dvl_obs());
    let mut joint = joint(&times, &ks, &bins, &dvl);
    // Poses on every knot and informative bins, so that the dense inverse the results are
    // compared with is accurate (with a pose on the first knot alone, the accelerometer's bias
    // and the knots' accelerations are nearly confounded over 0.15 s).
    for (k, pose) in joint.poses.poses.iter_mut().enumerate() {
        let d = Vector6::from_element(1e-3 * k as f64);
        *pose = Some((ks[k].pose * Se3::exp(&d), Matrix6::identity() * 1e8));
    }
    joint.info = vec![Vector6::from_element(1e4); bins.len()];
    let n = ks.len();
    // Theta of 17 columns: the IMU's 9 and the DVL's 8.
    {
        let mut st = state(true);
        for (i, b) in st.bias.values.iter_mut().enumerate() {
            b.accel.y -= 0.01 * i as f64;
        }
        let p = st.dim();
        assert_eq!(p, 17);
        let mut sys = BlockTridiagonal::<KB>::zeros(n);
        let lin = joint.linearise(&ks, &st, &mut sys);
        let (h, g) = dense_system(&sys, &lin, n);
        let nx = KB * n;
        // The knots' block is well conditioned (poses on every knot); the calibration's Schur
        // complement is not (0.15 s of motion), so it is compared as information, and the
        // covariance below is built from it.
        let a_chol = h
            .view((0, 0), (nx, nx))
            .into_owned()
            .cholesky()
            .expect("knots");
        let a_inv = a_chol.inverse();
        let cross = h.view((0, nx), (nx, p)).into_owned();
        let x = a_chol.solve(&cross);
        let schur = h.view((nx, nx), (p, p)) - cross.transpose() * &x;
        let s_red = g.rows(nx, p) - x.transpose() * g.rows(0, nx);
        let factor = sys.clone().factor().expect("factor");
        let (_, har, _) = schur_forms(&factor, &lin.cross);
        // Relative to the terms it is the difference of (the random walks' and the poses'
        // information make both large).
        let xtr = x.transpose() * g.rows(0, nx);
        let scale = lin.gth.amax() + xtr.amax();
        let err = (&lin.gth - har - &s_red).amax();
        assert!(
            err < 1e-10 * scale,
            "p {p}: reduced gradient off by {err} of {scale}"
        );
        let step = joint.step(&lin, sys).expect("step");
        let err = (&step.schur - &schur).amax();
        assert!(
            err < 1e-9 * schur.amax(),
            "p {p}: Schur complement off by {err} of {}",
            schur.amax()
        );
        let err = (&step.schur * &step.dth - &s_red).amax();
        // The Cholesky solution's backward error (its forward error is the condition's).
        let bound = 1e-12 * step.schur.amax() * step.dth.amax() * p as f64;
        assert!(
            err < bound,
            "p {p}: calibration step off by {err} (bound {bound})"
        );
        // The whole step solves the whole system: its residual is a backward error (the
        // knots' accelerations and the accelerometer's biases are nearly confounded over
        // 0.15 s, so a forward comparison with a dense solve would measure the condition).
        let mut z = DVector::zeros(nx + p);
        for k in 0..n {
            z.rows_mut(KB * k, KB).copy_from(&step.dx[k]);
        }
        z.rows_mut(nx, p).copy_from(&step.dth);
        // Row by row, against the magnitudes its terms cancel from (`|H| |z|`).
        let residual = &h * &z - &g;
        let magnitude = h.abs() * z.abs();
        for i in 0..nx + p {
            let bound = 1e-10 * magnitude[i] + 1e-300;
            assert!(
                residual[i].abs() <= bound,
                "p {p}: the step's residual in row {i} is {} (bound {bound})",
                residual[i]
            );
        }
        let decrement =
            (g.rows(0, nx).transpose() * &a_inv * g.rows(0, nx))[0] + s_red.dot(&step.dth);
        assert!((step.decrement - decrement).abs() < 1e-9 * decrement);

        // The redundancy from the dense joint covariance, residual block by residual block.
        let s_inv = step.schur.clone().cholesky().expect("schur").inverse();
        let xs = &x * &s_inv;
        let mut cov = nalgebra::DMatrix::zeros(nx + p, nx + p);
        cov.view_mut((0, 0), (nx, nx))
            .copy_from(&(&a_inv + &xs * x.transpose()));
        cov.view_mut((0, nx), (nx, p)).copy_from(&-&xs);
        cov.view_mut((nx, 0), (p, nx)).copy_from(&-xs.transpose());
        cov.view_mut((nx, nx), (p, p)).copy_from(&s_inv);
        let mut want = Redundancy::default();
        let add = |part: &mut (f64, f64),
                   jac: &nalgebra::DMatrix<f64>,
                   w: &nalgebra::DMatrix<f64>,
                   e: &DVector<f64>| {
            let proj = jac * &cov * jac.transpose();
            part.0 += (e.transpose() * w * e)[0];
            part.1 += e.len() as f64 - (w * proj).trace();
        };
        for (j, k, s) in joint.placed(st.time_offset_s) {
            let l = local_state(&ks[k], &ks[k + 1]);
            let mut t = bin_terms((k, &ks[k]), &l, s, times[k + 1] - times[k], &bins[j], &st);
            joint.hold_bin(&mut t.jth);
            let mut jac = nalgebra::DMatrix::zeros(6, nx + p);
            jac.view_mut((0, KB * k), (6, 18)).copy_from(&t.j1);
            jac.view_mut((0, KB * (k + 1)), (6, 18)).copy_from(&t.j2);
            for r in 0..6 {
                jac[(r, KB * k + 18 + r)] = 1.0 - t.u;
                jac[(r, KB * (k + 1) + 18 + r)] = t.u;
            }
            jac.view_mut((0, nx), (6, NFIXED)).copy_from(&t.jth);
            let w = &joint.info[j];
            for (part, r0) in [(&mut want.gyro, 0), (&mut want.accel, 3)] {
                let wd = nalgebra::DMatrix::from_diagonal(&w.rows(r0, 3).into_owned());
                add(
                    part,
                    &jac.rows(r0, 3).into_owned(),
                    &wd,
                    &DVector::from_column_slice(t.e.rows(r0, 3).as_slice()),
                );
            }
        }
        let pd = st.dvl.expect("dvl");
        for (i, k, tau) in joint.placed_dvl(&st) {
            let l = local_state(&ks[k], &ks[k + 1]);
            let t = joint.dvl_terms(&ks, k, tau, &l, i, &pd);
            let mut jac = nalgebra::DMatrix::zeros(3, nx + p);
            jac.view_mut((0, KB * k), (3, 18)).copy_from(&t.j1);
            jac.view_mut((0, KB * (k + 1)), (3, 18)).copy_from(&t.j2);
            jac.view_mut((0, nx + st.dvl_start()), (3, NPARAM))
                .copy_from(&t.jth);
            let w = nalgebra::DMatrix::from_column_slice(3, 3, joint.dvl_info[i].as_slice());
            add(
                &mut want.dvl,
                &jac,
                &w,
                &DVector::from_column_slice(t.e.as_slice()),
            );
        }
        let got = joint.redundancy(&ks, &st).expect("redundancy");
        // The redundancy is the blocks' dimension less a trace nearly as large: its error is
        // relative to the dimension (and limited by the dense inverse on this ill-conditioned
        // problem: an error of bookkeeping would be of order one).
        for (name, a, b, dim) in [
            ("gyro", got.gyro, want.gyro, 3 * bins.len()),
            ("accel", got.accel, want.accel, 3 * bins.len()),
            ("dvl", got.dvl, want.dvl, 3 * dvl.len()),
        ] {
            assert!(
                (a.0 - b.0).abs() < 1e-9 * b.0,
                "p {p} {name} chi-square {a:?} vs {b:?}"
            );
            assert!(
                (a.1 - b.1).abs() < 1e-7 * dim as f64,
                "p {p} {name} redundancy {a:?} vs {b:?}"
            );
        }
        // The redundancies are the blocks' dimensions less a share of the parameters.
        assert!(got.gyro.1 > 0.0 && got.gyro.1 < 3.0 * bins.len() as f64);
    }
}

/// The bins' terms are computed in parallel and summed in their order: the normal equations,
/// the cost and the redundancy are the same to the bit on one thread as on two or three, over
/// enough bins for several blocks of work.
#[test]
fn the_sums_do_not_depend_on_the_number_of_threads() {
    let (times, ks) = knots(400);
    let many: Vec<ImuBin> = (0..600)
        .map(|j| ImuBin {
            t: 0.003 + 0.016 * j as f64,
            gyro: Vector3::new(0.1, -0.3 + 1e-3 * j as f64, 0.2),
            accel: Vector3::new(0.5, 9.0, -2.0 + 1e-2 * (j % 7) as f64),
            n: 3,
        })
        .collect();
    let dvl = dvl_obs();
    let mut joint = joint(&times, &ks, &many, &dvl);
    for (k, pose) in joint.poses.poses.iter_mut().enumerate().step_by(4) {
        *pose = Some((ks[k].pose, Matrix6::identity() * 1e6));
    }
    let mut st = state(true);
    st.bias = BiasNodes::spanning(0.0, 10.0, 3.0, st.bias.values[0]).resampled(&times, 0.0);
    for (i, b) in st.bias.values.iter_mut().enumerate() {
        b.gyro.x += 1e-5 * (i % 5) as f64;
    }
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let mut sys = BlockTridiagonal::<KB>::zeros(ks.len());
            let lin = joint.linearise(&ks, &st, &mut sys);
            let red = joint.redundancy(&ks, &st).expect("redundancy");
            let blocks: Vec<f64> = sys
                .diag
                .iter()
                .chain(&sys.upper)
                .flat_map(|m| m.iter().copied())
                .chain(sys.rhs.iter().flat_map(|v| v.iter().copied()))
                .collect();
            (
                blocks,
                lin.cross.dense(),
                lin.hth,
                lin.gth,
                lin.cost,
                joint.cost(&ks, &st),
                [red.gyro, red.accel, red.dvl],
            )
        })
    };
    let one = run(1);
    assert!(one.1.iter().any(|x| *x != 0.0) && one.6[0].1 > 0.0);
    for threads in [2, 3] {
        let other = run(threads);
        let same = one.0 == other.0
            && one.1 == other.1
            && one.2 == other.2
            && one.3 == other.3
            && one.4.to_bits() == other.4.to_bits()
            && one.5.to_bits() == other.5.to_bits()
            && one.6 == other.6;
        assert!(same, "{threads} threads give other sums than one");
    }
}

/// A windows problem on a simulated IMU: `n` knots 0.1 s apart at the truth of a lively motion,
/// a pose on every fourth, the IMU preintegrated between them, nothing held.
fn windows_problem(
    n: usize,
) -> (
    Vec<f64>,
    Vec<Knot>,
    ImuState,
    Vec<crate::types::imu::ImuSample>,
    ImuNoise,
) {
    use crate::sim::imu::{ImuSimConfig, simulate_imu};
    use crate::sim::motion::{Motion, SinusoidMotion};
    let span = 0.1 * n as f64 + 2.0;
    let motion = SinusoidMotion::lively(span).expect("motion");
    let cfg = ImuSimConfig::default_truth();
    let imu = simulate_imu(&motion, &cfg, 0.0, span, 5).expect("imu");
    let times: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
    let ks = times
        .iter()
        .map(|&t| {
            let s = motion.state(t);
            Knot {
                pose: s.pose,
                twist: s.twist,
                rate: s.twist_rate,
            }
        })
        .collect();
    let st = ImuState {
        t_cam_imu: cfg.t_cam_imu,
        time_offset_s: cfg.time_offset_s,
        gravity_rotation: ImuState::gravity_rotation_of(&cfg.gravity_world),
        gravity_magnitude: cfg.gravity_world.norm(),
        bias: BiasNodes::spanning(0.0, span, span / 3.0, cfg.initial_bias)
            .resampled(&times, cfg.time_offset_s),
        dvl: None,
    };
    (times, ks, st, imu.samples, cfg.noise)
}

/// The windows' normal equations, filled in parallel runs of knots, equal a plain loop over the
/// windows (to rounding: at the runs' boundaries and in the sums on `theta` the order differs),
/// on enough knots for three runs.
#[test]
fn the_windows_in_runs_match_a_plain_loop() {
    let (times, ks, st, samples, noise) = windows_problem(2 * RUN + 90);
    let n = ks.len();
    let mut joint = joint(&times, &ks, &[], &[]);
    joint.held.clear();
    joint.noise = noise;
    // Without windows (and without bins): the prior, the pose and the bias walks alone.
    let mut want = BlockTridiagonal::<KB>::zeros(n);
    let base = joint.linearise(&ks, &st, &mut want);
    let w = Windows::new(
        &samples,
        &times,
        &st,
        &noise,
        Windows::stated_variances(&noise),
    );
    let (mut cross, mut hth, mut gth, mut cost) = (base.cross, base.hth, base.gth, base.cost);
    let mut count = 0;
    for k in 0..n - 1 {
        let Some(t) = joint.window_at(&w, &ks, k, &st) else {
            continue;
        };
        cost += window_normal(k, &t).add_into(&mut want, &mut cross, (&mut hth, &mut gth));
        count += 1;
    }
    assert_eq!(count, n - 1, "every window covered");
    joint.windows = Some(w);
    let mut sys = BlockTridiagonal::<KB>::zeros(n);
    let lin = joint.linearise(&ks, &st, &mut sys);
    let close = |a: &[f64], b: &[f64], what: &str| {
        let scale = b.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let diff = a
            .iter()
            .zip(b)
            .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(
            scale > 0.0 && diff <= 1e-12 * scale,
            "{what}: {diff} of {scale}"
        );
    };
    let flat = |s: &BlockTridiagonal<KB>| -> Vec<f64> {
        s.diag
            .iter()
            .chain(&s.upper)
            .flat_map(|m| m.iter().copied())
            .chain(s.rhs.iter().flat_map(|v| v.iter().copied()))
            .collect()
    };
    close(&flat(&sys), &flat(&want), "knots' system");
    close(
        lin.cross.dense().as_slice(),
        cross.dense().as_slice(),
        "coupling",
    );
    close(lin.hth.as_slice(), hth.as_slice(), "calibration block");
    close(lin.gth.as_slice(), gth.as_slice(), "calibration gradient");
    close(&[lin.cost], &[cost], "cost");
}

/// Sets up `joint` for the windows' tests: a pose on every fourth knot (`ks`'), the windows
/// integrated from `samples` at `st`, with `noise`.
fn with_poses_and_windows(
    joint: &mut ImuJoint,
    ks: &[Knot],
    st: &ImuState,
    samples: &[crate::types::imu::ImuSample],
    noise: &ImuNoise,
) {
    joint.noise = *noise;
    for (k, pose) in joint.poses.poses.iter_mut().enumerate().step_by(4) {
        *pose = Some((ks[k].pose, Matrix6::identity() * 1e6));
    }
    joint.windows = Some(Windows::new(
        samples,
        &joint.times,
        st,
        noise,
        Windows::stated_variances(noise),
    ));
}

/// The redundancy a solve's kept linearisation gives equals the one built again at its
/// solution, and a second call (nothing kept any more) builds it again.
#[test]
fn the_redundancy_from_the_kept_linearisation_equals_one_built_again() {
    let (times, ks, st, samples, noise) = windows_problem(120);
    let mut joint = joint(&times, &ks, &[], &[]);
    with_poses_and_windows(&mut joint, &ks, &st, &samples, &noise);
    let mut sol = joint.solve(ks.clone(), st, 10).expect("solve");
    // Kept a step behind the solution, the traces come from the point before it: they may
    // differ in the sixth digit, the chi-squares not at all.
    let trace_tol = match sol.kept_behind() {
        Some(true) => 1e-6,
        Some(false) => 1e-9,
        None => panic!("the solve kept no linearisation"),
    };
    let built = joint.redundancy(&sol.knots, &sol.state).expect("built");
    let kept = joint.redundancy_of(&mut sol).expect("kept");
    assert!(sol.kept_behind().is_none());
    let again = joint.redundancy_of(&mut sol).expect("again");
    for (a, b, c) in [
        (built.gyro, kept.gyro, again.gyro),
        (built.accel, kept.accel, again.accel),
    ] {
        assert!(a.1 > 1.0, "{a:?}");
        for (x, y, tol) in [
            (a.0, b.0, 1e-9),
            (a.1, b.1, trace_tol),
            (a.0, c.0, 1e-9),
            (a.1, c.1, 1e-9),
        ] {
            assert!((x - y).abs() <= tol * x.abs().max(1.0), "{a:?} {b:?} {c:?}");
        }
    }
}

#[test]
fn a_solve_stops_where_another_would_take_no_step() {
    // From a start well away (knots and calibration perturbed), Gauss-Newton with its stopping
    // rules, including the one that takes a last step without linearising after it: solving
    // again from where it stopped must find nothing left to do.
    let (times, ks, st, samples, noise) = windows_problem(120);
    let mut joint = joint(&times, &ks, &[], &[]);
    with_poses_and_windows(&mut joint, &ks, &st, &samples, &noise);
    let mut start = st.clone();
    let mut d = DVector::<f64>::zeros(start.dim());
    for (i, v) in [0.05, -0.08, 0.06, 0.05, -0.04, 0.06].iter().enumerate() {
        d[i] = *v;
    }
    start = start.retract(&d);
    let knots: Vec<Knot> = ks
        .iter()
        .map(|k| Knot {
            twist: k.twist * 1.1,
            ..*k
        })
        .collect();
    let sol = joint.solve(knots, start, 30).expect("solve");
    assert!(sol.converged);
    assert!(sol.iterations >= 2, "{} iterations", sol.iterations);
    assert_eq!(
        sol.kept_behind(),
        Some(true),
        "the last step was not taken unlinearised"
    );
    let again = joint
        .solve(sol.knots.clone(), sol.state.clone(), 30)
        .expect("again");
    assert_eq!(again.iterations, 0, "solving again took a step");
    assert!(
        (again.cost - sol.cost).abs() <= 1e-9 * sol.cost,
        "{} against {}",
        again.cost,
        sol.cost
    );
}
