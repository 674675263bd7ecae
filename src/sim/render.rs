//! Synthetic camera images of a board, for datasets with known truth.
//!
//! Pixels near an edge of the scene are supersampled (the others lie inside one uniform region
//! and take their centre's value, which every sample would give): each sample's ray (through the lens distortion) is intersected
//! with the board's planes and the tag cell it hits decides black or white. White paper surrounds
//! the tags (the whole board rectangle for grid boards, a square sheet around each tag for listed
//! tags); everything else is a mid-grey background. Exposure gain, vignetting, Gaussian blur and
//! additive Gaussian noise follow, in that order. The noise comes from the crate's own generator,
//! so an image is a deterministic function of its inputs and the generator's state.
//!
//! Tag bit patterns are libapriltag's own family data (codes and bit positions), so a rendered tag
//! is exactly the tag libapriltag decodes. A board printed the Kalibr way ([`TagPrint::Kalibr`])
//! is drawn with Kalibr's two-bit borders and its corner squares.

use std::sync::{Arc, Mutex};

use image::GrayImage;
use nalgebra::{Matrix2, Vector2, Vector3};

use crate::lie::Se3;
use crate::rng::Rng;
use crate::types::board::{Board, TagPrint};
use crate::types::camera::Camera;
use crate::vision::board_svg::grid_paper;
use crate::vision::family::tags_cells;
use crate::vision::kalibr::{KALIBR_CELLS_ACROSS, kalibr_tag_cells};

/// Image formation settings.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Standard deviation of the Gaussian blur, pixels (0: none).
    pub blur_sigma_px: f64,
    /// Standard deviation of the additive noise, grey levels (0..255 scale; 0: none).
    pub noise_sigma: f64,
    /// Relative darkening at the image corners: gain `1 - vignetting (r / r_corner)^2`.
    pub vignetting: f64,
    /// Gain applied to the scene radiance (1: white paper at 235, black print at 20).
    pub exposure: f64,
    /// Samples per pixel along each axis (the pixel gets `supersample^2` samples; at least 1).
    pub supersample: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            blur_sigma_px: 0.7,
            noise_sigma: 2.0,
            vignetting: 0.25,
            exposure: 1.0,
            supersample: 4,
        }
    }
}

impl RenderSettings {
    /// No blur, noise or vignetting, 64 samples per pixel: the ideal anti-aliased image.
    pub fn ideal() -> RenderSettings {
        RenderSettings {
            blur_sigma_px: 0.0,
            noise_sigma: 0.0,
            vignetting: 0.0,
            exposure: 1.0,
            supersample: 8,
        }
    }
}

/// Grey levels of the scene (before gain, vignetting and noise), 0..255.
const BLACK: f32 = 20.0;
const WHITE: f32 = 235.0;
const BACKGROUND: f32 = 128.0;

/// One tag, prepared for sampling: its black square's bottom-left corner and axes in its plane's
/// 2D coordinates, and its cells.
struct PreparedTag {
    origin: Vector2<f64>,
    ax: Vector2<f64>,
    ay: Vector2<f64>,
    /// Cell edge, m.
    cell: f64,
    /// Cells from the black square's edge to the pattern's edge.
    offset: f64,
    tw: usize,
    cells: Vec<Vec<bool>>,
}

/// A white rectangle of paper in a plane: origin, axes and extent in the plane's 2D coordinates.
struct Sheet {
    origin: Vector2<f64>,
    ax: Vector2<f64>,
    ay: Vector2<f64>,
    size: Vector2<f64>,
}

/// A plane of the board with its tags and paper, in the camera frame.
struct Plane {
    /// `T_cam_plane`.
    rot: nalgebra::Matrix3<f64>,
    trans: Vector3<f64>,
    /// The camera sees the front of the plane.
    front: bool,
    tags: Vec<PreparedTag>,
    sheets: Vec<Sheet>,
}

impl Plane {
    /// Grey level at the ray `r` (z = 1) and the depth of the hit, if it hits tags or paper.
    #[inline]
    fn sample(&self, r: &Vector3<f64>) -> Option<(f64, f32)> {
        let n = self.rot.column(2);
        let den = n.dot(r);
        if den.abs() < 1e-12 {
            return None;
        }
        let lambda = n.dot(&self.trans) / den;
        if lambda.is_nan() || lambda <= 0.0 {
            return None;
        }
        let p = self.rot.transpose() * (r * lambda - self.trans);
        let q = Vector2::new(p.x, p.y);
        for t in &self.tags {
            let d = q - t.origin;
            let a = d.dot(&t.ax) / t.cell + t.offset;
            let b = d.dot(&t.ay) / t.cell + t.offset;
            if a >= 0.0 && b >= 0.0 && a < t.tw as f64 && b < t.tw as f64 {
                let col = a as usize;
                let row = t.tw - 1 - b as usize;
                if !self.front {
                    return Some((lambda, BACKGROUND));
                }
                return Some((lambda, if t.cells[row][col] { BLACK } else { WHITE }));
            }
        }
        for s in &self.sheets {
            let d = q - s.origin;
            let a = d.dot(&s.ax);
            let b = d.dot(&s.ay);
            if a >= 0.0 && b >= 0.0 && a <= s.size.x && b <= s.size.y {
                return Some((lambda, if self.front { WHITE } else { BACKGROUND }));
            }
        }
        None
    }
}

/// Splits the board into planes (tags whose corners lie in a common plane) with their paper.
fn prepare(board: &Board, t_cam_board: &Se3) -> Vec<Plane> {
    let ids: Vec<u32> = board.tags.iter().map(|t| t.id).collect();
    // Cells across the whole pattern and across the black square, and each tag's cells.
    let (tw, wab, cells) = match board.print {
        TagPrint::Apriltag => {
            let Some((layout, cells)) = tags_cells(board.family, &ids) else {
                return vec![];
            };
            (
                layout.total_width as usize,
                layout.width_at_border.max(1) as f64,
                cells,
            )
        }
        TagPrint::Kalibr => {
            let Some(cells) = kalibr_tag_cells(&ids) else {
                return vec![];
            };
            let n = KALIBR_CELLS_ACROSS as usize;
            (n, n as f64, cells)
        }
    };
    let offset = (tw as f64 - wab) / 2.0;
    // (T_board_plane, tags) with tag indices.
    let mut groups: Vec<(Se3, Vec<usize>)> = vec![];
    for (i, t) in board.tags.iter().enumerate() {
        let pose = t.pose();
        let found = groups.iter_mut().find(|(p, _)| {
            let n = p.rot.column(2);
            let coplanar = t
                .corners
                .iter()
                .all(|c| (n.dot(&(c - p.trans))).abs() < 1e-6 * (1.0 + t.size_m));
            coplanar && n.dot(&pose.rot.column(2)) > 0.999_999
        });
        match found {
            Some((_, v)) => v.push(i),
            None => {
                // Grid boards use the board frame itself as the plane frame.
                let frame = if board.grid.is_some() {
                    Se3::identity()
                } else {
                    pose
                };
                groups.push((frame, vec![i]))
            }
        }
    }
    let mut planes = vec![];
    for (t_board_plane, members) in groups {
        let t_plane_board = t_board_plane.inverse();
        let to2 = |p: &Vector3<f64>| {
            let q = t_plane_board.transform_point(p);
            Vector2::new(q.x, q.y)
        };
        let mut tags = vec![];
        let mut sheets = vec![];
        for &i in &members {
            let t = &board.tags[i];
            let Some(c) = cells[i].clone() else { continue };
            let o = to2(&t.corners[0]);
            let ax = (to2(&t.corners[1]) - o).normalize();
            let ay = (to2(&t.corners[3]) - o).normalize();
            let cell = t.size_m / wab;
            if board.grid.is_none() {
                // A sheet of paper around each listed tag, one cell wider than the pattern.
                let m = (offset + 1.0) * cell;
                sheets.push(Sheet {
                    origin: o - ax * m - ay * m,
                    ax,
                    ay,
                    size: Vector2::new(t.size_m + 2.0 * m, t.size_m + 2.0 * m),
                });
            }
            tags.push(PreparedTag {
                origin: o,
                ax,
                ay,
                cell,
                offset,
                tw,
                cells: c,
            });
        }
        if let (TagPrint::Kalibr, Some(g)) = (board.print, &board.grid) {
            // Kalibr's corner squares: a one-cell black "tag" at every crossing of the gaps.
            let gap = g.spacing * g.tag_size_m;
            let pitch = g.tag_size_m + gap;
            if gap > 0.0 {
                for r in 0..=g.rows {
                    for c in 0..=g.cols {
                        tags.push(PreparedTag {
                            origin: Vector2::new(c as f64 * pitch - gap, r as f64 * pitch - gap),
                            ax: Vector2::new(1.0, 0.0),
                            ay: Vector2::new(0.0, 1.0),
                            cell: gap,
                            offset: 0.0,
                            tw: 1,
                            cells: vec![vec![true]],
                        });
                    }
                }
            }
        }
        if let Some(g) = &board.grid {
            let (lo, hi) = grid_paper(board, g);
            sheets.push(Sheet {
                origin: lo,
                ax: Vector2::new(1.0, 0.0),
                ay: Vector2::new(0.0, 1.0),
                size: hi - lo,
            });
        }
        let t_cam_plane = t_cam_board * &t_board_plane;
        let front = t_cam_plane.rot.column(2).dot(&t_cam_plane.trans) < 0.0;
        planes.push(Plane {
            rot: t_cam_plane.rot,
            trans: t_cam_plane.trans,
            front,
            tags,
            sheets,
        });
    }
    planes
}

/// Renders what `cam` sees of `board` when the board is at `t_cam_board`; background mid-grey.
///
/// Only the pixels that an edge of the scene may cross are supersampled (see `edge_mask`); any
/// other pixel lies inside one uniform region and gets its centre's value, which is what all its
/// samples would give. The result is bit-identical to [`render_exhaustive`].
pub fn render(
    board: &Board,
    cam: &Camera,
    t_cam_board: &Se3,
    s: &RenderSettings,
    rng: &mut Rng,
) -> GrayImage {
    render_impl(board, cam, t_cam_board, s, rng, true)
}

/// [`render`] with every pixel supersampled: the reference the edge mask is checked against.
pub fn render_exhaustive(
    board: &Board,
    cam: &Camera,
    t_cam_board: &Se3,
    s: &RenderSettings,
    rng: &mut Rng,
) -> GrayImage {
    render_impl(board, cam, t_cam_board, s, rng, false)
}

fn render_impl(
    board: &Board,
    cam: &Camera,
    t_cam_board: &Se3,
    s: &RenderSettings,
    rng: &mut Rng,
    adaptive: bool,
) -> GrayImage {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let planes = prepare(board, t_cam_board);
    let ss = s.supersample.clamp(1, 16) as usize;
    let mask = if adaptive && ss > 1 {
        edge_mask(cam, &planes)
    } else {
        vec![true; w * h]
    };
    let rays = pixel_rays(cam);
    let mut radiance = vec![0f32; w * h];
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(h.max(1));
    let rows_per = h.div_ceil(threads.max(1)).max(1);
    std::thread::scope(|scope| {
        for (chunk_i, chunk) in radiance.chunks_mut(rows_per * w).enumerate() {
            let planes = &planes;
            let mask = &mask;
            let rays = &rays;
            scope.spawn(move || {
                let y0 = chunk_i * rows_per;
                for (ry, row) in chunk.chunks_mut(w).enumerate() {
                    let y = y0 + ry;
                    let span = y * w..(y + 1) * w;
                    render_row(cam, planes, ss, row, &mask[span.clone()], &rays[span]);
                }
            });
        }
    });
    finish(radiance, w, h, cam, s, rng)
}

/// Pixels an edge of the scene may cross: every tag pattern's outline and the cell borders
/// inside it between cells of different colours, every paper edge, traced through the camera model in
/// steps of at most a quarter pixel, with the 3x3 pixels around each step marked. A pixel whose
/// footprint an edge enters contains an edge point within a quarter pixel of a step, so the step
/// lies in that pixel or a neighbour; the 3x3 margin also covers the samples' linearised rays.
fn edge_mask(cam: &Camera, planes: &[Plane]) -> Vec<bool> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut mask = vec![false; w * h];
    let Some(view) = view_box(cam) else {
        // No pixel has a ray: every pixel is background anyway.
        return mask;
    };
    for p in planes {
        let to_cam = |q: Vector2<f64>| p.rot * Vector3::new(q.x, q.y, 0.0) + p.trans;
        let mut segs: Vec<(Vector2<f64>, Vector2<f64>)> = vec![];
        for t in &p.tags {
            let at = |a: f64, b: f64| {
                t.origin + t.ax * ((a - t.offset) * t.cell) + t.ay * ((b - t.offset) * t.cell)
            };
            // The pattern's outline, then each unit of the inner grid lines that separates
            // cells of different colours (row 0 of `cells` is the top, b = tw).
            let n = t.tw as f64;
            let c = [at(0.0, 0.0), at(n, 0.0), at(n, n), at(0.0, n)];
            for k in 0..4 {
                segs.push((c[k], c[(k + 1) % 4]));
            }
            let black = |col: usize, b: usize| t.cells[t.tw - 1 - b][col];
            for i in 1..t.tw {
                for j in 0..t.tw {
                    let (fi, fj) = (i as f64, j as f64);
                    if black(i - 1, j) != black(i, j) {
                        segs.push((at(fi, fj), at(fi, fj + 1.0)));
                    }
                    if black(j, i - 1) != black(j, i) {
                        segs.push((at(fj, fi), at(fj + 1.0, fi)));
                    }
                }
            }
        }
        for sh in &p.sheets {
            let c = [
                sh.origin,
                sh.origin + sh.ax * sh.size.x,
                sh.origin + sh.ax * sh.size.x + sh.ay * sh.size.y,
                sh.origin + sh.ay * sh.size.y,
            ];
            for k in 0..4 {
                segs.push((c[k], c[(k + 1) % 4]));
            }
        }
        for (a, b) in segs {
            if let Some((a, b)) = clip_to_view(&to_cam(a), &to_cam(b), &view) {
                trace_segment(cam, &a, &b, &mut mask, 0);
            }
        }
    }
    mask
}

/// The box of normalised image coordinates `[x_lo, x_hi, y_lo, y_hi]` that holds the rays of all
/// pixels (and their samples), with a margin of a few pixels; `None` when no pixel has a ray.
fn view_box(cam: &Camera) -> Option<[f64; 4]> {
    let (w, h) = (cam.width as i64, cam.height as i64);
    let mut b = [f64::MAX, f64::MIN, f64::MAX, f64::MIN];
    let mut any = false;
    let mut add = |x: i64, y: i64| {
        let pd = Vector2::new((x as f64 - cam.pu) / cam.fu, (y as f64 - cam.pv) / cam.fv);
        if let Some(n) = cam.distortion.undistort(&pd) {
            any = true;
            b = [b[0].min(n.x), b[1].max(n.x), b[2].min(n.y), b[3].max(n.y)];
        }
    };
    // Every pixel of the border and a coarse grid inside (the distortion need not be monotonic).
    for x in 0..w {
        add(x, 0);
        add(x, h - 1);
    }
    for y in 0..h {
        add(0, y);
        add(w - 1, y);
    }
    for y in (0..h).step_by(8) {
        for x in (0..w).step_by(8) {
            add(x, y);
        }
    }
    if !any {
        return None;
    }
    // Margin: 10 % of the box and four pixels.
    let (mx, my) = (
        0.1 * (b[1] - b[0]) + 4.0 / cam.fu,
        0.1 * (b[3] - b[2]) + 4.0 / cam.fv,
    );
    Some([b[0] - mx, b[1] + mx, b[2] - my, b[3] + my])
}

/// The part of the camera-frame segment `a`-`b` whose points have normalised coordinates inside
/// `view` (and lie in front of the camera), by clipping against the five planes of that frustum.
fn clip_to_view(
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    view: &[f64; 4],
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    // Each constraint is linear in the point: f(p) >= 0.
    let f = |k: usize, p: &Vector3<f64>| match k {
        0 => p.z - 1e-6,
        1 => p.x - view[0] * p.z,
        2 => view[1] * p.z - p.x,
        3 => p.y - view[2] * p.z,
        _ => view[3] * p.z - p.y,
    };
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..5 {
        let (fa, fb) = (f(k, a), f(k, b));
        if fa < 0.0 && fb < 0.0 {
            return None;
        }
        if fa < 0.0 {
            t0 = t0.max(fa / (fa - fb));
        } else if fb < 0.0 {
            t1 = t1.min(fa / (fa - fb));
        }
    }
    if t0 > t1 {
        return None;
    }
    Some((a + (b - a) * t0, a + (b - a) * t1))
}

/// Marks the pixels along the image of the camera-frame segment `a`-`b` (in front of the camera
/// and inside the view), split in halves until the pieces' images are shorter than a quarter
/// pixel.
fn trace_segment(cam: &Camera, a: &Vector3<f64>, b: &Vector3<f64>, mask: &mut [bool], depth: u32) {
    let (Some(pa), Some(pb)) = (cam.project(a), cam.project(b)) else {
        return;
    };
    let (w, h) = (cam.width as f64, cam.height as f64);
    let mut mark = |p: &Vector2<f64>| {
        let (cx, cy) = (p.x.round(), p.y.round());
        if !(cx >= -2.0 && cy >= -2.0 && cx <= w + 1.0 && cy <= h + 1.0) {
            return;
        }
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (x, y) = (cx as i64 + dx, cy as i64 + dy);
                if x >= 0 && y >= 0 && (x as f64) < w && (y as f64) < h {
                    mask[y as usize * cam.width as usize + x as usize] = true;
                }
            }
        }
    };
    // The depth bound only guards against a degenerate camera model; inside the view box a piece
    // halves its image length at every level.
    if (pb - pa).norm() <= 0.25 || depth >= 24 {
        mark(&pa);
        mark(&pb);
        return;
    }
    let m = (a + b) * 0.5;
    trace_segment(cam, a, &m, mask, depth + 1);
    trace_segment(cam, &m, b, mask, depth + 1);
}

/// Undistorted normalised coordinates of every pixel centre (`None` where the distortion cannot
/// be inverted), row-major.
type RayTable = Vec<Option<Vector2<f64>>>;

/// The ray table of `cam`, computed once per camera model: a dataset renders hundreds of frames
/// with the same two cameras, and undistorting every pixel centre is a large part of a frame's
/// cost. The few most recent cameras are kept.
fn pixel_rays(cam: &Camera) -> Arc<RayTable> {
    static CACHE: Mutex<Vec<(Camera, Arc<RayTable>)>> = Mutex::new(Vec::new());
    if let Ok(c) = CACHE.lock()
        && let Some((_, t)) = c.iter().find(|(k, _)| k == cam)
    {
        return t.clone();
    }
    let (w, h) = (cam.width as usize, cam.height as usize);
    let table: RayTable = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let pd = Vector2::new((x - cam.pu) / cam.fu, (y - cam.pv) / cam.fv);
            cam.distortion.undistort(&pd)
        })
        .collect();
    let table = Arc::new(table);
    if let Ok(mut c) = CACHE.lock() {
        if c.len() >= 4 {
            c.remove(0);
        }
        c.push((cam.clone(), table.clone()));
    }
    table
}

/// One row of scene radiance. Each pixel centre is unprojected exactly (through the ray table); its samples use the
/// local inverse of the distortion (their rays differ from exact ones by a second-order term,
/// far below a pixel for any real lens). Pixels off the edge mask get their centre's value.
fn render_row(
    cam: &Camera,
    planes: &[Plane],
    ss: usize,
    row: &mut [f32],
    mask: &[bool],
    rays: &[Option<Vector2<f64>>],
) {
    let inv_f = Vector2::new(1.0 / cam.fu, 1.0 / cam.fv);
    let offs = sample_offsets(ss);
    let n_samples = offs.len() as f32;
    let hit = |r: &Vector3<f64>| {
        let mut best: Option<(f64, f32)> = None;
        for p in planes {
            if let Some((depth, v)) = p.sample(r) {
                if best.is_none_or(|(d, _)| depth < d) {
                    best = Some((depth, v));
                }
            }
        }
        best.map(|b| b.1).unwrap_or(BACKGROUND)
    };
    for (x, out) in row.iter_mut().enumerate() {
        let Some(n) = rays[x] else {
            *out = BACKGROUND;
            continue;
        };
        if !mask[x] {
            *out = hit(&Vector3::new(n.x, n.y, 1.0));
            continue;
        }
        let (_, j) = cam.distortion.distort(&n);
        let jinv = j.try_inverse().unwrap_or_else(Matrix2::identity);
        let mut acc = 0f32;
        for &(dx, dy) in &offs {
            let dn = jinv * Vector2::new(dx * inv_f.x, dy * inv_f.y);
            acc += hit(&Vector3::new(n.x + dn.x, n.y + dn.y, 1.0));
        }
        *out = acc / n_samples;
    }
}

/// Sample positions inside a pixel (offsets from its centre): `n^2` points of a rank-1 lattice,
/// so that every sample has its own x and its own y. An edge parallel to a pixel axis then gets
/// `n^2` coverage levels instead of `n`, which keeps rendered edges (and the corners a detector
/// fits to them) unbiased to a few hundredths of a pixel.
fn sample_offsets(n: usize) -> Vec<(f64, f64)> {
    let m = n * n;
    if m == 1 {
        return vec![(0.0, 0.0)];
    }
    // Generator near m / golden ratio, coprime with m.
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let mut g = ((m as f64) / 1.618_033_988_75).round() as usize;
    while gcd(g, m) != 1 {
        g += 1;
    }
    (0..m)
        .map(|i| {
            let x = (i as f64 + 0.5) / m as f64 - 0.5;
            let y = (((i * g) % m) as f64 + 0.5) / m as f64 - 0.5;
            (x, y)
        })
        .collect()
}

/// Gain, vignetting, blur, noise, quantisation.
fn finish(
    mut img: Vec<f32>,
    w: usize,
    h: usize,
    cam: &Camera,
    s: &RenderSettings,
    rng: &mut Rng,
) -> GrayImage {
    let r_corner2 = {
        let dx = cam.pu.abs().max((w as f64 - 1.0 - cam.pu).abs());
        let dy = cam.pv.abs().max((h as f64 - 1.0 - cam.pv).abs());
        (dx * dx + dy * dy).max(1.0)
    };
    for y in 0..h {
        for x in 0..w {
            let dx = x as f64 - cam.pu;
            let dy = y as f64 - cam.pv;
            let g = s.exposure * (1.0 - s.vignetting * (dx * dx + dy * dy) / r_corner2);
            img[y * w + x] *= g.max(0.0) as f32;
        }
    }
    if s.blur_sigma_px > 0.0 {
        gaussian_blur(&mut img, w, h, s.blur_sigma_px);
    }
    let mut out = GrayImage::new(w as u32, h as u32);
    for (i, p) in out.iter_mut().enumerate() {
        let mut v = img[i] as f64;
        if s.noise_sigma > 0.0 {
            v += s.noise_sigma * rng.normal();
        }
        *p = v.round().clamp(0.0, 255.0) as u8;
    }
    out
}

/// Separable Gaussian blur with edges clamped.
fn gaussian_blur(img: &mut [f32], w: usize, h: usize, sigma: f64) {
    let r = (3.0 * sigma).ceil() as isize;
    let mut k: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    let mut tmp = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut a = 0f32;
            for (j, kv) in k.iter().enumerate() {
                let xx = (x as isize + j as isize - r).clamp(0, w as isize - 1) as usize;
                a += kv * img[y * w + xx];
            }
            tmp[y * w + x] = a;
        }
    }
    for y in 0..h {
        for x in 0..w {
            let mut a = 0f32;
            for (j, kv) in k.iter().enumerate() {
                let yy = (y as isize + j as isize - r).clamp(0, h as isize - 1) as usize;
                a += kv * tmp[yy * w + x];
            }
            img[y * w + x] = a;
        }
    }
}
