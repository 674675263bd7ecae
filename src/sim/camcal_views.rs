//! Board poses for a camera calibration: what a person waving a board in front of a stereo rig
//! shows it.
//!
//! Each view `k` of [`calibration_views`] draws from its own stream of the seed:
//! 1. a target pixel anywhere on cam0's image (its corners and edges included, so that the lens
//!    distortion is seen out to the image corners);
//! 2. a distance at which the board spans 30..90 % of the image width (log-uniform, so near and
//!    far views are equally common);
//! 3. a tilt of up to 45 degrees about a random axis in the board plane and a roll of up to
//!    30 degrees about the optical axis.
//!
//! The board centre is put on the ray of the target pixel and the pose is kept when at least
//! [`MIN_VISIBLE_FRACTION`] of the board's tag corners fall on cam0's image and on cam1's (when the
//! chain has two or more cameras), with every corner in front of every camera. A rejected draw is
//! tried again with the target pulled a little towards the image centre (a board aimed at an image
//! corner is mostly off the image), so views stay spread over the whole image.

use nalgebra::{Matrix3, Vector2, Vector3};

use crate::lie::{Se3, so3};
use crate::rng::Rng;
use crate::sim::image_dataset::{board_centre, board_in_cameras};
use crate::types::board::Board;
use crate::types::camera::{Camchain, Camera};
use crate::vision::detect::TagDetection;

/// Smallest share of the board's tag corners that must fall on cam0's image and on cam1's.
pub const MIN_VISIBLE_FRACTION: f64 = 0.4;

/// Closest distance of a corner in front of a camera, m.
const MIN_DEPTH_M: f64 = 0.05;

/// Largest tilt of the board out of the image plane, rad.
const MAX_TILT_RAD: f64 = 45.0 * std::f64::consts::PI / 180.0;

/// Largest roll of the board about the optical axis, rad.
const MAX_ROLL_RAD: f64 = 30.0 * std::f64::consts::PI / 180.0;

/// Smallest and largest share of the image width the board spans.
const WIDTH_FRACTION: (f64, f64) = (0.3, 0.9);

/// Draws per view before the target is pulled all the way to the image centre.
const ATTEMPTS: usize = 60;

/// First stream number of the per-view streams (view `k` uses `VIEW_STREAM_BASE + k`).
const VIEW_STREAM_BASE: u64 = 0xCA11_B000_0000;

/// `n` board poses `T_board_cam0` for calibrating `chain` with `board`, deterministic from `seed`
/// (module docs: how they are drawn). A view for which no acceptable pose is found in 60 draws
/// falls back to a board facing cam0 at the far distance on the optical axis, so
/// that exactly `n` poses are returned; with a sensible board and chain that never happens.
pub fn calibration_views(chain: &Camchain, board: &Board, n: usize, seed: u64) -> Vec<Se3> {
    let Some(cam0) = chain.cams.first() else {
        return Vec::new();
    };
    let extent = board_extent(board);
    // Distance at which the board spans a share `f` of the image width.
    let dist_at = |f: f64| cam0.fu * extent / (f * f64::from(cam0.width.max(1)));
    let (d_near, d_far) = (dist_at(WIDTH_FRACTION.1), dist_at(WIDTH_FRACTION.0));
    (0..n as u64)
        .map(|k| {
            let mut rng = Rng::stream(seed, VIEW_STREAM_BASE.wrapping_add(k));
            draw_view(chain, board, cam0, (d_near, d_far), &mut rng)
                .unwrap_or_else(|| facing(board, Vector3::new(0.0, 0.0, 1.0), d_far, 0.0, None))
        })
        .collect()
}

/// One accepted pose of a view, or `None` when every draw was rejected.
fn draw_view(
    chain: &Camchain,
    board: &Board,
    cam0: &Camera,
    (d_near, d_far): (f64, f64),
    rng: &mut Rng,
) -> Option<Se3> {
    let (w, h) = (f64::from(cam0.width), f64::from(cam0.height));
    let target = Vector2::new(rng.uniform_in(-0.5, w - 0.5), rng.uniform_in(-0.5, h - 0.5));
    let centre = Vector2::new(cam0.pu, cam0.pv);
    for attempt in 0..ATTEMPTS {
        // Pulled towards the image centre by up to 60 % over the attempts.
        let pull = 0.6 * attempt as f64 / (ATTEMPTS - 1) as f64;
        let px = target + (centre - target) * pull;
        let d = (d_near.ln() + rng.uniform() * (d_far / d_near).ln()).exp();
        let roll = rng.uniform_in(-MAX_ROLL_RAD, MAX_ROLL_RAD);
        let tilt_dir = rng.uniform_in(0.0, std::f64::consts::TAU);
        let tilt = MAX_TILT_RAD * rng.uniform().sqrt();
        let Some(ray) = cam0.unproject(&px) else {
            continue;
        };
        let tilt_axis = Vector3::new(tilt_dir.cos(), tilt_dir.sin(), 0.0) * tilt;
        let t_board_cam0 = facing(board, ray, d, roll, Some(&tilt_axis));
        if acceptable(chain, board, &t_board_cam0) {
            return Some(t_board_cam0);
        }
    }
    None
}

/// `T_board_cam0` of a board whose centre lies on cam0's `ray` at depth `depth` (along the
/// optical axis), facing the camera (its z axis towards it, x along the image's x), then rolled
/// by `roll` about the optical axis and tilted about `tilt` (axis-angle in the board frame).
fn facing(
    board: &Board,
    ray: Vector3<f64>,
    depth: f64,
    roll: f64,
    tilt: Option<&Vector3<f64>>,
) -> Se3 {
    let flip = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    let r_roll = so3::exp(&Vector3::new(0.0, 0.0, roll));
    let r_tilt = tilt.map_or_else(Matrix3::identity, so3::exp);
    let r_cam_board = r_roll * flip * r_tilt;
    let centre_cam = ray * (depth / ray.z.max(1e-9));
    let t_cam_board = Se3::new(r_cam_board, centre_cam - r_cam_board * board_centre(board));
    t_cam_board.inverse()
}

/// The larger side of the board's tag area, m.
fn board_extent(board: &Board) -> f64 {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for c in board.tags.iter().flat_map(|t| t.corners.iter()) {
        lo = lo.inf(c);
        hi = hi.sup(c);
    }
    let size = hi - lo;
    if size.iter().all(|v| v.is_finite()) {
        size.x.max(size.y).max(1e-3)
    } else {
        1.0
    }
}

/// Whether a corner at `p` (camera frame) falls on `cam`'s image: projected inside it, and seen
/// through a part of the lens where the distortion is invertible (the projection's ray is `p`'s
/// own), so that a distortion polynomial folding back beyond the field of view cannot put a
/// corner on the image that the camera does not see.
fn on_image(cam: &Camera, p: &Vector3<f64>) -> bool {
    let Some(px) = cam.project(p) else {
        return false;
    };
    if !cam.in_image(&px) {
        return false;
    }
    cam.unproject(&px)
        .is_some_and(|r| (r.xy() - p.xy() / p.z).norm() < 1e-6)
}

/// Share of the board's tag corners on camera `cam`'s image with the board at `T_cam_board`.
pub fn visible_fraction(board: &Board, cam: &Camera, t_cam_board: &Se3) -> f64 {
    let n = board.tags.len() * 4;
    if n == 0 {
        return 0.0;
    }
    let seen = board
        .tags
        .iter()
        .flat_map(|t| t.corners.iter())
        .filter(|c| on_image(cam, &t_cam_board.transform_point(c)))
        .count();
    seen as f64 / n as f64
}

/// The visibility rule of [`calibration_views`]: every tag corner at least 5 cm in front of every
/// camera, and at least [`MIN_VISIBLE_FRACTION`] of them on cam0's image and on cam1's.
pub fn acceptable(chain: &Camchain, board: &Board, t_board_cam0: &Se3) -> bool {
    let poses = board_in_cameras(chain, t_board_cam0);
    let in_front = poses.iter().all(|t| {
        board
            .tags
            .iter()
            .flat_map(|tag| tag.corners.iter())
            .all(|c| t.transform_point(c).z > MIN_DEPTH_M)
    });
    in_front
        && chain
            .cams
            .iter()
            .zip(&poses)
            .take(2)
            .all(|(cam, t)| visible_fraction(board, cam, t) >= MIN_VISIBLE_FRACTION)
}

/// The detections an ideal detector would report of `board` seen by `cam` at `T_cam_board`: every
/// tag whose four corners project inside the image, its corners moved by Gaussian noise of
/// `sigma_px` per axis (drawn from `rng`, corner by corner in tag order).
pub fn synthetic_detections(
    board: &Board,
    cam: &Camera,
    t_cam_board: &Se3,
    sigma_px: f64,
    rng: &mut Rng,
) -> Vec<TagDetection> {
    board
        .tags
        .iter()
        .filter_map(|tag| {
            let mut corners = [Vector2::zeros(); 4];
            for (c, p) in corners.iter_mut().zip(&tag.corners) {
                let px = cam.project(&t_cam_board.transform_point(p))?;
                if !cam.in_image(&px) {
                    return None;
                }
                *c = px + Vector2::new(rng.normal(), rng.normal()) * sigma_px;
            }
            Some(TagDetection {
                id: tag.id,
                hamming: 0,
                decision_margin: 100.0,
                corners,
                border_bits: 1,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::image_dataset::{default_board, default_stereo_camchain};

    #[test]
    fn views_are_deterministic_and_count_right() {
        let chain = default_stereo_camchain();
        let board = default_board();
        let a = calibration_views(&chain, &board, 25, 7);
        let b = calibration_views(&chain, &board, 25, 7);
        let c = calibration_views(&chain, &board, 25, 8);
        assert_eq!(a.len(), 25);
        assert_eq!(a, b);
        assert_ne!(a, c);
        // A longer list starts with the shorter one (one stream per view).
        assert_eq!(calibration_views(&chain, &board, 10, 7)[..], a[..10]);
        assert!(calibration_views(&chain, &board, 0, 7).is_empty());
    }

    #[test]
    fn every_view_obeys_the_visibility_rule() {
        let chain = default_stereo_camchain();
        let board = default_board();
        for (k, t) in calibration_views(&chain, &board, 60, 3).iter().enumerate() {
            assert!(acceptable(&chain, &board, t), "view {k}");
            for (cam, t_cb) in chain.cams.iter().zip(board_in_cameras(&chain, t)) {
                let f = visible_fraction(&board, cam, &t_cb);
                assert!(f >= MIN_VISIBLE_FRACTION, "view {k}: {f}");
            }
        }
    }

    #[test]
    fn mono_chain_needs_only_cam0() {
        let mut chain = default_stereo_camchain();
        chain.cams.truncate(1);
        chain.t_cn_c0.truncate(1);
        chain.topics.truncate(1);
        let board = default_board();
        let views = calibration_views(&chain, &board, 20, 5);
        assert_eq!(views.len(), 20);
        assert!(views.iter().all(|t| acceptable(&chain, &board, t)));
    }

    #[test]
    fn views_spread_over_the_image_tilts_and_distances() {
        let chain = default_stereo_camchain();
        let board = default_board();
        let cam = &chain.cams[0];
        let views = calibration_views(&chain, &board, 30, 1);
        let (w, h) = (f64::from(cam.width), f64::from(cam.height));
        // Quadrants' outer thirds: [left, right] x [top, bottom].
        let mut reached = [[false; 2]; 2];
        let mut tilts = Vec::new();
        let mut depths = Vec::new();
        for t in &views {
            let t_cb = t.inverse();
            let normal = t_cb.rot * Vector3::z();
            tilts.push((-normal.z).clamp(-1.0, 1.0).acos());
            depths.push(t_cb.transform_point(&board_centre(&board)).z);
            for c in board.tags.iter().flat_map(|tag| tag.corners.iter()) {
                let p = t_cb.transform_point(c);
                if !on_image(cam, &p) {
                    continue;
                }
                let Some(px) = cam.project(&p) else { continue };
                let col = if px.x < w / 3.0 {
                    Some(0)
                } else if px.x > 2.0 * w / 3.0 {
                    Some(1)
                } else {
                    None
                };
                let row = if px.y < h / 3.0 {
                    Some(0)
                } else if px.y > 2.0 * h / 3.0 {
                    Some(1)
                } else {
                    None
                };
                if let (Some(c), Some(r)) = (col, row) {
                    reached[c][r] = true;
                }
            }
        }
        assert_eq!(reached, [[true; 2]; 2], "outer-third corners reached");
        // Tilted views (some beyond 25 degrees), none beyond 45.
        let max_tilt = tilts.iter().cloned().fold(0.0, f64::max);
        assert!(max_tilt > 25f64.to_radians(), "{max_tilt}");
        assert!(max_tilt <= 45.001f64.to_radians(), "{max_tilt}");
        // Distances spread over the range (board 30..90 % of the width: ~0.45..1.35 m).
        let lo = depths.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = depths.iter().cloned().fold(0.0, f64::max);
        assert!(lo < 0.7 && hi > 1.0 && hi < 1.5, "{lo} {hi}");
    }
}
