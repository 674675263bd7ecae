//! Boards (grid, list, Kalibr aprilgrid YAML) and cameras (projection, Jacobian, unprojection,
//! camchain files).

use dvlcal::Error;
use dvlcal::io::camchain::{camchain_yaml, parse_camchain, read_camchain};
use dvlcal::io::target::{board_yaml, parse_board, read_board};
use dvlcal::lie::Se3;
use dvlcal::types::board::{Board, TagFamily};
use dvlcal::types::camera::{Camchain, Camera, Distortion};
use dvlcal::vision::family::{family_layout, tag_cells};
use nalgebra::{Matrix2x3, Vector2, Vector3, Vector6};
use std::path::{Path, PathBuf};

fn tmp(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dvlcal_vision_board_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn close(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
    (a - b).norm() < 1e-12
}

#[test]
fn kalibr_grid_geometry_and_ids() {
    // Kalibr aprilgrid: 6x6, 88 mm tags, spacing 0.3 -> pitch 114.4 mm.
    let p = tmp(
        "april_6x6.yaml",
        "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n",
    );
    let b = read_board(&p).unwrap();
    assert_eq!(b.family, TagFamily::Tag36h11);
    assert_eq!(b.tags.len(), 36);
    let d = 0.088 * 1.3;
    // Tag 0: origin at its bottom-left corner; corners BL, BR, TR, TL.
    let t0 = b.tag(0).unwrap();
    assert!(close(&t0.corners[0], &Vector3::zeros()));
    assert!(close(&t0.corners[1], &Vector3::new(0.088, 0.0, 0.0)));
    assert!(close(&t0.corners[2], &Vector3::new(0.088, 0.088, 0.0)));
    assert!(close(&t0.corners[3], &Vector3::new(0.0, 0.088, 0.0)));
    // id = row * cols + col: tag 8 is row 1, col 2.
    let t8 = b.tag(8).unwrap();
    assert!(close(&t8.corners[0], &Vector3::new(2.0 * d, d, 0.0)));
    assert!(close(
        &t8.corners[2],
        &Vector3::new(2.0 * d + 0.088, d + 0.088, 0.0)
    ));
    let t35 = b.tag(35).unwrap();
    assert!(close(
        &t35.corners[2],
        &Vector3::new(5.0 * d + 0.088, 5.0 * d + 0.088, 0.0)
    ));
    assert!(b.tag(36).is_none());
    // Same as the constructor.
    assert_eq!(
        b.tags,
        Board::grid(TagFamily::Tag36h11, 6, 6, 0.088, 0.3, 0).tags
    );
}

#[test]
fn grid_yaml_with_first_id_and_family() {
    let p = tmp(
        "grid.yaml",
        "family: tagStandard41h12\nrows: 2\ncols: 3\ntag_size: 0.05\nspacing: 0.25\nfirst_id: 10\n",
    );
    let b = read_board(&p).unwrap();
    assert_eq!(b.family, TagFamily::TagStandard41h12);
    let ids: Vec<u32> = b.tags.iter().map(|t| t.id).collect();
    assert_eq!(ids, vec![10, 11, 12, 13, 14, 15]);
    // Tag 14 = row 1, col 1.
    let d = 0.05 * 1.25;
    assert!(close(
        &b.tag(14).unwrap().corners[0],
        &Vector3::new(d, d, 0.0)
    ));
    // to_yaml round trip.
    let back = parse_board(&board_yaml(&b), Path::new("x.yaml")).unwrap();
    assert_eq!(back.tags, b.tags);
}

#[test]
fn list_form_pose_and_matrix() {
    let text = "family: tag36h11\ntags:\n  - id: 3\n    size: 0.2\n    position: [1.0, 2.0, 0.0]\n    quaternion_xyzw: [0, 0, 0, 1]\n  - id: 7\n    size: 0.1\n    T_board_tag: [[0, -1, 0, 0.5], [1, 0, 0, 0], [0, 0, 1, 0.3], [0, 0, 0, 1]]\n";
    let b = parse_board(text, Path::new("wall.yaml")).unwrap();
    assert!(b.grid.is_none());
    let t3 = b.tag(3).unwrap();
    assert!(close(&t3.corners[0], &Vector3::new(0.9, 1.9, 0.0)));
    assert!(close(&t3.corners[2], &Vector3::new(1.1, 2.1, 0.0)));
    // Tag 7 rotated +90 deg about z: its bottom-left (-h, -h) goes to (h, -h) + t.
    let t7 = b.tag(7).unwrap();
    assert!(close(&t7.corners[0], &Vector3::new(0.55, -0.05, 0.3)));
    assert!(close(&t7.corners[1], &Vector3::new(0.55, 0.05, 0.3)));
    // The pose recovered from the corners.
    let p = t7.pose();
    assert!((p.trans - Vector3::new(0.5, 0.0, 0.3)).norm() < 1e-12);
    let back = parse_board(&board_yaml(&b), Path::new("x.yaml")).unwrap();
    for (a, c) in back.tags.iter().zip(&b.tags) {
        for k in 0..4 {
            assert!((a.corners[k] - c.corners[k]).norm() < 1e-9);
        }
    }
}

#[test]
fn shipped_boards_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("calib_boards");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "yaml") {
            let b = read_board(&p).unwrap_or_else(|e| panic!("{e}"));
            assert!(!b.tags.is_empty(), "{}", p.display());
            n += 1;
        }
    }
    assert!(n >= 4);
}

fn err_of(text: &str) -> String {
    match parse_board(text, Path::new("boards/bad.yaml")) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn board_errors_name_file_and_line() {
    let e = err_of("rows: 6\ncols: 6\ntag_size: oops\nspacing: 0.3\n");
    assert!(e.starts_with("boards/bad.yaml:3:"), "{e}");
    let e = err_of("family: tag99h1\nrows: 1\ncols: 1\ntag_size: 0.1\nspacing: 0.3\n");
    assert!(
        e.contains("boards/bad.yaml") && e.contains("tag99h1"),
        "{e}"
    );
    let e = err_of(
        "target_type: 'checkerboard'\ntagCols: 1\ntagRows: 1\ntagSize: 0.1\ntagSpacing: 0.3\n",
    );
    assert!(e.contains("checkerboard"), "{e}");
    let e = err_of("rows: 6\ncols: 6\ntag_size: -0.1\nspacing: 0.3\n");
    assert!(e.contains("tag_size"), "{e}");
    let e = err_of("rows: 30\ncols: 30\ntag_size: 0.1\nspacing: 0.3\nfamily: tag16h5\n");
    assert!(e.contains("does not exist"), "{e}");
    let e = err_of("tags:\n  - id: 1\n    size: 0.1\n");
    assert!(e.contains("position"), "{e}");
    let e = err_of(
        "tags:\n  - id: 1\n    size: 0.1\n    position: [0, 0, 0]\n  - id: 1\n    size: 0.1\n    position: [1, 0, 0]\n",
    );
    assert!(e.contains("twice"), "{e}");
    let e = err_of("rows: 6\ncols: 6\ntag_size: 0.1\nspacing: 0.3\ncolour: red\n");
    assert!(e.contains("colour"), "{e}");
    match read_board(Path::new("/nonexistent/board.yaml")) {
        Err(Error::Io { path, .. }) => assert_eq!(path, Path::new("/nonexistent/board.yaml")),
        other => panic!("{other:?}"),
    }
}

#[test]
fn family_names_and_library_data() {
    for f in TagFamily::ALL {
        assert_eq!(TagFamily::from_name(f.name()), Some(f));
        let l = family_layout(f).unwrap();
        assert_eq!(l.ncodes as usize, f.code_count(), "{}", f.name());
        let c = tag_cells(f, 0).unwrap();
        assert_eq!(c.len(), l.total_width as usize);
        assert!(tag_cells(f, l.ncodes).is_none());
    }
    assert_eq!(TagFamily::from_name("TAG36H11"), Some(TagFamily::Tag36h11));
    assert_eq!(TagFamily::from_name("36h11"), None);
    // tag36h11: 10x10 with a white outer ring and a black border ring.
    let c = tag_cells(TagFamily::Tag36h11, 0).unwrap();
    assert!((0..10).all(|i| !c[0][i] && !c[9][i] && !c[i][0] && !c[i][9]));
    assert!((1..9).all(|i| c[1][i] && c[8][i] && c[i][1] && c[i][8]));
}

fn cameras() -> Vec<Camera> {
    let base = Camera {
        fu: 460.0,
        fv: 458.0,
        pu: 370.0,
        pv: 245.0,
        distortion: Distortion::None,
        width: 752,
        height: 480,
    };
    vec![
        base.clone(),
        Camera {
            distortion: Distortion::RadTan {
                k1: -0.28,
                k2: 0.07,
                p1: 2e-4,
                p2: -1.5e-5,
            },
            ..base.clone()
        },
        Camera {
            distortion: Distortion::Equidistant {
                k1: -0.01,
                k2: 0.02,
                k3: -0.005,
                k4: 0.001,
            },
            ..base
        },
    ]
}

#[test]
fn projection_jacobian_matches_numeric() {
    let pts = [
        Vector3::new(0.1, -0.2, 1.5),
        Vector3::new(-0.6, 0.4, 1.0),
        Vector3::new(0.0, 0.0, 2.0),
        Vector3::new(0.3, 0.25, 0.7),
    ];
    for cam in cameras() {
        for p in &pts {
            let (uv, j) = cam.project_jacobian(p).unwrap();
            assert!((uv - cam.project(p).unwrap()).norm() < 1e-12);
            let mut num = Matrix2x3::zeros();
            let h = 1e-6;
            for k in 0..3 {
                let mut a = *p;
                let mut b = *p;
                a[k] += h;
                b[k] -= h;
                let d = (cam.project(&a).unwrap() - cam.project(&b).unwrap()) / (2.0 * h);
                num.set_column(k, &d);
            }
            assert!(
                (j - num).norm() < 1e-5 * (1.0 + j.norm()),
                "{:?}\n{j}\n{num}",
                cam.distortion
            );
        }
        assert!(cam.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
        assert!(cam.project_jacobian(&Vector3::new(1.0, 0.0, 0.0)).is_none());
    }
}

#[test]
fn unprojection_round_trips() {
    for cam in cameras() {
        for y in (0..480).step_by(37) {
            for x in (0..752).step_by(41) {
                let px = Vector2::new(x as f64 + 0.25, y as f64 - 0.3);
                let r = cam.unproject(&px).unwrap();
                assert_eq!(r.z, 1.0);
                let back = cam.project(&(r * 2.5)).unwrap();
                assert!(
                    (back - px).norm() < 1e-7,
                    "{:?} {px} {back}",
                    cam.distortion
                );
            }
        }
    }
}

fn stereo_chain() -> Camchain {
    let cams = cameras();
    let t10 = Se3::exp(&Vector6::new(-0.11, 0.001, -0.002, 0.01, -0.02, 0.005));
    Camchain {
        cams: vec![cams[1].clone(), cams[2].clone(), cams[0].clone()],
        t_cn_c0: vec![
            Se3::identity(),
            t10,
            Se3::exp(&Vector6::new(0.1, 0.2, 0.0, 0.0, 0.3, 0.0)) * t10,
        ],
        topics: vec![
            Some("/cam0/image_raw".into()),
            Some("/cam1/image_raw".into()),
            None,
        ],
    }
}

#[test]
fn camchain_round_trip() {
    let c = stereo_chain();
    let text = camchain_yaml(&c);
    let p = tmp("camchain.yaml", &text);
    let back = read_camchain(&p).unwrap();
    assert_eq!(back.cams, c.cams);
    assert_eq!(back.topics, c.topics);
    for (a, b) in back.t_cn_c0.iter().zip(&c.t_cn_c0) {
        assert!((a.to_matrix() - b.to_matrix()).norm() < 1e-12);
    }
}

#[test]
fn kalibr_camchain_as_written_by_kalibr() {
    // EuRoC's stereo pair as Kalibr writes it (extra keys ignored).
    let text = "cam0:
  cam_overlaps: [1]
  camera_model: pinhole
  distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
  distortion_model: radtan
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
cam1:
  T_cn_cnm1:
  - [0.9999972564778, 0.0023153148, 0.0003439456, -0.1100740994]
  - [-0.0023170293, 0.9999691971, 0.0075024107, 0.0003991557]
  - [-0.0003265698, -0.0075031855, 0.9999717966, -0.0008531152]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [0]
  camera_model: pinhole
  distortion_coeffs: [-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05]
  distortion_model: radtan
  intrinsics: [457.587, 456.134, 379.999, 255.238]
  resolution: [752, 480]
  rostopic: /cam1/image_raw
";
    let c = parse_camchain(text, Path::new("camchain.yaml")).unwrap();
    assert_eq!(c.cams.len(), 2);
    assert_eq!(c.cams[1].width, 752);
    assert!((c.t_cn_c0[1].trans.x + 0.1100740994).abs() < 1e-9);
    assert_eq!(c.topics[0].as_deref(), Some("/cam0/image_raw"));
    // Mono.
    let mono = text.split("cam1:").next().unwrap();
    assert_eq!(
        parse_camchain(mono, Path::new("m.yaml"))
            .unwrap()
            .cams
            .len(),
        1
    );
    // Errors name the file and the camera's line.
    let bad = text.replace(
        "distortion_model: radtan\n  intrinsics: [457",
        "distortion_model: fov\n  intrinsics: [457",
    );
    let e = parse_camchain(&bad, Path::new("camchain.yaml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("camchain.yaml:9:") && e.contains("fov"),
        "{e}"
    );
    let e = parse_camchain("cam1:\n  camera_model: pinhole\n", Path::new("c.yaml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("c.yaml") && e.contains("cam0"), "{e}");
}
