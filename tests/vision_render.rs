//! The renderer against the detector: rendered tags decode to their ids, and the corners the
//! detector reports land where the board's corners project (which also fixes the corner order of
//! `BoardTag::corners` to libapriltag's p[0..4]).

#[path = "vision_seq/mod.rs"]
mod vision_seq;

use dvlcal::io::target::read_board;
use dvlcal::lie::Se3;
use dvlcal::rng::Rng;
use dvlcal::sim::render::{RenderSettings, render, render_exhaustive};
use dvlcal::types::board::{Board, TagFamily};
use dvlcal::types::camera::{Camera, Distortion};
use dvlcal::vision::detect::{Detector, DetectorSettings};
use dvlcal::vision::family::tag_cells;
use nalgebra::{Matrix3, Vector3};
use vision_seq::facing;

fn camera(distortion: Distortion) -> Camera {
    Camera {
        fu: 460.0,
        fv: 458.0,
        pu: 371.3,
        pv: 244.6,
        distortion,
        width: 752,
        height: 480,
    }
}

fn radtan() -> Distortion {
    Distortion::RadTan {
        k1: -0.28,
        k2: 0.07,
        p1: 2e-4,
        p2: -1.5e-5,
    }
}

/// Detected against projected corners of one rendered image.
#[derive(Debug, Default)]
struct CornerStats {
    /// Mean and max distance, px.
    mean: f64,
    max: f64,
    /// RMS distance, px.
    rms: f64,
    /// Mean error vector (detected - projected), px.
    signed: nalgebra::Vector2<f64>,
    /// Mean error along the direction from the tag's centre out through the corner, px
    /// (negative: the detected squares are too small).
    outward: f64,
    /// Tags matched.
    tags: usize,
}

/// Renders `board` at `t` and compares the detected corners (with or without the line-fit
/// refinement, which is told the camera) with the projected board corners.
fn corner_stats(
    board: &Board,
    cam: &Camera,
    t: &Se3,
    s: &RenderSettings,
    refine_corners: bool,
    seed: u64,
) -> CornerStats {
    let img = render(board, cam, t, s, &mut Rng::new(seed));
    let mut det = Detector::new(&DetectorSettings {
        family: board.family,
        decimate: 1.0,
        refine_corners,
        ..DetectorSettings::default()
    })
    .unwrap();
    let dets = det.detect_with_camera(&img, Some(cam));
    let mut st = CornerStats::default();
    let mut sq = 0.0;
    for d in &dets {
        let tag = board
            .tag(d.id)
            .unwrap_or_else(|| panic!("unknown id {}", d.id));
        let want: Vec<nalgebra::Vector2<f64>> = (0..4)
            .map(|k| cam.project(&t.transform_point(&tag.corners[k])).unwrap())
            .collect();
        let centre = want.iter().sum::<nalgebra::Vector2<f64>>() / 4.0;
        for (got, want) in d.corners.iter().zip(&want) {
            let e = got - want;
            st.signed += e;
            st.outward += e.dot(&(want - centre).normalize());
            st.mean += e.norm();
            sq += e.norm_squared();
            st.max = st.max.max(e.norm());
        }
        st.tags += 1;
    }
    let n = (4 * st.tags.max(1)) as f64;
    st.signed /= n;
    st.outward /= n;
    st.mean /= n;
    st.rms = (sq / n).sqrt();
    st
}

/// Mean and max distance between detected corners and projected board corners, and the number of
/// tags matched (default detector settings).
fn corner_errors(board: &Board, cam: &Camera, t: &Se3, s: &RenderSettings) -> (f64, f64, usize) {
    let st = corner_stats(board, cam, t, s, true, 5);
    eprintln!("{st:?}");
    (st.mean, st.max, st.tags)
}

#[test]
fn rendered_corners_match_detections_exactly() {
    let board = Board::grid(TagFamily::Tag36h11, 6, 6, 0.035, 0.3, 0);
    let s = RenderSettings::ideal();
    for (dist, cam) in [(0.45, camera(Distortion::None)), (0.5, camera(radtan()))] {
        let t = facing(&board, dist, Vector3::new(0.25, -0.3, 0.1));
        let (mean, max, n) = corner_errors(&board, &cam, &t, &s);
        eprintln!(
            "{:?}: {n} tags, corner error mean {mean:.4} px, max {max:.4} px",
            cam.distortion
        );
        assert_eq!(n, 36);
        // The rendered edges are exact to < 0.01 px (see below); libapriltag alone gives a
        // mean of 0.07 px and a max of 0.25 px here.
        assert!(mean < 0.02, "mean corner error {mean} px");
        assert!(max < 0.06, "max corner error {max} px");
    }
}

#[test]
fn realistic_render_is_still_read() {
    let board = Board::grid(TagFamily::Tag36h11, 6, 6, 0.035, 0.3, 0);
    let cam = camera(radtan());
    let t = facing(&board, 0.6, Vector3::new(-0.3, 0.35, -0.2));
    let (mean, _max, n) = corner_errors(&board, &cam, &t, &RenderSettings::default());
    eprintln!("default settings: {n} tags, corner error mean {mean:.4} px");
    assert_eq!(n, 36);
    assert!(mean < 0.15, "{mean}");
}

/// The corner bias on rendered boards with known truth: the stereo sequence's camera (strong
/// barrel distortion), default image formation (0.7 px blur, noise, vignetting), a board seen
/// from 0.9 to 1.3 m at several angles. libapriltag alone shrinks the squares (negative outward
/// error); the line-fit refinement removes that and lowers the RMS.
#[test]
fn corner_bias_on_rendered_boards_is_below_five_hundredths_of_a_pixel() {
    let board = Board::grid(TagFamily::Tag36h11, 6, 6, 0.088, 0.3, 0);
    let cam = camera(radtan());
    let s = RenderSettings::default();
    let views = [
        (0.9, Vector3::new(0.3, -0.25, 0.1)),
        (1.1, Vector3::new(-0.2, 0.35, -0.3)),
        (1.3, Vector3::new(0.1, 0.1, 0.6)),
        (1.0, Vector3::new(-0.35, -0.3, 0.0)),
    ];
    let mut all = [(nalgebra::Vector2::zeros(), 0.0, 0.0); 2];
    for (i, (dist, tilt)) in views.iter().enumerate() {
        let t = facing(&board, *dist, *tilt);
        for refine in [false, true] {
            let st = corner_stats(&board, &cam, &t, &s, refine, 100 + i as u64);
            eprintln!(
                "view {i}, refine_corners {refine}: {} tags, mean error ({:.4}, {:.4}) px, \
                 outward {:.4} px, RMS {:.4} px, max {:.4} px",
                st.tags, st.signed.x, st.signed.y, st.outward, st.rms, st.max
            );
            assert_eq!(st.tags, 36);
            let a = &mut all[refine as usize];
            a.0 += st.signed / views.len() as f64;
            a.1 += st.outward / views.len() as f64;
            a.2 += st.rms * st.rms / views.len() as f64;
        }
    }
    for (refine, (signed, outward, ms)) in all.iter().enumerate() {
        eprintln!(
            "refine_corners {}: mean error ({:.4}, {:.4}) px, outward {:.4} px, RMS {:.4} px",
            refine == 1,
            signed.x,
            signed.y,
            outward,
            ms.sqrt()
        );
    }
    let (signed, outward, ms) = all[1];
    assert!(signed.norm() < 0.05, "bias {signed:?}");
    assert!(outward.abs() < 0.05, "outward bias {outward}");
    assert!(ms.sqrt() < 0.8 * all[0].2.sqrt(), "RMS not improved");
}

#[test]
fn other_families_and_listed_tags() {
    // tagStandard41h12's pattern reaches 0.4 tag sizes beyond its border: wide gaps.
    for (fam, spacing) in [
        (TagFamily::TagStandard41h12, 1.2),
        (TagFamily::Tag25h9, 0.4),
    ] {
        let board = Board::grid(fam, 3, 3, 0.05, spacing, 0);
        let cam = camera(Distortion::None);
        let t = facing(&board, 0.5, Vector3::new(0.1, 0.2, 0.0));
        let (mean, _, n) = corner_errors(&board, &cam, &t, &RenderSettings::ideal());
        eprintln!("{}: {n} tags, mean {mean:.4} px", fam.name());
        assert_eq!(n, 9, "{}", fam.name());
        assert!(mean < 0.02, "{}: {mean}", fam.name());
    }
    let wall = read_board(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("calib_boards/pool_wall_example.yaml"),
    )
    .unwrap();
    let cam = camera(radtan());
    // From 2.2 m in front of the wall, a little above, looking slightly down.
    let t = facing(&wall, 2.2, Vector3::new(0.35, 0.0, 0.0));
    let (mean, _, n) = corner_errors(&wall, &cam, &t, &RenderSettings::ideal());
    eprintln!("pool wall: {n} tags, mean {mean:.4} px");
    assert!(n >= 5, "{n}");
    assert!(mean < 0.08, "{mean}");
}

/// The same seed gives the same image, another seed another noise; a board behind the camera
/// leaves the background alone. (The renderer's speed is a benchmark's business:
/// docs/performance.md, "Renderer".)
#[test]
fn same_seed_same_image_and_nothing_drawn_behind_the_camera() {
    let board = Board::grid(TagFamily::Tag36h11, 6, 6, 0.035, 0.3, 0);
    let cam = camera(radtan());
    let t = facing(&board, 0.5, Vector3::new(0.1, 0.1, 0.0));
    let s = RenderSettings::default();
    let a = render(&board, &cam, &t, &s, &mut Rng::new(9));
    let b = render(&board, &cam, &t, &s, &mut Rng::new(9));
    assert_eq!(a, b);
    assert_ne!(a, render(&board, &cam, &t, &s, &mut Rng::new(10)));
    // Background, paper and print levels.
    let far = Se3::new(Matrix3::identity(), Vector3::new(0.0, 0.0, -1.0)); // behind the camera
    let img = render(
        &board,
        &cam,
        &far,
        &RenderSettings::ideal(),
        &mut Rng::new(1),
    );
    assert!(img.pixels().all(|p| p.0[0] == 128));
    assert!(tag_cells(TagFamily::Tag36h11, 0).is_some());
}

/// The renderer's own geometry, without the detector: along an image row, the white length left of
/// a tag's left edge (sum of the pixels' white fractions) puts the edge where the board projects.
#[test]
fn rendered_edges_sit_where_the_board_projects() {
    let board = Board::grid(TagFamily::Tag36h11, 6, 6, 0.035, 0.3, 0);
    for (dist, cam) in [(0.45, camera(Distortion::None)), (0.47, camera(radtan()))] {
        let t = facing(&board, dist, Vector3::new(0.0, 0.0, 0.0));
        let img = render(&board, &cam, &t, &RenderSettings::ideal(), &mut Rng::new(1));
        let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0);
        for tag in &board.tags {
            // Midpoint of the left edge (corners 0 -> 3) and its projection.
            let mid = (tag.corners[0] + tag.corners[3]) / 2.0;
            let p = cam.project(&t.transform_point(&mid)).unwrap();
            let y = p.y.round();
            // The exact edge crossing of this row: project points along the edge.
            let (mut lo, mut hi) = (tag.corners[0], tag.corners[3]);
            for _ in 0..60 {
                let m = (lo + hi) / 2.0;
                if cam.project(&t.transform_point(&m)).unwrap().y > y {
                    lo = m
                } else {
                    hi = m
                }
            }
            let x_edge = cam.project(&t.transform_point(&lo)).unwrap().x;
            let xa = x_edge.floor() as i64 - 3;
            let xb = x_edge.floor() as i64 + 2;
            let white: f64 = (xa..=xb)
                .map(|x| (img.get_pixel(x as u32, y as u32).0[0] as f64 - 20.0) / 215.0)
                .sum();
            let est = xa as f64 - 0.5 + white;
            let e = (est - x_edge).abs();
            sum += e;
            max = max.max(e);
            n += 1;
        }
        eprintln!(
            "{:?}: edge error mean {:.4} px, max {max:.4} px over {n} tags",
            cam.distortion,
            sum / n as f64
        );
        assert!(sum / (n as f64) < 0.01 && max < 0.03);
    }
}

/// Supersampling only the pixels near an edge gives exactly the image of supersampling every
/// pixel: grid boards and listed tags, with and without distortion, near and far, steep views,
/// a board partly behind the camera.
#[test]
fn edge_mask_render_equals_exhaustive_render() {
    let grid = Board::grid(TagFamily::Tag36h11, 6, 6, 0.035, 0.3, 0);
    let wall = read_board(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("calib_boards/pool_wall_example.yaml"),
    )
    .unwrap();
    let std41 = Board::grid(TagFamily::TagStandard41h12, 3, 3, 0.05, 1.2, 0);
    let s = RenderSettings {
        noise_sigma: 0.0,
        ..RenderSettings::default()
    };
    let cases: Vec<(&Board, Camera, Se3)> = vec![
        (
            &grid,
            camera(radtan()),
            facing(&grid, 0.5, Vector3::new(0.1, 0.1, 0.0)),
        ),
        (
            &grid,
            camera(Distortion::None),
            facing(&grid, 0.3, Vector3::new(0.6, -0.5, 0.3)),
        ),
        (
            &grid,
            camera(radtan()),
            facing(&grid, 2.5, Vector3::new(-0.2, 0.9, 1.0)),
        ),
        // Steep enough that part of the board is behind the camera.
        (
            &grid,
            camera(radtan()),
            facing(&grid, 0.08, Vector3::new(1.4, 0.0, 0.2)),
        ),
        (
            &wall,
            camera(radtan()),
            facing(&wall, 2.2, Vector3::new(0.35, 0.0, 0.0)),
        ),
        (
            &std41,
            camera(Distortion::None),
            facing(&std41, 0.5, Vector3::new(0.1, 0.2, 0.0)),
        ),
    ];
    for (i, (board, cam, t)) in cases.iter().enumerate() {
        let t0 = std::time::Instant::now();
        let fast = render(board, cam, t, &s, &mut Rng::new(3));
        let t1 = std::time::Instant::now();
        let full = render_exhaustive(board, cam, t, &s, &mut Rng::new(3));
        let t2 = std::time::Instant::now();
        let differ = fast
            .pixels()
            .zip(full.pixels())
            .filter(|(a, b)| a.0 != b.0)
            .count();
        eprintln!(
            "case {i}: edge-mask render {:.3} s, exhaustive {:.3} s, {differ} pixels differ",
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64()
        );
        assert_eq!(differ, 0, "case {i}");
    }
}
