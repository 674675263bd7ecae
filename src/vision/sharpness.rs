//! How blurred an image is: the width of its sharpest edges.
//!
//! A step edge of contrast `C` blurred by a Gaussian of standard deviation `s` pixels has the
//! steepest gradient `C / (s sqrt(2 pi))`. The image's contrast is taken as the spread between
//! its 1st and 99th intensity percentiles and its steepest gradients as the mean of the top
//! 0.2 % of central-difference gradient magnitudes (a board in view has many more edge pixels
//! than that); their ratio gives `s`, the edge width. A sharp edge measures about 0.8 px (the
//! central difference spreads a step over two pixels); motion blur or defocus widens it. The
//! measure compares frames of one recording: the same camera, board and water.

use image::GrayImage;

/// Images with less contrast than this (grey levels between the 1st and 99th percentiles) have
/// no edges to measure.
const MIN_CONTRAST: f64 = 10.0;

/// Fraction of the pixels whose gradients count as the steepest.
const TOP_FRACTION: f64 = 0.002;

/// Gradient histogram resolution, grey levels per pixel per bin.
const BIN: f64 = 0.25;

/// The width of the image's sharpest edges, px (the standard deviation of a Gaussian blur that
/// would give them); `None` for an image too small or too flat to measure.
pub fn edge_width_px(img: &GrayImage) -> Option<f64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w < 8 || h < 8 {
        return None;
    }
    let px = img.as_raw();
    let mut levels = [0usize; 256];
    for &v in px {
        levels[v as usize] += 1;
    }
    let n = px.len();
    let level_at = |q: f64| {
        let target = (q * n as f64).ceil() as usize;
        let mut seen = 0;
        for (v, &c) in levels.iter().enumerate() {
            seen += c;
            if seen >= target.max(1) {
                return v as f64;
            }
        }
        255.0
    };
    let contrast = level_at(0.99) - level_at(0.01);
    if contrast < MIN_CONTRAST {
        return None;
    }
    // Central differences: magnitudes up to 255 / sqrt(2).
    let bins = (256.0 / BIN) as usize;
    let mut grads = vec![0usize; bins];
    for y in 1..h - 1 {
        let row = y * w;
        for x in 1..w - 1 {
            let i = row + x;
            let gx = 0.5 * (f64::from(px[i + 1]) - f64::from(px[i - 1]));
            let gy = 0.5 * (f64::from(px[i + w]) - f64::from(px[i - w]));
            let b = ((gx * gx + gy * gy).sqrt() / BIN) as usize;
            grads[b.min(bins - 1)] += 1;
        }
    }
    let inner = (w - 2) * (h - 2);
    let top = ((TOP_FRACTION * inner as f64).ceil() as usize).max(1);
    let (mut taken, mut sum) = (0usize, 0.0);
    for (b, &c) in grads.iter().enumerate().rev() {
        let k = c.min(top - taken);
        sum += k as f64 * (b as f64 + 0.5) * BIN;
        taken += k;
        if taken == top {
            break;
        }
    }
    let steepest = sum / top as f64;
    (steepest > 0.0).then(|| contrast / ((2.0 * std::f64::consts::PI).sqrt() * steepest))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Vertical stripes 16 px wide, black and white, blurred by a Gaussian of `sigma` px.
    fn stripes(sigma: f64) -> GrayImage {
        let profile: Vec<f64> = (0..128)
            .map(|x| if (x / 16) % 2 == 0 { 40.0 } else { 220.0 })
            .collect();
        let blurred: Vec<f64> = (0..128i32)
            .map(|x| {
                if sigma == 0.0 {
                    return profile[x as usize];
                }
                let r = (4.0 * sigma).ceil() as i32;
                let (mut s, mut wsum) = (0.0, 0.0);
                for d in -r..=r {
                    let wgt = (-(d * d) as f64 / (2.0 * sigma * sigma)).exp();
                    s += wgt * profile[(x + d).clamp(0, 127) as usize];
                    wsum += wgt;
                }
                s / wsum
            })
            .collect();
        GrayImage::from_fn(128, 64, |x, _| {
            image::Luma([blurred[x as usize].round() as u8])
        })
    }

    #[test]
    fn the_edge_width_follows_the_blur() {
        let sharp = edge_width_px(&stripes(0.0)).expect("sharp");
        assert!((0.6..1.0).contains(&sharp), "{sharp}");
        for sigma in [2.0, 3.0, 5.0] {
            let w = edge_width_px(&stripes(sigma)).expect("blurred");
            assert!((w - sigma).abs() < 0.15 * sigma, "sigma {sigma}: {w}");
        }
        let flat = GrayImage::from_pixel(64, 64, image::Luma([120]));
        assert_eq!(edge_width_px(&flat), None);
    }
}
