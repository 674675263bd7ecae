//! Pose of cam0 in the board frame from the tag corners every camera of a chain sees at once.
//!
//! Per frame:
//! 1. An initial pose from the camera with the most corners: OpenCV's `solvePnP` (SQPnP, then
//!    IPPE and the iterative solver as fall-backs) on corners undistorted through our own
//!    [`crate::types::camera::Camera`] model, so every distortion model we read is handled the same way.
//! 2. Levenberg-Marquardt over the reprojection errors of all cameras, each corner reaching
//!    camera n through the stereo extrinsics `T_cn_c0`.
//! 3. Outlier tags: after each solve, the tag observation (one tag in one camera) with the largest
//!    reprojection RMS is dropped when that RMS exceeds
//!    `max(reject_min_px, reject_factor * median of all observations' RMS)`, and the pose is
//!    solved again, until no observation exceeds the threshold.
//! 4. The covariance of the pose, `sigma_px^2 (J^T J)^-1`, with `sigma_px` estimated from the
//!    residuals (`sqrt(SSR / (m - 6))`, `m` residuals) unless fixed in the options.
//! 5. With two or more cameras, the board's print scale this frame measures
//!    ([`FramePose::board_scale`]): the same observations fitted once more with a factor on the
//!    board's corners as a seventh unknown, which the baseline makes observable. The pose above
//!    is not changed by it.
//! 6. Per camera, the factor on its focal lengths this frame measures
//!    ([`FramePose::focal_scale`]): the camera's own observations fitted with the pose and the
//!    factor together (the perspective of a tilted board tells the focal length from the
//!    distance). The pose is not changed by it either.
//!
//! The pose is `T_board_cam0` (= `T_world_cam0`, the board frame being the world) and its
//! covariance belongs to the right perturbation `T = T_hat * exp(n)`, `n = [rho; phi]`
//! (translation first, metres and radians, cam0 frame), the convention of
//! [`crate::types::PoseMeasurement::cov`] (docs/conventions.md).

use nalgebra::{Matrix2x3, Matrix6, Vector2, Vector3, Vector6};
use opencv::core::{Mat, Point2d, Point3d, Vector};
use opencv::prelude::*;

use crate::error::{Error, Result};
use crate::lie::{Se3, hat, so3};
use crate::types::board::Board;
use crate::types::camera::Camchain;
use crate::vision::detect::TagDetection;

/// Settings of [`stereo_pose`].
#[derive(Clone, Debug, PartialEq)]
pub struct PnpOptions {
    /// Frames with fewer usable corners (all cameras together, after outlier rejection) get no
    /// pose. At least 4.
    pub min_corners: usize,
    /// A tag observation is an outlier when its reprojection RMS exceeds this many times the
    /// median RMS of the frame's observations ...
    pub reject_factor: f64,
    /// ... and this many pixels.
    pub reject_min_px: f64,
    /// Levenberg-Marquardt iterations per solve.
    pub max_iterations: usize,
    /// Pixel noise standard deviation for the covariance; `None`: estimated from the residuals.
    pub sigma_px: Option<f64>,
    /// Lower bound of the estimated pixel noise (keeps the covariance of noise-free or nearly
    /// noise-free corners from collapsing to zero).
    pub min_sigma_px: f64,
}

impl Default for PnpOptions {
    fn default() -> Self {
        PnpOptions {
            min_corners: 8,
            reject_factor: 3.0,
            reject_min_px: 1.0,
            max_iterations: 50,
            sigma_px: None,
            min_sigma_px: 0.02,
        }
    }
}

/// The pose of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FramePose {
    /// `T_world_cam0` with the board frame as world.
    pub t_board_cam0: Se3,
    /// Covariance of the right perturbation `[rho; phi]` of `t_board_cam0` (m, rad; cam0 frame).
    pub cov: Matrix6<f64>,
    /// Reprojection RMS over all used corners: `sqrt(sum |r_i|^2 / corners)`, the RMS pixel
    /// distance between detected and reprojected corners.
    pub rms_px: f64,
    /// Tag observations used (a tag seen by both cameras counts twice).
    pub tags_used: usize,
    /// Tag observations dropped as outliers (and ids seen twice by one camera).
    pub tags_rejected: usize,
    /// Corners used (4 per used observation).
    pub corners_used: usize,
    /// Pixel noise used for the covariance (estimated or fixed).
    pub sigma_px: f64,
    /// Detections whose id is not on the board (ignored).
    pub tags_unknown: usize,
    /// Reprojection RMS of each camera's used corners, px (`None`: the camera had none).
    pub rms_px_per_cam: Vec<Option<f64>>,
    /// The residuals of some of the used corners, for plots: per camera at most
    /// [`CORNER_SAMPLE_PER_CAMERA`], evenly spaced through that camera's corners in board order
    /// (all of them when there are fewer), so that memory stays small per frame.
    pub corner_sample: Vec<CornerResidual>,
    /// The board's print scale this frame measures with the chain's baseline (`None` unless two
    /// cameras saw the board, or when the fit failed). It does not change the pose.
    pub board_scale: Option<FrameScale>,
    /// Per camera, the factor on its focal lengths that this frame's view measures
    /// ([`crate::vision::focal`]; `None` for a camera with too few tags). It does not change
    /// the pose.
    pub focal_scale: Vec<Option<FrameScale>>,
}

/// The size of the board as one frame's cameras measure it: the factor its corners must be
/// multiplied by to fit the images best with the chain's baseline, pose and scale fitted
/// together (see [`solve_stereo`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameScale {
    /// The scale (1: the board is the size its file says).
    pub scale: f64,
    /// Its standard deviation, from the corner noise of the fit.
    pub std: f64,
}

/// Most corners per camera and frame kept in [`FramePose::corner_sample`].
pub const CORNER_SAMPLE_PER_CAMERA: usize = 12;

/// The reprojection residual of one used corner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CornerResidual {
    /// The camera that saw it.
    pub cam: u8,
    /// The detected corner's column, pixels (OpenCV's convention: the centre of the top-left
    /// pixel is 0, 0).
    pub u: f32,
    /// The detected corner's row, pixels.
    pub v: f32,
    /// Reprojected minus detected column, pixels.
    pub du: f32,
    /// Reprojected minus detected row, pixels.
    pub dv: f32,
}

impl CornerResidual {
    /// Length of the residual, pixels.
    pub fn norm(&self) -> f64 {
        (self.du as f64).hypot(self.dv as f64)
    }
}

/// Indices `0..n` of at most `cap` elements, evenly spaced, first included.
fn even_sample(n: usize, cap: usize) -> impl Iterator<Item = usize> {
    let k = n.min(cap);
    (0..k).map(move |i| i * n / k)
}

/// Why a frame got no pose, or its pose.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // one per frame, moved once
pub enum PoseOutcome {
    /// The frame's pose.
    Pose(FramePose),
    /// Fewer than `min_corners` corners on the board (before or after outlier rejection).
    TooFewCorners {
        /// Corners that were left (4 per usable tag observation).
        corners: usize,
    },
    /// No initial solution, or a degenerate configuration (singular normal equations).
    Failed(String),
}

/// One tag seen by one camera.
#[derive(Clone, Debug)]
struct Obs {
    cam: usize,
    board: [Vector3<f64>; 4],
    px: [Vector2<f64>; 4],
}

/// Pose of cam0 from the detections of each camera (`dets[n]` for camera n; a shorter list means
/// the remaining cameras saw nothing). `None` when the frame has too few corners or no solution;
/// [`solve_stereo`] tells which.
pub fn stereo_pose(
    board: &Board,
    chain: &Camchain,
    dets: &[Vec<TagDetection>],
    opts: &PnpOptions,
) -> Result<Option<FramePose>> {
    Ok(match solve_stereo(board, chain, dets, opts)? {
        PoseOutcome::Pose(p) => Some(p),
        _ => None,
    })
}

/// [`stereo_pose`] with the reason of a missing pose.
pub fn solve_stereo(
    board: &Board,
    chain: &Camchain,
    dets: &[Vec<TagDetection>],
    opts: &PnpOptions,
) -> Result<PoseOutcome> {
    if dets.len() > chain.cams.len() || chain.t_cn_c0.len() != chain.cams.len() {
        return Err(Error::Input(format!(
            "detections for {} cameras, but the camera chain has {} cameras and {} extrinsics",
            dets.len(),
            chain.cams.len(),
            chain.t_cn_c0.len()
        )));
    }
    if opts.min_corners < 4 {
        return Err(Error::Input("PnP needs min_corners >= 4".into()));
    }
    let mut obs = Vec::new();
    let mut unknown = 0;
    let mut rejected = 0;
    for (cam, list) in dets.iter().enumerate() {
        for d in list {
            let Some(tag) = board.tag(d.id) else {
                unknown += 1;
                continue;
            };
            let twice = list.iter().filter(|e| e.id == d.id).count() > 1;
            if twice
                || d.corners
                    .iter()
                    .any(|c| !(c.x.is_finite() && c.y.is_finite()))
            {
                rejected += 1;
                continue;
            }
            obs.push(Obs {
                cam,
                board: tag.corners,
                px: d.corners,
            });
        }
    }
    let corners = 4 * obs.len();
    if corners < opts.min_corners {
        return Ok(PoseOutcome::TooFewCorners { corners });
    }

    // Initial pose: cameras by decreasing corner count, the first that solves.
    let mut order: Vec<usize> = (0..dets.len()).collect();
    let count = |c: usize| obs.iter().filter(|o| o.cam == c).count();
    order.sort_by_key(|&c| std::cmp::Reverse(count(c)));
    let mut init = None;
    for &c in &order {
        if count(c) == 0 {
            break;
        }
        if let Some(t_cn_b) = initial_pose(chain, c, &obs) {
            init = Some(chain.t_cn_c0[c].inverse() * t_cn_b);
            break;
        }
    }
    let Some(t_c0_b) = init else {
        return Ok(PoseOutcome::Failed("no initial PnP solution".into()));
    };
    let mut t_b_c0 = t_c0_b.inverse();

    let mut active = vec![true; obs.len()];
    loop {
        let Some(t) = refine(chain, &obs, &active, &t_b_c0, opts.max_iterations) else {
            return Ok(PoseOutcome::Failed(
                "refinement failed (a corner behind a camera)".into(),
            ));
        };
        t_b_c0 = t;
        let rms: Vec<Option<f64>> = obs
            .iter()
            .zip(&active)
            .map(|(o, &a)| if a { obs_rms(chain, o, &t_b_c0) } else { None })
            .collect();
        let mut vals: Vec<f64> = rms.iter().flatten().copied().collect();
        if vals.len() < active.iter().filter(|&&a| a).count() {
            return Ok(PoseOutcome::Failed(
                "a corner projects behind a camera".into(),
            ));
        }
        vals.sort_by(f64::total_cmp);
        let median = vals[vals.len() / 2];
        let threshold = opts.reject_min_px.max(opts.reject_factor * median);
        let worst = rms
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.map(|r| (i, r)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match worst {
            Some((i, r)) if r > threshold => {
                active[i] = false;
                rejected += 1;
                let left = 4 * active.iter().filter(|&&a| a).count();
                if left < opts.min_corners {
                    return Ok(PoseOutcome::TooFewCorners { corners: left });
                }
            }
            _ => break,
        }
    }

    // Covariance at the solution.
    let mut h = Matrix6::zeros();
    let mut ssr = 0.0;
    let mut m = 0usize;
    let n_cams = chain.cams.len();
    let mut per_cam: Vec<Vec<CornerResidual>> = vec![Vec::new(); n_cams];
    let mut sq_cam = vec![0.0f64; n_cams];
    for (o, _) in obs.iter().zip(&active).filter(|(_, a)| **a) {
        for k in 0..4 {
            let Some((r, j)) = residual(chain, o, k, &t_b_c0) else {
                return Ok(PoseOutcome::Failed(
                    "a corner projects behind a camera".into(),
                ));
            };
            h += j.transpose() * j;
            ssr += r.norm_squared();
            m += 2;
            sq_cam[o.cam] += r.norm_squared();
            per_cam[o.cam].push(CornerResidual {
                cam: o.cam.min(u8::MAX as usize) as u8,
                u: o.px[k].x as f32,
                v: o.px[k].y as f32,
                du: r.x as f32,
                dv: r.y as f32,
            });
        }
    }
    let rms_px_per_cam: Vec<Option<f64>> = per_cam
        .iter()
        .zip(&sq_cam)
        .map(|(c, sq)| (!c.is_empty()).then(|| (sq / c.len() as f64).sqrt()))
        .collect();
    let corner_sample: Vec<CornerResidual> = per_cam
        .iter()
        .flat_map(|c| even_sample(c.len(), CORNER_SAMPLE_PER_CAMERA).map(|i| c[i]))
        .collect();
    let sigma = match opts.sigma_px {
        Some(s) => s,
        None => (ssr / (m.saturating_sub(6).max(1)) as f64)
            .sqrt()
            .max(opts.min_sigma_px),
    };
    let Some(hinv) = h.try_inverse() else {
        return Ok(PoseOutcome::Failed(
            "degenerate corner configuration".into(),
        ));
    };
    let cov = (hinv + hinv.transpose()) * (0.5 * sigma * sigma);
    if !cov.iter().all(|v| v.is_finite()) || cov.diagonal().iter().any(|&v| v <= 0.0) {
        return Ok(PoseOutcome::Failed(
            "degenerate corner configuration".into(),
        ));
    }
    let used = active.iter().filter(|&&a| a).count();
    let board_scale = scale_fit(chain, &obs, &active, &t_b_c0, opts);
    let focal_scale = focal_fit(chain, &obs, &active, &t_b_c0, opts);
    Ok(PoseOutcome::Pose(FramePose {
        t_board_cam0: t_b_c0,
        cov,
        rms_px: (ssr / (m / 2) as f64).sqrt(),
        tags_used: used,
        tags_rejected: rejected,
        corners_used: 4 * used,
        sigma_px: sigma,
        tags_unknown: unknown,
        rms_px_per_cam,
        corner_sample,
        board_scale,
        focal_scale,
    }))
}

type Matrix7 = nalgebra::SMatrix<f64, 7, 7>;
type Vector7 = nalgebra::SVector<f64, 7>;
type Matrix2x7 = nalgebra::SMatrix<f64, 2, 7>;

/// Largest Levenberg-Marquardt steps of [`scale_fit`].
const SCALE_FIT_ITERATIONS: usize = 20;

/// The board's scale that one frame measures: the pose and a factor `s` on every board corner
/// (`p_board = s b`) fitted together to the reprojection errors of the active observations,
/// from `t_b_c0` and `s = 1`. With one camera `s` and the distance cannot be told apart; with
/// two or more, the baseline fixes the distance. `None` unless at least two cameras have active
/// observations, and when the fit does not converge to finite values. Its standard deviation is
/// `sigma_px sqrt((J^T J)^-1)` at the solution, `sigma_px` as for the pose.
fn scale_fit(
    chain: &Camchain,
    obs: &[Obs],
    active: &[bool],
    t_b_c0: &Se3,
    opts: &PnpOptions,
) -> Option<FrameScale> {
    let mut seen = vec![false; chain.cams.len()];
    for (o, _) in obs.iter().zip(active).filter(|(_, a)| **a) {
        *seen.get_mut(o.cam)? = true;
    }
    if seen.iter().filter(|&&s| s).count() < 2 {
        return None;
    }
    let used: Vec<&Obs> = obs
        .iter()
        .zip(active)
        .filter(|(_, a)| **a)
        .map(|(o, _)| o)
        .collect();
    fit_with_factor(t_b_c0, opts, |t, s| {
        normal7(&used, |o, k| scaled_residual(chain, o, k, t, s))
    })
}

/// Fewest tag observations of one camera for its focal length's factor in a frame.
const MIN_FOCAL_TAGS: usize = 4;

/// The focal length each camera's view of one frame measures, as a factor on the camchain's
/// (`fu` and `fv` multiplied by it, the principal point and the distortion kept): per camera
/// with at least [`MIN_FOCAL_TAGS`] active observations, the pose and the factor fitted
/// together to that camera's reprojection errors alone. A view of the board straight on cannot
/// tell the focal length from the distance; the perspective of a tilted board can, and the
/// factor's standard deviation (as for the board's scale) says how well. A factor on the focal
/// length does not depend on the board's printed size (which one camera cannot see).
fn focal_fit(
    chain: &Camchain,
    obs: &[Obs],
    active: &[bool],
    t_b_c0: &Se3,
    opts: &PnpOptions,
) -> Vec<Option<FrameScale>> {
    (0..chain.cams.len())
        .map(|cam| {
            let used: Vec<&Obs> = obs
                .iter()
                .zip(active)
                .filter(|(o, a)| **a && o.cam == cam)
                .map(|(o, _)| o)
                .collect();
            if used.len() < MIN_FOCAL_TAGS {
                return None;
            }
            // One Gauss-Newton step from the frame's pose and the camchain's focal length:
            // linear in the residuals, so that the frames' factors average without the bias a
            // weight taken at each frame's own optimum would bring.
            let (c, h, g, m) = normal7(&used, |o, k| focal_residual(chain, o, k, t_b_c0))?;
            let chol = h.cholesky()?;
            let d = -chol.solve(&g);
            let left = (c + g.dot(&d)).max(0.0);
            let sigma = match opts.sigma_px {
                Some(sp) => sp,
                None => (left / (m.saturating_sub(7).max(1)) as f64)
                    .sqrt()
                    .max(opts.min_sigma_px),
            };
            let var = chol.inverse()[(6, 6)] * sigma * sigma;
            let scale = 1.0 + d[6];
            (scale.is_finite() && scale > 0.0 && var.is_finite() && var > 0.0).then(|| FrameScale {
                scale,
                std: var.sqrt(),
            })
        })
        .collect()
}

/// Cost, normal matrix, gradient and number of residuals of the corners of `used` under the
/// residual function `res` (a residual and its Jacobian over the pose and a factor).
fn normal7(
    used: &[&Obs],
    res: impl Fn(&Obs, usize) -> Option<(Vector2<f64>, Matrix2x7)>,
) -> Option<(f64, Matrix7, Vector7, usize)> {
    let mut h = Matrix7::zeros();
    let mut g = Vector7::zeros();
    let mut c = 0.0;
    let mut m = 0;
    for o in used {
        for k in 0..4 {
            let (r, j) = res(o, k)?;
            h += j.transpose() * j;
            g += j.transpose() * r;
            c += r.norm_squared();
            m += 2;
        }
    }
    Some((c, h, g, m))
}

/// Levenberg-Marquardt over a pose (from `t_b_c0`) and a factor (from 1) with the normal
/// equations `normal`; the factor and its standard deviation `sigma_px sqrt((J^T J)^-1)`, or
/// `None` when the fit does not end at finite values.
fn fit_with_factor(
    t_b_c0: &Se3,
    opts: &PnpOptions,
    normal: impl Fn(&Se3, f64) -> Option<(f64, Matrix7, Vector7, usize)>,
) -> Option<FrameScale> {
    let mut t = *t_b_c0;
    let mut s = 1.0;
    let (mut c, mut h, mut g, mut m) = normal(&t, s)?;
    let mut lambda = 1e-6;
    for _ in 0..SCALE_FIT_ITERATIONS {
        let mut a = h;
        for i in 0..7 {
            a[(i, i)] += lambda * h[(i, i)].max(1e-12);
        }
        let d = -a.cholesky()?.solve(&g);
        let cand_t = t.retract(&Vector6::from_iterator(d.iter().take(6).copied()));
        let cand_s = s + d[6];
        match normal(&cand_t, cand_s) {
            Some((cc, hh, gg, mm)) if cc <= c => {
                let small = d.norm() < 1e-12 || c - cc <= 1e-14 * c.max(1e-300);
                (t, s, c, h, g, m) = (cand_t, cand_s, cc, hh, gg, mm);
                lambda = (lambda * 0.1).max(1e-12);
                if small {
                    break;
                }
            }
            _ => {
                lambda *= 10.0;
                if lambda > 1e8 {
                    break;
                }
            }
        }
    }
    let sigma = match opts.sigma_px {
        Some(sp) => sp,
        None => (c / (m.saturating_sub(7).max(1)) as f64)
            .sqrt()
            .max(opts.min_sigma_px),
    };
    let var = h.try_inverse()?[(6, 6)] * sigma * sigma;
    (s.is_finite() && s > 0.0 && var.is_finite() && var > 0.0).then(|| FrameScale {
        scale: s,
        std: var.sqrt(),
    })
}

/// Residual of corner `k` of `o` (as [`residual`] gives it, at the camchain's focal lengths) and
/// its Jacobian with respect to the right perturbation of `T_board_cam0` (first six columns) and
/// to a factor `f` on its camera's focal lengths at `f = 1` (the last): `px = f fu x_d + pu`, so
/// `d px / d f = px - principal point`.
fn focal_residual(
    chain: &Camchain,
    o: &Obs,
    k: usize,
    t_b_c0: &Se3,
) -> Option<(Vector2<f64>, Matrix2x7)> {
    let (r, jp) = residual(chain, o, k, t_b_c0)?;
    let cam = chain.cams.get(o.cam)?;
    let mut j = Matrix2x7::zeros();
    j.fixed_view_mut::<2, 6>(0, 0).copy_from(&jp);
    let px = o.px[k] + r;
    j.set_column(6, &(px - Vector2::new(cam.pu, cam.pv)));
    Some((r, j))
}

/// Residual of corner `k` of `o` with the board scaled by `s`, and its Jacobian with respect to
/// the right perturbation of `T_board_cam0` (first six columns) and to `s` (the last).
fn scaled_residual(
    chain: &Camchain,
    o: &Obs,
    k: usize,
    t_b_c0: &Se3,
    s: f64,
) -> Option<(Vector2<f64>, Matrix2x7)> {
    let r_b_c0 = &t_b_c0.rot;
    let b = o.board[k];
    let p_c0 = r_b_c0.transpose() * (b * s - t_b_c0.trans);
    let t_cn = &chain.t_cn_c0[o.cam];
    let p_cn = t_cn.transform_point(&p_c0);
    let (px, jp) = chain.cams[o.cam].project_jacobian(&p_cn)?;
    let jr: Matrix2x3<f64> = jp * t_cn.rot;
    let mut j = Matrix2x7::zeros();
    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(-jr));
    j.fixed_view_mut::<2, 3>(0, 3).copy_from(&(jr * hat(&p_c0)));
    j.fixed_view_mut::<2, 1>(0, 6)
        .copy_from(&(jr * (r_b_c0.transpose() * b)));
    let r = px - o.px[k];
    (r.x.is_finite() && r.y.is_finite()).then_some((r, j))
}

/// Residual (projected minus detected pixel) of corner `k` of `o` and its Jacobian with respect
/// to the right perturbation of `T_board_cam0`.
fn residual(
    chain: &Camchain,
    o: &Obs,
    k: usize,
    t_b_c0: &Se3,
) -> Option<(Vector2<f64>, nalgebra::Matrix2x6<f64>)> {
    // p_c0 = T_b_c0^-1 p_b; with T_b_c0 exp(d): p_c0' = exp(-d) p_c0, d p_c0 / d[rho; phi] = [-I, p_c0^].
    let r_b_c0 = &t_b_c0.rot;
    let p_c0 = r_b_c0.transpose() * (o.board[k] - t_b_c0.trans);
    let t_cn = &chain.t_cn_c0[o.cam];
    let p_cn = t_cn.transform_point(&p_c0);
    let (px, jp) = chain.cams[o.cam].project_jacobian(&p_cn)?;
    let jr: Matrix2x3<f64> = jp * t_cn.rot;
    let mut j = nalgebra::Matrix2x6::zeros();
    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(-jr));
    j.fixed_view_mut::<2, 3>(0, 3).copy_from(&(jr * hat(&p_c0)));
    let r = px - o.px[k];
    if !(r.x.is_finite() && r.y.is_finite()) {
        return None;
    }
    Some((r, j))
}

/// RMS pixel distance of one observation's four corners.
fn obs_rms(chain: &Camchain, o: &Obs, t_b_c0: &Se3) -> Option<f64> {
    let mut s = 0.0;
    for k in 0..4 {
        s += residual(chain, o, k, t_b_c0)?.0.norm_squared();
    }
    Some((s / 4.0).sqrt())
}

/// Sum of squared residuals, normal matrix and gradient of the active observations.
fn normal_equations(
    chain: &Camchain,
    obs: &[Obs],
    active: &[bool],
    t: &Se3,
) -> Option<(f64, Matrix6<f64>, Vector6<f64>)> {
    let mut h = Matrix6::zeros();
    let mut g = Vector6::zeros();
    let mut c = 0.0;
    for (o, _) in obs.iter().zip(active).filter(|(_, a)| **a) {
        for k in 0..4 {
            let (r, j) = residual(chain, o, k, t)?;
            h += j.transpose() * j;
            g += j.transpose() * r;
            c += r.norm_squared();
        }
    }
    Some((c, h, g))
}

fn cost(chain: &Camchain, obs: &[Obs], active: &[bool], t: &Se3) -> Option<f64> {
    let mut c = 0.0;
    for (o, _) in obs.iter().zip(active).filter(|(_, a)| **a) {
        for k in 0..4 {
            c += residual(chain, o, k, t)?.0.norm_squared();
        }
    }
    Some(c)
}

/// Levenberg-Marquardt on the right perturbation of `T_board_cam0`.
fn refine(
    chain: &Camchain,
    obs: &[Obs],
    active: &[bool],
    start: &Se3,
    max_iterations: usize,
) -> Option<Se3> {
    let mut t = *start;
    let (mut c, mut h, mut g) = normal_equations(chain, obs, active, &t)?;
    let mut lambda = 1e-4;
    for _ in 0..max_iterations {
        let mut improved = false;
        while lambda < 1e12 {
            let mut a = h;
            for i in 0..6 {
                a[(i, i)] += lambda * h[(i, i)].max(1e-9);
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let d = -chol.solve(&g);
            let cand = t.retract(&d);
            match normal_equations(chain, obs, active, &cand) {
                Some((cc, hh, gg)) if cc <= c => {
                    let small = d.norm() < 1e-12 || c - cc <= 1e-14 * c.max(1e-300);
                    t = cand;
                    c = cc;
                    h = hh;
                    g = gg;
                    lambda = (lambda * 0.1).max(1e-12);
                    improved = true;
                    if small {
                        return Some(t);
                    }
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    // The start may have a corner behind a camera: then there is no solution from it.
    cost(chain, obs, active, &t).map(|_| t)
}

/// `T_cn_board` from camera `cam`'s corners alone, through OpenCV's solvePnP on undistorted
/// normalised coordinates.
fn initial_pose(chain: &Camchain, cam: usize, obs: &[Obs]) -> Option<Se3> {
    let camera = &chain.cams[cam];
    let mut object = Vector::<Point3d>::new();
    let mut image = Vector::<Point2d>::new();
    for o in obs.iter().filter(|o| o.cam == cam) {
        for k in 0..4 {
            let Some(ray) = camera.unproject(&o.px[k]) else {
                continue;
            };
            object.push(Point3d::new(o.board[k].x, o.board[k].y, o.board[k].z));
            image.push(Point2d::new(ray.x, ray.y));
        }
    }
    if object.len() < 4 {
        return None;
    }
    let k = Mat::from_slice_2d(&[[1.0f64, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).ok()?;
    let dist = Mat::default();
    use opencv::calib3d::{SOLVEPNP_IPPE, SOLVEPNP_ITERATIVE, SOLVEPNP_SQPNP, solve_pnp};
    for flags in [SOLVEPNP_SQPNP, SOLVEPNP_IPPE, SOLVEPNP_ITERATIVE] {
        let mut rvec = Mat::default();
        let mut tvec = Mat::default();
        match solve_pnp(
            &object, &image, &k, &dist, &mut rvec, &mut tvec, false, flags,
        ) {
            Ok(true) => {}
            _ => continue,
        }
        let (Some(r), Some(tr)) = (mat3(&rvec), mat3(&tvec)) else {
            continue;
        };
        let t = Se3::new(so3::exp(&r), tr);
        // All corners in front of the camera.
        if obs
            .iter()
            .filter(|o| o.cam == cam)
            .all(|o| o.board.iter().all(|p| t.transform_point(p).z > 0.0))
        {
            return Some(t);
        }
    }
    None
}

/// A 3-vector from a 3x1 or 1x3 CV_64F matrix (`None` unless all three are finite).
pub(crate) fn mat3(m: &Mat) -> Option<Vector3<f64>> {
    if m.total() != 3 {
        return None;
    }
    let mut v = Vector3::zeros();
    for i in 0..3 {
        v[i] = *m.at::<f64>(i as i32).ok()?;
    }
    v.iter().all(|x| x.is_finite()).then_some(v)
}
