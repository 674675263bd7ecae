//! The IMU's section of the DVL report, for a run that calibrated an IMU against the camera:
//! `T_cam_imu` (the rotation also as roll, pitch, yaw and axis-angle) and the IMU's clock
//! offset, each with its standard deviation and verdict, gravity, the biases at the start, the
//! noise factors, and the motion that observed (or failed to observe) each quantity.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::html::{estimate_table, put, quat, section, vec3};
use super::input::ImuReportInput;
use super::results::{verdict_cell, verdict_sentence};
use super::svg::escape;
use crate::calib::Verdict;

/// A noise factor from which the noise file is said to understate the IMU's noise.
const NOISE_UNDERSTATED: f64 = 1.5;

/// What observed a well-determined quantity, or what was missing (the verdict's reason says
/// it for a weak one).
fn observed_by(name: &str, v: &Verdict, by: &str) -> String {
    if v.ok {
        format!("{name}: observed by {by}.")
    } else {
        format!("{name}: not observed well; {}.", v.reason)
    }
}

/// The noise factors in words: the noise file's densities against what the residuals show.
fn noise_words(gyro: f64, accel: f64) -> String {
    let far: Vec<String> = [("gyro", gyro), ("accelerometer", accel)]
        .into_iter()
        .filter(|(_, f)| *f > NOISE_UNDERSTATED)
        .map(|(what, f)| format!("the {what}'s noise by a factor ~{f:.1}"))
        .collect();
    if far.is_empty() {
        format!(
            "The residuals agree with the noise file (factors {gyro:.2} for the gyro, \
             {accel:.2} for the accelerometer; 1 when the stated noise is right)."
        )
    } else {
        format!(
            "The noise file understates {}; the standard deviations were inflated by it (factors \
             {gyro:.2} for the gyro, {accel:.2} for the accelerometer).",
            far.join(" and ")
        )
    }
}

pub(super) fn imu_section(s: &mut String, imu: &ImuReportInput) {
    let (est, v) = (imu.estimate, imu.verdicts);
    let st = &est.state;
    let (s_rot, s_lever, s_off) = est.std();
    let s_rot_deg = s_rot.map(f64::to_degrees);
    section(s, "imu", "IMU");
    s.push_str(
        "<p>An IMU was calibrated against the same camera poses: T_cam_imu maps IMU-frame points \
         into the camera frame, and its clock runs t_cam = t_imu + offset.</p>\n",
    );
    let (gyro_factor, accel_factor) = est.noise_factor;
    let bias = st.bias.values.first();
    let rows = [
        (
            "rotation, quaternion_cam_imu_xyzw (std about IMU x, y, z)",
            quat(&st.t_cam_imu.quaternion_xyzw()),
            format!("{} deg", vec3(&s_rot_deg, 1.0, 3)),
            verdict_cell(&v.rotation, true),
        ),
        (
            "lever arm p_cam_imu (m, camera frame)",
            vec3(&st.t_cam_imu.trans, 1.0, 4),
            format!("{} mm", vec3(&s_lever, 1e3, 2)),
            verdict_cell(&v.lever_arm, true),
        ),
        (
            "clock offset imu_time_offset_s (t_cam = t_imu + offset)",
            format!("{:.5} s", st.time_offset_s),
            format!("{:.2} ms", 1e3 * s_off),
            verdict_cell(&v.time_offset, true),
        ),
        (
            "gravity in the world (board) frame (m/s^2)",
            vec3(&st.gravity_world(), 1.0, 3),
            String::new(),
            "",
        ),
        (
            "gyro bias at the start (rad/s)",
            bias.map_or("none".into(), |b| vec3(&b.gyro, 1.0, 5)),
            String::new(),
            "",
        ),
        (
            "accelerometer bias at the start (m/s^2)",
            bias.map_or("none".into(), |b| vec3(&b.accel, 1.0, 4)),
            String::new(),
            "",
        ),
        (
            "noise factors (gyro, accelerometer)",
            format!("{gyro_factor:.2}, {accel_factor:.2}"),
            String::new(),
            "",
        ),
    ];
    estimate_table(s, "imu-results", &rows);
    s.push_str("<ul class=\"verdicts\" id=\"imu-verdicts\">");
    for line in [
        verdict_sentence(
            "The IMU's rotation",
            &v.rotation,
            true,
            &format!("at most {:.3} deg about any axis", s_rot_deg.max()),
            None,
        ),
        verdict_sentence(
            "The IMU's lever arm",
            &v.lever_arm,
            true,
            &format!("at most {:.2} mm along any axis", 1e3 * s_lever.max()),
            None,
        ),
        verdict_sentence(
            "The IMU's clock offset",
            &v.time_offset,
            true,
            &format!("{:.2} ms", 1e3 * s_off),
            None,
        ),
    ] {
        put!(s, "<li>{}</li>", escape(&line));
    }
    s.push_str("</ul>\n");
    put!(
        s,
        "<p id=\"imu-noise\">{}</p>\n",
        escape(&noise_words(gyro_factor, accel_factor))
    );
    if let Some(p) = est.prior_shift {
        let (d_rot, d_lever, d_off) = est.data_std();
        put!(
            s,
            "<p id=\"imu-prior\">{}</p>\n",
            escape(&format!(
                "The standard deviations include the motion prior's share: a prior ten times \
                 looser moves the rotation by {} deg, the lever arm by {} mm and the clock \
                 offset by {:.3} ms, against standard deviations of {} deg, {} mm and {:.3} ms \
                 from the sensors' noise alone. Where the move is the larger, the motion, not \
                 the noise, limits what the recording says.",
                vec3(&p.rotation.map(f64::to_degrees), 1.0, 4),
                vec3(&p.lever_arm, 1e3, 2),
                1e3 * p.time_offset_s,
                vec3(&d_rot.map(f64::to_degrees), 1.0, 4),
                vec3(&d_lever, 1e3, 2),
                1e3 * d_off
            ))
        );
    }
    let m = &v.motion;
    let [a, b, c] = m.principal_rates;
    let r = |x: &Vector3<f64>| vec3(x, 1.0, 3);
    put!(
        s,
        "<p id=\"imu-motion\">The motion: the rig rotated at {:.3} rad/s RMS, {a:.3}, {b:.3} and \
         {c:.3} rad/s about the motion's principal axes ({} rad/s about the IMU's x, y, z), with \
         an angular acceleration of {:.3} rad/s^2 RMS; its rotation rate varied by {:.3} rad/s \
         RMS about its mean.</p>\n<ul class=\"verdicts\" id=\"imu-observed\">",
        m.rms_rate,
        escape(&r(&m.axis_rates)),
        m.rms_angular_accel,
        m.rate_variation
    );
    for line in [
        observed_by(
            "The rotation R_cam_imu",
            &v.rotation,
            "the rotation about more than one axis, which the gyro and the camera both measure",
        ),
        observed_by(
            "The lever arm p_cam_imu",
            &v.lever_arm,
            "the rotation rate and the angular acceleration, which move the IMU on a lever about \
             the camera",
        ),
        observed_by(
            "The clock offset",
            &v.time_offset,
            "the changes of the rotation rate, which the gyro sees at its own clock's times",
        ),
    ] {
        put!(s, "<li>{}</li>", escape(&line));
    }
    s.push_str("</ul>\n");
    s.push_str(&super::rotation::rotation_forms(
        "imu-rotation-forms",
        "R_cam_imu",
        "",
        &st.t_cam_imu.rot,
        None,
    ));
    let _ = writeln!(s, "</section>");
}
