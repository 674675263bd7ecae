//! How far a camera calibration can be trusted: the coverage of each image by corners, and the
//! weak points of a result in words.

use nalgebra::Vector2;

use crate::camcal::types::{CameraStd, Coverage};
use crate::types::camera::{Camchain, Camera};

/// Share of the grid cells that must hold corners before the distortion counts as measured over
/// the image.
pub const MIN_COVERED_FRACTION: f64 = 0.6;
/// Reach of the corners towards the image corners (1: all the way) below which the distortion
/// near the image corners is extrapolated.
pub const MIN_RADIAL_REACH: f64 = 0.85;
/// Relative standard deviation of a focal length above which it is poorly determined.
pub const MAX_FOCAL_REL_STD: f64 = 0.005;
/// Standard deviation of a principal point coordinate above which it is poorly determined, px.
pub const MAX_PRINCIPAL_STD_PX: f64 = 2.0;
/// Relative standard deviation of a baseline above which it is poorly determined.
pub const MAX_BASELINE_REL_STD: f64 = 0.01;
/// Standard deviation of the stereo rotation above which it is poorly determined, rad (0.1 deg).
pub const MAX_ROTATION_STD_RAD: f64 = 0.1 * std::f64::consts::PI / 180.0;
/// Below this tilt of the board (90th percentile over the views, degrees) the focal length and
/// the board's distance are nearly interchangeable: a small systematic corner error moves the
/// focal length far more than its standard deviation says.
pub const MIN_TILT_DEG: f64 = 25.0;
/// Fewer views than this make a weak calibration.
pub const MIN_GOOD_VIEWS: usize = 15;

/// The coverage of `cam`'s image by the pixels `px` on a grid `cells` wide.
pub fn coverage(cam: &Camera, px: impl Iterator<Item = Vector2<f64>>, cells: usize) -> Coverage {
    let (w, h) = (cam.width.max(1) as f64, cam.height.max(1) as f64);
    let cols = cells.max(1);
    let rows = ((cols as f64 * h / w).round() as usize).max(1);
    let mut counts = vec![0usize; cols * rows];
    let corner = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .map(|&(x, y)| ((x - 0.5 - cam.pu) / cam.fu).hypot((y - 0.5 - cam.pv) / cam.fv))
        .fold(0.0f64, f64::max);
    let mut reach = 0.0f64;
    for p in px {
        let cx = ((p.x + 0.5) / w * cols as f64).floor();
        let cy = ((p.y + 0.5) / h * rows as f64).floor();
        if cx >= 0.0 && cy >= 0.0 && (cx as usize) < cols && (cy as usize) < rows {
            counts[cy as usize * cols + cx as usize] += 1;
        }
        let r = ((p.x - cam.pu) / cam.fu).hypot((p.y - cam.pv) / cam.fv);
        if r.is_finite() {
            reach = reach.max(r);
        }
    }
    let covered = counts.iter().filter(|c| **c > 0).count();
    Coverage {
        cols,
        rows,
        covered_fraction: covered as f64 / counts.len() as f64,
        counts,
        radial_reach: if corner > 0.0 {
            (reach / corner).min(1.0)
        } else {
            0.0
        },
    }
}

/// The parts of the image (of nine: corners, edges, centre) where most grid cells are empty.
pub fn empty_regions(c: &Coverage) -> Vec<&'static str> {
    const NAMES: [[&str; 3]; 3] = [
        ["top-left corner", "top edge", "top-right corner"],
        ["left edge", "centre", "right edge"],
        ["bottom-left corner", "bottom edge", "bottom-right corner"],
    ];
    let mut out = Vec::new();
    for (ry, row) in NAMES.iter().enumerate() {
        for (rx, name) in row.iter().enumerate() {
            let (x0, x1) = (rx * c.cols / 3, (rx + 1) * c.cols / 3);
            let (y0, y1) = (ry * c.rows / 3, (ry + 1) * c.rows / 3);
            let mut cells = 0;
            let mut empty = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    cells += 1;
                    if c.counts.get(y * c.cols + x).is_some_and(|n| *n == 0) {
                        empty += 1;
                    }
                }
            }
            if cells > 0 && 2 * empty > cells {
                out.push(*name);
            }
        }
    }
    out
}

/// The weak points of a calibration, one sentence each (empty: none found).
pub fn weak_points(
    chain: &Camchain,
    std: &[CameraStd],
    coverage: &[Coverage],
    views: &[usize],
    tilt_p90_deg: f64,
) -> Vec<String> {
    let mut w = Vec::new();
    if tilt_p90_deg < MIN_TILT_DEG {
        w.push(format!(
            "the board hardly tilted against the cameras (90 % of the views within {tilt_p90_deg:.0} \
             deg of facing them): the focal lengths and the board's distance trade off, so the \
             focal lengths may be off by more than their standard deviations; record views \
             tilted 30 to 45 degrees"
        ));
    }
    for (i, cam) in chain.cams.iter().enumerate() {
        if let Some(c) = coverage.get(i) {
            let empty = empty_regions(c);
            if c.covered_fraction < MIN_COVERED_FRACTION || !empty.is_empty() {
                w.push(format!(
                    "cam{i}: board corners fell in {:.0} % of the image{}; the distortion there is \
                     extrapolated, not measured: record views with the board in those parts of \
                     the image",
                    100.0 * c.covered_fraction,
                    if empty.is_empty() {
                        String::new()
                    } else {
                        format!(" (none in the {})", empty.join(", "))
                    }
                ));
            }
            if c.radial_reach < MIN_RADIAL_REACH {
                w.push(format!(
                    "cam{i}: the corners reach {:.0} % of the way from the principal point to the \
                     image corners; beyond, the distortion is a guess",
                    100.0 * c.radial_reach
                ));
            }
        }
        if let Some(n) = views.get(i)
            && *n < MIN_GOOD_VIEWS
        {
            w.push(format!(
                "cam{i}: {n} views; {MIN_GOOD_VIEWS} or more from varied angles make a reliable \
                 calibration"
            ));
        }
        let Some(s) = std.get(i) else { continue };
        let rel = (s.intrinsics[0] / cam.fu).max(s.intrinsics[1] / cam.fv);
        if rel > MAX_FOCAL_REL_STD {
            w.push(format!(
                "cam{i}: focal length uncertain to {:.2} % (1 sigma): tilt the board more (up to \
                 45 degrees) and vary its distance",
                100.0 * rel
            ));
        }
        let pp = s.intrinsics[2].max(s.intrinsics[3]);
        if pp > MAX_PRINCIPAL_STD_PX {
            w.push(format!(
                "cam{i}: principal point uncertain to {pp:.1} px (1 sigma)"
            ));
        }
        if let (Some(rot), Some(b)) = (s.rotation_rad, s.baseline_m) {
            let base = chain
                .t_cn_c0
                .get(i)
                .zip(i.checked_sub(1).and_then(|m| chain.t_cn_c0.get(m)))
                .map(|(n, m)| (*n * m.inverse()).trans.norm())
                .unwrap_or(0.0);
            if base > 0.0 && b / base > MAX_BASELINE_REL_STD {
                w.push(format!(
                    "cam{i}: baseline {:.1} mm uncertain to {:.2} % (1 sigma)",
                    1e3 * base,
                    100.0 * b / base
                ));
            }
            let r = rot.iter().fold(0.0f64, |a, v| a.max(*v));
            if r > MAX_ROTATION_STD_RAD {
                w.push(format!(
                    "cam{i}: rotation to cam{} uncertain to {:.2} deg (1 sigma)",
                    i - 1,
                    r.to_degrees()
                ));
            }
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::camera::Distortion;

    fn cam() -> Camera {
        Camera {
            fu: 400.0,
            fv: 400.0,
            pu: 319.5,
            pv: 239.5,
            distortion: Distortion::None,
            width: 640,
            height: 480,
        }
    }

    #[test]
    fn full_grid_is_covered_and_a_left_half_is_not() {
        let c = cam();
        let all: Vec<Vector2<f64>> = (0..64)
            .flat_map(|i| (0..48).map(move |j| Vector2::new(i as f64 * 10.0, j as f64 * 10.0)))
            .collect();
        let full = coverage(&c, all.iter().copied(), 12);
        assert_eq!((full.cols, full.rows), (12, 9));
        assert_eq!(full.covered_fraction, 1.0);
        assert!(full.radial_reach > 0.97);
        assert!(empty_regions(&full).is_empty());
        let left = coverage(&c, all.iter().copied().filter(|p| p.x < 300.0), 12);
        assert!(left.covered_fraction <= 0.5);
        let e = empty_regions(&left);
        assert!(
            e.contains(&"right edge") && e.contains(&"top-right corner"),
            "{e:?}"
        );
        assert!(!e.contains(&"left edge"));
    }
}
