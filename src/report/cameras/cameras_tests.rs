//! The camera calibration report on hand-made results: every section and plot present, text
//! escaped, dropped frames named, the coverage sentence only where coverage is poor, a mono
//! chain and an empty result rendered, and (with Chromium) a render without console messages.

use std::path::Path;
use std::process::Command;

use nalgebra::{Vector2, Vector3};

use super::shared::coverage_poor;
use super::*;
use crate::camcal::quality::coverage as grid_coverage;
use crate::camcal::{CamCalResult, CameraModel, CameraStd, Coverage, FrameFit, Residual};
use crate::lie::{Se3, so3};
use crate::types::camera::{Camchain, Camera, Distortion};

/// A small deterministic generator of numbers in [-1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

fn cam(fu: f64) -> Camera {
    Camera {
        fu,
        fv: fu * 1.001,
        pu: 321.2,
        pv: 238.7,
        distortion: Distortion::RadTan {
            k1: -0.28,
            k2: 0.07,
            p1: 1.2e-4,
            p2: -3.0e-4,
        },
        width: 640,
        height: 480,
    }
}

fn std_of(i: usize) -> CameraStd {
    CameraStd {
        intrinsics: [0.41, 0.40, 0.33, 0.29],
        distortion: [1.1e-3, 2.3e-3, 4.0e-5, 3.5e-5],
        rotation_rad: (i > 0).then_some([1.2e-4, 2.0e-4, 0.9e-4]),
        translation_m: (i > 0).then_some([1.5e-4, 1.1e-4, 4.0e-4]),
        baseline_m: (i > 0).then_some(1.6e-4),
    }
}

/// A result of `cams` cameras over `frames` frames, frame 3 dropped as an outlier. With
/// `full_coverage` the corners cover every image; without, only its left half.
fn result(cams: usize, frames: usize, full_coverage: bool) -> CamCalResult {
    let chain_cams: Vec<Camera> = (0..cams).map(|i| cam(455.0 + i as f64)).collect();
    let mut t_cn_c0 = vec![Se3::identity()];
    for i in 1..cams {
        t_cn_c0.push(Se3::new(
            so3::exp(&Vector3::new(0.004 * i as f64, -0.011, 0.002)),
            Vector3::new(-0.121 * i as f64, 0.0008, 0.0015),
        ));
    }
    let chain = Camchain {
        cams: chain_cams.clone(),
        t_cn_c0: t_cn_c0.clone(),
        topics: vec![None; cams],
    };
    let mut initial = chain.clone();
    for c in &mut initial.cams {
        c.fu -= 2.5;
        c.pv += 1.3;
    }
    for t in initial.t_cn_c0.iter_mut().skip(1) {
        t.trans.x += 0.002;
    }
    let mut rng = Lcg(7);
    let mut residuals = Vec::new();
    let per_view = 36;
    for f in 0..frames {
        for c in 0..cams {
            for k in 0..per_view {
                let (u, v) = (0.5 * (rng.next() + 1.0), 0.5 * (rng.next() + 1.0));
                let u = if full_coverage { u * 639.0 } else { u * 300.0 };
                let mut res = Vector2::new(0.2 * rng.next(), 0.2 * rng.next());
                let mut used = true;
                if f == 3 {
                    res *= 15.0;
                    used = false;
                } else if k == 0 && f % 2 == 0 {
                    res = Vector2::new(2.5, -1.8);
                    used = false;
                }
                residuals.push(Residual {
                    frame: f,
                    cam: c,
                    px: Vector2::new(u, v * 479.0),
                    r: res,
                    used,
                });
            }
        }
    }
    let frame_fits: Vec<FrameFit> = (0..frames)
        .map(|f| {
            let dropped = (f == 3).then(|| {
                "reprojection RMS 2.20 px, over 3.0x the median frame's 0.12 px".to_owned()
            });
            FrameFit {
                frame: f,
                name: if f == 3 {
                    "img_<003>&.png".to_owned()
                } else {
                    format!("img_{f:03}.png")
                },
                t_ns: 1_000_000_000 + 100_000_000 * f as i64,
                corners: vec![per_view; cams],
                t_c0_board: dropped.is_none().then(Se3::identity),
                rms_px: (0..cams)
                    .map(|c| {
                        dropped
                            .is_none()
                            .then_some(0.1 + 0.002 * ((f * 7 + c) % 11) as f64)
                    })
                    .collect(),
                dropped,
            }
        })
        .collect();
    let coverage: Vec<Coverage> = (0..cams)
        .map(|c| {
            grid_coverage(
                &chain_cams[c],
                residuals
                    .iter()
                    .filter(|x| x.used && x.cam == c)
                    .map(|x| x.px),
                12,
            )
        })
        .collect();
    let used = residuals.iter().filter(|x| x.used).count();
    CamCalResult {
        chain,
        model: CameraModel::PinholeRadtan,
        std: (0..cams).map(std_of).collect(),
        sigma_px: 0.082,
        rms_px: 0.116,
        rms_px_per_cam: vec![0.116; cams],
        initial,
        initial_rms_px: vec![0.31; cams],
        frames: frame_fits,
        residuals,
        coverage,
        views_used: vec![frames - 1; cams],
        corners_used: used,
        corners_rejected: cams * frames * per_view - used,
        detections_unmatched: 2,
        tags_at_border: 1,
        tilt_p90_deg: 38.0,
        iterations: 9,
        warnings: vec![
            "cam1: <script>alert('x')</script> & a warning".to_owned(),
            "cam0: 11 views; 15 or more from varied angles make a reliable calibration".to_owned(),
        ],
    }
}

fn input() -> CamCalReportInput {
    CamCalReportInput {
        images: "data/<stereo> & co".to_owned(),
        target: "april_6x6 <board>.yaml".to_owned(),
        camchain_yaml: "cam0:\n  camera_model: pinhole # <b>\n".to_owned(),
        camchain_path: Some("out/camchain <1>.yaml".to_owned()),
        command: Some("dvlcal calibrate-cameras 'data/<stereo> & co'".to_owned()),
    }
}

fn svg_of<'a>(html: &'a str, id: &str) -> &'a str {
    let start = html
        .find(&format!("<svg id=\"{id}\""))
        .unwrap_or_else(|| panic!("plot {id} missing"));
    let len = html[start..].find("</svg>").expect("closed svg") + "</svg>".len();
    &html[start..start + len]
}

fn section_of<'a>(html: &'a str, id: &str) -> &'a str {
    let start = html
        .find(&format!("<section id=\"{id}\""))
        .unwrap_or_else(|| panic!("section {id} missing"));
    let len = html[start..].find("</section>").expect("closed section");
    &html[start..start + len]
}

const GUESS: &str = "Where there are no corners the distortion is a guess";

#[test]
fn stereo_report_has_every_section_and_plot() {
    let r = result(2, 12, false);
    let html = render_camcal_html(&r, &input()).expect("report");
    assert!(html.starts_with("<!DOCTYPE html>") && html.ends_with("</html>\n"));
    let mut last = 0;
    for id in CAMCAL_SECTION_IDS {
        let at = html
            .find(&format!("<section id=\"{id}\""))
            .unwrap_or_else(|| panic!("section {id} missing"));
        assert!(at > last, "section {id} out of order");
        last = at;
    }
    let ids = camcal_plot_ids(2);
    assert_eq!(
        ids.len(),
        2 * CAMCAL_CAMERA_PLOT_IDS.len() + CAMCAL_PLOT_IDS.len()
    );
    let mut last = 0;
    for id in &ids {
        let at = html.find(&format!("<svg id=\"{id}\"")).unwrap_or(0);
        assert!(at > last, "plot {id} missing or out of order");
        last = at;
        let svg = svg_of(&html, id);
        assert!(!svg.contains("data-empty"), "{id} has data");
        assert!(!svg.contains("NaN") && !svg.contains("inf"), "{id}");
    }
    assert_eq!(html.matches("<svg").count(), ids.len());
    assert_eq!(html.matches("</svg>").count(), ids.len());
    assert_eq!(
        html.matches("<section").count(),
        html.matches("</section>").count()
    );
    // Residual map: dots, rejected crosses and arrows; coverage: hatched empty cells.
    let map = svg_of(&html, "residual-map-cam1");
    assert!(map.contains("h0M") && map.contains("rejected") && map.contains("arrows x"));
    assert!(svg_of(&html, "coverage-grid-cam0").contains("-hatch)\""));
    // Results: values with std, the initial values, and the extrinsics of cam1.
    let res = section_of(&html, "results");
    assert!(
        res.contains("455.00 ± 0.41") && res.contains("452.50"),
        "{res}"
    );
    assert!(res.contains("baseline (mm)") && res.contains("cam1 from cam0"));
    assert!(
        res.contains("121.0") && res.contains("± 0.16"),
        "baseline with std"
    );
    // Summary figures and a verdict that names the poor coverage.
    let sum = section_of(&html, "summary");
    assert!(sum.contains("0.116 px") && sum.contains("0.082 px") && sum.contains("0.310 px"));
    assert!(sum.contains("11 used, 1 dropped"), "{sum}");
    assert!(sum.contains("class=\"weak\"") && sum.contains("cam0 and cam1"));
    assert!(sum.contains("2 warnings"));
}

#[test]
fn user_text_is_escaped() {
    let r = result(2, 8, true);
    let html = render_camcal_html(&r, &input()).expect("report");
    assert!(!html.to_lowercase().contains("<script"));
    assert!(html.contains("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; a warning"));
    assert!(html.contains("data/&lt;stereo&gt; &amp; co"));
    assert!(html.contains("april_6x6 &lt;board&gt;.yaml"));
    assert!(html.contains("# &lt;b&gt;") && !html.contains("<b>"));
    assert!(html.contains("img_&lt;003&gt;&amp;.png") && !html.contains("img_<003>"));
    assert!(html.contains("out/camchain &lt;1&gt;.yaml"));
}

#[test]
fn dropped_and_worst_frames_are_named() {
    let r = result(2, 12, true);
    let html = render_camcal_html(&r, &input()).expect("report");
    let fr = section_of(&html, "frames");
    let dropped = &fr[fr.find("id=\"dropped-frames\"").expect("dropped table")..];
    let dropped = &dropped[..dropped.find("id=\"worst-frames\"").expect("worst table")];
    assert!(dropped.contains("img_&lt;003&gt;&amp;.png"));
    assert!(dropped.contains("over 3.0x the median frame"));
    assert!(
        !dropped.contains("img_004.png"),
        "only dropped frames there"
    );
    // Frame 3 is drawn with the RMS of all its corners.
    assert!(svg_of(&html, "frame-rms").contains("dropped frame"));
    let worst = &fr[fr.find("id=\"worst-frames\"").expect("worst table")..];
    // The used frame with the largest RMS over its cameras heads the table.
    let top = r
        .frames
        .iter()
        .filter(|f| f.dropped.is_none())
        .max_by(|a, b| {
            let m = |f: &FrameFit| f.rms_px.iter().flatten().fold(0.0f64, |x, y| x.max(*y));
            m(a).total_cmp(&m(b)).then(b.frame.cmp(&a.frame))
        })
        .expect("a used frame");
    assert!(worst.contains(&top.name), "{worst}");
    assert!(
        !worst.contains("img_&lt;003"),
        "dropped frames are not among the worst"
    );
}

#[test]
fn coverage_sentence_only_when_coverage_is_poor() {
    let poor = result(2, 12, false);
    assert!(poor.coverage.iter().all(coverage_poor));
    let html = render_camcal_html(&poor, &input()).expect("report");
    let cov = section_of(&html, "coverage");
    assert_eq!(cov.matches(GUESS).count(), 2, "{cov}");
    assert!(
        cov.contains("right edge") && cov.contains("top-right corner"),
        "{cov}"
    );

    let full = result(2, 40, true);
    assert!(
        full.coverage.iter().all(|c| !coverage_poor(c)),
        "{:?}",
        full.coverage
    );
    let html = render_camcal_html(&full, &input()).expect("report");
    assert!(!html.contains(GUESS));
    assert!(section_of(&html, "coverage").contains("measured over the whole image"));
}

#[test]
fn mono_chain_renders_with_notes() {
    let mut r = result(1, 6, true);
    let html = render_camcal_html(&r, &input()).expect("report");
    for id in camcal_plot_ids(1) {
        svg_of(&html, &id);
    }
    assert!(!html.contains("residual-map-cam1"));
    assert!(section_of(&html, "results").contains("No extrinsics"));

    // No residuals, no frames, no coverage, no std: notes, not panics.
    r.residuals.clear();
    r.frames.clear();
    r.coverage.clear();
    r.std.clear();
    r.warnings.clear();
    r.views_used.clear();
    r.rms_px_per_cam.clear();
    r.initial_rms_px.clear();
    r.initial.cams.clear();
    r.corners_used = 0;
    r.rms_px = f64::NAN;
    let html = render_camcal_html(&r, &CamCalReportInput::default()).expect("report");
    for id in camcal_plot_ids(1) {
        assert!(svg_of(&html, &id).contains("data-empty=\"true\""), "{id}");
    }
    assert!(html.contains("No frame was dropped") && html.contains("No warnings"));
    assert!(html.contains("no camchain file was written") || html.contains("No camchain file"));
    assert!(!html.contains("NaN"));

    // No camera at all.
    r.chain.cams.clear();
    r.chain.t_cn_c0.clear();
    let html = render_camcal_html(&r, &CamCalReportInput::default()).expect("report");
    for id in CAMCAL_SECTION_IDS {
        section_of(&html, id);
    }
    svg_of(&html, "frame-rms");
    assert!(html.contains("Nothing was calibrated"));
}

#[test]
fn many_corners_give_a_bounded_page() {
    let r = result(2, 600, true);
    assert!(r.residuals.len() > 40_000);
    let html = render_camcal_html(&r, &input()).expect("report");
    assert!(html.len() < 2_500_000, "{} bytes", html.len());
}

#[test]
fn camera_report_renders_in_headless_chromium() {
    if std::env::var("DVLCAL_SKIP_BROWSER").is_ok_and(|v| v == "1") {
        eprintln!("DVLCAL_SKIP_BROWSER=1: browser check skipped");
        return;
    }
    let dir = std::env::temp_dir().join("dvlcal-camcal-report");
    std::fs::create_dir_all(&dir).expect("output dir");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/check_report.sh");
    for (name, r) in [
        ("stereo <&> cameras.html", result(2, 30, false)),
        ("mono.html", result(1, 10, true)),
    ] {
        let page = dir.join(name);
        std::fs::write(&page, render_camcal_html(&r, &input()).expect("report"))
            .expect("write report");
        let shot = dir.join(format!("{name}.png"));
        let out = Command::new("bash")
            .arg(&script)
            .arg(&page)
            .arg(&shot)
            .output()
            .expect("run scripts/check_report.sh");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && stdout.contains("renders without console messages"),
            "browser check of {} failed (set DVLCAL_SKIP_BROWSER=1 only where no Chromium can be \
             installed):\n{stdout}\n{}",
            page.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    eprintln!("camera reports checked in {}", dir.display());
}
