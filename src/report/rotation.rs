//! The rotation `R_cam_dvl` in the forms people read: roll, pitch and yaw in the convention of
//! `--rotation-prior` and `rpy_cam_dvl_deg` (`R = Rz(yaw) Ry(pitch) Rx(roll)`, see
//! [`crate::io::calib_yaml::rotation_from_rpy_deg`]), and an axis with an angle.

use std::fmt::Write as _;

use nalgebra::{Matrix3, Vector3};

use super::svg::escape;
use crate::lie::so3;

/// Below this `cos(pitch)` roll and yaw turn about the same axis (gimbal lock): roll is set to
/// zero and yaw carries their combination.
const GIMBAL_COS: f64 = 1e-9;

/// `[roll, pitch, yaw]` in degrees with `R = Rz(yaw) Ry(pitch) Rx(roll)`; pitch in
/// `[-90, 90]`, roll and yaw in `(-180, 180]`. At gimbal lock (pitch of +-90 degrees) roll is 0.
pub(super) fn rpy_deg(r: &Matrix3<f64>) -> [f64; 3] {
    let cp = r[(0, 0)].hypot(r[(1, 0)]);
    let pitch = (-r[(2, 0)]).atan2(cp);
    let (roll, yaw) = if cp > GIMBAL_COS {
        (r[(2, 1)].atan2(r[(2, 2)]), r[(1, 0)].atan2(r[(0, 0)]))
    } else {
        // R = [[0, -sin yaw, .], [0, cos yaw, .], [-+1, 0, 0]] with roll 0, for either sign.
        (0.0, (-r[(0, 1)]).atan2(r[(1, 1)]))
    };
    [roll.to_degrees(), pitch.to_degrees(), yaw.to_degrees()]
}

/// The rotation's axis (a unit vector; `None` for no rotation) and angle in degrees, `[0, 180]`.
pub(super) fn axis_angle_deg(r: &Matrix3<f64>) -> (Option<Vector3<f64>>, f64) {
    let v = so3::log(r);
    let angle = v.norm();
    let axis = (angle > 1e-12).then(|| v / angle);
    (axis, angle.to_degrees())
}

/// Roll, pitch, yaw and axis-angle of `R_cam_dvl` as a small HTML table (`start`: where the
/// refinement started, shown beside).
pub(super) fn rotation_table(r: &Matrix3<f64>, start: &Matrix3<f64>) -> String {
    rotation_forms(
        "rotation-forms",
        "R_cam_dvl",
        ", as --rotation-prior and rpy_cam_dvl_deg take them",
        r,
        Some(start),
    )
}

/// Roll, pitch, yaw and axis-angle of the rotation `name` as a small HTML table with the id
/// `id` (`takes`: which options take the angles, after the convention; `start`: where the
/// refinement started, shown beside).
pub(super) fn rotation_forms(
    id: &str,
    name: &str,
    takes: &str,
    r: &Matrix3<f64>,
    start: Option<&Matrix3<f64>>,
) -> String {
    let mut s = String::new();
    let rpy = rpy_deg(r);
    let (axis, angle) = axis_angle_deg(r);
    let axis_words = |a: Option<Vector3<f64>>, angle: f64| match a {
        Some(a) => format!("{angle:.3} deg about [{:.4}, {:.4}, {:.4}]", a.x, a.y, a.z),
        None => "no rotation".to_owned(),
    };
    let (head, rpy0, axis0) = match start {
        Some(start) => {
            let rpy0 = rpy_deg(start);
            let (axis0, angle0) = axis_angle_deg(start);
            (
                " <span class=\"start\">(refinement start)</span>",
                format!(
                    "<br><span class=\"start\">([{:.3}, {:.3}, {:.3}])</span>",
                    rpy0[0], rpy0[1], rpy0[2]
                ),
                format!(
                    "<br><span class=\"start\">({})</span>",
                    escape(&axis_words(axis0, angle0))
                ),
            )
        }
        None => ("", String::new(), String::new()),
    };
    let _ = write!(
        s,
        "<table id=\"{id}\"><tr><th>{name} as</th><th>value{head}</th></tr>\
         <tr><td>roll, pitch, yaw (deg; R = Rz(yaw) Ry(pitch) Rx(roll){takes})</td>\
         <td class=\"num\">[{:.3}, {:.3}, {:.3}]{rpy0}</td></tr>",
        rpy[0], rpy[1], rpy[2]
    );
    let _ = writeln!(
        s,
        "<tr><td>axis and angle (the axis has the same coordinates in the camera and the {} \
         frame)</td><td class=\"num\">{}{axis0}</td></tr></table>",
        name.rsplit('_').next().unwrap_or("sensor").to_uppercase(),
        escape(&axis_words(axis, angle)),
    );
    if rpy[1].abs() > 85.0 {
        let _ = writeln!(
            s,
            "<p>The pitch is {:.1} deg, near 90: roll and yaw then turn about nearly the same \
             axis, so small changes of the rotation move them a lot; the quaternion and the \
             axis-angle form are the stable ones to compare.</p>",
            rpy[1]
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::calib_yaml::rotation_from_rpy_deg;

    fn close(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
        (a - b).abs().max()
    }

    #[test]
    fn rpy_round_trips_through_the_prior_convention() {
        let mut cases = Vec::new();
        for roll in [-179.0, -120.0, -30.5, 0.0, 12.25, 90.0, 150.0, 180.0] {
            for pitch in [-89.0, -45.0, -3.0, 0.0, 7.5, 60.0, 89.0] {
                for yaw in [-170.0, -90.0, 0.0, 33.3, 135.0] {
                    cases.push([roll, pitch, yaw]);
                }
            }
        }
        for rpy in cases {
            let r = rotation_from_rpy_deg(&rpy);
            let back = rpy_deg(&r);
            // Away from the lock the angles themselves come back (180 and -180 are one roll).
            let wrap = |d: f64| (d + 540.0).rem_euclid(360.0) - 180.0;
            for k in 0..3 {
                assert!(wrap(back[k] - rpy[k]).abs() < 1e-9, "{rpy:?} -> {back:?}");
            }
            assert!(close(&rotation_from_rpy_deg(&back), &r) < 1e-12);
        }
    }

    #[test]
    fn rpy_near_and_at_gimbal_lock_gives_the_same_rotation() {
        for pitch in [90.0, -90.0, 89.99999, -89.99999, 89.9999999999, 90.0 - 1e-7] {
            for (roll, yaw) in [(0.0, 0.0), (25.0, -40.0), (-170.0, 170.0), (90.0, 90.0)] {
                let r = rotation_from_rpy_deg(&[roll, pitch, yaw]);
                let back = rpy_deg(&r);
                assert!(back.iter().all(|x| x.is_finite()), "{back:?}");
                assert!(back[1].abs() <= 90.0);
                let err = close(&rotation_from_rpy_deg(&back), &r);
                assert!(
                    err < 1e-9,
                    "pitch {pitch}, roll {roll}, yaw {yaw}: {back:?}, {err:e}"
                );
            }
        }
        // Exactly at the lock roll is zero and yaw holds the combination.
        let back = rpy_deg(&rotation_from_rpy_deg(&[20.0, 90.0, 50.0]));
        assert_eq!(back[0], 0.0);
        assert!((back[1] - 90.0).abs() < 1e-9);
        assert!((back[2] - 30.0).abs() < 1e-9, "{back:?}");
    }

    #[test]
    fn axis_angle_of_known_rotations() {
        let r = rotation_from_rpy_deg(&[0.0, 0.0, 30.0]);
        let (axis, angle) = axis_angle_deg(&r);
        assert!((angle - 30.0).abs() < 1e-12);
        assert!((axis.unwrap() - Vector3::z()).norm() < 1e-12);
        let a = Vector3::new(1.0, -2.0, 0.5).normalize();
        let r = so3::exp(&(a * 170f64.to_radians()));
        let (axis, angle) = axis_angle_deg(&r);
        assert!((angle - 170.0).abs() < 1e-9);
        assert!((axis.unwrap() - a).norm() < 1e-9);
        assert_eq!(axis_angle_deg(&Matrix3::identity()), (None, 0.0));
    }

    #[test]
    fn table_names_the_convention_and_warns_near_the_lock() {
        let r = rotation_from_rpy_deg(&[10.0, -20.0, 30.0]);
        let t = rotation_table(&r, &Matrix3::identity());
        assert!(t.contains("[10.000, -20.000, 30.000]"), "{t}");
        assert!(t.contains("Rz(yaw) Ry(pitch) Rx(roll)"));
        assert!(t.contains("no rotation"));
        assert!(!t.contains("near 90"));
        let r = rotation_from_rpy_deg(&[10.0, 88.0, 30.0]);
        assert!(rotation_table(&r, &r).contains("near 90"));
    }
}
