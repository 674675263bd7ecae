//! AprilTag detection: parity with Debian's `apriltag` CLI, the corner order, the sub-pixel bias
//! after the half-pixel conversion, and bad image files.

use std::path::{Path, PathBuf};
use std::process::Command;

use apriltag_sys as sys;
use dvlcal::io::image::load_gray;
use dvlcal::types::board::TagFamily;
use dvlcal::vision::detect::{Detector, DetectorSettings, TagDetection};
use nalgebra::Vector2;

// `image_u8_destroy` is not in Debian's libapriltag.so; it lives in libapriltag-utils.so.
#[link(name = "apriltag-utils")]
unsafe extern "C" {
    fn image_u8_destroy(im: *mut sys::image_u8_t);
}

/// The cells of a tag36h11 tag as `apriltag_to_image` draws it (true = black), row 0 at the top,
/// with the family's border geometry: (cells, total width, index of the first black-border cell).
fn tag36h11_cells(id: u32) -> (Vec<Vec<bool>>, usize, usize) {
    unsafe {
        let tf = sys::tag36h11_create();
        assert!(!tf.is_null());
        let im = sys::apriltag_to_image(tf, id);
        assert!(!im.is_null());
        let (w, h, stride) = (
            (*im).width as usize,
            (*im).height as usize,
            (*im).stride as usize,
        );
        let buf = std::slice::from_raw_parts((*im).buf, h * stride);
        let cells: Vec<Vec<bool>> = (0..h)
            .map(|r| (0..w).map(|c| buf[r * stride + c] < 128).collect())
            .collect();
        let total = (*tf).total_width as usize;
        let border = (total - (*tf).width_at_border as usize) / 2;
        image_u8_destroy(im);
        sys::tag36h11_destroy(tf);
        assert_eq!(w, total);
        (cells, total, border)
    }
}

/// A tag placed in an image: top-left of its cell grid at (x0, y0) in the OpenCV convention (centre
/// of the top-left pixel at (0, 0)), `cell` pixels per cell.
struct Placed {
    id: u32,
    x0: f64,
    y0: f64,
    cell: f64,
}

impl Placed {
    /// The black square's corners in libapriltag's order as documented in detect.rs: bottom-left,
    /// bottom-right, top-right, top-left (image y down), OpenCV convention.
    fn expected_corners(&self) -> [Vector2<f64>; 4] {
        let (_, total, border) = tag36h11_cells(self.id);
        let l = self.x0 + border as f64 * self.cell;
        let r = self.x0 + (total - border) as f64 * self.cell;
        let t = self.y0 + border as f64 * self.cell;
        let b = self.y0 + (total - border) as f64 * self.cell;
        [
            Vector2::new(l, b),
            Vector2::new(r, b),
            Vector2::new(r, t),
            Vector2::new(l, t),
        ]
    }
}

/// Overlap of [a0, a1] with [b0, b1].
fn overlap(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// Renders axis-aligned tags on white with exact area-averaged anti-aliasing: pixel (i, j) covers
/// [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]. Black is 20, white 235.
fn render(width: u32, height: u32, tags: &[Placed]) -> image::GrayImage {
    let mut black = vec![0.0f64; (width * height) as usize];
    for t in tags {
        let (cells, _, _) = tag36h11_cells(t.id);
        for (r, row) in cells.iter().enumerate() {
            for (c, &is_black) in row.iter().enumerate() {
                if !is_black {
                    continue;
                }
                let (x0, x1) = (t.x0 + c as f64 * t.cell, t.x0 + (c + 1) as f64 * t.cell);
                let (y0, y1) = (t.y0 + r as f64 * t.cell, t.y0 + (r + 1) as f64 * t.cell);
                let i0 = ((x0 - 0.5).floor().max(0.0)) as u32;
                let i1 = ((x1 + 0.5).ceil() as u32).min(width - 1);
                let j0 = ((y0 - 0.5).floor().max(0.0)) as u32;
                let j1 = ((y1 + 0.5).ceil() as u32).min(height - 1);
                for j in j0..=j1 {
                    let oy = overlap(j as f64 - 0.5, j as f64 + 0.5, y0, y1);
                    if oy == 0.0 {
                        continue;
                    }
                    for i in i0..=i1 {
                        let ox = overlap(i as f64 - 0.5, i as f64 + 0.5, x0, x1);
                        black[(j * width + i) as usize] += ox * oy;
                    }
                }
            }
        }
    }
    image::GrayImage::from_fn(width, height, |i, j| {
        let k = black[(j * width + i) as usize].clamp(0.0, 1.0);
        image::Luma([(235.0 - k * 215.0).round() as u8])
    })
}

/// Small deterministic generator (SplitMix64) for the test scenes.
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Four tags (ids 0..3) at sub-pixel offsets, two per row.
fn four_tag_scene() -> (image::GrayImage, Vec<Placed>) {
    let tags = vec![
        Placed {
            id: 0,
            x0: 20.3,
            y0: 15.7,
            cell: 12.0,
        },
        Placed {
            id: 1,
            x0: 160.6,
            y0: 18.2,
            cell: 11.5,
        },
        Placed {
            id: 2,
            x0: 22.45,
            y0: 150.1,
            cell: 10.25,
        },
        Placed {
            id: 3,
            x0: 158.9,
            y0: 146.35,
            cell: 12.75,
        },
    ];
    (render(310, 300, &tags), tags)
}

/// Runs Debian's `apriltag` CLI on a PNM file; rows of (id, hamming, corners in its convention).
fn apriltag_cli(file: &Path, decimate: f32, threads: usize) -> Vec<(u32, u32, [[f64; 2]; 4])> {
    let out = Command::new("apriltag")
        .args(["-q", "-v", "-f", "tag36h11", "-m", "1"])
        .args(["-x", &decimate.to_string(), "-t", &threads.to_string()])
        .arg(file)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run Debian's `apriltag` CLI ({e}); install it with `make deps` \
                 (package apriltag)"
            )
        });
    assert!(out.status.success(), "apriltag CLI failed: {out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    let mut rows = Vec::new();
    // vnlog: "# path Ndetections hamming margin id xc yc xlb ylb xrb yrb xrt yrt xlt ylt"; one row
    // per image with the count, then one per detection with "-" in Ndetections.
    let header = text
        .lines()
        .find(|l| l.starts_with("# path"))
        .unwrap_or_else(|| panic!("unexpected apriltag CLI output:\n{text}"));
    assert_eq!(
        header.split_whitespace().collect::<Vec<_>>(),
        "# path Ndetections hamming margin id xc yc xlb ylb xrb yrb xrt yrt xlt ylt"
            .split_whitespace()
            .collect::<Vec<_>>()
    );
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() != 15 || f[1] != "-" {
            continue;
        }
        let num = |k: usize| f[k].parse::<f64>().unwrap();
        let corners = std::array::from_fn(|c| [num(7 + 2 * c), num(8 + 2 * c)]);
        rows.push((f[4].parse().unwrap(), f[2].parse().unwrap(), corners));
    }
    rows.sort_by_key(|r: &(u32, u32, [[f64; 2]; 4])| r.0);
    rows
}

#[test]
fn parity_with_debian_apriltag_cli() {
    let (img, _) = four_tag_scene();
    // Binary PGM (P5), the format the CLI reads (the image crate would write PAM).
    let path = tmp_dir("vision_detect_parity").join("four_tags.pgm");
    let mut pgm = format!("P5\n{} {}\n255\n", img.width(), img.height()).into_bytes();
    pgm.extend_from_slice(img.as_raw());
    std::fs::write(&path, pgm).unwrap();
    for (decimate, threads) in [(2.0f32, 1usize), (1.0, 1), (2.0, 2)] {
        let cli = apriltag_cli(&path, decimate, threads);
        // libapriltag's own corners: our line-fit refinement is not part of the CLI.
        let settings = DetectorSettings {
            decimate,
            threads,
            refine_corners: false,
            ..DetectorSettings::default()
        };
        let ours = Detector::new(&settings)
            .unwrap()
            .detect(&load_gray(&path).unwrap());
        let ids: Vec<u32> = ours.iter().map(|d| d.id).collect();
        assert_eq!(ids, vec![0, 1, 2, 3], "decimate {decimate}");
        assert_eq!(
            cli.iter().map(|r| r.0).collect::<Vec<_>>(),
            ids,
            "decimate {decimate}"
        );
        let mut worst = 0.0f64;
        for (d, (id, hamming, corners)) in ours.iter().zip(&cli) {
            assert_eq!(d.id, *id);
            assert_eq!(d.hamming, *hamming);
            for (ours, theirs) in d.corners.iter().zip(corners) {
                // The CLI prints 6 decimals in libapriltag's convention.
                let ex = (ours.x - (theirs[0] - 0.5)).abs();
                let ey = (ours.y - (theirs[1] - 0.5)).abs();
                worst = worst.max(ex).max(ey);
            }
        }
        println!(
            "decimate {decimate}, threads {threads}: worst difference to the CLI {worst:.2e} px"
        );
        assert!(worst <= 1e-6, "corners differ from the CLI's by {worst} px");
    }
}

#[test]
fn corner_order_is_bottom_left_counter_clockwise() {
    let (img, tags) = four_tag_scene();
    let dets = Detector::new(&DetectorSettings::default())
        .unwrap()
        .detect(&img);
    assert_eq!(dets.len(), 4);
    for (d, t) in dets.iter().zip(&tags) {
        assert_eq!(d.id, t.id);
        let want = t.expected_corners();
        for (k, (got, want)) in d.corners.iter().zip(&want).enumerate() {
            let e = (got - want).norm();
            assert!(e < 0.5, "tag {} corner {k}: {got:?} vs {want:?}", t.id);
        }
        // Image y down: p0 bottom-left, p1 bottom-right, p2 top-right, p3 top-left.
        let c = &d.corners;
        assert!(
            c[0].y > c[3].y && c[1].y > c[2].y,
            "p0, p1 are the bottom corners"
        );
        assert!(
            c[1].x > c[0].x && c[2].x > c[3].x,
            "p1, p2 are the right corners"
        );
    }
}

/// Detections of many random single-tag scenes with their true corners.
fn bias_scenes(
    settings: &DetectorSettings,
    n: usize,
    blur: f32,
) -> Vec<(TagDetection, [Vector2<f64>; 4])> {
    let mut det = Detector::new(settings).unwrap();
    let mut rng = Rng(7);
    let mut out = Vec::new();
    for k in 0..n {
        let t = Placed {
            id: (k % 20) as u32,
            x0: 10.0 + 3.0 * rng.uniform(),
            y0: 10.0 + 3.0 * rng.uniform(),
            cell: 6.0 + 8.0 * rng.uniform(),
        };
        let size = (t.x0 + 10.0 * t.cell + 14.0).ceil() as u32;
        let want = t.expected_corners();
        let mut img = render(size, size, std::slice::from_ref(&t));
        if blur > 0.0 {
            img = image::imageops::blur(&img, blur);
        }
        let dets = det.detect(&img);
        assert_eq!(dets.len(), 1, "scene {k}");
        assert_eq!(dets[0].id, (k % 20) as u32);
        out.push((dets[0].clone(), want));
    }
    out
}

/// Mean error vector, mean |error| and RMS of the detected corners against the truth.
fn corner_stats(scenes: &[(TagDetection, [Vector2<f64>; 4])]) -> (Vector2<f64>, f64, f64) {
    let mut sum = Vector2::zeros();
    let (mut sum_abs, mut sum_sq, mut n) = (0.0, 0.0, 0.0);
    for (d, want) in scenes {
        for (got, want) in d.corners.iter().zip(want) {
            let e = got - want;
            sum += e;
            sum_abs += e.norm();
            sum_sq += e.norm_squared();
            n += 1.0;
        }
    }
    (sum / n, sum_abs / n, (sum_sq / n).sqrt())
}

/// On these scenes (60 tags, 240 corners, tag36h11, 6 to 14 px per cell, random sub-pixel
/// offsets, exact area sampling: independent of the crate's renderer), mean error vector / RMS:
///
/// | settings                  | libapriltag 3.3 alone             | with `refine_corners`    |
/// |---------------------------|-----------------------------------|--------------------------|
/// | decimate 2, sharp         | (-0.084, -0.090) px / 0.187 px    | (0.000, 0.000) / 0.002   |
/// | decimate 1, sharp         | (-0.075, -0.068) px / 0.202 px    | (0.000, 0.000) / 0.002   |
/// | decimate 2, blur 0.7 px   | (-0.072, -0.083) px / 0.173 px    | (0.000, 0.000) / 0.006   |
/// | decimate 2, blur 1.5 px   | (-0.040, -0.036) px / 0.143 px    | (0.000, 0.000) / 0.020   |
///
/// libapriltag's shift is the same at every corner and vanishes with its `refine_edges` off
/// (bias 0.01 px, but a scatter of 0.38 px). Without the half-pixel conversion the bias would be
/// about +0.42 px.
#[test]
fn subpixel_bias_after_half_pixel_conversion() {
    for (decimate, blur) in [(2.0f32, 0.0f32), (1.0, 0.0), (2.0, 0.7), (2.0, 1.5)] {
        let mut rms_of = [0.0; 2];
        for refine_corners in [false, true] {
            let settings = DetectorSettings {
                decimate,
                refine_corners,
                ..DetectorSettings::default()
            };
            let (bias, mean_abs, rms) = corner_stats(&bias_scenes(&settings, 60, blur));
            println!(
                "decimate {decimate}, blur {blur} px, refine_corners {refine_corners}: mean corner \
                 error ({:.4}, {:.4}) px, |bias| {:.4} px, mean |error| {:.4} px, RMS {:.4} px",
                bias.x,
                bias.y,
                bias.norm(),
                mean_abs,
                rms
            );
            rms_of[refine_corners as usize] = rms;
            // The conversion is applied: libapriltag's own convention would be off by about +0.5.
            assert!((bias + Vector2::new(0.5, 0.5)).norm() > 0.5);
            if refine_corners {
                assert!(bias.norm() < 0.05, "bias {bias:?}");
                assert!(bias.norm() < 0.005, "bias {bias:?}");
                assert!(rms < 0.03, "RMS {rms}");
            } else {
                // libapriltag alone: the bias the refinement exists for.
                assert!(bias.norm() > 0.03 && bias.norm() < 0.15, "bias {bias:?}");
                assert!(rms < 0.25, "RMS {rms}");
            }
        }
        assert!(rms_of[1] < 0.25 * rms_of[0], "{rms_of:?}");
    }
}

#[test]
fn bad_image_files_are_errors_naming_the_file() {
    let dir = tmp_dir("vision_detect_bad");
    let (img, _) = four_tag_scene();
    let good = dir.join("good.png");
    img.save(&good).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let truncated = dir.join("truncated.png");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let empty = dir.join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let text = dir.join("notes.jpg");
    std::fs::write(&text, b"this is not an image\n").unwrap();
    let missing = dir.join("missing.png");
    for p in [&truncated, &empty, &text, &missing] {
        let e = load_gray(p).expect_err("bad image accepted").to_string();
        assert!(e.contains(&p.display().to_string()), "{e}");
    }
    assert_eq!(load_gray(&good).unwrap().dimensions(), (310, 300));

    let exe = env!("CARGO_BIN_EXE_dvlcal");
    // Bad images are reported and skipped; the good one is detected.
    let out = Command::new(exe)
        .arg("tags")
        .args([&truncated, &good, &empty, &text])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    for p in [&truncated, &empty, &text] {
        assert!(stderr.contains(&p.display().to_string()), "{stderr}");
    }
    assert!(stderr.contains("3 of 4 images"), "{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(
        lines[0],
        "file,id,hamming,decision_margin,x0,y0,x1,y1,x2,y2,x3,y3,border_bits"
    );
    assert_eq!(lines.len(), 5, "{stdout}");
    for (id, line) in lines[1..].iter().enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 13);
        assert_eq!(f[0], good.display().to_string());
        assert_eq!(f[1], id.to_string());
        assert!(f[4..12].iter().all(|v| v.parse::<f64>().is_ok()));
        // Tags drawn the way libapriltag draws them: a one-bit border.
        assert_eq!(f[12], "1");
    }
    // Nothing readable: non-zero exit.
    let out = Command::new(exe)
        .arg("tags")
        .args([&empty, &missing])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.png"));
}

#[test]
fn tiny_and_blank_images_give_no_detections() {
    for decimate in [1.0f32, 2.0, 4.0] {
        let mut det = Detector::new(&DetectorSettings {
            decimate,
            ..DetectorSettings::default()
        })
        .unwrap();
        for (w, h) in [
            (0, 0),
            (1, 1),
            (7, 9),
            (8, 8),
            (9, 13),
            (16, 16),
            (64, 3),
            (3, 64),
            (100, 100),
        ] {
            let img = image::GrayImage::from_pixel(w, h, image::Luma([128]));
            assert!(det.detect(&img).is_empty(), "{w}x{h}");
        }
    }
}

#[test]
fn every_family_builds_and_settings_are_checked() {
    for f in TagFamily::ALL {
        let s = DetectorSettings {
            family: f,
            ..DetectorSettings::default()
        };
        let mut d = Detector::new(&s).unwrap_or_else(|e| panic!("{}: {e}", f.name()));
        assert!(d.detect(&image::GrayImage::new(32, 32)).is_empty());
    }
    let d = DetectorSettings::default();
    assert_eq!(
        (
            d.decimate,
            d.sigma,
            d.sharpening,
            d.refine_edges,
            d.refine_corners
        ),
        (2.0, 0.0, 0.25, true, true)
    );
    assert_eq!(
        (d.threads, d.max_hamming, d.family),
        (1, 1, TagFamily::Tag36h11)
    );
    for bad in [
        DetectorSettings {
            decimate: 0.5,
            ..d.clone()
        },
        DetectorSettings {
            decimate: f32::NAN,
            ..d.clone()
        },
        DetectorSettings {
            threads: 0,
            ..d.clone()
        },
        DetectorSettings {
            max_hamming: 4,
            ..d.clone()
        },
        DetectorSettings {
            sharpening: -1.0,
            ..d.clone()
        },
    ] {
        assert!(Detector::new(&bad).is_err(), "{bad:?}");
    }
    fn is_send<T: Send>() {}
    is_send::<Detector>();
}
