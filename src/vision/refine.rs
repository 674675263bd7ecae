//! Sub-pixel refinement of a tag's four corners: each side of the black square is re-located on
//! the full-resolution image, a straight line is fitted to each side, and the corners become the
//! intersections of adjacent lines.
//!
//! # Why
//!
//! Debian's libapriltag 3.3 leaves a systematic corner error after its own edge refinement
//! (`refine_edges`): on exactly area-sampled tags it is a common shift of about -0.08 px in x and
//! y; on blurred perspective renders it shrinks the detected squares slightly. Its edge search
//! reads whole pixels (no interpolation) and weights the gradient samples by their square, whose
//! centroid is not the edge position for an edge that falls inside a pixel. The refinement here is
//! built so that its estimate is unbiased for any symmetric blur:
//!
//! - along the normal of the current side estimate, the image is read with bilinear
//!   interpolation (OpenCV's convention, pixel centres at integers) at quarter-pixel steps,
//!   inside a window of ±`w` pixels centred on the current estimate;
//! - the edge is the centroid of the (polarity-matched, non-negative) differences of that
//!   profile. Summed by parts this is `n_end - ∫ (I - I_start) / (I_end - I_start)`, which is the
//!   exact edge position of an area-sampled step under any symmetric blur once the window reaches
//!   both flat sides; differences of the wrong sign (the inner edge of the black border, noise)
//!   are dropped;
//! - the window is re-centred on the new lines and the whole fit repeated a few times, so the
//!   clipped noise pulls toward the edge itself and not toward the first guess.
//!
//! With a camera model, the lines are fitted in undistorted pixel coordinates (where the sides of a
//! tag really are straight) and the corners mapped back through the distortion; without one, in
//! the image itself.

use image::GrayImage;
use nalgebra::{Matrix2, Vector2};

use crate::types::camera::Camera;

/// Passes of locate-fit-intersect (each re-centres the search windows on the previous lines).
const PASSES: usize = 3;
/// Step along the normal, pixels.
const STEP: f64 = 0.25;

/// Maps between the image and the space where the tag's sides are straight lines.
struct Space<'a> {
    cam: Option<&'a Camera>,
}

impl Space<'_> {
    /// Image pixel to line space (undistorted pixel coordinates with the camera's own focal
    /// lengths and principal point).
    fn to_line(&self, p: &Vector2<f64>) -> Option<Vector2<f64>> {
        match self.cam {
            None => Some(*p),
            Some(c) => {
                let r = c.unproject(p)?;
                Some(Vector2::new(c.fu * r.x + c.pu, c.fv * r.y + c.pv))
            }
        }
    }

    /// Line space to image pixel, with the Jacobian `d image / d line`.
    fn to_image_jac(&self, q: &Vector2<f64>) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        match self.cam {
            None => Some((*q, Matrix2::identity())),
            Some(c) => {
                let n = Vector2::new((q.x - c.pu) / c.fu, (q.y - c.pv) / c.fv);
                let (d, jd) = c.distortion.distort(&n);
                let p = Vector2::new(c.fu * d.x + c.pu, c.fv * d.y + c.pv);
                let j = Matrix2::new(
                    jd[(0, 0)],
                    jd[(0, 1)] * c.fu / c.fv,
                    jd[(1, 0)] * c.fv / c.fu,
                    jd[(1, 1)],
                );
                (p.iter().chain(j.iter()).all(|v| v.is_finite())).then_some((p, j))
            }
        }
    }

    /// Line space to image pixel.
    fn to_image(&self, q: &Vector2<f64>) -> Option<Vector2<f64>> {
        self.to_image_jac(q).map(|(p, _)| p)
    }
}

/// Bilinear interpolation, pixel centres at integers; `None` off the image.
#[inline]
pub(crate) fn bilinear(img: &GrayImage, x: f64, y: f64) -> Option<f64> {
    let (x0, y0) = cell_of(img, x, y)?;
    Some(interpolate(img, x, y, x0, y0))
}

/// The pixel whose 2x2 block holds `(x, y)` for [`bilinear`]: `None` when `x` or `y` is not in
/// `[0, size - 1)` (off the image, or NaN). That set is an interval in each axis, so every
/// point of a segment whose two ends pass passes too.
#[inline]
fn cell_of(img: &GrayImage, x: f64, y: f64) -> Option<(usize, usize)> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if !(x >= 0.0 && y >= 0.0) {
        return None;
    }
    // Both are non-negative here, so truncation is the floor (and `f64::floor` is a call into
    // libm on the baseline x86-64 target: a third of the cost of an interpolation).
    let (x0, y0) = (x as usize, y as usize);
    if x0 >= w.saturating_sub(1) || y0 >= h.saturating_sub(1) {
        return None;
    }
    Some((x0, y0))
}

/// [`bilinear`] at a point [`cell_of`] accepted; `(x0, y0)` is the cell it returned.
#[inline]
fn interpolate(img: &GrayImage, x: f64, y: f64, x0: usize, y0: usize) -> f64 {
    let w = img.width() as usize;
    let (a, b) = (x - x0 as f64, y - y0 as f64);
    let buf = img.as_raw();
    let k = y0 * w + x0;
    let (top, bottom) = (&buf[k..k + 2], &buf[k + w..k + w + 2]);
    (1.0 - a) * (1.0 - b) * top[0] as f64
        + a * (1.0 - b) * top[1] as f64
        + (1.0 - a) * b * bottom[0] as f64
        + a * b * bottom[1] as f64
}

/// [`interpolate`] at `(x, y)` without the checks: one truncating conversion per coordinate
/// and no bounds checks (a third of a profile's instructions). The same arithmetic in the same
/// order, so the same value to the last bit.
///
/// # Safety
/// `buf` holds the pixels of an image `width` pixels wide, and `(x, y)` is a point [`cell_of`]
/// accepts for that image: `0 <= x < width - 1` and `0 <= y < height - 1`.
#[inline(always)]
unsafe fn interpolate_unchecked(buf: &[u8], width: usize, x: f64, y: f64) -> f64 {
    // SAFETY: x and y are finite and in [0, 2^32) (the caller's contract), so the conversions
    // are defined and truncate, which is the floor of these non-negative values.
    let (x0, y0) = unsafe { (x.to_int_unchecked::<i64>(), y.to_int_unchecked::<i64>()) };
    let (a, b) = (x - x0 as f64, y - y0 as f64);
    let k = y0 as usize * width + x0 as usize;
    // SAFETY: x0 + 1 < width and y0 + 1 < height, so the 2x2 block at k is in the buffer.
    let px = |i: usize| unsafe { *buf.get_unchecked(i) } as f64;
    (1.0 - a) * (1.0 - b) * px(k)
        + a * (1.0 - b) * px(k + 1)
        + (1.0 - a) * b * px(k + width)
        + a * b * px(k + width + 1)
}

/// A line through `p` with unit normal `n`.
#[derive(Clone, Copy, Debug)]
struct Line {
    p: Vector2<f64>,
    n: Vector2<f64>,
}

fn intersect(a: &Line, b: &Line) -> Option<Vector2<f64>> {
    // n_a . x = n_a . p_a, n_b . x = n_b . p_b
    let m = Matrix2::new(a.n.x, a.n.y, b.n.x, b.n.y);
    let rhs = Vector2::new(a.n.dot(&a.p), b.n.dot(&b.p));
    let det = m.determinant();
    if det.abs() < 1e-6 {
        return None;
    }
    let x = m.try_inverse()? * rhs;
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Total least-squares line through weighted points.
fn fit_line(pts: &[(Vector2<f64>, f64)]) -> Option<Line> {
    let sw: f64 = pts.iter().map(|p| p.1).sum();
    if pts.len() < 3 || sw <= 0.0 {
        return None;
    }
    let mean = pts.iter().map(|(p, w)| p * *w).sum::<Vector2<f64>>() / sw;
    let mut c = Matrix2::zeros();
    for (p, w) in pts {
        let d = p - mean;
        c += d * d.transpose() * *w;
    }
    // Normal: eigenvector of the smallest eigenvalue.
    let e = c.symmetric_eigen();
    let k = if e.eigenvalues[0] <= e.eigenvalues[1] {
        0
    } else {
        1
    };
    let n: Vector2<f64> = e.eigenvectors.column(k).into();
    let norm = n.norm();
    (norm > 0.0 && norm.is_finite()).then(|| Line {
        p: mean,
        n: n / norm,
    })
}

/// The mean of a quad's four corners.
pub(crate) fn quad_centre(q: &[Vector2<f64>; 4]) -> Vector2<f64> {
    q.iter().sum::<Vector2<f64>>() / 4.0
}

/// Refines the four corners of one tag (OpenCV pixel convention, libapriltag's order around the
/// square). `cells_across` is the number of pattern cells across the square whose corners these
/// are (the family's `width_at_border`); it sets the search window to a fraction of a cell, so
/// that the window reaches neither the border's inner edge nor a neighbouring tag. `None` when a
/// side cannot be located (off the image, no contrast) or a corner would move by more than a
/// third of a cell; the caller then keeps its corners.
pub fn refine_corners(
    img: &GrayImage,
    corners: &[Vector2<f64>; 4],
    cells_across: f64,
    cam: Option<&Camera>,
) -> Option<[Vector2<f64>; 4]> {
    let space = Space { cam };
    let mut q = [Vector2::zeros(); 4];
    for (k, c) in corners.iter().enumerate() {
        q[k] = space.to_line(c)?;
    }
    let centre_img = quad_centre(corners);
    let side_img: f64 = (0..4)
        .map(|k| (corners[(k + 1) % 4] - corners[k]).norm())
        .sum::<f64>()
        / 4.0;
    let cell = side_img / cells_across.max(1.0);
    if !(cell.is_finite() && cell >= 1.5) {
        return None;
    }
    let w = (0.45 * cell).clamp(1.0, 3.0);
    let steps = (2.0 * w / STEP).round() as usize;
    let mut profiles: Vec<f64> = Vec::new();
    for _ in 0..PASSES {
        let mut lines = [Line {
            p: Vector2::zeros(),
            n: Vector2::zeros(),
        }; 4];
        for e in 0..4 {
            let (a, b) = (q[e], q[(e + 1) % 4]);
            let len = (b - a).norm();
            if !(len.is_finite() && len > 1.0) {
                return None;
            }
            let dir = (b - a) / len;
            // Keep clear of the corners, where the other side's edge enters the window.
            let margin = (w + 1.5).min(0.3 * len);
            let n_samples = ((len - 2.0 * margin) / 1.0).floor().max(0.0) as usize + 1;
            let mut pts: Vec<(Vector2<f64>, f64)> = Vec::with_capacity(n_samples);
            let mut polarity = 0.0;
            // Per sample: its point in line space, its outward normal in the image, the inverse
            // Jacobian of the distortion there; the profiles side by side in one buffer.
            let mut found: Vec<(Vector2<f64>, Vector2<f64>, Matrix2<f64>)> =
                Vec::with_capacity(n_samples);
            profiles.clear();
            for s in 0..n_samples {
                let t = if n_samples == 1 {
                    0.5 * len
                } else {
                    margin + (len - 2.0 * margin) * s as f64 / (n_samples - 1) as f64
                };
                let ql = a + dir * t;
                let Some((p, jac)) = space.to_image_jac(&ql) else {
                    continue;
                };
                let Some(jinv) = jac.try_inverse() else {
                    continue;
                };
                // The side's direction and outward normal in the image.
                let d_img = jac * dir;
                let dn = d_img.norm();
                if dn.is_nan() || dn <= 0.0 {
                    continue;
                }
                let mut nrm = Vector2::new(-d_img.y, d_img.x) / dn;
                if nrm.dot(&(p - centre_img)) < 0.0 {
                    nrm = -nrm;
                }
                // The profile's points move monotonically along each axis (every rounding
                // step is monotonic in `i`), so they are all on the image when its two ends are;
                // otherwise the profile is dropped.
                let point = |i: usize| {
                    let off = -w + i as f64 * STEP;
                    (p.x + off * nrm.x, p.y + off * nrm.y)
                };
                let ((xa, ya), (xb, yb)) = (point(0), point(steps));
                if cell_of(img, xa, ya).is_none() || cell_of(img, xb, yb).is_none() {
                    continue;
                }
                let start = profiles.len();
                let (buf, width) = (img.as_raw().as_slice(), img.width() as usize);
                profiles.extend((0..=steps).map(|i| {
                    let (x, y) = point(i);
                    // SAFETY: (x, y) lies between the profile's two ends, which `cell_of` put
                    // in [0, width - 1) x [0, height - 1) (see above).
                    unsafe { interpolate_unchecked(buf, width, x, y) }
                }));
                polarity += profiles[start + steps] - profiles[start];
                found.push((ql, nrm, jinv));
            }
            let sign = if polarity >= 0.0 { 1.0 } else { -1.0 };
            for (k, (ql, nrm, jinv)) in found.iter().enumerate() {
                let prof = &profiles[k * (steps + 1)..(k + 1) * (steps + 1)];
                let (mut sw, mut swn) = (0.0, 0.0);
                for i in 0..steps {
                    let d = sign * (prof[i + 1] - prof[i]);
                    if d > 0.0 {
                        let mid = -w + (i as f64 + 0.5) * STEP;
                        sw += d;
                        swn += d * mid;
                    }
                }
                // Too little contrast for an edge (grey levels across the window).
                if sw < 8.0 {
                    continue;
                }
                // The edge lies a fraction of a pixel from the sample (less with every pass):
                // mapped back to line space through the local inverse Jacobian.
                pts.push((ql + jinv * (nrm * (swn / sw)), sw));
            }
            let mut line = fit_line(&pts)?;
            // One pass of outlier removal: points far from the line (a neighbour's edge, a
            // reflection) are dropped and the line refitted.
            let dist: Vec<f64> = pts.iter().map(|(x, _)| (x - line.p).dot(&line.n)).collect();
            let mut abs: Vec<f64> = dist.iter().map(|d| d.abs()).collect();
            abs.sort_by(f64::total_cmp);
            let mad = abs[abs.len() / 2];
            let cut = (4.0 * 1.4826 * mad).max(0.3);
            if abs[abs.len() - 1] > cut {
                let kept: Vec<(Vector2<f64>, f64)> = pts
                    .iter()
                    .zip(&dist)
                    .filter(|(_, d)| d.abs() <= cut)
                    .map(|(p, _)| *p)
                    .collect();
                line = fit_line(&kept)?;
            }
            lines[e] = line;
        }
        // Side e runs from corner e to corner e+1: corner e+1 is where sides e and e+1 meet.
        let mut next = q;
        for e in 0..4 {
            next[(e + 1) % 4] = intersect(&lines[e], &lines[(e + 1) % 4])?;
        }
        q = next;
    }
    let mut out = [Vector2::zeros(); 4];
    for k in 0..4 {
        out[k] = space.to_image(&q[k])?;
        if (out[k] - corners[k]).norm() > (cell / 3.0).max(1.0) {
            return None;
        }
    }
    Some(out)
}
