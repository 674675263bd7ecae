//! The HTML calibration report: every section and plot present on a simulated calibration, text
//! escaped, size bounded for long logs, empty plots marked, and a render in headless Chromium
//! without console messages (`scripts/check_report.sh`).
//!
//! The browser test needs Debian's `chromium` (installed by `make deps`); it is skipped only when
//! `DVLCAL_SKIP_BROWSER=1`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use dvlcal::calib::Status;
use dvlcal::calib::offset::DvlObs;
use dvlcal::calib::{CalibOptions, CalibrationOutcome, Method, calibrate};
use dvlcal::io::dvl::DvlLogStats;
use dvlcal::report::{FrameDrop, FrameStat, PLOT_IDS, ReportInput, SECTION_IDS, render_html};
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::vision::pnp::CornerResidual;
use nalgebra::{Matrix3, Vector3};

struct Run {
    ds: SimDataset,
    outcome: CalibrationOutcome,
}

/// One simulated calibration shared by the tests.
fn run() -> &'static Run {
    static RUN: OnceLock<Run> = OnceLock::new();
    RUN.get_or_init(|| {
        let ds = simulate(&SimConfig {
            seed: 5,
            motion: MotionKind::CalmThenRotate,
            duration_s: 40.0,
            ..SimConfig::default()
        })
        .expect("simulation");
        let outcome = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
        Run { ds, outcome }
    })
}

/// Log counts with names that need escaping.
fn stats() -> DvlLogStats {
    DvlLogStats {
        path: PathBuf::from("logs/<dive & 2>.jsonl"),
        time_source_used: "time_of_validity (DVL clock)".into(),
        lines: 410,
        velocity_reports: 400,
        valid: 400,
        warnings: vec!["clock <jump> & gap near line 17".into()],
        first_time_s: Some(0.0),
        last_time_s: Some(39.9),
        ..DvlLogStats::default()
    }
}

/// Frame statistics at the pose times, every tenth frame without a pose; two cameras, cam1's
/// corners twice as far off as cam0's, growing toward the image edge.
fn frames(ds: &SimDataset) -> Vec<FrameStat> {
    ds.poses
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let posed = k % 10 != 3;
            let corners = (0..2u8)
                .flat_map(|cam| {
                    (0..12).map(move |j| {
                        let u = ((k * 37 + j * 61) % 752) as f32;
                        let v = ((k * 23 + j * 41) % 480) as f32;
                        let edge = ((u - 376.0).abs() / 376.0).max((v - 240.0).abs() / 240.0);
                        CornerResidual {
                            cam,
                            u,
                            v,
                            du: (0.1 + 0.9 * edge) * (1 + cam) as f32,
                            dv: 0.05,
                        }
                    })
                })
                .filter(|_| posed)
                .collect();
            FrameStat {
                t: p.t,
                posed,
                tags_detected: 20 + k % 7,
                tags_used: if posed { 18 + k % 5 } else { 0 },
                rms_px: posed.then_some(0.2 + 0.01 * (k % 13) as f64),
                rms_px_per_cam: if posed {
                    vec![Some(0.15 + 0.01 * (k % 13) as f64), Some(0.3)]
                } else {
                    Vec::new()
                },
                corners,
                edge_width_px: Some(0.9),
                dropped: (!posed).then_some(FrameDrop::TooFewCorners),
            }
        })
        .collect()
}

/// The image size of both cameras.
const SIZES: &[(u32, u32)] = &[(752, 480), (752, 480)];

fn svg_of<'a>(html: &'a str, id: &str) -> &'a str {
    let start = html
        .find(&format!("<svg id=\"{id}\""))
        .unwrap_or_else(|| panic!("plot {id} missing"));
    let len = html[start..].find("</svg>").expect("closed svg") + "</svg>".len();
    &html[start..start + len]
}

fn full_report(r: &Run, frames: &[FrameStat], st: &DvlLogStats) -> String {
    let input = ReportInput {
        title: "Dive <7> & friends",
        dataset: "poses.txt & <dvl>.jsonl",
        dvl_stats: Some(st),
        frames: Some(frames),
        result_name: Some("out/<result>.yaml"),
        result_yaml: Some("time_offset_s: 0.07 # <&>\n"),
        elapsed_s: Some(1.25),
        image_sizes: Some(SIZES),
        ..ReportInput::new(&r.outcome, &r.ds.poses)
    };
    render_html(&input).expect("report")
}

#[test]
fn report_has_every_section_and_plot_with_data() {
    let r = run();
    let fr = frames(&r.ds);
    let st = stats();
    let html = full_report(r, &fr, &st);
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.trim_end().ends_with("</html>"));
    for id in SECTION_IDS {
        assert!(
            html.contains(&format!("<section id=\"{id}\"")),
            "section {id}"
        );
    }
    let mut last = 0;
    for id in PLOT_IDS {
        let svg = svg_of(&html, id);
        assert!(!svg.contains("data-empty"), "plot {id} has no data");
        assert!(svg.contains("<path") || svg.contains("<rect x"), "{id}");
        // Page order follows PLOT_IDS.
        let at = html.find(svg).expect("found");
        assert!(at >= last, "plot {id} out of order");
        last = at;
    }
    assert_eq!(html.matches("<svg").count(), PLOT_IDS.len());
    assert_eq!(html.matches("</svg>").count(), PLOT_IDS.len());
    // Everything user-supplied is escaped; nothing is fetched or run.
    for raw in ["<7>", "<dvl>", "<dive", "<jump>", "<result>", "# <&>"] {
        assert!(!html.contains(raw), "unescaped {raw}");
    }
    assert!(html.contains("Dive &lt;7&gt; &amp; friends"));
    assert!(html.contains("logs/&lt;dive &amp; 2&gt;.jsonl"));
    assert!(html.contains("clock &lt;jump&gt; &amp; gap near line 17"));
    for bad in ["<script", "<link", "<img", "src=", "href=", "NaN", "inf\""] {
        assert!(!html.contains(bad), "report contains {bad}");
    }
    // The calm subset is shaded, the verdicts are in words, the warnings are listed.
    assert!(svg_of(&html, "angular-velocity").contains("class=\"sp\""));
    assert!(html.contains("is well determined"));
    assert!(html.len() < 1_500_000, "{} bytes", html.len());
    // Roll, pitch, yaw and axis-angle beside the quaternion; the correlation matrix with a cell
    // per pair; the residuals over time with their band; each camera's reprojection.
    assert!(html.contains("roll, pitch, yaw (deg; R = Rz(yaw) Ry(pitch) Rx(roll)"));
    assert!(html.contains("axis and angle"));
    let corr = &html[html.find("id=\"correlation-matrix\"").expect("matrix")..];
    let corr = &corr[..corr.find("</table>").expect("table end")];
    assert_eq!(corr.matches("<td class=\"num\"").count(), 64);
    assert_eq!(corr.matches(">+1.00</td>").count(), 8);
    assert!(html.contains("id=\"correlation-words\""));
    for axis in ["x", "y", "z"] {
        let svg = svg_of(&html, &format!("residual-time-{axis}"));
        assert!(svg.contains("±3σ stated noise"), "{axis}");
        assert!(svg.contains("stroke-dasharray"), "{axis}: the band");
    }
    assert!(html.contains("every sample drawn"));
    for cam in ["cam0", "cam1"] {
        let map = svg_of(&html, &format!("reprojection-map-{cam}"));
        assert!(
            map.contains("&lt; 0.25 px") || map.contains("0.25–0.5 px"),
            "{cam}"
        );
        assert!(map.contains("≥ 1 px"), "{cam}: the edge corners");
        assert!(svg_of(&html, &format!("reprojection-time-{cam}")).contains("frame RMS"));
    }
    let words = &html[html.find("id=\"reprojection-words\"").expect("words")..];
    let posed = fr.iter().filter(|f| f.posed).count();
    for cam in ["cam0", "cam1"] {
        let said = format!("{cam}: {posed} frames with corners");
        assert!(words.contains(&said), "{said}: {}", &words[..300]);
    }
}

#[test]
fn failed_status_is_at_the_top_with_its_reasons() {
    let r = run();
    let mut o = r.outcome.clone();
    o.status = Status::Failed(vec!["the velocity scale <0.5> is implausible".into()]);
    let html = render_html(&ReportInput::new(&o, &r.ds.poses)).expect("report");
    let failed = html.find("id=\"failed\"").expect("failure box");
    assert!(failed < html.find("<section id=\"results\"").expect("results"));
    assert!(html.contains("Calibration failed: this result cannot be trusted."));
    assert!(html.contains("<li>the velocity scale &lt;0.5&gt; is implausible</li>"));
}

#[test]
fn weak_lever_arm_is_explained_in_words() {
    let ds = simulate(&SimConfig {
        seed: 3,
        motion: MotionKind::WeakRotation,
        duration_s: 40.0,
        ..SimConfig::default()
    })
    .expect("simulation");
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    assert!(!o.verdicts.lever_arm.ok);
    let html = render_html(&ReportInput::new(&o, &ds.poses)).expect("report");
    assert!(html.contains("The lever arm is weakly observable: "));
    assert!(html.contains("the lever arm is weakly observable"));
    assert!(html.contains("Attention: the lever arm"));
}

#[test]
fn long_logs_give_a_small_report() {
    // 100k DVL samples over the trajectory: the plots thin them to their pixel size.
    let r = run();
    let mut o = r.outcome.clone();
    let (a, b) = o.fitted.span();
    let n = 100_000;
    let margin = 0.6;
    o.observations = (0..n)
        .map(|k| {
            let t = a + margin + (b - a - 2.0 * margin) * k as f64 / (n - 1) as f64;
            let phase = 0.37 * k as f64;
            DvlObs {
                t,
                v: Vector3::new(phase.sin(), phase.cos(), (1.3 * phase).sin()) * 0.3,
                cov: Matrix3::identity() * 1e-4,
            }
        })
        .collect();
    o.used = (0..n).collect();
    if let Some(init) = &mut o.init {
        init.offset.calm = (0..n / 2).collect();
    }
    let html = render_html(&ReportInput::new(&o, &r.ds.poses)).expect("report");
    eprintln!("report of {n} DVL samples: {} bytes", html.len());
    // Kept for a look in a browser.
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report");
    if std::fs::create_dir_all(&dir).is_ok() {
        let _ = std::fs::write(dir.join("long.html"), &html);
    }
    assert!(html.len() < 3_000_000, "{} bytes", html.len());
    for id in PLOT_IDS {
        svg_of(&html, id);
    }
    // The residual timeline is decimated, and says so.
    assert!(html.contains("drawn decimated: the lowest and highest residual of each of"));
    for axis in ["x", "y", "z"] {
        let svg = svg_of(&html, &format!("residual-time-{axis}"));
        assert!(svg.len() < 200_000, "{axis}: {} bytes", svg.len());
    }
}

#[test]
fn plots_without_data_say_why() {
    let r = run();
    let guess = r.ds.truth;
    let opts = CalibOptions {
        method: Method::Bcd(guess),
        ..CalibOptions::default()
    };
    let o = calibrate(&r.ds.poses, &r.ds.dvl, &opts).expect("calibration");
    let html = render_html(&ReportInput::new(&o, &r.ds.poses)).expect("report");
    for id in [
        "offset-coarse",
        "offset-fine",
        "frames-tags",
        "frames-rms",
        "reprojection-map-cam0",
        "reprojection-time-cam1",
    ] {
        assert!(svg_of(&html, id).contains("data-empty=\"true\""), "{id}");
    }
    for id in ["velocity-after-x", "cost", "trajectory", "lever-arm"] {
        assert!(!svg_of(&html, id).contains("data-empty"), "{id}");
    }
    assert!(html.contains("no clock-offset search"));
    assert!(html.contains("own counts were not given"));
}

fn browser_skipped() -> bool {
    std::env::var("DVLCAL_SKIP_BROWSER").is_ok_and(|v| v == "1")
}

fn check_in_browser(report: &Path, screenshot: &Path) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/check_report.sh");
    let out = Command::new("bash")
        .arg(&script)
        .arg(report)
        .arg(screenshot)
        .output()
        .expect("run scripts/check_report.sh");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "browser check of {} failed (set DVLCAL_SKIP_BROWSER=1 only where no Chromium can be \
         installed):\n{stdout}\n{stderr}",
        report.display()
    );
    assert!(
        stdout.contains("renders without console messages"),
        "{stdout}"
    );
    let png = std::fs::read(screenshot).expect("screenshot");
    assert!(png.starts_with(b"\x89PNG") && png.len() > 50_000);
}

#[test]
fn a_calibration_that_stops_with_an_error_still_writes_a_report() {
    // Clock offsets limited to where the two logs cannot overlap: the calibration stops.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report-failure");
    std::fs::create_dir_all(&dir).expect("output dir");
    let html = dir.join("failed.html");
    let _ = std::fs::remove_file(&html);
    let out = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .arg("calibrate")
        .arg("--poses")
        .arg(root.join("sample_data/poses/poses.txt"))
        .arg("--dvl")
        .arg(root.join("sample_data/poses/dvl.jsonl"))
        .arg("--offset-range=1000,1100")
        .arg("--out")
        .arg(dir.join("failed.yaml"))
        .arg("--report")
        .arg(&html)
        .output()
        .expect("run dvlcal");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("do not overlap"), "{stderr}");
    let text = std::fs::read_to_string(&html).expect("failure report written");
    assert!(text.contains("<body data-report=\"failure\">"));
    // The reason, what it means, the counts and the spans.
    assert!(text.contains("do not overlap by 10 s or more at any clock offset in [1000, 1100] s"));
    assert!(text.contains("cover no common stretch of time"));
    assert!(text.contains("<tr><th>camera poses</th><td>601</td></tr>"));
    assert!(text.contains("0.000 s to 60.000 s (60.0 s)"));
    assert!(text.contains("with the clocks as recorded"));
    assert!(text.contains("sample_data/poses/dvl.jsonl"));
    assert!(
        !dir.join("failed.yaml").exists(),
        "no result for a run that stopped"
    );
    if !browser_skipped() {
        check_in_browser(&html, &dir.join("failed.png"));
    }
}

#[test]
fn reports_render_in_headless_chromium() {
    if browser_skipped() {
        eprintln!("DVLCAL_SKIP_BROWSER=1: browser check skipped");
        return;
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report");
    std::fs::create_dir_all(&dir).expect("output dir");

    // From the library, with image statistics and names that need escaping.
    let r = run();
    let fr = frames(&r.ds);
    let st = stats();
    let lib = dir.join("simulated <&> report.html");
    std::fs::write(&lib, full_report(r, &fr, &st)).expect("write report");
    check_in_browser(&lib, &dir.join("simulated.png"));

    // From the command line, on the sample dataset.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let html = dir.join("sample.html");
    let out = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .arg("calibrate")
        .arg("--poses")
        .arg(root.join("sample_data/poses/poses.txt"))
        .arg("--dvl")
        .arg(root.join("sample_data/poses/dvl.jsonl"))
        .arg("--out")
        .arg(dir.join("sample.yaml"))
        .arg("--report")
        .arg(&html)
        .output()
        .expect("run dvlcal");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&html).expect("report written");
    assert!(
        text.contains("quaternion_cam_dvl_xyzw"),
        "result file embedded"
    );
    check_in_browser(&html, &dir.join("sample.png"));
}
