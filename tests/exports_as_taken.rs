//! Outputs a user takes as they are: the ready-made boards print on their paper at exact scale,
//! the URDF export is a robot ROS's own parser reads, an export never shows a value the data did
//! not measure without saying so, and `compare-calib` does not pass a failed estimate.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::io::calib_yaml::{Observability, read_calib_yaml};
use dvlcal::io::target::read_board;
use dvlcal::vision::detect::{Detector, DetectorSettings};

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir, dvlcal, s};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn text(o: &[u8]) -> String {
    String::from_utf8_lossy(o).into_owned()
}

/// The value of `name="..."` in an element's text (SVG, XML).
fn attr(el: &str, name: &str) -> Option<String> {
    let key = format!(" {name}=\"");
    let start = el.find(&key)? + key.len();
    let end = el[start..].find('"')? + start;
    Some(el[start..end].to_owned())
}

// ---------------------------------------------------------------------------------------------
// Boards

fn num(el: &str, name: &str) -> f64 {
    attr(el, name)
        .unwrap_or_else(|| panic!("no {name} in {el}"))
        .trim_end_matches("mm")
        .parse()
        .unwrap_or_else(|e| panic!("{name} of {el}: {e}"))
}

/// Everything drawn on a sheet, as axis-aligned boxes in mm (x0, y0, x1, y1) with what drew
/// them; and each tag's edge (mm) and centre on the sheet.
struct Sheet {
    width: f64,
    height: f64,
    viewbox: Vec<f64>,
    boxes: Vec<([f64; 4], String)>,
    tags: BTreeMap<u32, (f64, [f64; 2])>,
    /// The board's paper (the outlined rectangle), x0, y0, width, height.
    board: [f64; 4],
}

/// Reads what `dvlcal board` draws: rectangles, lines, arrow heads, text (its extent from the
/// monospace advance of 0.6 em, anchored at its start or end) and the tags (cell grids placed by
/// a `matrix(...)`, 10 cells across for tag36h11 with its white ring, 8 across the black square).
fn read_sheet(svg: &str) -> Sheet {
    let svg_el = svg.lines().find(|l| l.starts_with("<svg")).expect("<svg>");
    let mut sheet = Sheet {
        width: num(svg_el, "width"),
        height: num(svg_el, "height"),
        viewbox: attr(svg_el, "viewBox")
            .unwrap_or_default()
            .split(' ')
            .map(|v| v.parse().unwrap())
            .collect(),
        boxes: Vec::new(),
        tags: BTreeMap::new(),
        board: [f64::NAN; 4],
    };
    let mut font = 0.0;
    let mut in_tag = false;
    for l in svg.lines() {
        if let Some(f) = attr(l, "font-size") {
            font = f.parse().unwrap();
        }
        if let (Some(id), Some(m)) = (attr(l, "id"), attr(l, "transform")) {
            let id: u32 = id.trim_start_matches("tag").parse().unwrap();
            let m: Vec<f64> = m
                .trim_start_matches("matrix(")
                .trim_end_matches(')')
                .split(' ')
                .map(|v| v.parse().unwrap())
                .collect();
            // Upright tags: cell (u, v) -> (e + a u, f + d v).
            let (cell, e, f) = (m[0], m[4], m[5]);
            let bx = [e, f, e + 10.0 * cell, f + 10.0 * cell];
            sheet.boxes.push((bx, format!("tag {id}")));
            let centre = [e + 5.0 * cell, f + 5.0 * cell];
            sheet.tags.insert(id, (8.0 * cell, centre));
            in_tag = true;
            continue;
        }
        if l.starts_with("</g>") {
            in_tag = false;
        }
        if in_tag || l.starts_with("<svg") {
            continue;
        }
        if l.starts_with("<rect") {
            let (x, y, w, h) = (num(l, "x"), num(l, "y"), num(l, "width"), num(l, "height"));
            if l.contains("stroke=\"#bbbbbb\"") {
                sheet.board = [x, y, w, h];
            }
            if !(x == 0.0 && y == 0.0) {
                sheet.boxes.push(([x, y, x + w, y + h], l.to_owned()));
            }
        } else if l.starts_with("<line") {
            let (x1, y1, x2, y2) = (num(l, "x1"), num(l, "y1"), num(l, "x2"), num(l, "y2"));
            sheet.boxes.push((
                [x1.min(x2), y1.min(y2), x1.max(x2), y1.max(y2)],
                l.to_owned(),
            ));
        } else if l.starts_with("<path") {
            // "M x y l dx dy l dx dy z": the start point and the relative steps.
            let d = attr(l, "d").unwrap();
            let v: Vec<f64> = d.split(' ').filter_map(|t| t.parse::<f64>().ok()).collect();
            let (mut x, mut y) = (v[0], v[1]);
            let mut b = [x, y, x, y];
            for step in v[2..].chunks(2) {
                x += step[0];
                y += step[1];
                b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
            }
            sheet.boxes.push((b, l.to_owned()));
        } else if l.starts_with("<text") {
            let body = &l[l.find('>').unwrap() + 1..l.rfind("</text>").unwrap()];
            let chars = body
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&amp;", "&")
                .chars()
                .count() as f64;
            let (x, y) = (num(l, "x"), num(l, "y"));
            let w = chars * 0.6 * font;
            let x0 = if l.contains("text-anchor=\"end\"") {
                x - w
            } else {
                x
            };
            sheet
                .boxes
                .push(([x0, y - font, x0 + w, y + 0.25 * font], l.to_owned()));
        }
    }
    sheet
}

fn print_board(target: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["board", "--target", s(target), "--out", s(out)];
    args.extend_from_slice(extra);
    dvlcal(&args)
}

/// The SVG rendered by headless Chromium at 96 dpi, as grey.
fn render(svg_path: &Path, sheet: &Sheet, png: &Path) -> image::GrayImage {
    let px = 96.0 / 25.4;
    let (w, h) = (
        (sheet.width * px).ceil() as u32,
        (sheet.height * px).ceil() as u32,
    );
    let browser = std::env::var("CHROMIUM").unwrap_or_else(|_| "chromium".into());
    let out = Command::new(&browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            "--default-background-color=ffffffff",
        ])
        .arg(format!("--window-size={w},{h}"))
        .arg(format!("--screenshot={}", png.display()))
        .arg(format!("file://{}", svg_path.display()))
        .output()
        .unwrap_or_else(|e| {
            panic!("run {browser} (install Debian's chromium, or DVLCAL_SKIP_BROWSER=1): {e}")
        });
    assert!(png.exists(), "{}", text(&out.stderr));
    image::open(png).unwrap().to_luma8()
}

/// Each ready-made board prints on its own paper: the SVG is the paper's size, everything drawn
/// (tags, labels, axes, scale bar, legend) keeps 10 mm from every edge, the board is centred
/// across, the tags print at the YAML's tag_size, and rendered, every tag is detected at that
/// size.
#[test]
fn the_ready_made_boards_fit_their_paper_at_exact_scale() {
    let tmp = TmpDir::new("paper-boards");
    let browser = !std::env::var("DVLCAL_SKIP_BROWSER").is_ok_and(|v| v == "1");
    for (file, paper, tags) in [
        ("calib_boards/tag36h11_4x5_a4.yaml", (210.0, 297.0), 20),
        ("calib_boards/tag36h11_6x6_a3.yaml", (297.0, 420.0), 36),
    ] {
        let target = repo(file);
        let board = read_board(&target).unwrap();
        let tag_mm = board.grid.unwrap().tag_size_m * 1e3;
        let out = tmp.path(&format!("{}.svg", board.tags.len()));
        let r = print_board(&target, &out, &[]);
        assert!(r.status.success(), "{file}: {}", text(&r.stderr));
        let svg = std::fs::read_to_string(&out).unwrap();
        let sheet = read_sheet(&svg);
        assert_eq!((sheet.width, sheet.height), paper, "{file}");
        assert_eq!(sheet.viewbox, vec![0.0, 0.0, paper.0, paper.1], "{file}");
        for (b, what) in &sheet.boxes {
            assert!(
                b[0] >= 10.0 - 1e-6
                    && b[1] >= 10.0 - 1e-6
                    && b[2] <= paper.0 - 10.0 + 1e-6
                    && b[3] <= paper.1 - 10.0 + 1e-6,
                "{file}: {b:?} is within 10 mm of the paper's edge: {what}"
            );
        }
        let [bx, _, bw, _] = sheet.board;
        assert!(
            (bx + bw / 2.0 - paper.0 / 2.0).abs() < 1e-3,
            "{file}: board not centred across"
        );
        assert_eq!(sheet.tags.len(), tags, "{file}");
        for (id, (edge, _)) in &sheet.tags {
            assert!(
                (edge - tag_mm).abs() < 1e-6,
                "{file}: tag {id} prints {edge} mm, the YAML says {tag_mm}"
            );
        }
        // Neighbours in a row sit one pitch apart: tag size times (1 + spacing).
        let pitch = tag_mm * (1.0 + board.grid.unwrap().spacing);
        let (c0, c1) = (sheet.tags[&0].1, sheet.tags[&1].1);
        assert!(
            (c1[0] - c0[0] - pitch).abs() < 1e-6,
            "{file}: {c0:?} {c1:?}"
        );

        if !browser {
            eprintln!("DVLCAL_SKIP_BROWSER=1: render of {file} skipped");
            continue;
        }
        let img = render(&out, &sheet, &tmp.path(&format!("{tags}.png")));
        let mut det = Detector::new(&DetectorSettings::default()).unwrap();
        let found = det.detect(&img);
        let mut ids: Vec<u32> = found.iter().map(|d| d.id).collect();
        ids.sort_unstable();
        assert_eq!(ids, (0..tags as u32).collect::<Vec<_>>(), "{file}");
        let px_per_mm = 96.0 / 25.4;
        let edges: Vec<f64> = found
            .iter()
            .flat_map(|d| (0..4).map(move |k| (d.corners[(k + 1) % 4] - d.corners[k]).norm()))
            .collect();
        let edge_mm = edges.iter().sum::<f64>() / edges.len() as f64 / px_per_mm;
        assert!(
            (edge_mm / tag_mm - 1.0).abs() < 0.01,
            "{file}: detected tags {edge_mm:.2} mm, the YAML says {tag_mm}"
        );
    }
}

/// A board larger than its paper is refused with the size it needs and the tag size that fits;
/// `--paper` names another paper, landscape included, and an unknown paper is refused by name
/// (in the file, with its line).
#[test]
fn a_board_too_large_for_its_paper_is_refused_and_another_paper_can_be_named() {
    let tmp = TmpDir::new("paper-errors");
    let target = tmp.path("big.yaml");
    // The A4 board as shipped before: 35 mm tags need 231.9 mm across.
    std::fs::write(
        &target,
        "family: tag36h11\nrows: 5\ncols: 4\ntag_size: 0.035\nspacing: 0.3\npaper: A4\n",
    )
    .unwrap();
    let out = tmp.path("big.svg");
    let r = print_board(&target, &out, &[]);
    let err = text(&r.stderr);
    assert!(!r.status.success(), "{err}");
    assert!(
        !out.exists(),
        "nothing written for a board that does not fit"
    );
    assert!(err.contains("big.yaml"), "{err}");
    assert!(err.contains("231.9 x"), "{err}");
    assert!(err.contains("A4 paper (210 x 297 mm)"), "{err}");
    // 190 mm inside the margins: the board grows 5.5 tag sizes, its bands 39.4 mm.
    assert!(err.contains("tag_size of at most 0.0273 m"), "{err}");

    // The same board on A3, and on A2 turned: the SVG is that paper's size.
    for (paper, size) in [("a3", (297.0, 420.0)), ("A2 landscape", (594.0, 420.0))] {
        let r = print_board(&target, &out, &["--paper", paper]);
        assert!(r.status.success(), "{paper}: {}", text(&r.stderr));
        let sheet = read_sheet(&std::fs::read_to_string(&out).unwrap());
        assert_eq!((sheet.width, sheet.height), size, "{paper}");
        assert!(sheet.tags.values().all(|(e, _)| (e - 35.0).abs() < 1e-6));
    }

    let r = print_board(&target, &out, &["--paper", "A7"]);
    assert!(!r.status.success());
    assert!(text(&r.stderr).contains("--paper names an unknown paper 'A7'"));
    std::fs::write(
        &target,
        "family: tag36h11\nrows: 2\ncols: 2\ntag_size: 0.03\nspacing: 0.3\npaper: B5\n",
    )
    .unwrap();
    let r = print_board(&target, &out, &[]);
    let err = text(&r.stderr);
    assert!(!r.status.success(), "{err}");
    assert!(err.contains("big.yaml:6:") && err.contains("'B5'"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Exports

/// `check_urdf` of Debian's liburdfdom-tools on `urdf`: its output, after asserting it parsed.
fn check_urdf(urdf: &Path) -> String {
    let r = Command::new("check_urdf")
        .arg(urdf)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "check_urdf is needed to test the URDF export against ROS's parser: install \
             Debian's liburdfdom-tools (make test-deps): {e}"
            )
        });
    let out = text(&r.stdout);
    assert!(
        r.status.success(),
        "check_urdf refused {}: {out}{}",
        urdf.display(),
        text(&r.stderr)
    );
    out
}

/// The URDF export is a whole robot: ROS's parser reads it as is, with the camera as the root
/// link and the DVL its one child, joined at the calibrated lever arm.
#[test]
fn the_urdf_export_is_a_robot_that_ros_parses() {
    let tmp = TmpDir::new("urdf-robot");
    let out = tmp.path("cal.yaml");
    let r = dvlcal(&[
        "calibrate",
        s(&repo("sample_data/poses")),
        "--out",
        s(&out),
        "--frames",
        "camera_link,dvl_link",
    ]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let urdf = tmp.path("cal-urdf.xml");
    let parsed = check_urdf(&urdf);
    assert!(
        parsed.contains("root Link: camera_link has 1 child(ren)"),
        "{parsed}"
    );
    assert!(parsed.contains("child(1):  dvl_link"), "{parsed}");
    let xml = std::fs::read_to_string(&urdf).unwrap();
    assert!(xml.starts_with("<?xml"), "{xml}");
    assert_eq!(xml.matches("<link name=").count(), 2, "{xml}");
    // The joint carries the result's lever arm.
    let arm = read_calib_yaml(&out).unwrap().lever_arm_cam_m;
    let origin = xml.lines().find(|l| l.contains("<origin")).unwrap();
    let xyz: Vec<f64> = attr(origin, "xyz")
        .unwrap()
        .split(' ')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (0..3).all(|k| (xyz[k] - arm[k]).abs() < 1e-11),
        "{origin} {arm:?}"
    );
}

/// A dataset whose DVL reports cover only the calm first half of `dvlcal simulate`'s default
/// motion: the camera hardly rotates while the DVL measures, so the lever arm is not observed.
fn calm_dataset(tmp: &TmpDir, name: &str, calm: bool) -> PathBuf {
    let d = tmp.path(name);
    let r = dvlcal(&["simulate", "--out", s(&d), "--seed", "3"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    if calm {
        let log = std::fs::read_to_string(d.join("dvl.jsonl")).unwrap();
        let lines: Vec<&str> = log.lines().collect();
        let half = lines[..lines.len() / 2].join("\n") + "\n";
        std::fs::write(d.join("dvl.jsonl"), half).unwrap();
    }
    d
}

struct Exports {
    tf: String,
    urdf: String,
    kalibr: String,
}

fn exports(out: &Path) -> Exports {
    let read = |suffix: &str| {
        let stem = out.file_stem().unwrap().to_str().unwrap();
        std::fs::read_to_string(out.with_file_name(format!("{stem}-{suffix}")))
            .unwrap_or_else(|e| panic!("{suffix}: {e}"))
    };
    Exports {
        tf: read("tf.txt"),
        urdf: read("urdf.xml"),
        kalibr: read("camchain-imucam.yaml"),
    }
}

/// The comment lines of each export (tf, URDF, Kalibr) whose text starts with `what` and holds
/// `state`.
fn notes<'a>(e: &'a Exports, what: &str, state: &str) -> [Vec<&'a str>; 3] {
    let find = |t: &'a str, open: &str, close: &str| -> Vec<&'a str> {
        t.lines()
            .filter(|l| {
                let body = l.trim_start();
                body.ends_with(close)
                    && body
                        .strip_prefix(open)
                        .is_some_and(|b| b.trim_start().starts_with(what))
                    && l.contains(state)
            })
            .collect()
    };
    [
        find(&e.tf, "#", ""),
        find(&e.urdf, "<!--", "-->"),
        find(&e.kalibr, "#", ""),
    ]
}

/// The comment lines of an export that say a value is not measured, not estimated or poorly
/// determined.
fn caveats(t: &str) -> usize {
    t.lines()
        .filter(|l| {
            let b = l.trim_start();
            (b.starts_with('#') || b.starts_with("<!--"))
                && [": NOT MEASURED", ": NOT ESTIMATED", ": POORLY DETERMINED"]
                    .iter()
                    .any(|k| b.contains(k))
        })
        .count()
}

/// A lever arm the motion did not observe is held at the default prior (zero); each export
/// says, in a comment beside the numbers, that it was not measured, and still reads in its
/// tool. The same recording with its rotations says nothing of the kind.
#[test]
fn a_lever_arm_held_at_the_prior_is_marked_not_measured_in_every_export() {
    let tmp = TmpDir::new("prior-exports");
    for calm in [true, false] {
        let data = calm_dataset(&tmp, if calm { "calm" } else { "full" }, calm);
        let out = tmp.path(if calm { "calm.yaml" } else { "full.yaml" });
        let r = dvlcal(&["calibrate", s(&data), "--out", s(&out)]);
        assert!(r.status.success(), "{}", text(&r.stderr));
        let f = read_calib_yaml(&out).unwrap();
        let lever = f.observability.as_ref().unwrap().lever_arm;
        let e = exports(&out);
        let [tf, urdf, kalibr] = notes(&e, "lever arm", "NOT MEASURED");
        if !calm {
            assert_ne!(lever, Observability::Prior);
            for t in [&e.tf, &e.urdf, &e.kalibr] {
                assert!(!t.contains("NOT MEASURED"), "{t}");
            }
            continue;
        }
        assert_eq!(lever, Observability::Prior);
        assert_eq!(f.lever_arm_cam_m, [0.0; 3]);
        // tf: before the commands that carry the zeros.
        assert_eq!(tf.len(), 1, "{}", e.tf);
        let at = |t: &str, l: &str| t.find(l).unwrap();
        assert!(at(&e.tf, tf[0]) < at(&e.tf, "rosrun"), "{}", e.tf);
        assert!(tf[0].contains("prior"), "{}", tf[0]);
        // URDF: in the joint, above the origin, and ROS's parser still reads the file.
        assert_eq!(urdf.len(), 1, "{}", e.urdf);
        assert!(at(&e.urdf, urdf[0]) < at(&e.urdf, "<origin"), "{}", e.urdf);
        check_urdf(&out.with_file_name("calm-urdf.xml"));
        // Kalibr: in the header, and a pointer beside the camera's transform; still YAML with
        // the cameras alone at the top level.
        assert_eq!(kalibr.len(), 1, "{}", e.kalibr);
        assert!(at(&e.kalibr, kalibr[0]) < at(&e.kalibr, "\n  T_cam_imu:"));
        assert!(
            e.kalibr
                .contains("  # not all of the values below were measured")
        );
        let v: serde_yaml::Value = serde_yaml::from_str(&e.kalibr).unwrap();
        let top: Vec<&str> = v
            .as_mapping()
            .unwrap()
            .keys()
            .filter_map(|k| k.as_str())
            .collect();
        assert_eq!(top, ["cam0"]);
        // The rotation, clock and scale were measured: no note for them.
        for t in [&e.tf, &e.urdf, &e.kalibr] {
            assert_eq!(caveats(t), 1, "{t}");
        }
    }
}

/// Parameters held at the value given (`--method fixed --init`) are marked as not estimated in
/// each export, the clock offset and scale included; a failed calibration exported with
/// `--force` says it failed, with the reasons, at the top of each.
#[test]
fn held_parameters_and_a_forced_failure_are_said_in_every_export() {
    let tmp = TmpDir::new("held-exports");
    let data = repo("sample_data/poses");
    let truth_path = data.join("truth/calibration.yaml");
    let out = tmp.path("fixed.yaml");
    let r = dvlcal(&[
        "calibrate",
        s(&data),
        "--method",
        "fixed",
        "--init",
        s(&truth_path),
        "--out",
        s(&out),
    ]);
    assert!(r.status.success(), "{}", text(&r.stdout));
    let e = exports(&out);
    for what in [
        "rotation",
        "lever arm",
        "clock offset",
        "DVL velocity scale",
    ] {
        let [tf, urdf, kalibr] = notes(&e, what, "NOT ESTIMATED: held at the value given");
        assert_eq!(
            (tf.len(), urdf.len(), kalibr.len()),
            (1, 1, 1),
            "{what}:\n{}\n{}\n{}",
            e.tf,
            e.urdf,
            e.kalibr
        );
    }
    assert!(!e.tf.contains("FAILED"));
    check_urdf(&out.with_file_name("fixed-urdf.xml"));

    // A clock 530 ms off, held: the run fails; with --force the exports are written and say so.
    let truth = std::fs::read_to_string(&truth_path).unwrap();
    let guess = tmp.path("guess.yaml");
    std::fs::write(
        &guess,
        truth.replace("time_offset_s: 0.07\n", "time_offset_s: 0.6\n"),
    )
    .unwrap();
    let out = tmp.path("forced.yaml");
    let r = dvlcal(&[
        "calibrate",
        s(&data),
        "--method",
        "fixed",
        "--init",
        s(&guess),
        "--out",
        s(&out),
        "--force",
    ]);
    assert!(!r.status.success(), "{}", text(&r.stdout));
    let f = read_calib_yaml(&out).unwrap();
    assert!(!f.failure.is_empty());
    let e = exports(&out);
    let [tf, urdf, kalibr] = notes(&e, "THIS CALIBRATION FAILED", "--force");
    assert_eq!((tf.len(), kalibr.len()), (1, 1), "{}\n{}", e.tf, e.kalibr);
    // XML comments may not hold "--": the URDF spells the option "- -force".
    assert!(urdf.is_empty());
    let [_, urdf, _] = notes(&e, "THIS CALIBRATION FAILED", "- -force");
    assert_eq!(urdf.len(), 1, "{}", e.urdf);
    // The first reason of the result file, in words, in each.
    let first: String = f.failure[0].split_whitespace().collect::<Vec<_>>()[..6].join(" ");
    for (t, first) in [
        (&e.tf, first.clone()),
        (&e.urdf, first.replace("--", "- -")),
        (&e.kalibr, first.clone()),
    ] {
        assert!(t.contains(&first), "{first}\n{t}");
    }
    check_urdf(&out.with_file_name("forced-urdf.xml"));
}

// ---------------------------------------------------------------------------------------------
// compare-calib

/// An estimate equal to the truth with honest standard deviations passes; the same file marked
/// `status: failed` is reported as failed, with the reason it records, and exits non-zero.
#[test]
fn compare_calib_does_not_pass_a_failed_estimate() {
    let tmp = TmpDir::new("compare-failed");
    let truth = repo("sample_data/poses/truth/calibration.yaml");
    let body = std::fs::read_to_string(&truth).unwrap();
    let std = "std:\n  rotation_deg: [0.1, 0.1, 0.1]\n  lever_arm_m: [0.01, 0.01, 0.01]\n  \
               time_offset_s: 0.002\n  velocity_scale: 0.002\n";
    let ok = tmp.path("ok.yaml");
    std::fs::write(&ok, format!("{body}{std}")).unwrap();
    let r = dvlcal(&["compare-calib", "--estimate", s(&ok), "--truth", s(&truth)]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(
        text(&r.stdout).contains("within 3 std"),
        "{}",
        text(&r.stdout)
    );

    let reason = "the DVL's velocities do not fit the camera's motion (normalized cost 41.2)";
    let failed = tmp.path("failed.yaml");
    std::fs::write(
        &failed,
        format!("status: failed\nfailure:\n  - \"{reason}\"\n{body}{std}"),
    )
    .unwrap();
    let r = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&failed),
        "--truth",
        s(&truth),
    ]);
    let (out, err) = (text(&r.stdout), text(&r.stderr));
    assert_eq!(r.status.code(), Some(1), "{out}{err}");
    assert!(!out.contains("within 3 std"), "{out}");
    assert!(
        out.lines().nth(1).unwrap_or_default().contains("FAILED") && out.contains(reason),
        "{out}"
    );
    assert!(
        err.contains("failed.yaml is a failed calibration (status: failed)")
            && err.contains(reason),
        "{err}"
    );

    // A failed file without reasons says it records none.
    std::fs::write(&failed, format!("status: failed\n{body}{std}")).unwrap();
    let r = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&failed),
        "--truth",
        s(&truth),
    ]);
    assert!(!r.status.success());
    assert!(
        text(&r.stderr).contains("records no reason"),
        "{}",
        text(&r.stderr)
    );
}
