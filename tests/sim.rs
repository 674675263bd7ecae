//! Tests of the simulator: random numbers, motions and datasets.

use dvlcal::Error;
use dvlcal::lie::Se3;
use dvlcal::rng::{Rng, splitmix64};
use dvlcal::sim::motion::{
    MeanReversion, Motion, SampledConfig, SampledMotion, ScrewMotion, SinusoidMotion,
};
use dvlcal::sim::{MotionKind, SimConfig, build_motion, dvl_model, simulate};
use nalgebra::{Vector3, Vector6};

// ---------------------------------------------------------------------------------------------
// Random numbers
// ---------------------------------------------------------------------------------------------

#[test]
fn rng_matches_reference_algorithms() {
    // splitmix64 from state 0 (reference output of the published algorithm).
    let mut sm = 0u64;
    assert_eq!(splitmix64(&mut sm), 0xE220_A839_7B1D_CDAF);
    // xoshiro256** from state [1, 2, 3, 4] (reference outputs of the published algorithm).
    let mut r = Rng::from_state([1, 2, 3, 4]);
    let first: Vec<u64> = (0..4).map(|_| r.next_u64()).collect();
    assert_eq!(first, [11520, 0, 1509978240, 1215971899390074240]);
}

#[test]
fn rng_fixed_seed_gives_fixed_values() {
    let mut r = Rng::new(42);
    let bits: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
    assert_eq!(bits, FIXED_BITS);
    let mut r = Rng::new(42);
    let u: Vec<u64> = (0..3).map(|_| r.uniform().to_bits()).collect();
    assert_eq!(u, FIXED_UNIFORM_BITS);
    let mut r = Rng::new(42);
    let n: Vec<u64> = (0..3).map(|_| r.normal().to_bits()).collect();
    assert_eq!(n, FIXED_NORMAL_BITS);
    // Streams are deterministic and distinct.
    assert_eq!(Rng::stream(42, 3), Rng::stream(42, 3));
    assert_ne!(Rng::stream(42, 3).next_u64(), Rng::stream(42, 4).next_u64());
}

// First outputs for seed 42. These must never change: datasets are identified by their seed.
const FIXED_BITS: [u64; 3] = [
    1546998764402558742,
    6990951692964543102,
    12544586762248559009,
];
const FIXED_UNIFORM_BITS: [u64; 3] = [
    4590707384586612416,
    4600498721180566606,
    4604300506050280595,
];
const FIXED_NORMAL_BITS: [u64; 3] = [
    13828088456880829303,
    4597152819617802828,
    4602033494962232142,
];

#[test]
fn rng_moments_are_within_statistical_bounds() {
    let n = 100_000;
    let mut r = Rng::new(7);
    let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
    let mean = xs.iter().sum::<f64>() / n as f64;
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let third = xs.iter().map(|x| x.powi(3)).sum::<f64>() / n as f64;
    let fourth = xs.iter().map(|x| x.powi(4)).sum::<f64>() / n as f64;
    // Five standard errors.
    assert!(mean.abs() < 5.0 / (n as f64).sqrt(), "mean {mean}");
    assert!(
        (var - 1.0).abs() < 5.0 * (2.0 / n as f64).sqrt(),
        "var {var}"
    );
    assert!(third.abs() < 5.0 * (15.0 / n as f64).sqrt(), "skew {third}");
    assert!(
        (fourth - 3.0).abs() < 5.0 * (96.0 / n as f64).sqrt(),
        "kurt {fourth}"
    );

    let us: Vec<f64> = (0..n).map(|_| r.uniform()).collect();
    assert!(us.iter().all(|u| (0.0..1.0).contains(u)));
    let umean = us.iter().sum::<f64>() / n as f64;
    assert!((umean - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());

    let v = r.normal_vec6();
    assert!(v.iter().all(|x| x.is_finite()));
}

// ---------------------------------------------------------------------------------------------
// Motions
// ---------------------------------------------------------------------------------------------

/// Largest difference between the twist and the central difference of the pose at `times`.
fn pose_derivative_error(m: &dyn Motion, times: &[f64], h: f64) -> f64 {
    times
        .iter()
        .map(|&t| {
            let a = m.state(t - h).pose;
            let b = m.state(t + h).pose;
            let numeric = (a.inverse() * b).log() / (2.0 * h);
            (numeric - m.state(t).twist).amax()
        })
        .fold(0.0, f64::max)
}

/// Largest difference between the twist rate and the central difference of the twist.
fn rate_derivative_error(m: &dyn Motion, times: &[f64], h: f64) -> f64 {
    times
        .iter()
        .map(|&t| {
            let numeric = (m.state(t + h).twist - m.state(t - h).twist) / (2.0 * h);
            (numeric - m.state(t).twist_rate).amax()
        })
        .fold(0.0, f64::max)
}

/// Times inside `(0, duration)` that are not grid points of a 1 ms grid.
fn test_times(duration: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = duration * (i as f64 + 0.5) / n as f64;
            (t * 1000.0).floor() / 1000.0 + 0.000_37
        })
        .collect()
}

fn sampled_motions() -> Vec<(&'static str, SampledMotion)> {
    vec![
        (
            "wnoj",
            SampledMotion::wnoj(
                3,
                20.0,
                [0.01, 0.01, 0.01, 0.1, 0.1, 0.1],
                Vector6::new(0.2, -0.1, 0.05, 0.3, -0.2, 0.4),
            )
            .unwrap(),
        ),
        (
            "calm_then_rotate",
            SampledMotion::calm_then_rotate(5, 60.0).unwrap(),
        ),
        (
            "weak_rotation",
            SampledMotion::weak_rotation(5, 30.0).unwrap(),
        ),
    ]
}

#[test]
fn screw_motion_is_exact() {
    let start = Se3::exp(&Vector6::new(1.0, -2.0, 0.5, 0.3, 0.2, -0.1));
    let twist = Vector6::new(0.3, 0.1, -0.2, 0.5, -1.2, 0.8);
    let m = ScrewMotion::new(start, twist, 10.0).unwrap();
    assert_eq!(m.span(), (0.0, 10.0));
    for &t in &[0.0, 0.7, 3.1, 9.9] {
        let s = m.state(t);
        let expected = start * Se3::exp(&(twist * t));
        assert!((s.pose.to_matrix() - expected.to_matrix()).amax() < 1e-15);
        assert_eq!(s.twist, twist);
        assert_eq!(s.twist_rate, Vector6::zeros());
        // A finite step of a constant twist is exact.
        let step = (s.pose.inverse() * m.state(t + 0.5).pose).log() / 0.5;
        assert!((step - twist).amax() < 1e-12);
    }
    assert!(pose_derivative_error(&m, &[1.0, 5.0], 1e-4) < 1e-9);
    assert!(matches!(
        ScrewMotion::new(start, twist, 0.0),
        Err(Error::Input(_))
    ));
}

#[test]
fn sinusoid_motion_twist_and_rate_are_consistent() {
    let m = SinusoidMotion::lively(30.0).unwrap();
    let times = test_times(30.0, 50);
    let e_pose = pose_derivative_error(&m, &times, 2e-5);
    assert!(e_pose < 1e-7, "pose derivative error {e_pose}");
    let e_rate = rate_derivative_error(&m, &times, 1e-5);
    assert!(e_rate < 1e-6, "rate derivative error {e_rate}");
    // Lively: fast rotation and about 0.5 m/s.
    let states: Vec<_> = (0..3000).map(|i| m.state(i as f64 * 0.01)).collect();
    let rms = |f: &dyn Fn(&Vector6<f64>) -> f64| {
        (states.iter().map(|s| f(&s.twist).powi(2)).sum::<f64>() / states.len() as f64).sqrt()
    };
    let w_rms = rms(&|x| x.fixed_rows::<3>(3).norm());
    let v_rms = rms(&|x| x.fixed_rows::<3>(0).norm());
    assert!(w_rms > 1.2, "w rms {w_rms}");
    assert!((0.3..0.8).contains(&v_rms), "v rms {v_rms}");
    assert!(matches!(
        SinusoidMotion::lively(f64::NAN),
        Err(Error::Input(_))
    ));
}

#[test]
fn sampled_motions_twist_matches_pose_derivative() {
    for (name, m) in sampled_motions() {
        let (_, end) = m.span();
        let times = test_times(end, 200);
        // The central difference itself is accurate to about 1e-9 at this step.
        let e = pose_derivative_error(&m, &times, 1e-5);
        assert!(e < 1e-7, "{name}: pose derivative error {e}");
        // Also across grid points (the twist is continuous there).
        let grid: Vec<f64> = (1..20).map(|k| m.grid_time(k * 997)).collect();
        let e = pose_derivative_error(&m, &grid, 1e-5);
        assert!(e < 1e-7, "{name}: pose derivative error at grid points {e}");
    }
}

#[test]
fn sampled_motions_rate_matches_twist_derivative() {
    for (name, m) in sampled_motions() {
        let (_, end) = m.span();
        let times = test_times(end, 200);
        let scale = times
            .iter()
            .map(|&t| m.state(t).twist_rate.amax())
            .fold(1.0, f64::max);
        let e = rate_derivative_error(&m, &times, 1e-6);
        assert!(
            e < 1e-6 * scale,
            "{name}: rate derivative error {e} (scale {scale})"
        );
    }
}

#[test]
fn sampled_motion_states_at_grid_points_equal_the_grid() {
    for (name, m) in sampled_motions() {
        for k in (0..m.grid_len()).step_by(613).chain([m.grid_len() - 1]) {
            let g = m.grid_state(k).unwrap();
            let s = m.state(m.grid_time(k));
            assert_eq!(s, g, "{name}: grid point {k}");
        }
        assert!(m.grid_state(m.grid_len()).is_none());
        // Continuity just before a grid point.
        let t = m.grid_time(5000);
        let a = m.state(t - 1e-9);
        let b = m.grid_state(5000).unwrap();
        assert!((a.pose.inverse() * b.pose).log().amax() < 1e-8, "{name}");
        assert!((a.twist - b.twist).amax() < 1e-6, "{name}");
    }
}

#[test]
fn wnoj_grid_increments_have_the_model_covariance() {
    let qc = [0.5, 1.0, 2.0, 0.1, 0.2, 4.0];
    let m = SampledMotion::wnoj(11, 40.0, qc, Vector6::zeros()).unwrap();
    let dt = m.dt();
    let n = m.grid_len() - 1;
    for (i, &q) in qc.iter().enumerate() {
        let (mut s_rate, mut s_twist) = (0.0, 0.0);
        for k in 0..n {
            let a = m.grid_state(k).unwrap();
            let b = m.grid_state(k + 1).unwrap();
            s_rate += (b.twist_rate[i] - a.twist_rate[i]).powi(2);
            s_twist += (b.twist[i] - a.twist[i] - dt * a.twist_rate[i]).powi(2);
        }
        let var_rate = s_rate / n as f64 / (q * dt);
        let var_twist = s_twist / n as f64 / (q * dt * dt * dt / 3.0);
        let bound = 5.0 * (2.0 / n as f64).sqrt();
        assert!(
            (var_rate - 1.0).abs() < bound,
            "component {i}: rate var ratio {var_rate}"
        );
        assert!(
            (var_twist - 1.0).abs() < bound,
            "component {i}: twist var ratio {var_twist}"
        );
    }
}

fn speeds(m: &SampledMotion, from: f64, to: f64) -> (f64, f64, f64, f64) {
    let states: Vec<_> = (0..)
        .map(|i| from + i as f64 * 0.01)
        .take_while(|&t| t < to)
        .map(|t| m.state(t))
        .collect();
    let w: Vec<f64> = states
        .iter()
        .map(|s| s.twist.fixed_rows::<3>(3).norm())
        .collect();
    let v: Vec<f64> = states
        .iter()
        .map(|s| s.twist.fixed_rows::<3>(0).norm())
        .collect();
    let rms = |x: &[f64]| (x.iter().map(|a| a * a).sum::<f64>() / x.len() as f64).sqrt();
    let max = |x: &[f64]| x.iter().copied().fold(0.0, f64::max);
    (rms(&w), max(&w), rms(&v), max(&v))
}

#[test]
fn calm_then_rotate_has_a_calm_and_a_strong_phase() {
    for seed in [1, 2, 3] {
        let m = SampledMotion::calm_then_rotate(seed, 60.0).unwrap();
        let (_, w_max, v_rms, v_max) = speeds(&m, 0.0, 29.99);
        assert!(w_max < 1e-3, "seed {seed}: calm max |w| {w_max}");
        assert!(
            (0.1..0.6).contains(&v_rms),
            "seed {seed}: calm v rms {v_rms}"
        );
        assert!(v_max < 1.5, "seed {seed}: calm v max {v_max}");
        let (w_rms, _, v_rms, v_max) = speeds(&m, 35.0, 60.0);
        assert!(
            (0.4..2.5).contains(&w_rms),
            "seed {seed}: strong |w| rms {w_rms}"
        );
        assert!(
            (0.1..0.6).contains(&v_rms),
            "seed {seed}: strong v rms {v_rms}"
        );
        assert!(v_max < 1.5, "seed {seed}: strong v max {v_max}");
    }
}

#[test]
fn weak_rotation_rotates_slowly() {
    for seed in [1, 2, 3] {
        let m = SampledMotion::weak_rotation(seed, 60.0).unwrap();
        let (w_rms, w_max, v_rms, _) = speeds(&m, 0.0, 60.0);
        assert!(
            (0.01..0.08).contains(&w_rms),
            "seed {seed}: |w| rms {w_rms}"
        );
        assert!(w_max < 0.2, "seed {seed}: |w| max {w_max}");
        assert!((0.1..0.6).contains(&v_rms), "seed {seed}: v rms {v_rms}");
    }
}

#[test]
fn sampled_motion_rejects_invalid_configs() {
    let bad = |c: SampledConfig| matches!(SampledMotion::generate(&c), Err(Error::Input(_)));
    let ok = SampledConfig::new(1, 1.0, [1.0; 6]);
    assert!(SampledMotion::generate(&ok).is_ok());
    assert!(bad(SampledConfig {
        duration_s: -1.0,
        ..ok.clone()
    }));
    assert!(bad(SampledConfig {
        duration_s: f64::INFINITY,
        ..ok.clone()
    }));
    assert!(bad(SampledConfig {
        dt_s: 0.0,
        ..ok.clone()
    }));
    assert!(bad(SampledConfig {
        duration_s: 1e9,
        ..ok.clone()
    }));
    assert!(bad(SampledConfig {
        phases: vec![],
        ..ok.clone()
    }));
    assert!(bad(SampledConfig {
        phases: vec![(0.0, [-1.0; 6])],
        ..ok.clone()
    }));
    assert!(bad(SampledConfig {
        phases: vec![(0.5, [1.0; 6]), (0.2, [1.0; 6])],
        ..ok.clone()
    }));
    assert!(bad(SampledConfig {
        mean_reversion: Some(MeanReversion {
            omega0: 0.0,
            zeta: 0.7
        }),
        ..ok.clone()
    }));
    let mut c = ok.clone();
    c.initial_pose.rot[(0, 0)] = 2.0;
    assert!(bad(c));
    let mut c = ok.clone();
    c.initial_twist[2] = f64::NAN;
    assert!(bad(c));
    assert!(matches!(
        SampledMotion::calm_then_rotate(1, 0.0),
        Err(Error::Input(_))
    ));
}

// ---------------------------------------------------------------------------------------------
// Datasets
// ---------------------------------------------------------------------------------------------

fn bits3(v: &Vector3<f64>) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn pose_bits(t: &Se3) -> Vec<u64> {
    t.rot
        .iter()
        .chain(t.trans.iter())
        .map(|x| x.to_bits())
        .collect()
}

#[test]
fn simulation_is_deterministic_per_seed() {
    for motion in [
        MotionKind::Prior,
        MotionKind::CalmThenRotate,
        MotionKind::WeakRotation,
        MotionKind::Sinusoid,
    ] {
        let cfg = SimConfig {
            duration_s: 20.0,
            seed: 9,
            motion,
            ..SimConfig::default()
        };
        let a = simulate(&cfg).unwrap();
        let b = simulate(&cfg).unwrap();
        assert_eq!(a.poses.len(), b.poses.len());
        assert_eq!(a.dvl.len(), b.dvl.len());
        for (p, q) in a.poses.iter().zip(&b.poses) {
            assert_eq!(p.t.to_bits(), q.t.to_bits());
            assert_eq!(pose_bits(&p.pose), pose_bits(&q.pose));
        }
        for (p, q) in a.dvl.iter().zip(&b.dvl) {
            assert_eq!(p.t.to_bits(), q.t.to_bits());
            assert_eq!(bits3(&p.v), bits3(&q.v));
        }
        let c = simulate(&SimConfig {
            seed: 10,
            ..cfg.clone()
        })
        .unwrap();
        assert_ne!(pose_bits(&a.poses[5].pose), pose_bits(&c.poses[5].pose));
        assert_ne!(bits3(&a.dvl[5].v), bits3(&c.dvl[5].v));
    }
}

#[test]
fn simulation_layout_and_time_stamps() {
    let cfg = SimConfig::default();
    let d = simulate(&cfg).unwrap();
    assert_eq!(d.epoch.sec, 1_700_000_000);
    assert_eq!(d.poses.len(), 601);
    assert_eq!(d.truth_poses.len(), d.poses.len());
    assert_eq!(d.dvl.len(), d.dvl_truth.len());
    assert!(
        (d.dvl.len() as i64 - 600).abs() <= 2,
        "{} DVL samples",
        d.dvl.len()
    );
    let (t0, t1) = (d.poses[0].t, d.poses.last().unwrap().t);
    assert_eq!((t0, t1), (0.0, 60.0));
    assert!(d.poses.windows(2).all(|w| w[0].t < w[1].t));
    assert!(d.dvl.windows(2).all(|w| w[0].t < w[1].t));
    let motion = build_motion(&cfg).unwrap();
    for (s, truth) in d.dvl.iter().zip(&d.dvl_truth) {
        let t_cam = s.t + d.truth.time_offset_s;
        assert!(
            (t0..=t1).contains(&t_cam),
            "DVL camera time {t_cam} outside the span"
        );
        assert!(s.valid);
        assert_eq!(s.cov.unwrap(), nalgebra::Matrix3::identity() * 1e-4);
        assert_eq!(motion.state(t_cam), *truth);
        // Regular grid on the DVL clock plus at most the jitter.
        let off_grid = s.t * cfg.dvl_rate_hz - (s.t * cfg.dvl_rate_hz).round();
        assert!(off_grid.abs() <= cfg.dvl_time_jitter_s * cfg.dvl_rate_hz + 1e-9);
    }
    for (p, truth) in d.poses.iter().zip(&d.truth_poses) {
        assert_eq!(motion.state(p.t), *truth);
        let cov = p.cov.unwrap();
        assert!((cov[(0, 0)] - 4e-6).abs() < 1e-18 && (cov[(5, 5)] - 4e-6).abs() < 1e-18);
    }
}

fn std_dev(xs: &[f64]) -> f64 {
    (xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64).sqrt()
}

#[test]
fn noise_has_the_configured_standard_deviations() {
    for motion in [MotionKind::CalmThenRotate, MotionKind::Sinusoid] {
        let cfg = SimConfig {
            seed: 4,
            pose_sigma_pos_m: 0.003,
            pose_sigma_rot_rad: 0.001,
            dvl_sigma: 0.02,
            motion,
            ..SimConfig::default()
        };
        let d = simulate(&cfg).unwrap();
        let (mut rho, mut phi) = (Vec::new(), Vec::new());
        for (p, truth) in d.poses.iter().zip(&d.truth_poses) {
            let n = (truth.pose.inverse() * p.pose).log();
            rho.extend(n.iter().take(3));
            phi.extend(n.iter().skip(3));
        }
        let mut res = Vec::new();
        for (s, truth) in d.dvl.iter().zip(&d.dvl_truth) {
            res.extend((s.v - dvl_model(&d.truth, &truth.twist)).iter());
        }
        for (name, xs, sigma) in [
            ("rho", &rho, cfg.pose_sigma_pos_m),
            ("phi", &phi, cfg.pose_sigma_rot_rad),
            ("dvl", &res, cfg.dvl_sigma),
        ] {
            let n = xs.len() as f64;
            let mean = xs.iter().sum::<f64>() / n;
            let sd = std_dev(xs);
            assert!(mean.abs() < 5.0 * sigma / n.sqrt(), "{name}: mean {mean}");
            assert!(
                (sd / sigma - 1.0).abs() < 5.0 / (2.0 * n).sqrt(),
                "{name}: std {sd} vs {sigma}"
            );
        }
    }
}

#[test]
fn dvl_model_holds_exactly_without_noise() {
    let cfg = SimConfig {
        pose_sigma_pos_m: 0.0,
        pose_sigma_rot_rad: 0.0,
        dvl_sigma: 0.0,
        motion: MotionKind::Sinusoid,
        ..SimConfig::default()
    };
    let d = simulate(&cfg).unwrap();
    let r_dvl_cam = d.truth.t_cam_dvl.rot.transpose();
    let lever = d.truth.t_cam_dvl.trans;
    for (s, truth) in d.dvl.iter().zip(&d.dvl_truth) {
        let v = truth.twist.fixed_rows::<3>(0).into_owned();
        let w = truth.twist.fixed_rows::<3>(3).into_owned();
        let expected = r_dvl_cam * (v + w.cross(&lever)) * d.truth.velocity_scale;
        assert!((s.v - expected).amax() < 1e-14);
        // The DVL origin's velocity from differentiating its world position agrees.
        let t_cam = s.t + d.truth.time_offset_s;
        let motion = build_motion(&cfg).unwrap();
        let h = 1e-4;
        let pos = |t: f64| motion.state(t).pose.transform_point(&lever);
        let world_vel = (pos(t_cam + h) - pos(t_cam - h)) / (2.0 * h);
        let r_world_dvl = truth.pose.rot * d.truth.t_cam_dvl.rot;
        let expected = r_world_dvl.transpose() * world_vel * d.truth.velocity_scale;
        assert!((s.v - expected).amax() < 1e-6);
    }
    for (p, truth) in d.poses.iter().zip(&d.truth_poses) {
        assert!((p.pose.to_matrix() - truth.pose.to_matrix()).amax() < 1e-15);
    }
}

#[test]
fn default_truth_is_a_downward_looking_mount() {
    let truth = SimConfig::default_truth();
    let r = truth.t_cam_dvl.rot;
    assert!((r.transpose() * r - nalgebra::Matrix3::identity()).amax() < 1e-12);
    // DVL z axis points roughly along camera +y (down).
    let z_dvl_in_cam = r.column(2);
    assert!(z_dvl_in_cam.y > 0.99);
    assert_eq!(truth.time_offset_s, 0.07);
    assert_eq!(truth.velocity_scale, 1.01);
}

#[test]
fn invalid_configs_are_rejected() {
    let bad = |c: SimConfig| matches!(simulate(&c), Err(Error::Input(_)));
    let ok = SimConfig::default();
    assert!(bad(SimConfig {
        duration_s: 0.0,
        ..ok.clone()
    }));
    assert!(bad(SimConfig {
        duration_s: f64::NAN,
        ..ok.clone()
    }));
    assert!(bad(SimConfig {
        duration_s: 1e12,
        ..ok.clone()
    }));
    assert!(bad(SimConfig {
        camera_rate_hz: -10.0,
        ..ok.clone()
    }));
    assert!(bad(SimConfig {
        dvl_rate_hz: f64::INFINITY,
        ..ok.clone()
    }));
    assert!(bad(SimConfig {
        dvl_sigma: -0.1,
        ..ok.clone()
    }));
    assert!(bad(SimConfig {
        dvl_time_jitter_s: 0.05,
        ..ok.clone()
    }));
    let mut c = ok.clone();
    c.truth.t_cam_dvl.rot *= 2.0;
    assert!(bad(c));
    let mut c = ok.clone();
    c.truth.time_offset_s = f64::NAN;
    assert!(bad(c));
    let mut c = ok.clone();
    c.truth.velocity_scale = 0.0;
    assert!(bad(c));
    let mut c = ok.clone();
    c.duration_s = 0.01;
    c.dvl_time_jitter_s = 0.0;
    c.truth.time_offset_s = 0.03;
    assert!(bad(c), "no DVL sample inside a one-pose span");
    let mut c = ok.clone();
    c.motion = MotionKind::Prior;
    c.prior_qc[0] = -1.0;
    assert!(bad(c));
}
