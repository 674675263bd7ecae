//! The joint bundle adjustment of all cameras' intrinsics, the extrinsics `T_cn_c0` and every
//! frame's board pose `T_c0_board`.
//!
//! Residual of a corner `X` (board frame) seen by camera `c` in frame `f` at pixel `u`:
//! `r = pi_c(T_c_c0 T_c0_board(f) X) - u`, with `pi_c` the pinhole-with-distortion projection of
//! [`Camera::project`]. Unknowns: per camera `[fu, fv, pu, pv, d1..d4]`; per camera after cam0 a
//! left perturbation of `T_c_c0`; per frame a left perturbation of `T_c0_board`
//! (`T <- exp([rho; phi]) T`). The frame poses are eliminated from the Levenberg-Marquardt
//! normal equations frame by frame (each is a 6x6 block), which leaves a small dense system in
//! the camera parameters (22 unknowns for a stereo pair).
//!
//! The covariance of the camera parameters is `sigma^2 S^-1`, `S` the undamped Schur complement
//! at the solution (the frame poses marginalised) and `sigma^2 = SSR / (m - n)` over the `m`
//! residual components and `n` unknowns.

use nalgebra::{
    DMatrix, DVector, Matrix2x3, Matrix3, Matrix3x6, Matrix6, SMatrix, Vector2, Vector3, Vector6,
};

use crate::camcal::init::initial_estimate;
use crate::camcal::quality::{coverage, weak_points};
use crate::camcal::types::{
    CamCalOptions, CamCalResult, CameraModel, CameraStd, CornerObs, FrameFit, FrameTags, Residual,
};
use crate::camcal::views::match_views;
use crate::error::{Error, Result};
use crate::io::camchain::{camchain_yaml, parse_camchain};
use crate::lie::{Se3, hat};
use crate::types::board::Board;
use crate::types::camera::{Camchain, Camera};

/// Intrinsic unknowns per camera: `fu, fv, pu, pv` and four distortion coefficients.
const NI: usize = 8;

/// Largest overall reprojection RMS (px) of a calibration that is written: beyond it the model,
/// the board's size or the detections are wrong.
pub const MAX_RMS_PX: f64 = 2.0;

/// Largest share of the frames that may be dropped as outlier frames; beyond it the model fits
/// the data badly and dropping frames would hide it.
const MAX_DROPPED_FRAME_SHARE: f64 = 0.2;

/// Intrinsics and distortion of the model `m` from a camera.
fn params(c: &Camera) -> [f64; NI] {
    let k = c.distortion.coeffs();
    let g = |i: usize| k.get(i).copied().unwrap_or(0.0);
    [c.fu, c.fv, c.pu, c.pv, g(0), g(1), g(2), g(3)]
}

fn camera(p: &[f64; NI], model: CameraModel, w: u32, h: u32) -> Camera {
    Camera {
        fu: p[0],
        fv: p[1],
        pu: p[2],
        pv: p[3],
        distortion: model.distortion([p[4], p[5], p[6], p[7]]),
        width: w,
        height: h,
    }
}

/// The unknowns.
#[derive(Clone, Debug)]
struct State {
    model: CameraModel,
    cams: Vec<Camera>,
    /// `T_cn_c0` (identity for cam0).
    ext: Vec<Se3>,
    /// `T_c0_board` per frame.
    poses: Vec<Option<Se3>>,
}

impl State {
    fn chain(&self) -> Camchain {
        Camchain {
            cams: self.cams.clone(),
            t_cn_c0: self.ext.clone(),
            topics: vec![None; self.cams.len()],
        }
    }

    /// Residual of one corner and, with `jac`, its Jacobians: intrinsics (2x8), the frame pose
    /// (2x6), and the extrinsics (2x6, zero for cam0). `None` when the corner is behind the camera.
    fn residual(&self, o: &CornerObs, jac: bool) -> Option<(Vector2<f64>, Option<Jacs>)> {
        let t_c0_b = self.poses[o.frame]?;
        let p0 = t_c0_b.transform_point(&o.board);
        let (pc, r_c_c0) = if o.cam == 0 {
            (p0, Matrix3::identity())
        } else {
            (self.ext[o.cam].transform_point(&p0), self.ext[o.cam].rot)
        };
        if pc.z.is_nan() || pc.z <= 1e-9 {
            return None;
        }
        let cam = &self.cams[o.cam];
        let iz = 1.0 / pc.z;
        let n = Vector2::new(pc.x * iz, pc.y * iz);
        let (d, jd) = cam.distortion.distort(&n);
        let u = Vector2::new(cam.fu * d.x + cam.pu, cam.fv * d.y + cam.pv);
        let r = u - o.px;
        if !jac {
            return Some((r, None));
        }
        let jk = cam.distortion.coeff_jacobian(&n);
        let mut ji = SMatrix::<f64, 2, NI>::zeros();
        ji[(0, 0)] = d.x;
        ji[(1, 1)] = d.y;
        ji[(0, 2)] = 1.0;
        ji[(1, 3)] = 1.0;
        for k in 0..4 {
            ji[(0, 4 + k)] = cam.fu * jk[(0, k)];
            ji[(1, 4 + k)] = cam.fv * jk[(1, k)];
        }
        let jn = Matrix2x3::new(iz, 0.0, -n.x * iz, 0.0, iz, -n.y * iz);
        let jf = nalgebra::Matrix2::new(cam.fu, 0.0, 0.0, cam.fv);
        let jp = jf * jd * jn;
        let point = |p: &Vector3<f64>| {
            let mut m = Matrix3x6::zeros();
            m.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&Matrix3::identity());
            m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-hat(p)));
            m
        };
        let jpose = jp * r_c_c0 * point(&p0);
        let jext = if o.cam == 0 {
            SMatrix::<f64, 2, 6>::zeros()
        } else {
            jp * point(&pc)
        };
        Some((
            r,
            Some(Jacs {
                intr: ji,
                pose: jpose,
                ext: jext,
            }),
        ))
    }
}

struct Jacs {
    intr: SMatrix<f64, 2, NI>,
    pose: SMatrix<f64, 2, 6>,
    ext: SMatrix<f64, 2, 6>,
}

/// One frame's part of the normal equations: its index, `H_ff`, `H_tf` and `g_f`.
type FrameBlock = (usize, Matrix6<f64>, DMatrix<f64>, Vector6<f64>);

/// The normal equations, frame poses separate.
struct Normal {
    /// Camera block (intrinsics of every camera, then extrinsics of cam1..).
    htt: DMatrix<f64>,
    gt: DVector<f64>,
    /// Per frame (only frames with active corners): index, H_ff, H_tf, g_f.
    frames: Vec<FrameBlock>,
    /// Per frame (same order): the frame's share of `gt`.
    gt_frame: Vec<DVector<f64>>,
    cost: f64,
}

fn camera_dim(cams: usize) -> usize {
    NI * cams + 6 * cams.saturating_sub(1)
}

fn build(state: &State, obs: &[CornerObs], active: &[bool]) -> Option<Normal> {
    let cams = state.cams.len();
    let c = camera_dim(cams);
    let mut htt = DMatrix::zeros(c, c);
    let mut gt = DVector::zeros(c);
    let mut frames: Vec<FrameBlock> = Vec::new();
    let mut gt_frame: Vec<DVector<f64>> = Vec::new();
    let mut cost = 0.0;
    for (o, _) in obs.iter().zip(active).filter(|(_, a)| **a) {
        let (r, j) = state.residual(o, true)?;
        let j = j?;
        cost += r.norm_squared();
        if frames.last().is_none_or(|f| f.0 != o.frame) {
            frames.push((
                o.frame,
                Matrix6::zeros(),
                DMatrix::zeros(c, 6),
                Vector6::zeros(),
            ));
            gt_frame.push(DVector::zeros(c));
        }
        let fr = frames.last_mut()?;
        let fg = gt_frame.last_mut()?;
        // Local camera Jacobian: 8 intrinsic columns, then 6 extrinsic ones (cam n > 0; for cam0
        // only the first 8 are used). Fixed-size, so nothing is allocated per corner.
        let ii = NI * o.cam;
        let ie = NI * cams + 6 * o.cam.saturating_sub(1);
        let width = if o.cam > 0 { NI + 6 } else { NI };
        let idx: [usize; NI + 6] =
            std::array::from_fn(|a| if a < NI { ii + a } else { ie + a - NI });
        let mut jl = SMatrix::<f64, 2, { NI + 6 }>::zeros();
        jl.fixed_view_mut::<2, NI>(0, 0).copy_from(&j.intr);
        jl.fixed_view_mut::<2, 6>(0, NI).copy_from(&j.ext);
        let hl = jl.transpose() * jl;
        let gl = jl.transpose() * r;
        let hlf = jl.transpose() * j.pose;
        for a in 0..width {
            let ia = idx[a];
            gt[ia] += gl[a];
            fg[ia] += gl[a];
            for b in 0..width {
                htt[(ia, idx[b])] += hl[(a, b)];
            }
            for k in 0..6 {
                fr.2[(ia, k)] += hlf[(a, k)];
            }
        }
        fr.1 += j.pose.transpose() * j.pose;
        fr.3 += j.pose.transpose() * r;
    }
    Some(Normal {
        htt,
        gt,
        frames,
        gt_frame,
        cost,
    })
}

/// The cost of the active corners at a state; `None` when a corner falls behind its camera.
fn cost(state: &State, obs: &[CornerObs], active: &[bool]) -> Option<f64> {
    let mut s = 0.0;
    for (o, _) in obs.iter().zip(active).filter(|(_, a)| **a) {
        s += state.residual(o, false)?.0.norm_squared();
    }
    Some(s)
}

/// The Schur complement `S` and right side `b` with damping `lambda` (Marquardt: the diagonal
/// scaled by `1 + lambda`), and the inverses of the damped frame blocks.
fn schur(n: &Normal, lambda: f64) -> (DMatrix<f64>, DVector<f64>, Vec<Option<Matrix6<f64>>>) {
    let mut s = n.htt.clone();
    for i in 0..s.nrows() {
        s[(i, i)] += lambda * n.htt[(i, i)].max(1e-12);
    }
    let mut b = n.gt.clone();
    let mut invs = Vec::with_capacity(n.frames.len());
    for (_, hff, htf, gf) in &n.frames {
        let mut h = *hff;
        for i in 0..6 {
            h[(i, i)] += lambda * hff[(i, i)].max(1e-12);
        }
        let inv = h.try_inverse();
        if let Some(inv) = inv {
            let w = htf * inv;
            s -= &w * htf.transpose();
            b -= &w * gf;
        }
        invs.push(inv);
    }
    (s, b, invs)
}

/// Applies a step to a state.
fn step(state: &State, n: &Normal, dt: &DVector<f64>, invs: &[Option<Matrix6<f64>>]) -> State {
    let cams = state.cams.len();
    let mut next = state.clone();
    for c in 0..cams {
        let mut p = params(&state.cams[c]);
        for (k, v) in p.iter_mut().enumerate() {
            *v += dt[NI * c + k];
        }
        let cam = &state.cams[c];
        next.cams[c] = camera(&p, state.model, cam.width, cam.height);
    }
    for c in 1..cams {
        let i = NI * cams + 6 * (c - 1);
        let xi = Vector6::from_iterator((0..6).map(|k| dt[i + k]));
        next.ext[c] = (Se3::exp(&xi) * state.ext[c]).renormalized();
    }
    for ((f, _, htf, gf), inv) in n.frames.iter().zip(invs) {
        let Some(inv) = inv else { continue };
        let Some(t) = state.poses[*f] else { continue };
        let df = -(inv * (gf + htf.transpose() * dt));
        next.poses[*f] = Some((Se3::exp(&df) * t).renormalized());
    }
    next
}

/// Levenberg-Marquardt from `state` over the active corners; returns the iterations taken.
fn adjust(state: &mut State, obs: &[CornerObs], active: &[bool], max_iter: usize) -> Result<usize> {
    let mut lambda = 1e-4;
    let mut iterations = 0;
    for _ in 0..max_iter {
        let n = build(state, obs, active).ok_or_else(|| {
            Error::Input("a board corner fell behind its camera during the adjustment".into())
        })?;
        iterations += 1;
        let mut accepted = false;
        for _ in 0..12 {
            let (s, b, invs) = schur(&n, lambda);
            let Some(ch) = s.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let dt = -ch.solve(&b);
            let next = step(state, &n, &dt, &invs);
            match cost(&next, obs, active) {
                Some(c) if c <= n.cost => {
                    let gain = n.cost - c;
                    *state = next;
                    lambda = (lambda / 3.0).max(1e-12);
                    accepted = true;
                    if gain <= 1e-12 * n.cost.max(1e-30) {
                        return Ok(iterations);
                    }
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !accepted {
            break;
        }
    }
    Ok(iterations)
}

/// Median of absolute values times 1.4826: the standard deviation of Gaussian values, robust to
/// outliers.
fn robust_sigma(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    for x in v.iter_mut() {
        *x = x.abs();
    }
    v.sort_by(f64::total_cmp);
    1.4826 * v[v.len() / 2]
}

/// Calibrates every camera of a chain from the board detections of `frames`; `sizes` are the
/// image sizes (width, height) per camera. See the module documentation of [`crate::camcal`].
pub fn calibrate_cameras(
    board: &Board,
    frames: &[FrameTags],
    sizes: &[(u32, u32)],
    opts: &CamCalOptions,
) -> Result<CamCalResult> {
    if sizes.is_empty() {
        return Err(Error::Input("camera calibration: no cameras".into()));
    }
    if !(opts.outlier_sigmas > 1.0 && opts.frame_rms_factor > 1.0) {
        return Err(Error::Input(
            "camera calibration: the outlier thresholds must exceed 1".into(),
        ));
    }
    let cams = sizes.len();
    let matched = match_views(board, frames, sizes, opts.border_px, opts.min_view_corners);
    let obs = matched.obs;
    for cam in 0..cams {
        let views = count_views(&obs, cam);
        if views < opts.min_views.max(3) {
            return Err(Error::Input(format!(
                "cam{cam}: the board was seen with at least {} corners in {views} frames; a camera \
                 calibration needs at least {} (better 30 or more, from many angles, covering the \
                 whole image)",
                opts.min_view_corners,
                opts.min_views.max(3)
            )));
        }
    }
    let init = initial_estimate(&obs, frames.len(), sizes, opts.model)?;
    let mut state = State {
        model: opts.model,
        cams: init.chain.cams.clone(),
        ext: init.chain.t_cn_c0.clone(),
        poses: init.t_c0_board.clone(),
    };
    let mut active: Vec<bool> = obs.iter().map(|o| state.poses[o.frame].is_some()).collect();
    let mut dropped: Vec<Option<String>> = vec![None; frames.len()];
    let mut warnings = Vec::new();
    let mut iterations = 0;
    for _round in 0..10 {
        iterations = adjust(&mut state, &obs, &active, opts.max_iterations)?;
        let res: Vec<Option<Vector2<f64>>> = obs
            .iter()
            .map(|o| state.residual(o, false).map(|r| r.0))
            .collect();
        let mut comps: Vec<f64> = res
            .iter()
            .zip(&active)
            .filter(|(_, a)| **a)
            .filter_map(|(r, _)| *r)
            .flat_map(|r| [r.x, r.y])
            .collect();
        let sigma = robust_sigma(&mut comps);
        let limit = (opts.outlier_sigmas * sigma).max(0.2);
        let mut changed = false;
        for (a, r) in active.iter_mut().zip(&res) {
            if *a && r.is_none_or(|r| r.norm() > limit) {
                *a = false;
                changed = true;
            }
        }
        // A view (one camera in one frame) most of whose corners are outliers is wrong as a
        // whole (a misread tag, a moving board, a smeared image): its frame goes.
        let mut total = vec![vec![0usize; cams]; frames.len()];
        let mut kept = vec![vec![0usize; cams]; frames.len()];
        for (o, a) in obs.iter().zip(&active) {
            if dropped[o.frame].is_none() && state.poses[o.frame].is_some() {
                total[o.frame][o.cam] += 1;
                kept[o.frame][o.cam] += usize::from(*a);
            }
        }
        for f in 0..frames.len() {
            let Some(c) = (0..cams).find(|&c| total[f][c] > 0 && 2 * kept[f][c] < total[f][c])
            else {
                continue;
            };
            dropped[f] = Some(format!(
                "{} of cam{c}'s {} corners were outliers (over {limit:.2} px)",
                total[f][c] - kept[f][c],
                total[f][c]
            ));
            for (a, o) in active.iter_mut().zip(&obs) {
                if o.frame == f {
                    *a = false;
                }
            }
            changed = true;
        }
        // Outlier frames: RMS over the frame's used corners far above the median frame's.
        let rms = frame_rms(&obs, &active, &res, frames.len());
        let mut sorted: Vec<f64> = rms.iter().flatten().copied().collect();
        sorted.sort_by(f64::total_cmp);
        if let Some(&median) = sorted.get(sorted.len() / 2) {
            let cut = (opts.frame_rms_factor * median).max(0.3);
            let bad: Vec<usize> = (0..frames.len())
                .filter(|&f| rms[f].is_some_and(|r| r > cut))
                .collect();
            let already = dropped.iter().filter(|d| d.is_some()).count();
            if !bad.is_empty() {
                if (already + bad.len()) as f64 > MAX_DROPPED_FRAME_SHARE * frames.len() as f64 {
                    let msg = format!(
                        "{} frames have a reprojection RMS above {cut:.2} px ({}x the median \
                         frame's); too many to drop: the {} model may not fit these lenses",
                        bad.len(),
                        opts.frame_rms_factor,
                        opts.model.name()
                    );
                    if !warnings.contains(&msg) {
                        warnings.push(msg);
                    }
                } else {
                    for f in bad {
                        dropped[f] = Some(format!(
                            "reprojection RMS {:.2} px, over {:.1}x the median frame's {median:.2} px",
                            rms[f].unwrap_or(f64::NAN),
                            opts.frame_rms_factor
                        ));
                        for (a, o) in active.iter_mut().zip(&obs) {
                            if o.frame == f {
                                *a = false;
                            }
                        }
                    }
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }

    // Final residuals, noise and covariance.
    let res: Vec<Option<Vector2<f64>>> = obs
        .iter()
        .map(|o| state.residual(o, false).map(|r| r.0))
        .collect();
    let used = active.iter().filter(|a| **a).count();
    let n = build(&state, &obs, &active).ok_or_else(|| {
        Error::Input("a board corner fell behind its camera at the solution".into())
    })?;
    let unknowns = camera_dim(cams) + 6 * n.frames.len();
    let m = 2 * used;
    if m <= unknowns {
        return Err(Error::Input(format!(
            "camera calibration: {used} corners cannot determine {unknowns} unknowns"
        )));
    }
    let sigma2 = n.cost / (m - unknowns) as f64;
    let (s, _, _) = schur(&n, 0.0);
    let s_inv = s.clone().cholesky().map(|c| c.inverse()).ok_or_else(|| {
        Error::Input(
            "the views do not determine every camera parameter (the board was seen from too few \
             angles or distances)"
                .into(),
        )
    })?;
    // Two covariances of the camera unknowns: the model's, `sigma^2 S^-1` (corner errors
    // independent), and the one clustered by frame, `F/(F-1) sum_f u_f u_f^T` with
    // `u_f = S^-1 g_f` (the frame's share of the camera gradient; its pose's own gradient is zero
    // at the solution), which holds whatever the errors' correlation within a frame (corner
    // errors shared by a tag's corners, or by a whole view's blur and tilt). Each parameter's
    // standard deviation is the larger of the two.
    let model_cov = &s_inv * sigma2;
    let nf = n.gt_frame.len() as f64;
    let mut clustered = DMatrix::zeros(s_inv.nrows(), s_inv.ncols());
    for g in &n.gt_frame {
        let u = &s_inv * g;
        clustered += &u * u.transpose();
    }
    if nf > 1.0 {
        clustered *= nf / (nf - 1.0);
    }
    let cov = larger_variances(&model_cov, &clustered);
    let std = camera_std(&state, &cov);
    let chain = state.chain();
    // What comes back from the file must be what was found.
    let yaml = camchain_yaml(&chain);
    parse_camchain(&yaml, std::path::Path::new("<fitted camchain>")).map_err(|e| {
        Error::Input(format!(
            "the fitted cameras are not a valid camera chain ({e}); the views do not determine \
             the lens"
        ))
    })?;

    let residuals: Vec<Residual> = obs
        .iter()
        .zip(&res)
        .zip(&active)
        .filter_map(|((o, r), a)| {
            r.map(|r| Residual {
                frame: o.frame,
                cam: o.cam,
                px: o.px,
                r,
                used: *a,
            })
        })
        .collect();
    let mut rms_cam = vec![0.0; cams];
    let mut cnt_cam = vec![0usize; cams];
    for r in residuals.iter().filter(|r| r.used) {
        rms_cam[r.cam] += r.r.norm_squared();
        cnt_cam[r.cam] += 1;
    }
    let total: f64 = rms_cam.iter().sum();
    let rms_px = (total / used.max(1) as f64).sqrt();
    for (v, n) in rms_cam.iter_mut().zip(&cnt_cam) {
        *v = (*v / (*n).max(1) as f64).sqrt();
    }
    if rms_px.is_nan() || rms_px > MAX_RMS_PX {
        return Err(Error::Input(format!(
            "camera calibration failed: reprojection RMS {rms_px:.2} px (at most {MAX_RMS_PX} px \
             is expected of a good fit); check the board's tag size and the camera model ({})",
            opts.model.name()
        )));
    }
    let frame_fits = frame_fits(
        frames,
        &matched.corners,
        &state,
        &obs,
        &active,
        &res,
        &dropped,
    );
    let coverage: Vec<_> = (0..cams)
        .map(|c| {
            coverage(
                &chain.cams[c],
                residuals
                    .iter()
                    .filter(|r| r.used && r.cam == c)
                    .map(|r| r.px),
                opts.coverage_cells,
            )
        })
        .collect();
    let views_used: Vec<usize> = (0..cams)
        .map(|c| {
            frame_fits
                .iter()
                .filter(|f| f.dropped.is_none() && f.rms_px.get(c).is_some_and(|r| r.is_some()))
                .count()
        })
        .collect();
    let mut tilts: Vec<f64> = frame_fits
        .iter()
        .filter(|f| f.dropped.is_none())
        .filter_map(|f| f.t_c0_board)
        .map(|t| t.rot[(2, 2)].abs().min(1.0).acos().to_degrees())
        .collect();
    tilts.sort_by(f64::total_cmp);
    let tilt_p90_deg = tilts
        .get((tilts.len() * 9 / 10).min(tilts.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    warnings.extend(weak_points(
        &chain,
        &std,
        &coverage,
        &views_used,
        tilt_p90_deg,
    ));
    Ok(CamCalResult {
        chain,
        model: opts.model,
        std,
        sigma_px: sigma2.sqrt(),
        rms_px,
        rms_px_per_cam: rms_cam,
        initial: init.chain,
        initial_rms_px: init.rms_px,
        frames: frame_fits,
        residuals,
        coverage,
        views_used,
        corners_used: used,
        corners_rejected: obs.len() - used,
        detections_unmatched: matched.unmatched,
        tags_at_border: matched.at_border,
        tilt_p90_deg,
        iterations,
        warnings,
    })
}

fn count_views(obs: &[CornerObs], cam: usize) -> usize {
    let mut frames: Vec<usize> = obs
        .iter()
        .filter(|o| o.cam == cam)
        .map(|o| o.frame)
        .collect();
    frames.dedup();
    frames.len()
}

fn frame_rms(
    obs: &[CornerObs],
    active: &[bool],
    res: &[Option<Vector2<f64>>],
    frames: usize,
) -> Vec<Option<f64>> {
    let mut sq = vec![0.0; frames];
    let mut n = vec![0usize; frames];
    for ((o, a), r) in obs.iter().zip(active).zip(res) {
        if let (true, Some(r)) = (a, r) {
            sq[o.frame] += r.norm_squared();
            n[o.frame] += 1;
        }
    }
    sq.iter()
        .zip(&n)
        .map(|(s, &k)| (k > 0).then(|| (s / k as f64).sqrt()))
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn frame_fits(
    frames: &[FrameTags],
    corners: &[Vec<usize>],
    state: &State,
    obs: &[CornerObs],
    active: &[bool],
    res: &[Option<Vector2<f64>>],
    dropped: &[Option<String>],
) -> Vec<FrameFit> {
    let cams = state.cams.len();
    let mut sq = vec![vec![0.0; cams]; frames.len()];
    let mut n = vec![vec![0usize; cams]; frames.len()];
    for ((o, a), r) in obs.iter().zip(active).zip(res) {
        if let (true, Some(r)) = (a, r) {
            sq[o.frame][o.cam] += r.norm_squared();
            n[o.frame][o.cam] += 1;
        }
    }
    frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let rms: Vec<Option<f64>> = (0..cams)
                .map(|c| (n[i][c] > 0).then(|| (sq[i][c] / n[i][c] as f64).sqrt()))
                .collect();
            let used = rms.iter().any(Option::is_some);
            let why = dropped[i]
                .clone()
                .or_else(|| (!used).then(|| "no camera saw enough of the board".to_string()));
            FrameFit {
                frame: i,
                name: f.name.clone(),
                t_ns: f.t_ns,
                corners: corners.get(i).cloned().unwrap_or_else(|| vec![0; cams]),
                t_c0_board: if used { state.poses[i] } else { None },
                rms_px: rms,
                dropped: why,
            }
        })
        .collect()
}

/// The covariance whose every variance is the larger of the two, with the correlations of `a`
/// (each row and column of `a` scaled by the ratio of the standard deviations).
fn larger_variances(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let k: Vec<f64> = (0..a.nrows())
        .map(|i| {
            let (va, vb) = (a[(i, i)], b[(i, i)]);
            if va > 0.0 && vb > va {
                (vb / va).sqrt()
            } else {
                1.0
            }
        })
        .collect();
    DMatrix::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] * k[i] * k[j])
}

/// Standard deviations from the covariance of the camera unknowns.
fn camera_std(state: &State, cov: &DMatrix<f64>) -> Vec<CameraStd> {
    let cams = state.cams.len();
    let sd = |i: usize| cov[(i, i)].max(0.0).sqrt();
    (0..cams)
        .map(|c| {
            let b = NI * c;
            let intrinsics = [sd(b), sd(b + 1), sd(b + 2), sd(b + 3)];
            let distortion = [sd(b + 4), sd(b + 5), sd(b + 6), sd(b + 7)];
            if c == 0 {
                return CameraStd {
                    intrinsics,
                    distortion,
                    rotation_rad: None,
                    translation_m: None,
                    baseline_m: None,
                };
            }
            // T_cn_cnm1 = T_cn_c0 T_cm_c0^-1 (m = n - 1); its left perturbation is
            // eta = eps_n - Ad(T_cn_cm) eps_m, and its translation moves by [I, -t^] eta.
            let t_n_m = state.ext[c] * state.ext[c - 1].inverse();
            let base = NI * cams;
            let mut a = DMatrix::<f64>::zeros(6, cov.nrows());
            let i_n = base + 6 * (c - 1);
            for k in 0..6 {
                a[(k, i_n + k)] = 1.0;
            }
            if c >= 2 {
                let ad = t_n_m.adjoint();
                let i_m = base + 6 * (c - 2);
                for r in 0..6 {
                    for k in 0..6 {
                        a[(r, i_m + k)] = -ad[(r, k)];
                    }
                }
            }
            let ce = &a * cov * a.transpose();
            let mut bt = DMatrix::<f64>::zeros(3, 6);
            bt.view_mut((0, 0), (3, 3)).copy_from(&Matrix3::identity());
            bt.view_mut((0, 3), (3, 3)).copy_from(&(-hat(&t_n_m.trans)));
            let ct = &bt * &ce * bt.transpose();
            let t = t_n_m.trans;
            let base_len = t.norm();
            let u = if base_len > 0.0 {
                t / base_len
            } else {
                Vector3::zeros()
            };
            let var_b = (u.transpose() * ct.fixed_view::<3, 3>(0, 0) * u)[(0, 0)];
            CameraStd {
                intrinsics,
                distortion,
                rotation_rad: Some([
                    ce[(3, 3)].max(0.0).sqrt(),
                    ce[(4, 4)].max(0.0).sqrt(),
                    ce[(5, 5)].max(0.0).sqrt(),
                ]),
                translation_m: Some([
                    ct[(0, 0)].max(0.0).sqrt(),
                    ct[(1, 1)].max(0.0).sqrt(),
                    ct[(2, 2)].max(0.0).sqrt(),
                ]),
                baseline_m: Some(var_b.max(0.0).sqrt()),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camcal::CameraModel;
    use crate::lie::so3;
    use crate::rng::Rng;
    use crate::sim::camcal_views::synthetic_detections;
    use crate::sim::image_dataset::{default_board, default_stereo_camchain};

    /// Board poses in front of cam0 spread over the image, with tilts.
    fn views(n: usize, rng: &mut Rng) -> Vec<Se3> {
        (0..n)
            .map(|_| {
                let tilt = Vector3::new(
                    rng.uniform_in(-0.6, 0.6),
                    rng.uniform_in(-0.6, 0.6),
                    rng.uniform_in(-0.4, 0.4),
                );
                // Board frame: x right, y up; camera: x right, y down: flip about x.
                let flip = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
                let rot = so3::exp(&tilt) * flip;
                let z = rng.uniform_in(0.7, 1.4);
                let centre = Vector3::new(
                    rng.uniform_in(-0.45, 0.45) * z,
                    rng.uniform_in(-0.3, 0.3) * z,
                    z,
                );
                let board_mid = Vector3::new(0.33, 0.33, 0.0);
                Se3::new(rot, centre - rot * board_mid)
            })
            .collect()
    }

    /// Corner detections of every tag fully in the image, with Gaussian pixel noise.
    fn synth(
        chain: &Camchain,
        board: &Board,
        poses: &[Se3],
        sigma: f64,
        rng: &mut Rng,
    ) -> Vec<FrameTags> {
        poses
            .iter()
            .enumerate()
            .map(|(i, t_c0_b)| {
                let dets = chain
                    .cams
                    .iter()
                    .zip(&chain.t_cn_c0)
                    .map(|(cam, t_cn_c0)| {
                        synthetic_detections(board, cam, &(*t_cn_c0 * *t_c0_b), sigma, rng)
                    })
                    .collect();
                FrameTags {
                    name: format!("f{i}"),
                    t_ns: i as i64,
                    dets,
                }
            })
            .collect()
    }

    #[test]
    fn jacobians_match_differences() {
        let chain = default_stereo_camchain();
        let board = default_board();
        let mut rng = Rng::new(3);
        let poses = views(2, &mut rng);
        let state = State {
            model: CameraModel::PinholeRadtan,
            cams: chain.cams.clone(),
            ext: chain.t_cn_c0.clone(),
            poses: poses.iter().map(|p| Some(*p)).collect(),
        };
        let o = CornerObs {
            frame: 1,
            cam: 1,
            tag: 0,
            corner: 2,
            board: board.tags[7].corners[2],
            px: Vector2::new(300.0, 200.0),
        };
        let (r0, j) = state.residual(&o, true).unwrap();
        let j = j.unwrap();
        let h = 1e-6;
        for k in 0..NI {
            let mut s = state.clone();
            let mut p = params(&s.cams[1]);
            p[k] += h;
            s.cams[1] = camera(&p, s.model, 752, 480);
            let d = (s.residual(&o, false).unwrap().0 - r0) / h;
            assert!(
                (d - j.intr.column(k)).norm() < 1e-4 * (1.0 + d.norm()),
                "intrinsic {k}: {d} vs {}",
                j.intr.column(k)
            );
        }
        for k in 0..6 {
            let mut xi = Vector6::zeros();
            xi[k] = h;
            let mut s = state.clone();
            s.poses[1] = Some(Se3::exp(&xi) * poses[1]);
            let d = (s.residual(&o, false).unwrap().0 - r0) / h;
            assert!(
                (d - j.pose.column(k)).norm() < 1e-3 * (1.0 + d.norm()),
                "pose {k}"
            );
            let mut s = state.clone();
            s.ext[1] = Se3::exp(&xi) * chain.t_cn_c0[1];
            let d = (s.residual(&o, false).unwrap().0 - r0) / h;
            assert!(
                (d - j.ext.column(k)).norm() < 1e-3 * (1.0 + d.norm()),
                "ext {k}"
            );
        }
    }

    #[test]
    fn recovers_a_stereo_chain_with_honest_std() {
        let truth = default_stereo_camchain();
        let board = default_board();
        let mut rng = Rng::new(11);
        let poses = views(40, &mut rng);
        let frames = synth(&truth, &board, &poses, 0.1, &mut rng);
        let r = calibrate_cameras(
            &board,
            &frames,
            &[(752, 480), (752, 480)],
            &CamCalOptions::default(),
        )
        .unwrap();
        assert!((r.sigma_px - 0.1).abs() < 0.01, "sigma {}", r.sigma_px);
        for c in 0..2 {
            let (t, e) = (&truth.cams[c], &r.chain.cams[c]);
            let err = [e.fu - t.fu, e.fv - t.fv, e.pu - t.pu, e.pv - t.pv];
            for (k, (e, s)) in err.iter().zip(&r.std[c].intrinsics).enumerate() {
                assert!(e.abs() < 4.0 * s, "cam{c} intrinsic {k}: {e} vs std {s}");
            }
            let (tk, ek) = (t.distortion.coeffs(), e.distortion.coeffs());
            for k in 0..4 {
                assert!(
                    (ek[k] - tk[k]).abs() < 4.0 * r.std[c].distortion[k],
                    "cam{c} distortion {k}"
                );
            }
        }
        let t_true = truth.t_cn_c0[1];
        let t_est = r.chain.t_cn_c0[1];
        let s = &r.std[1];
        let dt = t_est.trans - t_true.trans;
        for k in 0..3 {
            assert!(
                dt[k].abs() < 4.0 * s.translation_m.unwrap()[k],
                "translation {k}: {} vs {}",
                dt[k],
                s.translation_m.unwrap()[k]
            );
        }
        assert!(
            r.corners_rejected < r.corners_used / 100,
            "{} rejected",
            r.corners_rejected
        );
        assert!(
            r.frames
                .iter()
                .all(|f| f.dropped.is_none() || f.rms_px.iter().all(Option::is_none))
        );
    }

    #[test]
    fn a_wrong_corner_and_a_wrong_frame_are_dropped() {
        let truth = default_stereo_camchain();
        let board = default_board();
        let mut rng = Rng::new(5);
        let poses = views(30, &mut rng);
        let mut frames = synth(&truth, &board, &poses, 0.1, &mut rng);
        // One corner 5 px off; one frame whose every cam0 corner is shifted by noise of 2 px.
        frames[3].dets[0][0].corners[1].x += 5.0;
        for d in frames[7].dets[0].iter_mut() {
            for c in d.corners.iter_mut() {
                *c += Vector2::new(rng.normal() * 2.0, rng.normal() * 2.0);
            }
        }
        let r = calibrate_cameras(
            &board,
            &frames,
            &[(752, 480), (752, 480)],
            &CamCalOptions::default(),
        )
        .unwrap();
        assert!(r.frames[7].dropped.is_some(), "{:?}", r.frames[7]);
        assert!(r.frames.iter().filter(|f| f.dropped.is_some()).count() <= 2);
        let bad = r
            .residuals
            .iter()
            .find(|x| {
                x.frame == 3 && x.cam == 0 && (x.px - frames[3].dets[0][0].corners[1]).norm() < 1e-9
            })
            .unwrap();
        assert!(!bad.used && bad.r.norm() > 3.0);
        assert!(r.rms_px < 0.2, "rms {}", r.rms_px);
    }
}
