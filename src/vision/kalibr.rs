//! Aprilgrids printed by Kalibr (`kalibr_create_target_pdf`): tag36h11 codes inside a black
//! border **two** bits wide, with no white ring of their own, and a black square in the gap at
//! every tag corner, touching the corner diagonally (and the neighbouring tags' corners).
//!
//! # Why libapriltag alone does not read them
//!
//! libapriltag 3 finds a tag as the boundary between a black region and the white region all
//! around it. On a Kalibr board the corner squares join each tag's black border to its
//! neighbours' at the corners (in a blurred image the diagonal contact is a few grey pixels wide),
//! so the white around a tag is cut into four pieces and no quad is fitted. And its decoder reads
//! the bits of a one-bit border: even a quad it finds is sampled on the wrong grid.
//!
//! # How dvlcal reads them (two passes, in [`crate::vision::detect::Detector`])
//!
//! 1. libapriltag is given, beside tag36h11, a copy of tag36h11 whose border is two bits wide
//!    (`width_at_border` 10, every bit one cell further in): it decodes every Kalibr tag whose
//!    quad its segmentation finds in the image as it is (on sharp, high-resolution photos, all).
//! 2. When that pass found no tag at all, or at least one Kalibr tag, libapriltag's segmentation
//!    runs again on two half-resolution images in which every pixel is the brightest of its 2x2
//!    block ([`max_decimate`]), the second after a 3x3 brightest filter ([`max3`]). That widens
//!    every white region by about half a pixel (one and a half) of the full image, which opens
//!    the diagonal contacts; the black squares of the tags become separate quads. Each quad is
//!    moved out by what the brightening took off, refined on the full-resolution image
//!    (`vision::refine`, after a wider re-fit of its sides when a corner kept a piece of a
//!    corner square), and decoded there: the bits are read through the refined corners'
//!    homography against a threshold halfway between a plane fitted to the black border and a
//!    plane fitted to the white just outside it. A quad is a tag when the border is black, the
//!    outside white, the contrast clear and the code within the allowed number of corrected bits
//!    of a tag36h11 code (in one of its four rotations). When the board is known
//!    (`DetectorSettings::board_ids`), the pass stops as soon as every one of its ids is found.
//!
//! When the board is also known to be a Kalibr print (`DetectorSettings::kalibr_print`, set by
//! the pipeline for a Kalibr aprilgrid YAML), the first image of pass 2 runs before pass 1, and
//! pass 1 and the second image of pass 2 only while ids of the board are still missing: on such
//! a print pass 2 is the one that finds the tags, so pass 1 is mostly work for nothing.
//!
//! The corners of every Kalibr tag end on the saddle points of the X-junctions between the tag
//! and its corner squares, which the ink spread of a printer does not move. Tags found twice (by
//! both passes, or by both families) are kept once: same id, centres closer than a quarter of the
//! tag's side. docs/method.md ("Board detection") has the figures.

use std::os::raw::{c_char, c_int, c_void};

use apriltag_sys as sys;
use image::GrayImage;
use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3};

use crate::types::board::TagFamily;
use crate::vision::family::{FamilyCodes, TagCells, tags_cells};
use crate::vision::refine::{bilinear, quad_centre};

/// Width of a Kalibr tag's black border, in bits.
pub const KALIBR_BORDER_BITS: u32 = 2;

/// Cells across a Kalibr tag36h11's black square: 6 data bits and two border bits each side.
pub const KALIBR_CELLS_ACROSS: u32 = 10;

/// Makes libapriltag's tag36h11 family read Kalibr's two-bit border: the square the quad is
/// fitted to is 10 cells wide (not 8), every data bit one cell further in.
///
/// # Safety
/// `tf` must be a family just made by `tag36h11_create` and not yet given to a detector.
pub(crate) unsafe fn widen_border(tf: *mut sys::apriltag_family_t) -> bool {
    // SAFETY: the caller passes a live, unshared family; its bit arrays hold `nbits` entries.
    unsafe {
        let f = &mut *tf;
        if f.bit_x.is_null() || f.bit_y.is_null() || f.width_at_border != 8 {
            return false;
        }
        f.width_at_border = KALIBR_CELLS_ACROSS as c_int;
        f.total_width = KALIBR_CELLS_ACROSS as c_int + 2;
        for i in 0..f.nbits as usize {
            *f.bit_x.add(i) += 1;
            *f.bit_y.add(i) += 1;
        }
        true
    }
}

/// The cells of tag36h11 tags as Kalibr prints them (`true` = black), row 0 at the top, in the
/// canonical orientation: 10 x 10 cells over the black square, the 6 x 6 code in the middle and a
/// black border two cells wide. `None` for an id tag36h11 does not have. (libapriltag's own
/// pattern is the same code in a one-cell border inside a white ring, also 10 x 10: the ring
/// becomes the outer border cell.)
pub fn kalibr_tag_cells(ids: &[u32]) -> Option<Vec<Option<TagCells>>> {
    let (layout, cells) = tags_cells(TagFamily::Tag36h11, ids)?;
    if layout.total_width != KALIBR_CELLS_ACROSS || layout.width_at_border != 8 {
        return None;
    }
    let n = KALIBR_CELLS_ACROSS as usize;
    Some(
        cells
            .into_iter()
            .map(|c| {
                c.map(|mut c| {
                    for (r, row) in c.iter_mut().enumerate() {
                        for (k, cell) in row.iter_mut().enumerate() {
                            if r == 0 || k == 0 || r == n - 1 || k == n - 1 {
                                *cell = true;
                            }
                        }
                    }
                    c
                })
            })
            .collect(),
    )
}

/// A half-resolution image in which each pixel is the brightest of its 2x2 block (odd last
/// rows and columns dropped).
pub fn max_decimate(img: &GrayImage) -> GrayImage {
    let (w, h) = img.dimensions();
    let (hw, hh) = (w / 2, h / 2);
    let src = img.as_raw();
    let stride = w as usize;
    let mut out = vec![0u8; hw as usize * hh as usize];
    for (y, row) in out.chunks_exact_mut(hw.max(1) as usize).enumerate() {
        let a = &src[2 * y * stride..2 * y * stride + 2 * row.len()];
        let b = &src[(2 * y + 1) * stride..(2 * y + 1) * stride + 2 * row.len()];
        // Pairs of rows, then pairs of columns: loops the compiler turns into vector code.
        for ((o, a), b) in row.iter_mut().zip(a.chunks_exact(2)).zip(b.chunks_exact(2)) {
            *o = a[0].max(a[1]).max(b[0].max(b[1]));
        }
    }
    GrayImage::from_raw(hw, hh, out).unwrap_or_default()
}

/// The image with every pixel replaced by the brightest of its 3x3 neighbourhood (clamped at
/// the borders): white regions grow by one pixel.
pub fn max3(img: &GrayImage) -> GrayImage {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w == 0 || h == 0 {
        return img.clone();
    }
    let src = img.as_raw();
    let mut rows = vec![0u8; w * h];
    for y in 0..h {
        let r = &src[y * w..(y + 1) * w];
        let o = &mut rows[y * w..(y + 1) * w];
        for x in 0..w {
            o[x] = r[x.saturating_sub(1)].max(r[x]).max(r[(x + 1).min(w - 1)]);
        }
    }
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        let (a, b, c) = (y.saturating_sub(1), y, (y + 1).min(h - 1));
        for x in 0..w {
            out[y * w + x] = rows[a * w + x].max(rows[b * w + x]).max(rows[c * w + x]);
        }
    }
    GrayImage::from_raw(w as u32, h as u32, out).unwrap_or_default()
}

/// `max_decimate(&max3(img))` in one pass, without the full-resolution intermediate image:
/// pixel (x, y) of the half-resolution result is the brightest of the full-resolution pixels in
/// columns 2x-1..=2x+2 and rows 2y-1..=2y+2 (within the image), which is the union of the 3x3
/// neighbourhoods of the 2x2 block that `max_decimate` reads.
pub fn max3_decimate(img: &GrayImage) -> GrayImage {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (hw, hh) = (w / 2, h / 2);
    if hw == 0 || hh == 0 {
        return GrayImage::new(hw as u32, hh as u32);
    }
    let src = img.as_raw();
    let row = |r: usize| &src[r * w..(r + 1) * w];
    let mut out = vec![0u8; hw * hh];
    // Brightest of the four (or, at the top and bottom, three) rows, column by column.
    let mut vmax = vec![0u8; w];
    for (y, o) in out.chunks_exact_mut(hw).enumerate() {
        let (r1, r2) = (2 * y, 2 * y + 1);
        let r0 = r1.saturating_sub(1);
        let r3 = (r2 + 1).min(h - 1);
        for (((v, a), b), (c, d)) in vmax
            .iter_mut()
            .zip(row(r0))
            .zip(row(r1))
            .zip(row(r2).iter().zip(row(r3)))
        {
            *v = (*a).max(*b).max((*c).max(*d));
        }
        for (x, px) in o.iter_mut().enumerate() {
            let left = vmax[(2 * x).saturating_sub(1)];
            let right = vmax[(2 * x + 2).min(w - 1)];
            *px = vmax[2 * x].max(vmax[2 * x + 1]).max(left.max(right));
        }
    }
    GrayImage::from_raw(hw as u32, hh as u32, out).unwrap_or_default()
}

/// libapriltag 3.3's `struct quad` (corners in its pixel convention; the homographies are
/// not set by `apriltag_quad_thresh`).
#[repr(C)]
struct RawQuad {
    p: [[f32; 2]; 4],
    reversed_border: bool,
    h: *mut c_void,
    hinv: *mut c_void,
}

/// libapriltag's `zarray_t`.
#[repr(C)]
struct RawZarray {
    el_sz: usize,
    size: c_int,
    alloc: c_int,
    data: *mut c_char,
}

unsafe extern "C" {
    // Exported by Debian's libapriltag 3.3; not in apriltag-sys's bindings.
    fn apriltag_quad_thresh(
        td: *mut sys::apriltag_detector_t,
        im: *mut sys::image_u8_t,
    ) -> *mut RawZarray;
}

/// The quads (black squares with a white outside) libapriltag's segmentation finds in `img`,
/// in `img`'s pixels with libapriltag's convention (pixel centres at +0.5). Empty when the
/// detector has not run yet (its worker pool is made by the first detection) or the library's
/// quad record is not the one this code was written for.
///
/// # Safety
/// `td` must be a live detector used by this thread only.
pub(crate) unsafe fn quads(
    td: *mut sys::apriltag_detector_t,
    img: &GrayImage,
) -> Vec<[[f64; 2]; 4]> {
    let (w, h) = img.dimensions();
    if w < 8 || h < 8 || w > i32::MAX as u32 || h > i32::MAX as u32 {
        return Vec::new();
    }
    let mut im = sys::image_u8_t {
        width: w as i32,
        height: h as i32,
        stride: w as i32,
        // libapriltag reads the image and never writes to it.
        buf: img.as_raw().as_ptr() as *mut u8,
    };
    let mut out = Vec::new();
    // SAFETY: the detector is live and ours; `im` points at w * h bytes that outlive the call.
    // The returned array and its elements are read through the sizes it states (after checking
    // the element size) and freed as libapriltag allocates them (plain malloc).
    unsafe {
        if (*td).wp.is_null() {
            return out;
        }
        let za = apriltag_quad_thresh(td, &mut im);
        if za.is_null() {
            return out;
        }
        let z = &*za;
        let n = usize::try_from(z.size).unwrap_or(0);
        let sized = z.el_sz == std::mem::size_of::<RawQuad>();
        if !z.data.is_null() {
            for i in 0..n {
                let q = &*(z.data.add(i * z.el_sz) as *const RawQuad);
                if sized && !q.reversed_border {
                    out.push(q.p.map(|c| [c[0] as f64, c[1] as f64]));
                }
                if sized {
                    libc::free(q.h);
                    libc::free(q.hinv);
                }
            }
            libc::free(z.data as *mut c_void);
        }
        libc::free(za as *mut c_void);
    }
    out
}

/// A tag read off a quad by [`decode_quad`].
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Decoded {
    pub id: u32,
    pub hamming: u32,
    /// Mean distance of the data bits' grey levels from their threshold.
    pub margin: f32,
    /// Corners of the black square (OpenCV pixels): bottom-left, bottom-right, top-right,
    /// top-left of the upright tag.
    pub corners: [Vector2<f64>; 4],
}

/// The homography mapping the four `src` points to the four `dst` points.
fn homography(src: &[Vector2<f64>; 4], dst: &[Vector2<f64>; 4]) -> Option<Matrix3<f64>> {
    let mut a = SMatrix::<f64, 8, 8>::zeros();
    let mut b = SVector::<f64, 8>::zeros();
    for k in 0..4 {
        let (x, y) = (src[k].x, src[k].y);
        let (u, v) = (dst[k].x, dst[k].y);
        let r = 2 * k;
        a[(r, 0)] = x;
        a[(r, 1)] = y;
        a[(r, 2)] = 1.0;
        a[(r, 6)] = -u * x;
        a[(r, 7)] = -u * y;
        b[r] = u;
        a[(r + 1, 3)] = x;
        a[(r + 1, 4)] = y;
        a[(r + 1, 5)] = 1.0;
        a[(r + 1, 6)] = -v * x;
        a[(r + 1, 7)] = -v * y;
        b[r + 1] = v;
    }
    let h = a.lu().solve(&b)?;
    let m = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0);
    m.iter().all(|v| v.is_finite()).then_some(m)
}

fn apply(h: &Matrix3<f64>, u: f64, v: f64) -> Option<Vector2<f64>> {
    let p = h * Vector3::new(u, v, 1.0);
    (p.z.abs() > 1e-12).then(|| Vector2::new(p.x / p.z, p.y / p.z))
}

/// Least-squares plane `a + b u + c v` through `(u, v, value)` samples; the mean when the
/// samples do not span a plane.
fn fit_plane(s: &[(f64, f64, f64)]) -> [f64; 3] {
    let mut m = Matrix3::zeros();
    let mut r = Vector3::zeros();
    for &(u, v, g) in s {
        let x = Vector3::new(1.0, u, v);
        m += x * x.transpose();
        r += x * g;
    }
    match m.try_inverse() {
        Some(inv) if s.len() >= 6 => {
            let p = inv * r;
            [p.x, p.y, p.z]
        }
        _ => {
            let mean = s.iter().map(|x| x.2).sum::<f64>() / s.len().max(1) as f64;
            [mean, 0.0, 0.0]
        }
    }
}

fn plane_at(p: &[f64; 3], u: f64, v: f64) -> f64 {
    p[0] + p[1] * u + p[2] * v
}

/// Lowest contrast between the white outside and the black border of a decoded quad, grey
/// levels.
const MIN_CONTRAST: f64 = 12.0;

/// Reads a Kalibr tag (two-bit border, tag36h11 code) off a quad of the full-resolution image.
/// `quad`: the black square's corners in OpenCV pixels, in any order around the square.
/// `None` when the quad is not such a tag (see the module documentation for the tests).
pub(crate) fn decode_quad(
    img: &GrayImage,
    quad: &[Vector2<f64>; 4],
    book: &FamilyCodes,
    max_hamming: u32,
) -> Option<Decoded> {
    let n = KALIBR_CELLS_ACROSS as f64;
    // Order the corners as the tag's bottom-left, bottom-right, top-right, top-left appear on
    // screen for some rotation: clockwise in image coordinates (y down), which is a negative
    // shoelace sum.
    let area: f64 = (0..4)
        .map(|k| {
            let (a, b) = (quad[k], quad[(k + 1) % 4]);
            a.x * b.y - b.x * a.y
        })
        .sum();
    if !(area.is_finite() && area.abs() > 16.0) {
        return None;
    }
    let q = if area < 0.0 {
        *quad
    } else {
        [quad[0], quad[3], quad[2], quad[1]]
    };
    // Tag cell coordinates: u to the right, v down from the top-left corner of the black square.
    let tag = [
        Vector2::new(0.0, n),
        Vector2::new(n, n),
        Vector2::new(n, 0.0),
        Vector2::new(0.0, 0.0),
    ];
    let h = homography(&tag, &q)?;
    // A grey level at tag coordinates: the mean of five bilinear samples inside the cell.
    let value = |u: f64, v: f64| -> Option<f64> {
        let mut acc = 0.0;
        for (du, dv) in [
            (0.0, 0.0),
            (-0.2, -0.2),
            (0.2, -0.2),
            (-0.2, 0.2),
            (0.2, 0.2),
        ] {
            let p = apply(&h, u + du, v + dv)?;
            acc += bilinear(img, p.x, p.y)?;
        }
        Some(acc / 5.0)
    };
    let mut black = Vec::with_capacity(64);
    let nc = KALIBR_CELLS_ACROSS as usize;
    for r in 0..nc {
        for c in 0..nc {
            let border = |i: usize| i < 2 || i >= nc - 2;
            if border(r) || border(c) {
                let (u, v) = (c as f64 + 0.5, r as f64 + 0.5);
                black.push((u, v, value(u, v)?));
            }
        }
    }
    // Just outside each side, away from the corner squares.
    let mut white = Vec::with_capacity(32);
    for i in 1..nc - 1 {
        let t = i as f64 + 0.5;
        for (u, v) in [(-0.5, t), (n + 0.5, t), (t, -0.5), (t, n + 0.5)] {
            white.push((u, v, value(u, v)?));
        }
    }
    let pb = fit_plane(&black);
    let pw = fit_plane(&white);
    let mean = |s: &[(f64, f64, f64)]| s.iter().map(|x| x.2).sum::<f64>() / s.len() as f64;
    if mean(&white) - mean(&black) < MIN_CONTRAST {
        return None;
    }
    let thr = |u: f64, v: f64| 0.5 * (plane_at(&pb, u, v) + plane_at(&pw, u, v));
    let dark = black.iter().filter(|s| s.2 < thr(s.0, s.1)).count();
    let light = white.iter().filter(|s| s.2 > thr(s.0, s.1)).count();
    if (dark as f64) < 0.9 * black.len() as f64 || (light as f64) < 0.8 * white.len() as f64 {
        return None;
    }
    let nbits = book.bits.len();
    if nbits == 0 || nbits > 64 {
        return None;
    }
    // The data cells as read in the quad's own frame, and whether each is white.
    let mut cells = [[(false, 0.0f64); KALIBR_CELLS_ACROSS as usize]; KALIBR_CELLS_ACROSS as usize];
    for (r, row) in cells.iter_mut().enumerate().take(nc - 2).skip(2) {
        for (c, cell) in row.iter_mut().enumerate().take(nc - 2).skip(2) {
            let (u, v) = (c as f64 + 0.5, r as f64 + 0.5);
            let g = value(u, v)?;
            let th = thr(u, v);
            *cell = (g > th, (g - th).abs());
        }
    }
    // Taking the quad's corner `shift` as the tag's bottom-left turns the tag: a cell (column c,
    // row r) of the turned tag is cell (r, n - 1 - c) of the quad's frame, once per quarter turn.
    let mut best: Option<(u32, usize, u32, f64)> = None; // (hamming, shift, id, margin)
    for shift in 0..4 {
        let mut code = 0u64;
        let mut margin = 0.0;
        for &(bx, by) in &book.bits {
            let (mut c, mut r) = (bx as usize + 1, by as usize + 1);
            if c >= nc || r >= nc {
                return None;
            }
            for _ in 0..shift {
                (c, r) = (r, nc - 1 - c);
            }
            let (white, m) = cells[r][c];
            code = (code << 1) | u64::from(white);
            margin += m;
        }
        for (id, &c) in book.codes.iter().enumerate() {
            let d = (c ^ code).count_ones();
            if d <= max_hamming && best.is_none_or(|b| d < b.0) {
                best = Some((d, shift, id as u32, margin / nbits as f64));
            }
        }
    }
    let (hamming, shift, id, margin) = best?;
    Some(Decoded {
        id,
        hamming,
        margin: margin as f32,
        corners: std::array::from_fn(|i| q[(i + shift) % 4]),
    })
}

/// A quick test before a rough quad is refined and decoded: some cell of the code area is
/// clearly lighter than the border. Quads that are not tags (the corner squares, solid dark
/// shapes) fail it and cost no refinement. Sampled through the rough quad's homography, so it
/// holds for quads a pixel or two off.
pub(crate) fn has_light_code_cell(img: &GrayImage, quad: &[Vector2<f64>; 4]) -> bool {
    let n = KALIBR_CELLS_ACROSS as f64;
    let tag = [
        Vector2::new(0.0, n),
        Vector2::new(n, n),
        Vector2::new(n, 0.0),
        Vector2::new(0.0, 0.0),
    ];
    let Some(h) = homography(&tag, quad) else {
        return false;
    };
    let at = |u: f64, v: f64| apply(&h, u, v).and_then(|p| bilinear(img, p.x, p.y));
    let (mut border, mut count) = (0.0, 0usize);
    for i in 0..KALIBR_CELLS_ACROSS {
        let t = i as f64 + 0.5;
        for (u, v) in [(1.0, t), (n - 1.0, t), (t, 1.0), (t, n - 1.0)] {
            if let Some(g) = at(u, v) {
                border += g;
                count += 1;
            }
        }
    }
    if count == 0 {
        return false;
    }
    let border = border / count as f64;
    (2..KALIBR_CELLS_ACROSS - 2).any(|r| {
        (2..KALIBR_CELLS_ACROSS - 2)
            .any(|c| at(c as f64 + 0.5, r as f64 + 0.5).is_some_and(|g| g - border >= MIN_CONTRAST))
    })
}

/// The quad with every side moved outward (away from the centre) by `d` pixels.
pub(crate) fn grow(q: &[Vector2<f64>; 4], d: f64) -> Option<[Vector2<f64>; 4]> {
    let centre = quad_centre(q);
    // Side k runs from corner k to corner k + 1, moved out along its normal.
    let mut sides = [(Vector2::zeros(), Vector2::zeros()); 4];
    for k in 0..4 {
        let (a, b) = (q[k], q[(k + 1) % 4]);
        let dir = b - a;
        let len = dir.norm();
        if !(len.is_finite() && len > 1e-9) {
            return None;
        }
        let mut nrm = Vector2::new(-dir.y, dir.x) / len;
        if nrm.dot(&(a - centre)) < 0.0 {
            nrm = -nrm;
        }
        sides[k] = (a + nrm * d, dir / len);
    }
    let mut out = [Vector2::zeros(); 4];
    for k in 0..4 {
        // Corner k is where side k - 1 meets side k.
        let (p1, d1) = sides[(k + 3) % 4];
        let (p2, d2) = sides[k];
        let m = nalgebra::Matrix2::new(d1.x, -d2.x, d1.y, -d2.y);
        let t = m.try_inverse()? * (p2 - p1);
        out[k] = p1 + d1 * t.x;
        if !out[k].iter().all(|v| v.is_finite()) {
            return None;
        }
    }
    Some(out)
}

/// Re-fits the four sides of a rough quad on the full-resolution image before the fine
/// refinement: along the middle half of each side, the strongest dark-to-light step going
/// outward within `reach` pixels of the side is taken as the edge, a line is fitted to those
/// points (points more than a pixel off dropped, then refitted), and the corners become the
/// intersections. A corner of a second-pass quad can sit several pixels off where the
/// segmentation kept a bit of a corner square; the middle of each side is clear of that.
/// `None` when a side has too few edge points or the result is not a plausible quad.
pub(crate) fn coarse_fit(
    img: &GrayImage,
    q: &[Vector2<f64>; 4],
    reach: f64,
) -> Option<[Vector2<f64>; 4]> {
    const STEP: f64 = 0.5;
    let centre = quad_centre(q);
    let mut lines = [(Vector2::zeros(), Vector2::zeros()); 4];
    for k in 0..4 {
        let (a, b) = (q[k], q[(k + 1) % 4]);
        let len = (b - a).norm();
        if !(len.is_finite() && len > 4.0) {
            return None;
        }
        let dir = (b - a) / len;
        let mut nrm = Vector2::new(-dir.y, dir.x);
        if nrm.dot(&(a - centre)) < 0.0 {
            nrm = -nrm;
        }
        let steps = (2.0 * reach / STEP).round() as usize;
        let n = (0.5 * len).floor().max(2.0) as usize;
        let mut pts = Vec::with_capacity(n);
        for i in 0..n {
            let p = a + dir * (len * (0.25 + 0.5 * i as f64 / (n - 1) as f64));
            let mut prev = None;
            let mut best = (0.0, 0.0);
            for j in 0..=steps {
                let off = -reach + j as f64 * STEP;
                let x = p + nrm * off;
                let Some(g) = bilinear(img, x.x, x.y) else {
                    prev = None;
                    continue;
                };
                if let Some(g0) = prev {
                    let d = g - g0;
                    if d > best.0 {
                        best = (d, off - 0.5 * STEP);
                    }
                }
                prev = Some(g);
            }
            if best.0 > 2.0 {
                pts.push(p + nrm * best.1);
            }
        }
        if pts.len() < 3 {
            return None;
        }
        let mut line = tls(&pts)?;
        let kept: Vec<Vector2<f64>> = pts
            .iter()
            .copied()
            .filter(|x| (x - line.0).dot(&Vector2::new(-line.1.y, line.1.x)).abs() <= 1.0)
            .collect();
        if kept.len() >= 3 && kept.len() < pts.len() {
            line = tls(&kept)?;
        }
        lines[k] = line;
    }
    let mut out = [Vector2::zeros(); 4];
    for k in 0..4 {
        // Corner k is where side k - 1 meets side k.
        let (p1, d1) = lines[(k + 3) % 4];
        let (p2, d2) = lines[k];
        let m = nalgebra::Matrix2::new(d1.x, -d2.x, d1.y, -d2.y);
        let t = m.try_inverse()? * (p2 - p1);
        out[k] = p1 + d1 * t.x;
        let side = (q[(k + 1) % 4] - q[k])
            .norm()
            .min((q[(k + 3) % 4] - q[k]).norm());
        if !(out[k].iter().all(|v| v.is_finite()) && (out[k] - q[k]).norm() < 0.5 * side) {
            return None;
        }
    }
    Some(out)
}

/// Total least-squares line through points: a point on it and its unit direction.
fn tls(pts: &[Vector2<f64>]) -> Option<(Vector2<f64>, Vector2<f64>)> {
    let n = pts.len() as f64;
    let mean = pts.iter().sum::<Vector2<f64>>() / n;
    let mut c = nalgebra::Matrix2::zeros();
    for p in pts {
        let d = p - mean;
        c += d * d.transpose();
    }
    let e = c.symmetric_eigen();
    let k = if e.eigenvalues[0] >= e.eigenvalues[1] {
        0
    } else {
        1
    };
    let d: Vector2<f64> = e.eigenvectors.column(k).into();
    let norm = d.norm();
    (norm > 0.0 && norm.is_finite()).then(|| (mean, d / norm))
}

/// The saddle point of the X-junction at `c` where a Kalibr tag's corner meets a corner square:
/// the point `x` that minimises `sum_q w_q (g_q . (q - x))^2` over the pixels `q` of a window
/// of `radius` pixels (`g_q`: the image gradient, `w_q`: a Gaussian weight): every gradient of
/// the four edges meeting at the junction points across an edge through `x`. Iterated from
/// `c` until the point moves by less than 0.005 px. `None` when the window leaves the image,
/// the gradients do not fix a point (no junction), or the point leaves the window.
pub(crate) fn saddle_point(img: &GrayImage, c: &Vector2<f64>, radius: f64) -> Option<Vector2<f64>> {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let buf = img.as_raw();
    let at = |x: i64, y: i64| buf[(y * w + x) as usize] as f64;
    let r = radius.max(1.0);
    let ri = r.ceil() as i64;
    // Gaussian weight with a standard deviation of half the window.
    let s2 = 2.0 * (0.5 * r) * (0.5 * r);
    let mut x = *c;
    for _ in 0..10 {
        if !x.iter().all(|v| v.is_finite()) {
            return None;
        }
        let (cx, cy) = (x.x.round() as i64, x.y.round() as i64);
        if cx - ri - 1 < 0 || cy - ri - 1 < 0 || cx + ri + 1 >= w || cy + ri + 1 >= h {
            return None;
        }
        let mut a = nalgebra::Matrix2::zeros();
        let mut b = Vector2::zeros();
        for qy in cy - ri..=cy + ri {
            for qx in cx - ri..=cx + ri {
                let q = Vector2::new(qx as f64, qy as f64);
                let d2 = (q - x).norm_squared();
                if d2 > r * r {
                    continue;
                }
                let g = Vector2::new(
                    0.5 * (at(qx + 1, qy) - at(qx - 1, qy)),
                    0.5 * (at(qx, qy + 1) - at(qx, qy - 1)),
                );
                let gg = g * g.transpose() * (-d2 / s2).exp();
                a += gg;
                b += gg * q;
            }
        }
        let e = a.symmetric_eigen();
        let (lo, hi) = (e.eigenvalues.min(), e.eigenvalues.max());
        if !(lo > 0.0 && lo > 1e-3 * hi) {
            return None;
        }
        let next = a.try_inverse()? * b;
        if !next.iter().all(|v| v.is_finite()) || (next - c).norm() > r {
            return None;
        }
        let moved = (next - x).norm();
        x = next;
        if moved < 0.005 {
            break;
        }
    }
    Some(x)
}
