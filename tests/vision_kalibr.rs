//! Kalibr-printed aprilgrids (two-bit borders, corner squares): found on real photographs (against
//! an independent detector's output committed in `tests/fixtures/kalibr_photos/reference.csv`),
//! found on renders with the corners and poses of today's boards, nothing invented on images
//! without a board, and printed by `dvlcal board` the way Kalibr prints them.

#[path = "vision_seq/mod.rs"]
mod vision_seq;
use vision_seq::facing;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dvlcal::io::camchain::read_camchain;
use dvlcal::io::image::load_gray;
use dvlcal::io::target::{board_yaml, parse_board, read_board};
use dvlcal::lie::Se3;
use dvlcal::rng::Rng;
use dvlcal::sim::render::{RenderSettings, render};
use dvlcal::types::board::{Board, TagFamily, TagPrint};
use dvlcal::types::camera::{Camera, Distortion};
use dvlcal::vision::detect::{Detector, DetectorSettings, TagDetection};
use nalgebra::{DMatrix, DVector, Matrix3, Vector2, Vector3};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/kalibr_photos")
}

fn camera() -> Camera {
    Camera {
        fu: 460.0,
        fv: 458.0,
        pu: 371.3,
        pv: 244.6,
        distortion: Distortion::RadTan {
            k1: -0.28,
            k2: 0.07,
            p1: 2e-4,
            p2: -1.5e-5,
        },
        width: 752,
        height: 480,
    }
}

fn kalibr_board() -> Board {
    Board::grid(TagFamily::Tag36h11, 6, 6, 0.088, 0.3, 0).printed_by_kalibr()
}

fn apriltag_board() -> Board {
    Board::grid(TagFamily::Tag36h11, 6, 6, 0.088, 0.3, 0)
}

/// Corner errors (px) of the tags detected on one render: RMS, max, signed mean, tags.
fn render_errors(
    board: &Board,
    t: &Se3,
    s: &RenderSettings,
    seed: u64,
) -> (f64, f64, Vector2<f64>, usize) {
    let cam = camera();
    let img = render(board, &cam, t, s, &mut Rng::new(seed));
    let dets = Detector::new(&DetectorSettings::default())
        .unwrap()
        .detect_with_camera(&img, Some(&cam));
    let (mut sq, mut max, mut signed) = (0.0, 0.0f64, Vector2::zeros());
    for d in &dets {
        let tag = board
            .tag(d.id)
            .unwrap_or_else(|| panic!("unknown id {}", d.id));
        for (got, c) in d.corners.iter().zip(&tag.corners) {
            let e = got - cam.project(&t.transform_point(c)).unwrap();
            sq += e.norm_squared();
            max = max.max(e.norm());
            signed += e;
        }
    }
    let n = (4 * dets.len().max(1)) as f64;
    ((sq / n).sqrt(), max, signed / n, dets.len())
}

/// One tag's four corners (OpenCV pixels) by id, per photo.
type PhotoTags = BTreeMap<String, BTreeMap<u32, [Vector2<f64>; 4]>>;

/// The independent detector's tags (see `make_reference.py` beside the photos).
fn reference() -> PhotoTags {
    let text = std::fs::read_to_string(fixtures().join("reference.csv")).unwrap();
    let mut out = PhotoTags::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 10, "{line}");
        let v: Vec<f64> = f[2..].iter().map(|x| x.parse().unwrap()).collect();
        let corners = std::array::from_fn(|k| Vector2::new(v[2 * k], v[2 * k + 1]));
        out.entry(f[0].to_string())
            .or_default()
            .insert(f[1].parse().unwrap(), corners);
    }
    out
}

const PHOTOS: [&str; 7] = [
    "TUM_VI.png",
    "iphone.png",
    "r45.png",
    "right.png",
    "top.png",
    "top_right.png",
    "two_boards.png",
];

fn detect_file(path: &Path) -> Vec<TagDetection> {
    let img = load_gray(path).unwrap();
    Detector::new(&DetectorSettings::default())
        .unwrap()
        .detect(&img)
}

/// Our tags on every photo (default settings, no camera model).
fn ours() -> PhotoTags {
    let mut out = PhotoTags::new();
    for name in PHOTOS {
        let dets = detect_file(&fixtures().join(name));
        let m = out.entry(name.to_string()).or_default();
        for d in dets {
            assert_eq!(
                d.border_bits, 2,
                "{name}: tag {} with a one-bit border",
                d.id
            );
            assert!(
                m.insert(d.id, d.corners).is_none(),
                "{name}: id {} twice",
                d.id
            );
        }
    }
    out
}

/// Columns of the grid on each photo (the six TUM-VI photos show one 6 x 6 grid; the phone
/// photo an 11 x 6 grid; `two_boards.png` two 6 x 6 grids, ids 0..35 and 36..71).
fn layout(name: &str) -> (u32, u32) {
    match name {
        "iphone.png" => (11, 66),
        "two_boards.png" => (6, 72),
        _ => (6, 36),
    }
}

/// The corners of tag `id` of a grid with `cols` columns, in tag sizes (Kalibr spacing 0.3);
/// ids from 36 on are a second grid.
fn grid_corners(id: u32, cols: u32) -> [Vector2<f64>; 4] {
    let i = if cols == 11 { id } else { id % 36 };
    let (r, c) = ((i / cols) as f64, (i % cols) as f64);
    let d = 1.3;
    let (x, y) = (c * d, r * d);
    [
        Vector2::new(x, y),
        Vector2::new(x + 1.0, y),
        Vector2::new(x + 1.0, y + 1.0),
        Vector2::new(x, y + 1.0),
    ]
}

/// The photos of the 6 x 6 TUM-VI grid (36 tags each).
const SIX_BY_SIX: [&str; 5] = [
    "TUM_VI.png",
    "r45.png",
    "right.png",
    "top.png",
    "top_right.png",
];

#[test]
fn sixteen_bit_photos_are_read_at_full_range() {
    let path = fixtures().join("TUM_VI.png");
    let wide = image::open(&path).unwrap().into_luma16();
    let gray = load_gray(&path).unwrap();
    assert_eq!(wide.dimensions(), gray.dimensions());
    let mut worst = 0i32;
    for (a, b) in wide.as_raw().iter().zip(gray.as_raw()) {
        worst = worst.max(((*a as f64 / 257.0).round() as i32 - *b as i32).abs());
    }
    assert!(worst <= 1, "16-bit to 8-bit differs by {worst} grey levels");
    let (lo, hi) = gray
        .as_raw()
        .iter()
        .fold((255u8, 0u8), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(lo < 10 && hi > 250, "grey range {lo}..{hi}");
}

#[test]
fn every_reference_tag_is_found_with_its_id_and_nothing_off_the_grid() {
    let (refs, ours) = (reference(), ours());
    for name in PHOTOS {
        let (r, o) = (&refs[name], &ours[name]);
        let (_, n_ids) = layout(name);
        let missing: Vec<u32> = r.keys().filter(|id| !o.contains_key(id)).copied().collect();
        let extra: Vec<u32> = o.keys().filter(|id| !r.contains_key(id)).copied().collect();
        // Same tags, same corners: median corner distance to the reference's.
        let mut dist: Vec<f64> = r
            .iter()
            .filter_map(|(id, rc)| o.get(id).map(|oc| (rc, oc)))
            .flat_map(|(rc, oc)| (0..4).map(move |k| (rc[k] - oc[k]).norm()))
            .collect();
        dist.sort_by(f64::total_cmp);
        let median = dist[dist.len() / 2];
        eprintln!(
            "{name}: {} tags (reference {}), missing {missing:?}, only ours {extra:?}, \
             median corner distance {median:.3} px",
            o.len(),
            r.len()
        );
        assert!(
            missing.is_empty(),
            "{name}: reference tags {missing:?} not found"
        );
        assert!(o.keys().all(|&id| id < n_ids), "{name}: ids {:?}", o.keys());
        assert!(median < 0.1, "{name}: median corner distance {median} px");
    }
    // Every visible tag of the 6 x 6 photos is found (the reference misses some of the more
    // oblique and blurred ones).
    for name in SIX_BY_SIX {
        assert_eq!(ours[name].len(), 36, "{name}");
    }
    assert_eq!(ours["iphone.png"].len(), 66);
    assert_eq!(ours["two_boards.png"].len(), 72);
}

/// Fits `image = f(board)` with `f` a polynomial of degree `deg` in both coordinates (least
/// squares over all corners); returns each tag's largest corner residual, px.
fn poly_residuals(
    tags: &BTreeMap<u32, [Vector2<f64>; 4]>,
    cols: u32,
    deg: usize,
) -> Vec<(u32, f64)> {
    let mono = |p: &Vector2<f64>| -> Vec<f64> {
        let mut v = Vec::new();
        for i in 0..=deg {
            for j in 0..=deg - i {
                v.push(p.x.powi(i as i32) * p.y.powi(j as i32));
            }
        }
        v
    };
    let pts: Vec<(Vector2<f64>, Vector2<f64>)> = tags
        .iter()
        .flat_map(|(&id, c)| {
            let g = grid_corners(id, cols);
            (0..4).map(move |k| (g[k], c[k]))
        })
        .collect();
    let m = mono(&pts[0].0).len();
    let a = DMatrix::from_fn(pts.len(), m, |r, c| mono(&pts[r].0)[c]);
    let svd = a.clone().svd(true, true);
    let fit = |sel: fn(&Vector2<f64>) -> f64| {
        let b = DVector::from_iterator(pts.len(), pts.iter().map(|p| sel(&p.1)));
        a.clone() * svd.solve(&b, 1e-12).unwrap()
    };
    let (fx, fy) = (fit(|v| v.x), fit(|v| v.y));
    tags.keys()
        .enumerate()
        .map(|(t, &id)| {
            let worst = (0..4)
                .map(|k| {
                    let r = 4 * t + k;
                    (Vector2::new(fx[r], fy[r]) - pts[r].1).norm()
                })
                .fold(0.0, f64::max);
            (id, worst)
        })
        .collect()
}

#[test]
fn tags_beyond_the_reference_sit_where_the_grid_puts_them() {
    // A tag read with a wrong id lands a whole grid pitch (over a tag side) away from where a
    // smooth map of the board puts it; the fisheye photos need a cubic map.
    let ours = ours();
    for name in SIX_BY_SIX {
        let o = &ours[name];
        let res = poly_residuals(o, 6, 3);
        for (id, r) in res {
            let c = &o[&id];
            let side = (0..4).map(|k| (c[(k + 1) % 4] - c[k]).norm()).sum::<f64>() / 4.0;
            assert!(
                r < 0.2 * side,
                "{name}: tag {id} is {r:.1} px off the grid (side {side:.0} px)"
            );
        }
    }
}

/// Reprojection RMS (px) of a homography fitted to the corners of a flat grid (normalised DLT).
fn homography_rms(tags: &[(u32, [Vector2<f64>; 4])], cols: u32) -> f64 {
    let pts: Vec<(Vector2<f64>, Vector2<f64>)> = tags
        .iter()
        .flat_map(|(id, c)| {
            let g = grid_corners(*id, cols);
            (0..4).map(move |k| (g[k], c[k]))
        })
        .collect();
    let norm = |v: Vec<Vector2<f64>>| {
        let mean = v.iter().sum::<Vector2<f64>>() / v.len() as f64;
        let s = v.iter().map(|p| (p - mean).norm()).sum::<f64>() / v.len() as f64;
        let k = std::f64::consts::SQRT_2 / s;
        Matrix3::new(k, 0.0, -k * mean.x, 0.0, k, -k * mean.y, 0.0, 0.0, 1.0)
    };
    let tb = norm(pts.iter().map(|p| p.0).collect());
    let ti = norm(pts.iter().map(|p| p.1).collect());
    let mut a = DMatrix::zeros(2 * pts.len(), 9);
    for (r, (b, i)) in pts.iter().enumerate() {
        let b = tb * Vector3::new(b.x, b.y, 1.0);
        let i = ti * Vector3::new(i.x, i.y, 1.0);
        let row1 = [0.0, 0.0, 0.0, -b.x, -b.y, -1.0, i.y * b.x, i.y * b.y, i.y];
        let row2 = [b.x, b.y, 1.0, 0.0, 0.0, 0.0, -i.x * b.x, -i.x * b.y, -i.x];
        for c in 0..9 {
            a[(2 * r, c)] = row1[c];
            a[(2 * r + 1, c)] = row2[c];
        }
    }
    let svd = a.svd(false, true);
    let vt = svd.v_t.unwrap();
    let (k, _) = svd
        .singular_values
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(y.1))
        .unwrap();
    let h = vt.row(k);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let hm = ti.try_inverse().unwrap() * hn * tb;
    let sq: f64 = pts
        .iter()
        .map(|(b, i)| {
            let p = hm * Vector3::new(b.x, b.y, 1.0);
            (Vector2::new(p.x / p.z, p.y / p.z) - i).norm_squared()
        })
        .sum();
    (sq / pts.len() as f64).sqrt()
}

#[test]
fn corners_fit_a_flat_board_no_worse_than_the_reference() {
    let (refs, ours) = (reference(), ours());
    // The phone photos are close to pinhole images of flat boards (the TUM-VI ones are fisheye).
    for (name, ids, cols) in [
        ("two_boards.png", 0..36, 6),
        ("two_boards.png", 36..72, 6),
        ("iphone.png", 0..66, 11),
    ] {
        let pick = |m: &BTreeMap<u32, [Vector2<f64>; 4]>| -> Vec<(u32, [Vector2<f64>; 4])> {
            m.iter()
                .filter(|(id, _)| ids.contains(*id))
                .map(|(id, c)| (*id - ids.start, *c))
                .collect()
        };
        let (o, r) = (pick(&ours[name]), pick(&refs[name]));
        assert_eq!(o.len(), r.len(), "{name}");
        let (eo, er) = (homography_rms(&o, cols), homography_rms(&r, cols));
        eprintln!("{name} ids {ids:?}: homography RMS ours {eo:.4} px, reference {er:.4} px");
        assert!(
            eo <= er * 1.01 + 1e-3,
            "{name}: ours {eo} px, reference {er} px"
        );
    }
}

#[test]
fn a_known_board_gives_the_same_tags_as_an_unknown_one() {
    // With the board's ids the second pass stops once every one is found: the tags and their
    // corners are the same to the last bit, on the photos (each with its grid's ids) and on
    // renders, where pass 1 finds most tags and the second pass the rest.
    let known = |ids: Vec<u32>| {
        Detector::new(&DetectorSettings {
            board_ids: Some(ids),
            ..DetectorSettings::default()
        })
        .unwrap()
    };
    let mut unknown = Detector::new(&DetectorSettings::default()).unwrap();
    for name in PHOTOS {
        let img = load_gray(&fixtures().join(name)).unwrap();
        let all = unknown.detect(&img);
        let got = known((0..layout(name).1).collect()).detect(&img);
        assert_eq!(got, all, "{name}");
        // A board of which the photo shows only part: the pass runs to the end.
        let got = known((0..layout(name).1 + 5).collect()).detect(&img);
        assert_eq!(got, all, "{name}, board larger than the photo's");
    }
    let cam = camera();
    let board = kalibr_board();
    let ids: Vec<u32> = board.tags.iter().map(|t| t.id).collect();
    let mut det = known(ids);
    for (i, tilt) in [Vector3::zeros(), Vector3::new(0.5, -0.3, 0.4)]
        .iter()
        .enumerate()
    {
        let t = facing(&board, 1.1, *tilt);
        let img = render(
            &board,
            &cam,
            &t,
            &RenderSettings::default(),
            &mut Rng::new(40 + i as u64),
        );
        let all = unknown.detect_with_camera(&img, Some(&cam));
        assert_eq!(all.len(), 36, "view {i}");
        assert_eq!(det.detect_with_camera(&img, Some(&cam)), all, "view {i}");
    }
}

#[test]
fn no_tags_invented_without_a_board() {
    // The photos mirrored (about 300 Kalibr tags read backwards, corner squares and all), and the
    // left of right.png (a checkerboard, posters, a whiteboard, no aprilgrid).
    let mut det = Detector::new(&DetectorSettings::default()).unwrap();
    let mut seen = 0;
    for name in PHOTOS {
        let img = load_gray(&fixtures().join(name)).unwrap();
        let mirrored = image::imageops::flip_horizontal(&img);
        let d = det.detect(&mirrored);
        assert!(
            d.is_empty(),
            "{name} mirrored: {:?}",
            d.iter().map(|d| d.id).collect::<Vec<_>>()
        );
        seen += 1;
    }
    assert_eq!(seen, 7);
    let right = load_gray(&fixtures().join("right.png")).unwrap();
    let left = image::imageops::crop_imm(&right, 0, 0, 700, right.height()).to_image();
    assert!(det.detect(&left).is_empty());
    // And the board itself is still found in the same detector afterwards.
    assert_eq!(det.detect(&right).len(), 36);
}

#[test]
fn rendered_kalibr_boards_give_corners_close_to_todays() {
    // The same geometry printed both ways, seen from the same poses; corners against the
    // projected board corners (the camera model is given to the detector, as `detect` does).
    let views = [
        Vector3::zeros(),
        Vector3::new(0.3, -0.4, 0.2),
        Vector3::new(-0.5, 0.2, 0.8),
        Vector3::new(0.6, 0.5, -0.3),
    ];
    for (s, label) in [
        (RenderSettings::default(), "realistic"),
        (RenderSettings::ideal(), "ideal"),
    ] {
        let (mut worst_k, mut worst_a) = (0.0f64, 0.0f64);
        for (i, tilt) in views.iter().enumerate() {
            let (kb, ab) = (kalibr_board(), apriltag_board());
            let t = facing(&kb, 0.9, *tilt);
            let (rk, mk, bk, nk) = render_errors(&kb, &t, &s, 3 + i as u64);
            let (ra, _, _, na) = render_errors(&ab, &t, &s, 3 + i as u64);
            eprintln!(
                "{label} view {i}: Kalibr print {nk} tags, RMS {rk:.4} px (max {mk:.3}, mean \
                 [{:.4}, {:.4}]); libapriltag print {na} tags, RMS {ra:.4} px",
                bk.x, bk.y
            );
            // The same tags, except that a Kalibr tag has ten cells across its black square
            // where today's has eight: in the most oblique view one tag, at 2.2 px per cell,
            // is lost in the ideal image (the realistic one keeps it).
            assert!(
                nk + 1 >= na && nk <= na,
                "{label} view {i}: {nk} tags, today's {na}"
            );
            assert!(mk < 0.25, "{label} view {i}: max corner error {mk} px");
            assert!(
                bk.norm() < 0.02,
                "{label} view {i}: mean corner error {bk:?} px"
            );
            worst_k = worst_k.max(rk);
            worst_a = worst_a.max(ra);
        }
        // Observed: Kalibr corners (X-junction saddles) 0.03-0.06 px RMS, today's (line fits)
        // 0.005-0.03 px: both far below the noise of real images.
        assert!(worst_k < 0.08, "{label}: Kalibr corner RMS {worst_k} px");
        assert!(
            worst_a < 0.08,
            "{label}: libapriltag-print corner RMS {worst_a} px"
        );
    }
}

/// Translation (m) and rotation (rad) RMS of the poses of a rendered stereo sequence of `board`,
/// and the number of frames posed, with the detector settings `det` made for the board read
/// back from the sequence's target YAML.
fn sequence_errors(
    board: &Board,
    n: usize,
    name: &str,
    det: impl Fn(&Board) -> DetectorSettings,
) -> (f64, f64, usize) {
    use dvlcal::io::images::scan_images;
    use dvlcal::vision::frames::detect_frames;
    use dvlcal::vision::pnp::PnpOptions;
    let d = vision_seq::fresh_dir(name);
    let (truth, _) = vision_seq::write_sequence_of(&d, n, &RenderSettings::default(), 11, board);
    let chain = read_camchain(&d.join("camchain.yaml")).unwrap();
    let target = read_board(&d.join("target.yaml")).unwrap();
    assert_eq!(
        target.print,
        TagPrint::Kalibr,
        "a Kalibr YAML is a Kalibr print"
    );
    let (frames, _) = scan_images(&d, 2, 1_000_000).unwrap();
    let (res, st) = detect_frames(
        &frames,
        &target,
        &chain,
        &det(&target),
        &PnpOptions::default(),
        false,
    )
    .unwrap();
    let (mut st2, mut sr2) = (0.0, 0.0);
    for (k, r) in res.iter().enumerate() {
        if let Some(p) = &r.pose {
            let e = (truth[k].inverse() * p.t_board_cam0).log();
            st2 += e.fixed_rows::<3>(0).norm_squared();
            sr2 += e.fixed_rows::<3>(3).norm_squared();
        }
    }
    let _ = std::fs::remove_dir_all(&d);
    let m = st.poses.max(1) as f64;
    ((st2 / m).sqrt(), (sr2 / m).sqrt(), st.poses)
}

#[test]
fn rendered_kalibr_sequence_poses_within_1_6_times_todays_errors() {
    let n = 16;
    let default = |_: &Board| DetectorSettings::default();
    let kalibr = vision_seq::board().printed_by_kalibr();
    let (tk, rk, nk) = sequence_errors(&kalibr, n, "kalibr-seq", default);
    let (ta, ra, na) = sequence_errors(&vision_seq::board(), n, "apriltag-seq", default);
    eprintln!(
        "{n} stereo frames: Kalibr print {nk} poses, RMS {:.3} mm {:.4} deg; libapriltag print \
         {na} poses, RMS {:.3} mm {:.4} deg",
        tk * 1e3,
        rk.to_degrees(),
        ta * 1e3,
        ra.to_degrees()
    );
    assert_eq!(nk, n, "every frame of the Kalibr print posed");
    assert_eq!(na, n);
    // Observed on these 16 frames: 0.166 mm and 0.0086 deg with the Kalibr print, 0.118 mm and
    // 0.0056 deg with today's (the corners of Kalibr tags, at X-junctions with the corner
    // squares, are 0.03-0.05 px off on these blurred renders against 0.02-0.03 px for today's
    // line fits). Both far below what a real recording's pose noise allows for; held here to
    // within 1.6 times today's, and to absolute bounds.
    assert!(tk <= 1.6 * ta, "translation {tk} m vs {ta} m");
    assert!(rk <= 1.6 * ra, "rotation {rk} rad vs {ra} rad");
    assert!(tk < 3e-4 && rk < 0.015f64.to_radians(), "{tk} m, {rk} rad");
    // The pipeline's settings (`dvlcal detect`): the board's ids, and the Kalibr print known
    // from the Kalibr target YAML, so that the brightened pass runs first. The poses are as
    // good as with today's order (observed: the same to 0.1 %).
    let pipeline = |b: &Board| dvlcal::pipeline::detector_settings(b, &Default::default());
    assert!(pipeline(&kalibr).kalibr_print && !pipeline(&vision_seq::board()).kalibr_print);
    let (tp, rp, np) = sequence_errors(&kalibr, n, "kalibr-seq-pipeline", pipeline);
    eprintln!(
        "pipeline settings: {np} poses, RMS {:.3} mm {:.4} deg",
        tp * 1e3,
        rp.to_degrees()
    );
    assert_eq!(np, n);
    assert!(
        tp <= 1.05 * tk && rp <= 1.05 * rk,
        "{tp} m {rp} rad against {tk} m {rk} rad"
    );
}

#[test]
fn both_kinds_of_board_in_one_image() {
    // A Kalibr-printed 6 x 6 grid (ids 0..35) on the left, a libapriltag-printed one (ids
    // 100..135) on the right, in one image.
    let cam = camera();
    let kb = Board::grid(TagFamily::Tag36h11, 6, 6, 0.05, 0.3, 0).printed_by_kalibr();
    let ab = Board::grid(TagFamily::Tag36h11, 6, 6, 0.05, 0.3, 100);
    let mut tk = facing(&kb, 0.8, Vector3::new(0.1, 0.25, 0.05));
    tk.trans.x -= 0.22;
    let mut ta = facing(&ab, 0.8, Vector3::new(-0.1, -0.2, 0.0));
    ta.trans.x += 0.22;
    let s = RenderSettings::default();
    let left = render(&kb, &cam, &tk, &s, &mut Rng::new(21));
    let right = render(&ab, &cam, &ta, &s, &mut Rng::new(22));
    let mut img = left.clone();
    for (x, y, p) in img.enumerate_pixels_mut() {
        if x >= cam.width / 2 {
            *p = *right.get_pixel(x, y);
        }
    }
    let dets = Detector::new(&DetectorSettings::default())
        .unwrap()
        .detect_with_camera(&img, Some(&cam));
    let kalibr: Vec<u32> = dets
        .iter()
        .filter(|d| d.border_bits == 2)
        .map(|d| d.id)
        .collect();
    let apriltag: Vec<u32> = dets
        .iter()
        .filter(|d| d.border_bits == 1)
        .map(|d| d.id)
        .collect();
    assert_eq!(kalibr, (0..36).collect::<Vec<_>>());
    assert_eq!(apriltag, (100..136).collect::<Vec<_>>());
    for d in &dets {
        let (board, t) = if d.id < 100 { (&kb, &tk) } else { (&ab, &ta) };
        let tag = board.tag(d.id).unwrap();
        for (got, c) in d.corners.iter().zip(&tag.corners) {
            let e = (got - cam.project(&t.transform_point(c)).unwrap()).norm();
            assert!(e < 0.25, "tag {}: corner {e} px off", d.id);
        }
    }
}

/// One printed tag: its cells (row 0 at the top, `true` = black) and the page transform of its
/// cell grid (`matrix(a b c d e f)`, mm).
struct PrintedTag {
    cells: Vec<Vec<bool>>,
    m: [f64; 6],
}

/// The tags and the corner squares (x, y, width, height in mm) of an SVG `dvlcal board` wrote.
fn parse_svg(svg: &str) -> (BTreeMap<u32, PrintedTag>, Vec<[f64; 4]>) {
    let attr = |line: &str, name: &str| -> Option<String> {
        let start = line.find(&format!(" {name}=\""))? + name.len() + 3;
        let end = line[start..].find('"')? + start;
        Some(line[start..end].to_string())
    };
    let num = |line: &str, name: &str| attr(line, name).unwrap().parse::<f64>().unwrap();
    let (mut tags, mut squares) = (BTreeMap::new(), Vec::new());
    let mut current: Option<(u32, PrintedTag)> = None;
    let mut in_squares = false;
    for line in svg.lines() {
        if let Some(id) = attr(line, "id").and_then(|i| i.strip_prefix("tag").map(str::to_owned)) {
            let m: Vec<f64> = attr(line, "transform")
                .unwrap()
                .trim_start_matches("matrix(")
                .trim_end_matches(')')
                .split(' ')
                .map(|v| v.parse().unwrap())
                .collect();
            let cells = vec![vec![false; 10]; 10];
            current = Some((
                id.parse().unwrap(),
                PrintedTag {
                    cells,
                    m: std::array::from_fn(|k| m[k]),
                },
            ));
        } else if line.contains("id=\"corner-squares\"") {
            in_squares = true;
        } else if line.starts_with("</g>") {
            if let Some((id, t)) = current.take() {
                tags.insert(id, t);
            }
            in_squares = false;
        } else if line.starts_with("<rect") {
            if let Some((_, t)) = &mut current {
                let (x, y, w) = (
                    num(line, "x") as usize,
                    num(line, "y") as usize,
                    num(line, "width") as usize,
                );
                for c in x..x + w {
                    t.cells[y][c] = true;
                }
            } else if in_squares {
                squares.push([
                    num(line, "x"),
                    num(line, "y"),
                    num(line, "width"),
                    num(line, "height"),
                ]);
            }
        }
    }
    (tags, squares)
}

fn print_board(yaml: &str, name: &str) -> String {
    let d = vision_seq::fresh_dir(name);
    let (target, out) = (d.join("target.yaml"), d.join("board.svg"));
    std::fs::write(&target, yaml).unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(["board", "--target"])
        .arg(&target)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let svg = std::fs::read_to_string(&out).unwrap();
    let _ = std::fs::remove_dir_all(&d);
    svg
}

#[test]
fn a_kalibr_yaml_prints_kalibrs_layout_and_dvlcals_yaml_todays() {
    use dvlcal::vision::family::tag_cells;
    // 4 rows x 5 cols of 60 mm tags, spacing 0.25: Kalibr's YAML and dvlcal's of the same grid.
    let kalibr = print_board(
        "target_type: 'aprilgrid'\ntagCols: 5\ntagRows: 4\ntagSize: 0.06\ntagSpacing: 0.25\n",
        "print-kalibr",
    );
    let ours = print_board(
        "family: tag36h11\nrows: 4\ncols: 5\ntag_size: 0.06\nspacing: 0.25\n",
        "print-dvlcal",
    );
    let (kt, ks) = parse_svg(&kalibr);
    let (ot, os) = parse_svg(&ours);
    assert_eq!((kt.len(), ot.len()), (20, 20));
    assert!(
        kalibr.contains("Kalibr aprilgrid"),
        "the legend names the print"
    );
    for id in 0..20u32 {
        // libapriltag's pattern of the tag: a white ring, a one-cell border, the code.
        let code = tag_cells(TagFamily::Tag36h11, id).unwrap();
        let (k, o) = (&kt[&id], &ot[&id]);
        #[allow(clippy::needless_range_loop)] // the same cell of three grids at once
        for r in 0..10 {
            for c in 0..10 {
                let ring = r == 0 || c == 0 || r == 9 || c == 9;
                let border = !ring && (r == 1 || c == 1 || r == 8 || c == 8);
                // Today's print: the library's pattern as it is.
                assert_eq!(o.cells[r][c], code[r][c], "tag {id} cell {r},{c}");
                if ring {
                    assert!(!o.cells[r][c], "today's print has a white ring");
                }
                // Kalibr's: the ring black too (a border two cells wide), the same code inside.
                if ring || border {
                    assert!(k.cells[r][c], "tag {id}: Kalibr border cell {r},{c} white");
                } else {
                    assert_eq!(k.cells[r][c], code[r][c], "tag {id} code cell {r},{c}");
                }
            }
        }
        // Kalibr's bit is a tenth of the tag (the whole black square is 10 bits); today's an
        // eighth (the black square is 8 cells; the ring lies outside it).
        assert!(
            (k.m[0] - 6.0).abs() < 1e-6 && (o.m[0] - 7.5).abs() < 1e-6,
            "{} {}",
            k.m[0],
            o.m[0]
        );
    }
    // Corner squares: none in today's print; in Kalibr's, one at every crossing of the gaps,
    // of edge spacing x tag size (15 mm), each touching the corners of the tags around it.
    assert!(os.is_empty() && !ours.contains("corner-squares"));
    assert_eq!(ks.len(), 5 * 6);
    for s in &ks {
        assert!(
            (s[2] - 15.0).abs() < 1e-3 && (s[3] - 15.0).abs() < 1e-3,
            "{s:?}"
        );
    }
    let touches = |p: (f64, f64)| {
        ks.iter().any(|s| {
            [
                (s[0], s[1]),
                (s[0] + s[2], s[1]),
                (s[0], s[1] + s[3]),
                (s[0] + s[2], s[1] + s[3]),
            ]
            .iter()
            .any(|q| (q.0 - p.0).abs() < 1e-3 && (q.1 - p.1).abs() < 1e-3)
        })
    };
    for (id, t) in &kt {
        // The black square's corners on the page: the cell grid's corners (no ring outside).
        let (x0, y0, side) = (t.m[4], t.m[5], 10.0 * t.m[0]);
        for p in [
            (x0, y0),
            (x0 + side, y0),
            (x0, y0 + side),
            (x0 + side, y0 + side),
        ] {
            assert!(touches(p), "tag {id}: no corner square at {p:?}");
        }
        // And no square overlaps the tag.
        for s in &ks {
            let overlap_x = s[0] < x0 + side - 1e-6 && s[0] + s[2] > x0 + 1e-6;
            let overlap_y = s[1] < y0 + side - 1e-6 && s[1] + s[3] > y0 + 1e-6;
            assert!(!(overlap_x && overlap_y), "tag {id} overlaps {s:?}");
        }
    }
    // Tag 0 at the bottom left, ids along the rows (Kalibr's numbering): tag 1 right of tag 0,
    // tag 5 above it.
    let (t0, t1, t5) = (&kt[&0], &kt[&1], &kt[&5]);
    assert!((t1.m[4] - t0.m[4] - 75.0).abs() < 1e-3 && (t1.m[5] - t0.m[5]).abs() < 1e-3);
    assert!((t0.m[5] - t5.m[5] - 75.0).abs() < 1e-3 && (t5.m[4] - t0.m[4]).abs() < 1e-3);
}

#[test]
fn a_kalibr_board_reads_back_as_a_kalibr_print() {
    let yaml =
        "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n";
    let b = parse_board(yaml, Path::new("t.yaml")).unwrap();
    assert_eq!(b.print, TagPrint::Kalibr);
    let back = parse_board(&board_yaml(&b), Path::new("t.yaml")).unwrap();
    assert_eq!(back, b);
    assert!(board_yaml(&b).contains("target_type: 'aprilgrid'"));
    let ours = parse_board(
        "rows: 6\ncols: 6\ntag_size: 0.088\nspacing: 0.3\n",
        Path::new("o.yaml"),
    )
    .unwrap();
    assert_eq!(ours.print, TagPrint::Apriltag);
    // The same tag corners either way: one printed board, one geometry.
    assert_eq!(ours.tags, b.tags);
}

/// The first number in `attr="..."` of the first line containing `marker`.
fn svg_number(svg: &str, marker: &str, attr: &str) -> f64 {
    let line = svg
        .lines()
        .find(|l| l.contains(marker))
        .unwrap_or_else(|| panic!("no line with {marker}"));
    let key = format!(" {attr}=\"");
    let start = line
        .find(&key)
        .unwrap_or_else(|| panic!("{attr} in {line}"))
        + key.len();
    let end = start + line[start..].find('"').unwrap();
    line[start..end].trim_end_matches("mm").parse().unwrap()
}

/// The SVG rendered by headless Chromium at 96 dpi (px per mm = 96 / 25.4), as grey.
fn render_svg(svg: &str, name: &str) -> image::GrayImage {
    let d = vision_seq::fresh_dir(name);
    let (file, png) = (d.join("board.svg"), d.join("board.png"));
    std::fs::write(&file, svg).unwrap();
    let px = 96.0 / 25.4;
    let w = (svg_number(svg, "<svg", "width") * px).ceil() as u32 + 2;
    let h = (svg_number(svg, "<svg", "height") * px).ceil() as u32 + 2;
    let browser = std::env::var("CHROMIUM").unwrap_or_else(|_| "chromium".into());
    let out = std::process::Command::new(&browser)
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
        .arg(format!("file://{}", file.display()))
        .output()
        .unwrap_or_else(|e| {
            panic!("run {browser} (install Debian's chromium, or DVLCAL_SKIP_BROWSER=1): {e}")
        });
    assert!(png.exists(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = image::open(&png).unwrap().to_luma8();
    let _ = std::fs::remove_dir_all(&d);
    img
}

/// A printed board, rendered: every tag is found; the scale bar measures its stated length
/// against the tags' own edges; the origin ticks sit on the first tag's lower-left corner; the id
/// labels stand level with their rows.
#[test]
fn a_printed_board_shows_its_scale_ids_and_origin_without_hiding_a_tag() {
    if std::env::var("DVLCAL_SKIP_BROWSER").is_ok_and(|v| v == "1") {
        eprintln!("DVLCAL_SKIP_BROWSER=1: render of the board print skipped");
        return;
    }
    let px = 96.0 / 25.4;
    for (yaml, name, first) in [
        (
            "family: tag36h11\nrows: 3\ncols: 4\ntag_size: 0.04\nspacing: 0.3\nfirst_id: 10\n",
            "print-scale-dvlcal",
            10u32,
        ),
        (
            "target_type: 'aprilgrid'\ntagCols: 4\ntagRows: 3\ntagSize: 0.04\ntagSpacing: 0.3\n",
            "print-scale-kalibr",
            0,
        ),
    ] {
        let svg = print_board(yaml, name);
        let img = render_svg(&svg, name);
        let mut det = Detector::new(&DetectorSettings::default()).unwrap();
        let found: BTreeMap<u32, TagDetection> =
            det.detect(&img).into_iter().map(|d| (d.id, d)).collect();
        let ids: Vec<u32> = found.keys().copied().collect();
        assert_eq!(ids, (first..first + 12).collect::<Vec<_>>(), "{name}");
        // Tag edge in pixels, from the detected corners of every tag.
        let edges: Vec<f64> = found
            .values()
            .flat_map(|d| (0..4).map(move |k| (d.corners[(k + 1) % 4] - d.corners[k]).norm()))
            .collect();
        let edge_px = edges.iter().sum::<f64>() / edges.len() as f64;
        assert!(
            (edge_px / (40.0 * px) - 1.0).abs() < 0.01,
            "{name}: {edge_px}"
        );

        // The scale bar, measured along its middle row: its outline's first and last dark pixels.
        let len_mm = svg_number(&svg, "id=\"scale-bar\"", "data-length-mm");
        let bar = "fill=\"none\" stroke=\"black\" stroke-width=\"0.2\"";
        let (bx, by) = (svg_number(&svg, bar, "x"), svg_number(&svg, bar, "y"));
        let row = ((by + 1.0) * px) as u32;
        let dark: Vec<u32> = (0..img.width())
            .filter(|&x| img.get_pixel(x, row)[0] < 128)
            .collect();
        let (x0, x1) = (dark[0], *dark.last().unwrap());
        assert!(
            (x0 as f64 - bx * px).abs() < 2.0,
            "{name}: bar starts at {x0}"
        );
        let bar_px = (x1 - x0 + 1) as f64;
        let ratio = (bar_px / edge_px) / (len_mm / 40.0);
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "{name}: the {len_mm} mm bar is {bar_px} px against {edge_px} px per 40 mm tag"
        );

        // Origin ticks on the first tag's lower-left corner (OpenCV convention: page * px - 0.5).
        let c = found[&first].corners[0];
        let ox = svg_number(&svg, "id=\"board-axes\"", "data-origin-x-mm") * px - 0.5;
        let oy = svg_number(&svg, "id=\"board-axes\"", "data-origin-y-mm") * px - 0.5;
        assert!(
            (ox - c.x).abs() < 1.0 && (oy - c.y).abs() < 1.0,
            "{name}: {ox},{oy} vs {c}"
        );

        // Each row's id labels: the row's ids left to right, level with the detected centres.
        for line in svg.lines().filter(|l| l.contains("data-ids=")) {
            let start = line.find("data-ids=\"").unwrap() + 10;
            let row_ids: Vec<u32> = line[start..start + line[start..].find('"').unwrap()]
                .split(' ')
                .map(|v| v.parse().unwrap())
                .collect();
            let centre = |id: &u32| found[id].corners.iter().sum::<Vector2<f64>>() / 4.0;
            let xs: Vec<f64> = row_ids.iter().map(|id| centre(id).x).collect();
            assert!(xs.windows(2).all(|w| w[0] < w[1]), "{name}: {line}");
            let label_y = svg_number(line, "data-ids", "y") * px;
            let row_y = centre(&row_ids[0]).y;
            assert!((label_y - row_y).abs() < 0.25 * edge_px, "{name}: {line}");
        }
    }
}

/// The second pass's brightened half-resolution image made in one pass equals the 3x3
/// brightest filter followed by the 2x2 brightest decimation, at even and odd sizes, on noise
/// and on a rendered board.
#[test]
fn one_pass_brightest_decimation_equals_the_two_steps() {
    use dvlcal::vision::kalibr::{max_decimate, max3, max3_decimate};
    let mut rng = Rng::new(5);
    for (w, h) in [
        (1, 1),
        (2, 2),
        (3, 5),
        (8, 8),
        (17, 10),
        (64, 33),
        (752, 480),
    ] {
        let img =
            image::GrayImage::from_fn(w, h, |_, _| image::Luma([(rng.uniform() * 256.0) as u8]));
        assert_eq!(max3_decimate(&img), max_decimate(&max3(&img)), "{w}x{h}");
    }
    let board = kalibr_board();
    let cam = camera();
    let img = render(
        &board,
        &cam,
        &facing(&board, 0.6, Vector3::new(0.2, -0.1, 0.1)),
        &RenderSettings::default(),
        &mut Rng::new(2),
    );
    assert_eq!(max3_decimate(&img), max_decimate(&max3(&img)));
}

/// A detector for a known board of `ids`, told (`kalibr_print`) or not that it is a Kalibr print.
fn board_detector(ids: Vec<u32>, kalibr_print: bool) -> Detector {
    Detector::new(&DetectorSettings {
        board_ids: Some(ids),
        kalibr_print,
        ..DetectorSettings::default()
    })
    .unwrap()
}

/// Largest distance (px) between the corners of the same ids; panics when the ids differ.
fn largest_corner_move(a: &[TagDetection], b: &[TagDetection], what: &str) -> f64 {
    let ids = |v: &[TagDetection]| v.iter().map(|d| d.id).collect::<Vec<_>>();
    assert_eq!(ids(a), ids(b), "{what}: the two orders find different tags");
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..4).map(move |k| (x.corners[k] - y.corners[k]).norm()))
        .fold(0.0, f64::max)
}

#[test]
fn a_board_known_as_a_kalibr_print_gives_the_same_tags_as_accurately() {
    // The brightened pass first and libapriltag's own detection only for ids it leaves
    // unfound, against today's order (libapriltag first), with the same board's ids.
    // Photos: the same tags, corners within a hundredth of a pixel (observed: 0.0014 px), and
    // as good a fit to a flat board.
    for name in PHOTOS {
        let img = load_gray(&fixtures().join(name)).unwrap();
        let ids: Vec<u32> = (0..layout(name).1).collect();
        let today = board_detector(ids.clone(), false).detect(&img);
        let first = board_detector(ids, true).detect(&img);
        let moved = largest_corner_move(&today, &first, name);
        eprintln!(
            "{name}: {} tags, corners moved by up to {moved:.4} px",
            first.len()
        );
        assert!(moved < 0.01, "{name}: corners moved by {moved} px");
    }
    for (name, ids, cols) in [
        ("two_boards.png", 0..36, 6),
        ("two_boards.png", 36..72, 6),
        ("iphone.png", 0..66, 11),
    ] {
        let img = load_gray(&fixtures().join(name)).unwrap();
        let all: Vec<u32> = (0..layout(name).1).collect();
        let rms = |kalibr_print: bool| {
            let d = board_detector(all.clone(), kalibr_print).detect(&img);
            let tags: Vec<(u32, [Vector2<f64>; 4])> = d
                .iter()
                .filter(|d| ids.contains(&d.id))
                .map(|d| (d.id - ids.start, d.corners))
                .collect();
            homography_rms(&tags, cols)
        };
        let (today, first) = (rms(false), rms(true));
        eprintln!("{name} ids {ids:?}: homography RMS {first:.4} px, today's order {today:.4} px");
        assert!(
            first <= today * 1.01 + 1e-4,
            "{name}: {first} px against {today} px"
        );
    }
    // Renders at three distances and four tilts, against the projected board corners: the same
    // number of tags and the same corner RMS within 2 % (observed: within 0.8 %). Where the
    // brightened pass finds every tag, libapriltag's detection does not run (observed: 7 of the
    // 9 renders that show all 36 tags); where tags are out of view or too oblique to read, it
    // runs as before.
    let cam = camera();
    let board = kalibr_board();
    let ids: Vec<u32> = board.tags.iter().map(|t| t.id).collect();
    let views = [
        Vector3::zeros(),
        Vector3::new(0.3, -0.4, 0.2),
        Vector3::new(-0.5, 0.2, 0.8),
        Vector3::new(0.6, 0.5, -0.3),
    ];
    let (mut fast, mut today) = (
        board_detector(ids.clone(), true),
        board_detector(ids.clone(), false),
    );
    let mut images = 0;
    for (s, label) in [
        (RenderSettings::default(), "realistic"),
        (RenderSettings::ideal(), "ideal"),
    ] {
        for (i, tilt) in views.iter().enumerate() {
            for dist in [0.9, 1.3, 2.0] {
                let t = facing(&board, dist, *tilt);
                let img = render(&board, &cam, &t, &s, &mut Rng::new(70 + i as u64));
                images += 1;
                let err = |det: &mut Detector| {
                    let d = det.detect_with_camera(&img, Some(&cam));
                    let mut sq = 0.0;
                    for d in &d {
                        let tag = board.tag(d.id).unwrap();
                        for (got, c) in d.corners.iter().zip(&tag.corners) {
                            sq +=
                                (got - cam.project(&t.transform_point(c)).unwrap()).norm_squared();
                        }
                    }
                    ((sq / (4 * d.len().max(1)) as f64).sqrt(), d.len())
                };
                let ((et, nt), (ef, nf)) = (err(&mut today), err(&mut fast));
                eprintln!(
                    "{label} view {i} at {dist} m: {nf} tags, RMS {ef:.4} px; today's order {nt} \
                     tags, RMS {et:.4} px"
                );
                assert_eq!(nf, nt, "{label} view {i} at {dist} m");
                assert!(
                    ef <= 1.02 * et + 1e-3,
                    "{label} view {i} at {dist} m: {ef} px, {et} px"
                );
            }
        }
    }
    eprintln!(
        "libapriltag's detection ran on {} of {images} renders (today's order: {})",
        fast.library_detections(),
        today.library_detections()
    );
    assert_eq!(today.library_detections(), images);
    assert!(fast.library_detections() <= images - 5);

    // A fresh detector's first image: the brightened pass needs libapriltag's worker pool,
    // which its own detection makes; the detector makes it on a blank image first, so a board
    // wholly in view is read without libapriltag's detection of the image.
    let t = facing(&board, 0.9, Vector3::zeros());
    let img = render(
        &board,
        &cam,
        &t,
        &RenderSettings::default(),
        &mut Rng::new(70),
    );
    let mut fresh = board_detector(ids.clone(), true);
    assert_eq!(fresh.detect_with_camera(&img, Some(&cam)).len(), 36);
    assert_eq!(fresh.library_detections(), 0);
}
