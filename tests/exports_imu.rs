//! The exports of a run with an IMU: with the DVL beside it, each file is the one the earlier
//! writers (the DVL's text with the IMU added afterwards) gave for the same input, kept in
//! `tests/fixtures/exports_imu`; without a DVL (a camera and IMU run), the URDF is a robot ROS's
//! parser reads and the Kalibr file is YAML whose one sensor is the IMU.

use std::path::Path;
use std::process::Command;

use dvlcal::io::exports::{
    Export, ExportNotes, FrameNames, ImuExport, KalibrCamera, kalibr_camchain_imucam,
    ros_static_transform, urdf_robot,
};
use dvlcal::lie::Se3;
use dvlcal::types::CalibrationParams;
use nalgebra::{Matrix3, Matrix4, Vector3, Vector6};

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::TmpDir;

fn dvl() -> CalibrationParams {
    CalibrationParams {
        t_cam_dvl: Se3::exp(&Vector6::new(0.1, -0.2, 0.3, 0.4, -0.5, 0.6)),
        time_offset_s: 0.125,
        velocity_scale: 1.01,
    }
}

fn imu() -> ImuExport {
    ImuExport {
        t_cam_imu: Se3::exp(&Vector6::new(0.02, 0.05, -0.01, -1.2, 0.3, 1.6)),
        time_offset_s: -0.0375,
        frame: "imu".into(),
    }
}

/// A stereo chain: cam1 12 cm beside cam0.
fn cams() -> Vec<KalibrCamera> {
    let t_c1_c0 = Se3::new(Matrix3::identity(), Vector3::new(-0.12, 0.0, 0.0));
    vec![
        KalibrCamera {
            entry: "  camera_model: pinhole\n  intrinsics: [460.0, 459.5, 367.0, 248.0]\n".into(),
            t_cn_c0: Matrix4::identity(),
            overlaps: vec![1],
        },
        KalibrCamera {
            entry: "  camera_model: pinhole\n  intrinsics: [457.0, 456.0, 379.0, 255.0]\n".into(),
            t_cn_c0: t_c1_c0.to_matrix(),
            overlaps: vec![0],
        },
    ]
}

/// A fixture with this build's version in place of `VERSION`.
fn golden(name: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/exports_imu")
        .join(name);
    std::fs::read_to_string(&p)
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        .replace("dvlcal VERSION:", &format!("dvlcal {}:", env!("CARGO_PKG_VERSION")))
}

/// The DVL and an IMU: ROS commands, URDF and Kalibr file, byte for byte as the writers that
/// added the IMU to the DVL's finished text wrote them.
#[test]
fn with_the_dvl_the_imus_exports_are_what_they_were() {
    let (c, imu) = (dvl(), imu());
    let names = FrameNames::parse("camera_link,dvl_link").unwrap();
    let notes = ExportNotes::default();
    let e = Export::dvl(&c, &names, &notes).with_imu(Some(&imu));
    assert_eq!(ros_static_transform(&e), golden("tf.txt"));
    assert_eq!(urdf_robot(&e), golden("urdf.xml"));
    assert_eq!(
        kalibr_camchain_imucam(&e, &cams()),
        golden("camchain-imucam.yaml")
    );
}

fn matrix_of(v: &serde_yaml::Value) -> Matrix4<f64> {
    let mut m = Matrix4::from_element(f64::NAN);
    for (r, row) in v.as_sequence().into_iter().flatten().enumerate() {
        for (k, x) in row.as_sequence().into_iter().flatten().enumerate() {
            m[(r, k)] = x.as_f64().unwrap_or(f64::NAN);
        }
    }
    m
}

/// The camera and an IMU without a DVL: the Kalibr file parses, holds the two cameras as its
/// only top-level keys, each with the IMU in Kalibr's IMU keys (composed with the camera's
/// `T_cn_c0`, the time shift `-imu_time_offset_s`) and no DVL key; the URDF is a robot
/// `check_urdf` reads with the IMU as the camera's one child; the ROS commands publish the IMU
/// alone.
#[test]
fn without_a_dvl_the_exports_hold_the_imu_alone_and_parse() {
    let imu = imu();
    let names = FrameNames::default();
    let notes = ExportNotes::default();
    let e = Export {
        dvl: None,
        imu: Some(&imu),
        names: &names,
        notes: &notes,
    };
    let cams = cams();
    let text = kalibr_camchain_imucam(&e, &cams);
    let v: serde_yaml::Value = serde_yaml::from_str(&text).expect("valid YAML");
    let keys: Vec<&str> = v
        .as_mapping()
        .into_iter()
        .flatten()
        .filter_map(|(k, _)| k.as_str())
        .collect();
    assert_eq!(keys, ["cam0", "cam1"]);
    for (n, cam) in ["cam0", "cam1"].into_iter().enumerate() {
        let want = cams[n].t_cn_c0 * imu.t_cam_imu.to_matrix();
        let d = (matrix_of(&v[cam]["T_cam_imu"]) - want).abs().max();
        assert!(d < 1e-11, "{cam} T_cam_imu off by {d}");
        assert_eq!(v[cam]["timeshift_cam_imu"].as_f64(), Some(0.0375));
        let cam_keys: Vec<&str> = v[cam]
            .as_mapping()
            .into_iter()
            .flatten()
            .filter_map(|(k, _)| k.as_str())
            .collect();
        assert!(!cam_keys.iter().any(|k| k.contains("dvl")), "{cam_keys:?}");
    }
    assert!(!text.contains("DVL"), "{text}");

    let tmp = TmpDir::new("exports-imu-only");
    let urdf = tmp.path("imu-urdf.xml");
    std::fs::write(&urdf, urdf_robot(&e)).unwrap();
    let r = Command::new("check_urdf")
        .arg(&urdf)
        .output()
        .expect("check_urdf (Debian's liburdfdom-tools) runs");
    let parsed = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{parsed}");
    assert!(
        parsed.contains("root Link: cam0 has 1 child(ren)") && parsed.contains("child(1):  imu"),
        "{parsed}"
    );

    let tf = ros_static_transform(&e);
    assert_eq!(tf.matches("rosrun").count(), 1, "{tf}");
    assert!(tf.contains("--frame-id cam0 --child-frame-id imu"), "{tf}");
    assert!(tf.contains("# clock: t_cam = t_imu + -0.0375 s"), "{tf}");
}
