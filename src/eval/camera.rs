//! Accuracy of a camera calibration against known truth, and the reference a user would otherwise
//! run: OpenCV's `calibrateCamera` per camera and `stereoCalibrate` for the extrinsics.
//!
//! Two cameras are compared by where they send the same ray ([`ray_pixel_error`]): a difference
//! of focal length that a difference of distortion makes up for leaves the image unchanged and
//! scores zero, while comparing the parameters one by one would count it twice.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector2, Vector3};
use opencv::core::{Mat, Point2f, Point3f, Size, TermCriteria, TermCriteria_Type, Vector};
use opencv::prelude::*;

use crate::camcal::FrameTags;
use crate::error::{Error, Result};
use crate::lie::{Se3, so3};
use crate::types::board::Board;
use crate::types::camera::{Camchain, Camera, Distortion};

/// The pixel distance between where a true and an estimated camera model send the same rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayError {
    /// Root mean square of the distances, px.
    pub rms_px: f64,
    /// Largest distance, px.
    pub max_px: f64,
    /// Grid pixels compared.
    pub points: usize,
    /// Grid pixels skipped: the true model could not be inverted there, or the estimated model
    /// could not project the ray (behind it or a non-finite pixel).
    pub skipped: usize,
}

/// The pixel distance between where `truth` and `est` send the same ray, over a grid of pixels
/// `step_px` apart covering `truth`'s image (from pixel 0 to the last row and column, both
/// included): each grid pixel is unprojected with the true model and its ray projected with the
/// estimated one. `None` when `step_px` is not a positive number or no grid pixel could be
/// compared.
pub fn ray_pixel_error(truth: &Camera, est: &Camera, step_px: f64) -> Option<RayError> {
    if !(step_px.is_finite() && step_px > 0.0) {
        return None;
    }
    let us = grid(truth.width, step_px);
    let vs = grid(truth.height, step_px);
    let (mut sq, mut max, mut points, mut skipped) = (0.0, 0.0f64, 0usize, 0usize);
    for &v in &vs {
        for &u in &us {
            let px = Vector2::new(u, v);
            let back = truth.unproject(&px).and_then(|ray| est.project(&ray));
            match back {
                Some(q) if q.x.is_finite() && q.y.is_finite() => {
                    let d = (q - px).norm();
                    sq += d * d;
                    max = max.max(d);
                    points += 1;
                }
                _ => skipped += 1,
            }
        }
    }
    (points > 0).then(|| RayError {
        rms_px: (sq / points as f64).sqrt(),
        max_px: max,
        points,
        skipped,
    })
}

/// Pixel coordinates `0, step, 2 step, ...` below `size - 1`, then `size - 1` itself (the last
/// pixel centre), so that the image's edges are always on the grid.
fn grid(size: u32, step: f64) -> Vec<f64> {
    let last = f64::from(size.max(1) - 1);
    let mut out: Vec<f64> = (0..)
        .map(|k| k as f64 * step)
        .take_while(|&x| x < last - 1e-9)
        .collect();
    out.push(last);
    out
}

/// The error of an estimated extrinsic transform against the truth: the translation error
/// `|t_est - t_true|` (m, same units as the transforms) and the rotation error, the angle of
/// `R_est R_true^T` (rad).
pub fn extrinsic_error(truth: &Se3, est: &Se3) -> (f64, f64) {
    let dt = (est.trans - truth.trans).norm();
    let dr = so3::log(&(est.rot * truth.rot.transpose())).norm();
    (dt, dr)
}

/// The baseline error `|t_est| - |t_true|` of an estimated extrinsic transform (m, same units as
/// the transforms): positive when the estimate puts the cameras too far apart.
pub fn baseline_error(truth: &Se3, est: &Se3) -> f64 {
    est.trans.norm() - truth.trans.norm()
}

/// Smallest number of board corners of a view OpenCV is given.
pub const REFERENCE_MIN_CORNERS: usize = 12;

/// Smallest number of views per camera (and shared frames per camera pair).
pub const REFERENCE_MIN_VIEWS: usize = 3;

/// The board corners one camera saw in one frame, in tag-id order: board points and pixels.
type ViewCorners = BTreeMap<u32, ([Vector3<f64>; 4], [Vector2<f64>; 4])>;

/// The board corners camera `cam` saw in `frame`: detections with an id on the board, seen once
/// in the image and with finite corners.
fn view_corners(board: &Board, frame: &FrameTags, cam: usize) -> ViewCorners {
    let mut out = ViewCorners::new();
    let Some(dets) = frame.dets.get(cam) else {
        return out;
    };
    for d in dets {
        let Some(tag) = board.tag(d.id) else { continue };
        let once = dets.iter().filter(|e| e.id == d.id).count() == 1;
        let finite = d.corners.iter().all(|c| c.x.is_finite() && c.y.is_finite());
        if once && finite {
            out.insert(d.id, (tag.corners, d.corners));
        }
    }
    out
}

/// OpenCV's object and image points of the tags in `ids` of one view, as one-row matrices
/// (`CV_32FC3` and `CV_32FC2`, the types `calibrateCamera` wants).
fn cv_points<'a>(view: &ViewCorners, ids: impl Iterator<Item = &'a u32>) -> Result<(Mat, Mat)> {
    let mut obj = Vec::new();
    let mut img = Vec::new();
    for id in ids {
        if let Some((b, px)) = view.get(id) {
            for (p, q) in b.iter().zip(px) {
                obj.push(Point3f::new(p.x as f32, p.y as f32, 0.0));
                img.push(Point2f::new(q.x as f32, q.y as f32));
            }
        }
    }
    let err = cv_err("point matrix");
    let obj = Mat::from_slice(&obj)
        .and_then(|m| m.try_clone())
        .map_err(&err)?;
    let img = Mat::from_slice(&img)
        .and_then(|m| m.try_clone())
        .map_err(&err)?;
    Ok((obj, img))
}

fn cv_err(what: &'static str) -> impl Fn(opencv::Error) -> Error {
    move |e| Error::Input(format!("OpenCV {what}: {e}"))
}

/// One camera as OpenCV holds it: camera matrix and distortion `[k1, k2, p1, p2, k3]`.
struct CvCamera {
    k: Mat,
    dist: Mat,
}

/// OpenCV's termination criteria of both calibrations: 100 iterations or a relative change below
/// 1e-12.
fn criteria() -> Result<TermCriteria> {
    TermCriteria::new(
        TermCriteria_Type::COUNT as i32 + TermCriteria_Type::EPS as i32,
        100,
        1e-12,
    )
    .map_err(cv_err("TermCriteria"))
}

fn cv_size(cam: usize, (w, h): (u32, u32)) -> Result<Size> {
    match (i32::try_from(w), i32::try_from(h)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => Ok(Size::new(w, h)),
        _ => Err(Error::Input(format!(
            "cam{cam}: image size {w}x{h} is not a usable size"
        ))),
    }
}

/// The [`Camera`] OpenCV's camera matrix and distortion describe (radtan: OpenCV's k3 is fixed at
/// zero and left out).
fn to_camera(cam: usize, c: &CvCamera, (w, h): (u32, u32)) -> Result<Camera> {
    let err = cv_err("result");
    let k = |r: i32, col: i32| c.k.at_2d::<f64>(r, col).copied().map_err(&err);
    let d = |i: i32| c.dist.at::<f64>(i).copied().map_err(&err);
    let camera = Camera {
        fu: k(0, 0)?,
        fv: k(1, 1)?,
        pu: k(0, 2)?,
        pv: k(1, 2)?,
        distortion: Distortion::RadTan {
            k1: d(0)?,
            k2: d(1)?,
            p1: d(2)?,
            p2: d(3)?,
        },
        width: w,
        height: h,
    };
    let all = [camera.fu, camera.fv, camera.pu, camera.pv]
        .into_iter()
        .chain(camera.distortion.coeffs());
    if all.into_iter().any(|v| !v.is_finite()) || camera.fu <= 0.0 || camera.fv <= 0.0 {
        return Err(Error::Numerical(format!(
            "cam{cam}: OpenCV returned an unusable camera {camera:?}"
        )));
    }
    Ok(camera)
}

/// The camera calibration a user would otherwise run with OpenCV, as a reference for
/// [`crate::camcal`]: `sizes[n]` is camera n's image size and `frames[k].dets[n]` its
/// detections in frame k (a missing list: the camera saw nothing).
///
/// 1. Per camera, `calibrateCamera` with `CALIB_FIX_K3` (Kalibr's four-coefficient radtan) on the
///    frames where it saw at least [`REFERENCE_MIN_CORNERS`] board corners: object points are the
///    board corners of the detected tags (`z = 0`), image points the detected corners in the same
///    order.
/// 2. For every camera n after cam0, `stereoCalibrate` against cam0 with
///    `CALIB_USE_INTRINSIC_GUESS | CALIB_FIX_K3`, on the frames where both saw at least
///    [`REFERENCE_MIN_CORNERS`] corners, with the tags both saw. OpenCV's `(R, T)` maps cam0
///    points into camera n (`p_n = R p_0 + T`): it is `T_cn_c0`.
///
/// The intrinsics returned are those `stereoCalibrate` refined: camera n's from its pair with
/// cam0, cam0's from its pair with cam1 (from `calibrateCamera` for a single camera).
///
/// Errors: no camera, an unusable image size, detections for more cameras than sizes, a board
/// whose corners are not all on its `z = 0` plane, a camera with fewer than
/// [`REFERENCE_MIN_VIEWS`] usable views (or pair with fewer shared frames), and OpenCV's own
/// failures.
pub fn opencv_stereo_reference(
    board: &Board,
    frames: &[FrameTags],
    sizes: &[(u32, u32)],
) -> Result<Camchain> {
    if sizes.is_empty() {
        return Err(Error::Input(
            "the OpenCV reference needs at least one camera".into(),
        ));
    }
    let cv_sizes: Vec<Size> = sizes
        .iter()
        .enumerate()
        .map(|(i, s)| cv_size(i, *s))
        .collect::<Result<_>>()?;
    if let Some((k, f)) = frames
        .iter()
        .enumerate()
        .find(|(_, f)| f.dets.len() > sizes.len())
    {
        return Err(Error::Input(format!(
            "frame {k} ({}) has detections for {} cameras, but {} image sizes were given",
            f.name,
            f.dets.len(),
            sizes.len()
        )));
    }
    let planar = board
        .tags
        .iter()
        .flat_map(|t| t.corners.iter())
        .all(|c| c.z.abs() < 1e-9 && c.x.is_finite() && c.y.is_finite());
    if !planar {
        return Err(Error::Input(
            "OpenCV's calibrateCamera needs a planar board: every tag corner at z = 0".into(),
        ));
    }
    let views: Vec<Vec<ViewCorners>> = frames
        .iter()
        .map(|f| {
            (0..sizes.len())
                .map(|c| view_corners(board, f, c))
                .collect()
        })
        .collect();
    let crit = criteria()?;

    // 1. Each camera alone.
    let mut cams = Vec::with_capacity(sizes.len());
    for (cam, size) in cv_sizes.iter().enumerate() {
        let mut obj = Vector::<Mat>::new();
        let mut img = Vector::<Mat>::new();
        for v in &views {
            let view = &v[cam];
            if 4 * view.len() >= REFERENCE_MIN_CORNERS {
                let (o, i) = cv_points(view, view.keys())?;
                obj.push(o);
                img.push(i);
            }
        }
        if obj.len() < REFERENCE_MIN_VIEWS {
            return Err(Error::TooFewSamples {
                what: format!(
                    "frames in which cam{cam} saw at least {REFERENCE_MIN_CORNERS} board corners"
                ),
                found: obj.len(),
                needed: REFERENCE_MIN_VIEWS,
            });
        }
        let mut c = CvCamera {
            k: Mat::default(),
            dist: Mat::default(),
        };
        let mut rvecs = Vector::<Mat>::new();
        let mut tvecs = Vector::<Mat>::new();
        opencv::calib3d::calibrate_camera(
            &obj,
            &img,
            *size,
            &mut c.k,
            &mut c.dist,
            &mut rvecs,
            &mut tvecs,
            opencv::calib3d::CALIB_FIX_K3,
            crit,
        )
        .map_err(cv_err("calibrateCamera"))?;
        cams.push(c);
    }

    // 2. Every camera against cam0.
    let mut t_cn_c0 = vec![Se3::identity()];
    let mut refined: Vec<Option<CvCamera>> = (0..sizes.len()).map(|_| None).collect();
    for cam in 1..sizes.len() {
        let mut obj = Vector::<Mat>::new();
        let mut img0 = Vector::<Mat>::new();
        let mut img1 = Vector::<Mat>::new();
        for v in &views {
            let (a, b) = (&v[0], &v[cam]);
            let shared: Vec<u32> = a.keys().filter(|id| b.contains_key(id)).copied().collect();
            if 4 * shared.len() >= REFERENCE_MIN_CORNERS {
                let (o, i0) = cv_points(a, shared.iter())?;
                let (_, i1) = cv_points(b, shared.iter())?;
                obj.push(o);
                img0.push(i0);
                img1.push(i1);
            }
        }
        if obj.len() < REFERENCE_MIN_VIEWS {
            return Err(Error::TooFewSamples {
                what: format!(
                    "frames in which cam0 and cam{cam} both saw at least \
                     {REFERENCE_MIN_CORNERS} board corners"
                ),
                found: obj.len(),
                needed: REFERENCE_MIN_VIEWS,
            });
        }
        let mut c0 = CvCamera {
            k: cams[0].k.try_clone().map_err(cv_err("copy"))?,
            dist: cams[0].dist.try_clone().map_err(cv_err("copy"))?,
        };
        let mut c1 = CvCamera {
            k: cams[cam].k.try_clone().map_err(cv_err("copy"))?,
            dist: cams[cam].dist.try_clone().map_err(cv_err("copy"))?,
        };
        let (mut r, mut t, mut e, mut f) = (
            Mat::default(),
            Mat::default(),
            Mat::default(),
            Mat::default(),
        );
        opencv::calib3d::stereo_calibrate(
            &obj,
            &img0,
            &img1,
            &mut c0.k,
            &mut c0.dist,
            &mut c1.k,
            &mut c1.dist,
            cv_sizes[0],
            &mut r,
            &mut t,
            &mut e,
            &mut f,
            opencv::calib3d::CALIB_USE_INTRINSIC_GUESS | opencv::calib3d::CALIB_FIX_K3,
            crit,
        )
        .map_err(cv_err("stereoCalibrate"))?;
        let err = cv_err("stereoCalibrate result");
        let mut rot = Matrix3::zeros();
        let mut trans = Vector3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                rot[(i, j)] = *r.at_2d::<f64>(i as i32, j as i32).map_err(&err)?;
            }
            trans[i] = *t.at::<f64>(i as i32).map_err(&err)?;
        }
        if !(rot.iter().chain(trans.iter()).all(|v| v.is_finite())) {
            return Err(Error::Numerical(format!(
                "cam{cam}: OpenCV's stereoCalibrate returned a non-finite transform"
            )));
        }
        t_cn_c0.push(Se3::new(rot, trans).renormalized());
        if cam == 1 {
            refined[0] = Some(c0);
        }
        refined[cam] = Some(c1);
    }

    let cams = cams
        .into_iter()
        .zip(refined)
        .enumerate()
        .map(|(i, (alone, stereo))| to_camera(i, stereo.as_ref().unwrap_or(&alone), sizes[i]))
        .collect::<Result<Vec<_>>>()?;
    Ok(Camchain {
        topics: vec![None; cams.len()],
        cams,
        t_cn_c0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::sim::camcal_views::synthetic_detections;
    use crate::sim::image_dataset::{default_board, default_stereo_camchain};

    #[test]
    fn ray_error_of_a_camera_against_itself_is_zero() {
        let cam = &default_stereo_camchain().cams[0];
        let e = ray_pixel_error(cam, cam, 16.0).unwrap();
        assert!(e.rms_px < 1e-8 && e.max_px < 1e-8, "{e:?}");
        // 752 / 16 -> 0..736 step 16 plus 751: 48 columns; 480 -> 0..464 plus 479: 31 rows.
        assert_eq!(e.points + e.skipped, 48 * 31);
        assert_eq!(e.skipped, 0);
        assert!(ray_pixel_error(cam, cam, 0.0).is_none());
        assert!(ray_pixel_error(cam, cam, f64::NAN).is_none());
    }

    #[test]
    fn grid_reaches_the_last_pixel() {
        assert_eq!(grid(5, 2.0), vec![0.0, 2.0, 4.0]);
        assert_eq!(grid(6, 2.0), vec![0.0, 2.0, 4.0, 5.0]);
        assert_eq!(grid(1, 3.0), vec![0.0]);
    }

    #[test]
    fn extrinsic_and_baseline_errors() {
        let truth = default_stereo_camchain().t_cn_c0[1];
        assert_eq!(extrinsic_error(&truth, &truth), (0.0, 0.0));
        let d = Se3::new(
            so3::exp(&Vector3::new(0.0, 0.001, 0.0)),
            Vector3::new(0.0, 0.0, 0.0),
        );
        let est = Se3::new(d.rot * truth.rot, truth.trans * 1.01);
        let (dt, dr) = extrinsic_error(&truth, &est);
        assert!((dt - 0.01 * truth.trans.norm()).abs() < 1e-12);
        assert!((dr - 0.001).abs() < 1e-12);
        assert!((baseline_error(&truth, &est) - 0.01 * truth.trans.norm()).abs() < 1e-12);
    }

    #[test]
    fn reference_recovers_a_chain_from_exact_corners() {
        let chain = default_stereo_camchain();
        let board = default_board();
        let views = crate::sim::camcal_views::calibration_views(&chain, &board, 25, 2);
        let mut rng = Rng::new(4);
        let frames: Vec<FrameTags> = views
            .iter()
            .enumerate()
            .map(|(k, t)| FrameTags {
                name: format!("{k}"),
                t_ns: 0,
                dets: chain
                    .cams
                    .iter()
                    .zip(crate::sim::image_dataset::board_in_cameras(&chain, t))
                    .map(|(cam, t_cb)| synthetic_detections(&board, cam, &t_cb, 0.05, &mut rng))
                    .collect(),
            })
            .collect();
        let sizes: Vec<(u32, u32)> = chain.cams.iter().map(|c| (c.width, c.height)).collect();
        let est = opencv_stereo_reference(&board, &frames, &sizes).unwrap();
        for (t, e) in chain.cams.iter().zip(&est.cams) {
            let r = ray_pixel_error(t, e, 8.0).unwrap();
            assert!(r.rms_px < 0.1, "{r:?}");
        }
        let (dt, dr) = extrinsic_error(&chain.t_cn_c0[1], &est.t_cn_c0[1]);
        assert!(dt < 2e-3 && dr < 2e-3, "{dt} {dr}");

        // Bad input is an error, not a panic.
        assert!(opencv_stereo_reference(&board, &frames, &[]).is_err());
        assert!(opencv_stereo_reference(&board, &frames, &sizes[..1]).is_err());
        assert!(opencv_stereo_reference(&board, &frames[..2], &sizes).is_err());
        assert!(opencv_stereo_reference(&board, &frames, &[(0, 480), (752, 480)]).is_err());
        let mut raised = board.clone();
        raised.tags[0].corners[0].z = 0.01;
        assert!(opencv_stereo_reference(&raised, &frames, &sizes).is_err());
    }
}
