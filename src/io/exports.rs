//! The calibration in the forms other tools read: a ROS static transform and a Kalibr-style
//! camchain block.
//!
//! ROS's `static_transform_publisher` takes the pose of the child frame in the parent frame,
//! which for parent `cam0` and child `dvl` is `T_cam_dvl` (translation `p_cam_dvl`, quaternion
//! `q_cam_dvl`). Kalibr's camchain-imucam file gives, per camera, `T_cam_imu` (IMU points into
//! the camera frame) and `timeshift_cam_imu` with `t_imu = t_cam + timeshift`; the DVL block
//! follows the same pattern, so `timeshift_cam_dvl = -time_offset_s`.

use std::fmt::Write as _;

use nalgebra::Matrix4;

use crate::types::CalibrationParams;

/// Frame names used in the exports.
#[derive(Clone, Debug)]
pub struct FrameNames {
    /// Name of the camera frame, the parent of the transform (default `cam0`).
    pub camera: String,
    /// Name of the DVL frame, the child of the transform (default `dvl`).
    pub dvl: String,
}

impl Default for FrameNames {
    fn default() -> Self {
        FrameNames {
            camera: "cam0".into(),
            dvl: "dvl".into(),
        }
    }
}

fn fmt_f(x: f64) -> String {
    // Enough digits to round-trip a double, no exponent noise for ordinary values.
    let s = format!("{x:.12}");
    let s = s.trim_end_matches('0');
    let s = s
        .strip_suffix('.')
        .map(|p| format!("{p}.0"))
        .unwrap_or(s.to_owned());
    if s == "-0.0" { "0.0".into() } else { s }
}

/// The ROS 1 and ROS 2 command lines publishing `T_cam_dvl` as a static transform, one per
/// line, each preceded by a comment line.
pub fn ros_static_transform(c: &CalibrationParams, names: &FrameNames) -> String {
    let t = c.t_cam_dvl.trans;
    let q = c.t_cam_dvl.quaternion_xyzw();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# ROS 1 (tf2_ros): x y z qx qy qz qw parent child; the DVL frame in the camera frame"
    );
    let [x, y, z, qx, qy, qz, qw] = [t.x, t.y, t.z, q[0], q[1], q[2], q[3]].map(fmt_f);
    let (parent, child) = (&names.camera, &names.dvl);
    let _ = writeln!(
        s,
        "rosrun tf2_ros static_transform_publisher {x} {y} {z} {qx} {qy} {qz} {qw} {parent} {child}"
    );
    let _ = writeln!(s, "# ROS 2 (tf2_ros)");
    let _ = writeln!(
        s,
        "ros2 run tf2_ros static_transform_publisher --x {x} --y {y} --z {z} --qx {qx} --qy {qy} \
         --qz {qz} --qw {qw} --frame-id {parent} --child-frame-id {child}"
    );
    let _ = writeln!(
        s,
        "# clock: t_cam = t_dvl + {} s; DVL velocity scale {}",
        fmt_f(c.time_offset_s),
        fmt_f(c.velocity_scale)
    );
    s
}

fn matrix_rows(s: &mut String, indent: &str, m: &Matrix4<f64>) {
    for r in 0..4 {
        let _ = writeln!(
            s,
            "{indent}- [{}, {}, {}, {}]",
            fmt_f(m[(r, 0)]),
            fmt_f(m[(r, 1)]),
            fmt_f(m[(r, 2)]),
            fmt_f(m[(r, 3)])
        );
    }
}

/// A Kalibr-style camchain block for the DVL: for each camera `n`, `T_cam_dvl` (DVL points into
/// camera n) and `timeshift_cam_dvl`; then a `dvl0` entry with the scale and the DVL-to-cam0
/// transform. `t_cn_c0[n]` maps cam0 points into camera n (identity first); with poses from
/// elsewhere pass just the identity.
pub fn kalibr_dvl_block(c: &CalibrationParams, t_cn_c0: &[Matrix4<f64>]) -> String {
    let t_c0_dvl = c.t_cam_dvl.to_matrix();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# DVL extrinsics in the style of Kalibr's camchain-imucam.yaml:\n\
         # T_cam_dvl maps DVL-frame points into the camera frame; t_dvl = t_cam + timeshift_cam_dvl"
    );
    for (n, t_cn) in t_cn_c0.iter().enumerate() {
        let _ = writeln!(s, "cam{n}:");
        let _ = writeln!(s, "  T_cam_dvl:");
        matrix_rows(&mut s, "  ", &(t_cn * t_c0_dvl));
        let _ = writeln!(s, "  timeshift_cam_dvl: {}", fmt_f(-c.time_offset_s));
    }
    let _ = writeln!(s, "dvl0:");
    let _ = writeln!(s, "  T_dvl_cam0:");
    matrix_rows(&mut s, "  ", &c.t_cam_dvl.inverse().to_matrix());
    let _ = writeln!(s, "  velocity_scale: {}", fmt_f(c.velocity_scale));
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::Se3;
    use nalgebra::{Vector3, Vector6};

    fn params() -> CalibrationParams {
        CalibrationParams {
            t_cam_dvl: Se3::exp(&Vector6::new(0.1, -0.2, 0.3, 0.4, -0.5, 0.6)),
            time_offset_s: 0.125,
            velocity_scale: 1.01,
        }
    }

    #[test]
    fn ros_line_carries_the_pose_of_the_dvl_in_the_camera() {
        let c = params();
        let text = ros_static_transform(&c, &FrameNames::default());
        let line = text
            .lines()
            .find(|l| l.starts_with("rosrun"))
            .unwrap_or_default();
        let nums: Vec<f64> = line
            .split_whitespace()
            .skip(3)
            .take(7)
            .filter_map(|x| x.parse().ok())
            .collect();
        assert_eq!(nums.len(), 7, "{line}");
        let back = Se3::from_quaternion_xyzw(
            &[nums[3], nums[4], nums[5], nums[6]],
            Vector3::new(nums[0], nums[1], nums[2]),
        );
        let d = (back.inverse() * c.t_cam_dvl).log().norm();
        assert!(d < 1e-10, "round trip off by {d}");
        assert!(line.ends_with("cam0 dvl"));
        assert!(text.contains("--frame-id cam0 --child-frame-id dvl"));
    }

    #[test]
    fn kalibr_block_composes_the_stereo_extrinsics_and_negates_the_offset() {
        let c = params();
        let t_c1_c0 = Se3::new(nalgebra::Matrix3::identity(), Vector3::new(-0.12, 0.0, 0.0));
        let text = kalibr_dvl_block(&c, &[Matrix4::identity(), t_c1_c0.to_matrix()]);
        let v: serde_yaml::Value = serde_yaml::from_str(&text).expect("valid YAML");
        let m = |cam: &str| -> Matrix4<f64> {
            let rows = v[cam]["T_cam_dvl"]
                .as_sequence()
                .cloned()
                .unwrap_or_default();
            let mut m = Matrix4::zeros();
            for (r, row) in rows.iter().enumerate() {
                for (k, x) in row.as_sequence().into_iter().flatten().enumerate() {
                    m[(r, k)] = x.as_f64().unwrap_or(f64::NAN);
                }
            }
            m
        };
        let d0 = (m("cam0") - c.t_cam_dvl.to_matrix()).abs().max();
        let d1 = (m("cam1") - t_c1_c0.to_matrix() * c.t_cam_dvl.to_matrix())
            .abs()
            .max();
        assert!(d0 < 1e-11 && d1 < 1e-11, "{d0} {d1}");
        assert_eq!(v["cam1"]["timeshift_cam_dvl"].as_f64(), Some(-0.125));
        assert_eq!(v["dvl0"]["velocity_scale"].as_f64(), Some(1.01));
    }

    #[test]
    fn numbers_print_plainly() {
        assert_eq!(fmt_f(1.0), "1.0");
        assert_eq!(fmt_f(-0.0), "0.0");
        assert_eq!(fmt_f(0.125), "0.125");
        assert_eq!(fmt_f(-2.5e-13), "0.0");
    }
}
