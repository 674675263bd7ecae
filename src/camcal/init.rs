//! The starting point of the adjustment: OpenCV's `calibrateCamera` per camera, the stereo
//! extrinsics from the board poses two cameras saw in the same frames, and a board pose for every
//! frame.
//!
//! `calibrateCamera` (flag `CALIB_FIX_K3`, so that its model is Kalibr's four-coefficient radtan)
//! starts from the board's homographies and refines each camera alone. For the equidistant model
//! the radtan curve it finds is converted: the equidistant coefficients are the least-squares fit
//! of `theta_d(theta)` to the radtan radius `r (1 + k1 r^2 + k2 r^4)` over the radii the corners
//! reached, a linear problem in the four coefficients.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use opencv::core::{Mat, Point2f, Point3f, Size, TermCriteria, TermCriteria_Type, Vector};
use opencv::prelude::*;

use crate::camcal::types::{CameraModel, CornerObs};
use crate::error::{Error, Result};
use crate::lie::{Se3, so3};
use crate::types::camera::{Camchain, Camera, Distortion};
use crate::vision::pnp::mat3;

/// Views per camera given to OpenCV's calibrateCamera.
pub const INIT_VIEWS: usize = 30;

/// The initial estimate.
#[derive(Clone, Debug)]
pub struct Initial {
    /// The chain: OpenCV's intrinsics per camera, `T_cn_c0` from shared frames.
    pub chain: Camchain,
    /// OpenCV's reprojection RMS per camera, px.
    pub rms_px: Vec<f64>,
    /// `T_c0_board` of every frame with a usable view (indexed by frame; `None`: no view).
    pub t_c0_board: Vec<Option<Se3>>,
}

/// The initial estimate from the observations of `frames` frames; `sizes` are the image sizes
/// (width, height) per camera.
pub fn initial_estimate(
    obs: &[CornerObs],
    frames: usize,
    sizes: &[(u32, u32)],
    model: CameraModel,
) -> Result<Initial> {
    if obs.iter().any(|o| o.board.z.abs() > 1e-9) {
        return Err(Error::Input(
            "camera calibration needs a flat board (all tag corners at z = 0 in the board frame)"
                .into(),
        ));
    }
    let cams = sizes.len();
    let mut chain = Camchain {
        cams: Vec::with_capacity(cams),
        t_cn_c0: Vec::with_capacity(cams),
        topics: vec![None; cams],
    };
    let mut rms = Vec::with_capacity(cams);
    // Per camera: frame -> T_cam_board.
    let mut poses: Vec<BTreeMap<usize, Se3>> = Vec::with_capacity(cams);
    for (cam, &(w, h)) in sizes.iter().enumerate() {
        let (camera, r, p) = calibrate_one(obs, cam, w, h, model)?;
        chain.cams.push(camera);
        rms.push(r);
        poses.push(p);
    }
    // Stereo extrinsics: cam n against cam0 over the frames both saw.
    chain.t_cn_c0.push(Se3::identity());
    for (cam, seen) in poses.iter().enumerate().skip(1) {
        let pairs: Vec<Se3> = seen
            .iter()
            .filter_map(|(f, t_cn_b)| poses[0].get(f).map(|t_c0_b| *t_cn_b * t_c0_b.inverse()))
            .collect();
        if pairs.is_empty() {
            return Err(Error::Input(format!(
                "cam{cam} never saw the board in the same frame as cam0: the stereo extrinsics \
                 cannot be found (record frames in which both cameras see the board)"
            )));
        }
        chain.t_cn_c0.push(mean_transform(&pairs));
    }
    // A board pose per frame: cam0's own, or another camera's brought to cam0.
    let mut t_c0_board = vec![None; frames];
    for (f, slot) in t_c0_board.iter_mut().enumerate() {
        *slot = (0..cams).find_map(|c| {
            poses[c]
                .get(&f)
                .map(|t_cn_b| chain.t_cn_c0[c].inverse() * *t_cn_b)
        });
    }
    Ok(Initial {
        chain,
        rms_px: rms,
        t_c0_board,
    })
}

/// OpenCV's calibration of camera `cam`: the camera, its RMS and `T_cam_board` per frame.
fn calibrate_one(
    obs: &[CornerObs],
    cam: usize,
    w: u32,
    h: u32,
    model: CameraModel,
) -> Result<(Camera, f64, BTreeMap<usize, Se3>)> {
    let cv = |e: opencv::Error| Error::Input(format!("cam{cam}: OpenCV calibrateCamera: {e}"));
    // One Mat of points per view (CV_32FC3 and CV_32FC2 rows, as calibrateCamera wants them).
    let mut object = Vector::<Mat>::new();
    let mut image = Vector::<Mat>::new();
    let mut frames = Vec::new();
    let mut current: Option<usize> = None;
    let mut o3: Vec<Point3f> = Vec::new();
    let mut o2: Vec<Point2f> = Vec::new();
    let mut flush = |o3: &mut Vec<Point3f>, o2: &mut Vec<Point2f>| -> Result<()> {
        object.push(
            Mat::from_slice(o3)
                .and_then(|m| m.try_clone())
                .map_err(cv)?,
        );
        image.push(
            Mat::from_slice(o2)
                .and_then(|m| m.try_clone())
                .map_err(cv)?,
        );
        o3.clear();
        o2.clear();
        Ok(())
    };
    for o in obs.iter().filter(|o| o.cam == cam) {
        if current != Some(o.frame) {
            if let Some(f) = current {
                flush(&mut o3, &mut o2)?;
                frames.push(f);
            }
            current = Some(o.frame);
        }
        o3.push(Point3f::new(o.board.x as f32, o.board.y as f32, 0.0));
        o2.push(Point2f::new(o.px.x as f32, o.px.y as f32));
    }
    if let Some(f) = current {
        flush(&mut o3, &mut o2)?;
        frames.push(f);
    }
    if frames.len() < 3 {
        return Err(Error::Input(format!(
            "cam{cam}: the board was usable in {} frames; a camera calibration needs views from at \
             least 3 (better 20 or more) different angles",
            frames.len()
        )));
    }
    // calibrateCamera solves one dense system over every view's pose: its cost grows with the
    // cube of the view count. A start needs a few dozen views spread over the recording; the
    // other views get their board pose from solvePnP with its camera.
    let step = frames.len().div_ceil(INIT_VIEWS).max(1);
    let mut sub_object = Vector::<Mat>::new();
    let mut sub_image = Vector::<Mat>::new();
    for i in (0..frames.len()).step_by(step) {
        sub_object.push(object.get(i).map_err(cv)?);
        sub_image.push(image.get(i).map_err(cv)?);
    }
    let mut k = Mat::default();
    let mut dist = Mat::default();
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let criteria = TermCriteria::new(
        TermCriteria_Type::COUNT as i32 + TermCriteria_Type::EPS as i32,
        30,
        f64::EPSILON,
    )
    .map_err(cv)?;
    let rms = opencv::calib3d::calibrate_camera(
        &sub_object,
        &sub_image,
        Size::new(w as i32, h as i32),
        &mut k,
        &mut dist,
        &mut rvecs,
        &mut tvecs,
        opencv::calib3d::CALIB_FIX_K3,
        criteria,
    )
    .map_err(cv)?;
    let at = |m: &Mat, r: i32, c: i32| m.at_2d::<f64>(r, c).copied().map_err(cv);
    let d: Vec<f64> = (0..4)
        .map(|i| dist.at::<f64>(i).copied().map_err(cv))
        .collect::<Result<_>>()?;
    let mut camera = Camera {
        fu: at(&k, 0, 0)?,
        fv: at(&k, 1, 1)?,
        pu: at(&k, 0, 2)?,
        pv: at(&k, 1, 2)?,
        distortion: Distortion::RadTan {
            k1: d[0],
            k2: d[1],
            p1: d[2],
            p2: d[3],
        },
        width: w,
        height: h,
    };
    let finite = [camera.fu, camera.fv, camera.pu, camera.pv]
        .iter()
        .chain(&d)
        .all(|v| v.is_finite());
    if !finite || camera.fu <= 0.0 || camera.fv <= 0.0 {
        return Err(Error::Input(format!(
            "cam{cam}: OpenCV's calibrateCamera found no usable camera (focal lengths {:.1}, {:.1})",
            camera.fu, camera.fv
        )));
    }
    if model == CameraModel::PinholeEqui {
        let reach = obs
            .iter()
            .filter(|o| o.cam == cam)
            .filter_map(|o| {
                let x = (o.px.x - camera.pu) / camera.fu;
                let y = (o.px.y - camera.pv) / camera.fv;
                Some((x * x + y * y).sqrt()).filter(|r| r.is_finite())
            })
            .fold(0.0f64, f64::max);
        camera.distortion = equidistant_from_radtan(&camera.distortion, reach);
    }
    let mut poses = BTreeMap::new();
    for (i, f) in frames.iter().enumerate() {
        let (o, im) = (object.get(i).map_err(cv)?, image.get(i).map_err(cv)?);
        let mut r = Mat::default();
        let mut t = Mat::default();
        let solved = opencv::calib3d::solve_pnp(
            &o,
            &im,
            &k,
            &dist,
            &mut r,
            &mut t,
            false,
            opencv::calib3d::SOLVEPNP_IPPE,
        )
        .unwrap_or(false);
        // A view whose pose cannot be found starts without one (its frame may still get one
        // from another camera).
        if let (true, Some(r), Some(t)) = (solved, mat3(&r), mat3(&t)) {
            poses.insert(*f, Se3::new(so3::exp(&r), t));
        }
    }
    Ok((camera, rms, poses))
}

/// The equidistant coefficients whose radial curve best matches a radtan one out to the
/// distorted normalised radius `reach` (tangential terms are left out: the adjustment finds
/// what remains).
pub fn equidistant_from_radtan(d: &Distortion, reach: f64) -> Distortion {
    let Distortion::RadTan { k1, k2, .. } = *d else {
        return *d;
    };
    let zero = Distortion::Equidistant {
        k1: 0.0,
        k2: 0.0,
        k3: 0.0,
        k4: 0.0,
    };
    // Undistorted radii whose radtan image stays within reach (and before any fold).
    let mut rows: Vec<(f64, f64)> = Vec::new();
    let steps = 200;
    let mut last = 0.0;
    for i in 1..=steps * 4 {
        let r = 0.01 * i as f64;
        let rd = r * (1.0 + k1 * r * r + k2 * r.powi(4));
        if rd <= last || rd > reach.max(0.05) {
            break;
        }
        last = rd;
        rows.push((r.atan(), rd));
    }
    if rows.len() < 8 {
        return zero;
    }
    // theta_d - theta = k1 theta^3 + k2 theta^5 + k3 theta^7 + k4 theta^9, with theta_d = rd
    // (the equidistant image radius is theta_d in normalised units).
    let a = DMatrix::from_fn(rows.len(), 4, |i, j| rows[i].0.powi(3 + 2 * j as i32));
    let b = DVector::from_fn(rows.len(), |i, _| rows[i].1 - rows[i].0);
    // Ridge-damped normal equations: the high powers are nearly collinear over short reaches.
    let mut ata = a.transpose() * &a;
    let scale = ata.diagonal().max().max(1e-30);
    for j in 0..4 {
        ata[(j, j)] += 1e-9 * scale;
    }
    let atb = a.transpose() * b;
    match ata.cholesky() {
        Some(c) => {
            let k = c.solve(&atb);
            if k.iter().all(|v| v.is_finite()) {
                Distortion::Equidistant {
                    k1: k[0],
                    k2: k[1],
                    k3: k[2],
                    k4: k[3],
                }
            } else {
                zero
            }
        }
        None => zero,
    }
}

/// The mean of nearby transforms: the rotation that best fits the rotations (projection of their
/// sum onto SO(3)) and the component-wise median translation (robust to a bad board pose).
pub fn mean_transform(ts: &[Se3]) -> Se3 {
    let sum: Matrix3<f64> = ts.iter().map(|t| t.rot).sum();
    let svd = sum.svd(true, true);
    let rot = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => {
            let mut d = Matrix3::identity();
            if (u * vt).determinant() < 0.0 {
                d[(2, 2)] = -1.0;
            }
            u * d * vt
        }
        _ => ts.first().map_or(Matrix3::identity(), |t| t.rot),
    };
    let median = |k: usize| {
        let mut v: Vec<f64> = ts.iter().map(|t| t.trans[k]).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            0.0
        } else if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    Se3::new(rot, Vector3::new(median(0), median(1), median(2))).renormalized()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equidistant_fit_follows_the_radtan_curve() {
        let rt = Distortion::RadTan {
            k1: -0.28,
            k2: 0.074,
            p1: 0.0,
            p2: 0.0,
        };
        let eq = equidistant_from_radtan(&rt, 0.9);
        // Same distorted radius for the same ray, within 0.2 % of the radius, out to the reach.
        for i in 1..60 {
            let r = 0.015 * i as f64;
            let (a, _) = rt.distort(&nalgebra::Vector2::new(r, 0.0));
            if a.x > 0.9 {
                break;
            }
            let (b, _) = eq.distort(&nalgebra::Vector2::new(r, 0.0));
            assert!((a.x - b.x).abs() < 2e-3 * a.x, "r {r}: {} vs {}", a.x, b.x);
        }
    }

    #[test]
    fn mean_of_one_is_itself_and_median_resists_an_outlier() {
        let t = Se3::new(
            so3::exp(&Vector3::new(0.01, -0.02, 0.03)),
            Vector3::new(-0.11, 0.0, 0.001),
        );
        let m = mean_transform(&[t]);
        assert!((m.rot - t.rot).norm() < 1e-12 && (m.trans - t.trans).norm() < 1e-12);
        let bad = Se3::new(t.rot, Vector3::new(5.0, 5.0, 5.0));
        let m = mean_transform(&[t, t, bad]);
        assert!((m.trans - t.trans).norm() < 1e-12);
    }
}
