//! Stereo PnP on synthetic corner projections with a known pose: exactness without noise,
//! covariance consistency (NEES) with pixel noise, stereo against mono, outlier tags.

use nalgebra::{Matrix3, Vector2, Vector3, Vector6};

use dvlcal::lie::{Se3, so3};
use dvlcal::rng::Rng;
use dvlcal::sim::camcal_views::synthetic_detections;
use dvlcal::types::board::{Board, TagFamily};
use dvlcal::types::camera::{Camchain, Camera, Distortion};
use dvlcal::vision::detect::TagDetection;
use dvlcal::vision::pnp::{
    CORNER_SAMPLE_PER_CAMERA, PnpOptions, PoseOutcome, solve_stereo, stereo_pose,
};

fn camera(distortion: Distortion) -> Camera {
    Camera {
        fu: 458.0,
        fv: 457.0,
        pu: 367.0,
        pv: 248.0,
        distortion,
        width: 752,
        height: 480,
    }
}

fn radtan() -> Distortion {
    Distortion::RadTan {
        k1: -0.28,
        k2: 0.07,
        p1: 2e-4,
        p2: 1.8e-5,
    }
}

/// Stereo pair with an 11 cm baseline: cam1 to the right of cam0, slightly rotated.
fn stereo(distortion: Distortion) -> Camchain {
    let r = so3::exp(&Vector3::new(0.004, -0.01, 0.002));
    let t_c1_c0 = Se3::new(r, r * Vector3::new(-0.11, 0.0, 0.0));
    Camchain {
        cams: vec![camera(distortion), camera(distortion)],
        t_cn_c0: vec![Se3::identity(), t_c1_c0],
        topics: vec![None, None],
    }
}

fn board() -> Board {
    Board::grid(TagFamily::Tag36h11, 6, 6, 0.088, 0.3, 0)
}

/// `T_board_cam0` looking at the board's centre from about `dist` metres, perturbed by `rng`.
fn pose(rng: &mut Rng, dist: f64) -> Se3 {
    // Camera axes in the board frame: x along board x, y down (-board y), z into the board.
    let r0 = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let tilt = so3::exp(&Vector3::new(
        rng.uniform_in(-0.3, 0.3),
        rng.uniform_in(-0.3, 0.3),
        rng.uniform_in(-0.5, 0.5),
    ));
    let r = r0 * tilt;
    let centre = Vector3::new(0.33, 0.33, 0.0)
        + Vector3::new(rng.uniform_in(-0.1, 0.1), rng.uniform_in(-0.1, 0.1), 0.0);
    // Camera at distance `dist` from the centre along its optical axis.
    let t = centre - r * Vector3::new(0.0, 0.0, dist);
    Se3::new(r, t)
}

/// Detections of the tags wholly inside each camera's image, with pixel noise `sigma`.
fn detections(
    b: &Board,
    chain: &Camchain,
    t_b_c0: &Se3,
    sigma: f64,
    rng: &mut Rng,
) -> Vec<Vec<TagDetection>> {
    let t_c0_b = t_b_c0.inverse();
    chain
        .cams
        .iter()
        .zip(&chain.t_cn_c0)
        .map(|(cam, t_cn_c0)| {
            let t = t_cn_c0 * &t_c0_b;
            synthetic_detections(b, cam, &t, sigma, rng)
        })
        .collect()
}

/// Right-perturbation error `log(T_true^-1 T_est)`.
fn error(t_true: &Se3, t_est: &Se3) -> Vector6<f64> {
    (t_true.inverse() * *t_est).log()
}

#[test]
fn noise_free_corners_give_the_exact_pose() {
    let b = board();
    let mut rng = Rng::new(1);
    for dist in [
        Distortion::None,
        radtan(),
        Distortion::Equidistant {
            k1: -0.01,
            k2: 0.02,
            k3: -0.01,
            k4: 0.003,
        },
    ] {
        let chain = stereo(dist);
        for _ in 0..10 {
            let t = pose(&mut rng, 0.9);
            let dets = detections(&b, &chain, &t, 0.0, &mut rng);
            let p = stereo_pose(&b, &chain, &dets, &PnpOptions::default())
                .unwrap()
                .expect("a pose");
            let e = error(&t, &p.t_board_cam0);
            assert!(e.norm() < 1e-8, "error {e:?}");
            assert!(p.rms_px < 1e-6);
            assert_eq!(p.tags_rejected, 0);
            assert_eq!(p.corners_used, 4 * p.tags_used);
            // Mono (cam0 only) is exact too.
            let mono = Camchain::mono(chain.cams[0].clone());
            let p = stereo_pose(&b, &mono, &dets[..1], &PnpOptions::default())
                .unwrap()
                .expect("a pose");
            assert!(error(&t, &p.t_board_cam0).norm() < 1e-8);
        }
    }
}

/// Mean NEES over many noisy trials, the mean squared translation error and the mean trace of
/// the translation covariance.
fn trials(chain: &Camchain, cams: usize, n: usize, sigma: f64, seed: u64) -> (f64, f64, f64, f64) {
    let b = board();
    let mut rng = Rng::new(seed);
    let (mut nees, mut sq, mut tr, mut sig) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..n {
        let t = pose(&mut rng, 1.2);
        let dets = detections(&b, chain, &t, sigma, &mut rng);
        let p = stereo_pose(&b, chain, &dets[..cams], &PnpOptions::default())
            .unwrap()
            .expect("a pose");
        let e = error(&t, &p.t_board_cam0);
        let info = p.cov.try_inverse().unwrap();
        nees += (e.transpose() * info * e)[(0, 0)];
        sq += e.fixed_rows::<3>(0).norm_squared();
        tr += p.cov.fixed_view::<3, 3>(0, 0).trace();
        sig += p.sigma_px;
    }
    let n = n as f64;
    (nees / n, sq / n, tr / n, sig / n)
}

#[test]
fn covariance_is_consistent_with_the_errors() {
    let chain = stereo(radtan());
    let n = 400;
    let (nees, sq, tr, sig) = trials(&chain, 2, n, 0.5, 7);
    eprintln!(
        "stereo: NEES {nees:.3}, translation MSE {sq:.3e} m^2 vs trace {tr:.3e}, sigma {sig:.3}"
    );
    // Mean of n chi-square(6) draws: standard deviation sqrt(12 / n) ~ 0.17.
    assert!((nees - 6.0).abs() < 0.6, "mean NEES {nees}");
    assert!((sig - 0.5).abs() < 0.03, "estimated sigma {sig}");
    assert!((sq / tr - 1.0).abs() < 0.25, "MSE {sq} vs predicted {tr}");
    let mono = Camchain::mono(chain.cams[0].clone());
    let (nees, _, _, _) = trials(&mono, 1, n, 0.5, 8);
    eprintln!("mono: NEES {nees:.3}");
    assert!((nees - 6.0).abs() < 0.6, "mean NEES {nees}");
}

#[test]
fn stereo_is_more_accurate_than_mono() {
    let chain = stereo(radtan());
    let (_, sq_stereo, tr_stereo, _) = trials(&chain, 2, 200, 0.5, 11);
    let (_, sq_mono, tr_mono, _) = trials(&chain, 1, 200, 0.5, 11);
    eprintln!(
        "translation RMS: stereo {:.3} mm, mono {:.3} mm",
        sq_stereo.sqrt() * 1e3,
        sq_mono.sqrt() * 1e3
    );
    assert!(sq_stereo < 0.8 * sq_mono);
    assert!(tr_stereo < 0.8 * tr_mono);
}

#[test]
fn outlier_tags_are_rejected() {
    let b = board();
    let chain = stereo(radtan());
    let mut rng = Rng::new(3);
    for trial in 0..20 {
        let t = pose(&mut rng, 1.0);
        let mut dets = detections(&b, &chain, &t, 0.3, &mut rng);
        let clean = stereo_pose(&b, &chain, &dets, &PnpOptions::default())
            .unwrap()
            .unwrap();
        // One tag in cam0 shifted by several pixels, another in cam1 with its corners rotated
        // (a wrong orientation decode).
        let i = trial % dets[0].len();
        for c in dets[0][i].corners.iter_mut() {
            *c += Vector2::new(6.0, -4.0);
        }
        let j = (trial * 7) % dets[1].len();
        dets[1][j].corners.rotate_left(1);
        let p = stereo_pose(&b, &chain, &dets, &PnpOptions::default())
            .unwrap()
            .unwrap();
        assert_eq!(p.tags_rejected, 2, "trial {trial}");
        assert_eq!(p.tags_used, clean.tags_used - 2);
        let e = error(&clean.t_board_cam0, &p.t_board_cam0);
        let sd = p.cov.diagonal().map(f64::sqrt);
        for k in 0..6 {
            assert!(e[k].abs() < 4.0 * sd[k], "trial {trial}: {e:?} vs {sd:?}");
        }
        assert!(p.rms_px < 0.6);
        // Without rejection the pose is visibly worse.
        let keep = PnpOptions {
            reject_min_px: 1e9,
            ..PnpOptions::default()
        };
        let q = stereo_pose(&b, &chain, &dets, &keep).unwrap().unwrap();
        assert_eq!(q.tags_rejected, 0);
        assert!(q.rms_px > 2.0 * p.rms_px);
    }
}

#[test]
fn per_camera_rms_and_the_corner_sample() {
    // cam1's corners carry three times cam0's noise: the per-camera RMS tells them apart and
    // combine to the frame's RMS; the sample holds evenly drawn corners of each camera with
    // their own residuals.
    let b = board();
    let chain = stereo(radtan());
    let mut rng = Rng::new(11);
    let t = pose(&mut rng, 1.0);
    let mut dets = detections(&b, &chain, &t, 0.1, &mut rng);
    let noisy = detections(&b, &chain, &t, 0.3, &mut rng);
    dets[1] = noisy[1].clone();
    let p = stereo_pose(&b, &chain, &dets, &PnpOptions::default())
        .unwrap()
        .unwrap();
    assert_eq!(p.tags_rejected, 0);
    let r0 = p.rms_px_per_cam[0].expect("cam0 corners");
    let r1 = p.rms_px_per_cam[1].expect("cam1 corners");
    assert!(r1 > 2.0 * r0, "cam0 {r0}, cam1 {r1}");
    let n0 = 4 * dets[0].len();
    let n1 = 4 * dets[1].len();
    let all = ((r0 * r0 * n0 as f64 + r1 * r1 * n1 as f64) / (n0 + n1) as f64).sqrt();
    assert!(
        (all - p.rms_px).abs() < 1e-9 * p.rms_px,
        "{all} {}",
        p.rms_px
    );
    for cam in 0..2u8 {
        let s: Vec<_> = p.corner_sample.iter().filter(|c| c.cam == cam).collect();
        assert_eq!(
            s.len(),
            CORNER_SAMPLE_PER_CAMERA.min(4 * dets[cam as usize].len())
        );
        // Each sampled corner is a detected one, spread over the camera's list (not its start).
        let det: Vec<_> = dets[cam as usize]
            .iter()
            .flat_map(|d| d.corners.iter())
            .collect();
        let at: Vec<usize> = s
            .iter()
            .map(|c| {
                det.iter()
                    .position(|d| ((d.x - c.u as f64).abs() + (d.y - c.v as f64).abs()) < 1e-3)
                    .expect("a detected corner")
            })
            .collect();
        assert_eq!(at[0], 0);
        assert!(
            *at.last().unwrap()
                >= det.len() * (CORNER_SAMPLE_PER_CAMERA - 1) / CORNER_SAMPLE_PER_CAMERA - 1
        );
        for c in s {
            assert!(c.norm() < 6.0 * if cam == 0 { 0.1 } else { 0.3 });
        }
    }
    // Mono: one camera, no entry for a second.
    let mono = Camchain::mono(chain.cams[0].clone());
    let p = stereo_pose(&b, &mono, &dets[..1], &PnpOptions::default())
        .unwrap()
        .unwrap();
    assert_eq!(p.rms_px_per_cam.len(), 1);
    assert!((p.rms_px_per_cam[0].unwrap() - p.rms_px).abs() < 1e-12);
}

#[test]
fn too_few_corners_unknown_ids_and_bad_input() {
    let b = board();
    let chain = stereo(radtan());
    let mut rng = Rng::new(5);
    let t = pose(&mut rng, 1.0);
    let mut dets = detections(&b, &chain, &t, 0.0, &mut rng);
    // One tag in one camera: 4 corners, fewer than the default 8.
    let one = vec![vec![dets[0][0].clone()], vec![]];
    assert_eq!(
        solve_stereo(&b, &chain, &one, &PnpOptions::default()).unwrap(),
        PoseOutcome::TooFewCorners { corners: 4 }
    );
    assert!(
        stereo_pose(&b, &chain, &one, &PnpOptions::default())
            .unwrap()
            .is_none()
    );
    // ... but enough for min_corners 4.
    let four = PnpOptions {
        min_corners: 4,
        ..PnpOptions::default()
    };
    let p = stereo_pose(&b, &chain, &one, &four).unwrap().unwrap();
    assert!(error(&t, &p.t_board_cam0).norm() < 1e-6);
    // Ids not on the board are ignored and counted.
    let mut extra = dets[0][0].clone();
    extra.id = 999;
    dets[1].push(extra);
    let p = stereo_pose(&b, &chain, &dets, &PnpOptions::default())
        .unwrap()
        .unwrap();
    assert_eq!(p.tags_unknown, 1);
    assert!(error(&t, &p.t_board_cam0).norm() < 1e-8);
    // Nothing seen at all.
    assert_eq!(
        solve_stereo(&b, &chain, &[vec![], vec![]], &PnpOptions::default()).unwrap(),
        PoseOutcome::TooFewCorners { corners: 0 }
    );
    // More detection lists than cameras is an error, not a panic.
    let three = vec![vec![], vec![], vec![]];
    assert!(stereo_pose(&b, &chain, &three, &PnpOptions::default()).is_err());
    // Non-finite corners are dropped.
    dets[0][1].corners[2].x = f64::NAN;
    let p = stereo_pose(&b, &chain, &dets, &PnpOptions::default())
        .unwrap()
        .unwrap();
    assert!(error(&t, &p.t_board_cam0).norm() < 1e-8);
}

#[test]
fn each_frame_measures_each_cameras_focal_length() {
    use dvlcal::vision::scale::combine;
    // The images come from a pair whose cam1 has a focal length 2 % longer than the chain the
    // frames are solved with says.
    let b = board();
    let given = stereo(radtan());
    let mut truth = given.clone();
    truth.cams[1].fu *= 1.02;
    truth.cams[1].fv *= 1.02;
    let mut rng = Rng::new(11);
    let expect = [1.0, 1.02];
    for sigma in [0.0, 0.3] {
        let mut fits = [Vec::new(), Vec::new()];
        let mut z2 = [0.0, 0.0];
        for _ in 0..200 {
            let t = pose(&mut rng, 1.0);
            let dets = detections(&b, &truth, &t, sigma, &mut rng);
            let opts = PnpOptions {
                sigma_px: (sigma > 0.0).then_some(sigma),
                ..PnpOptions::default()
            };
            let p = stereo_pose(&b, &given, &dets, &opts)
                .unwrap()
                .expect("a pose");
            assert_eq!(p.focal_scale.len(), 2);
            for cam in 0..2 {
                let f = p.focal_scale[cam].expect("a factor");
                if sigma == 0.0 {
                    // One Gauss-Newton step from the stereo pose: exact up to the step's
                    // second-order term.
                    assert!((f.scale - expect[cam]).abs() < 2e-3, "cam{cam}: {f:?}");
                } else {
                    z2[cam] += ((f.scale - expect[cam]) / f.std).powi(2);
                }
                fits[cam].push(f);
            }
        }
        if sigma > 0.0 {
            for cam in 0..2 {
                let rms = (z2[cam] / 200.0).sqrt();
                let c = combine(&fits[cam], 10, 0.0).expect("combined");
                println!("cam{cam}: RMS error/std {rms:.2}, combined {c:?}");
                // The frames' std are honest, and the recording's factor is the truth's.
                assert!((rms - 1.0).abs() < 0.2, "cam{cam}: RMS error/std {rms}");
                assert!(
                    (c.value - expect[cam]).abs() < 3.0 * c.std,
                    "cam{cam}: {c:?}"
                );
                assert!(c.std < 2e-3, "{c:?}");
            }
        }
    }
}
