//! The report of the two calibrations with an IMU that lack one of the DVL report's inputs:
//! camera + IMU (no DVL log) and DVL + IMU (no camera). One self-contained page like the DVL
//! report: what was calibrated and whether it can be trusted, each estimate with its standard
//! deviation and verdict in words, the IMU's gravity, biases and noise factors, the warnings and
//! the result file. The DVL report's plots need a camera trajectory and DVL residuals against
//! it, which these modes do not have; they are not drawn.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::html::{estimate_table, page_start, put, quat, section, vec3};
use super::input::ImuReportInput;
use super::results::{verdict_cell, verdict_sentence};
use super::summary::warnings;
use super::svg::escape;
use crate::calib::Verdict;
use crate::calib::imu::dvl::DvlImuEstimate;

/// The sections of a camera + IMU report, in page order.
pub const CAMERA_IMU_SECTION_IDS: &[&str] = &["summary", "imu", "warnings", "result-file"];

/// The sections of a DVL + IMU report, in page order.
pub const DVL_IMU_SECTION_IDS: &[&str] = &["summary", "dvl-imu", "warnings", "result-file"];

/// Which calibration the report is of.
#[derive(Clone, Copy, Debug)]
pub enum ImuOnlyKind<'a> {
    /// The IMU against the camera (no DVL log).
    CameraImu(ImuReportInput<'a>),
    /// The DVL against the IMU (no camera): the estimate and its verdicts on the rotation, the
    /// lever arm, the clock offset and the scale.
    DvlImu {
        /// The estimate (`params.t_cam_dvl` holds `T_imu_dvl`).
        estimate: &'a DvlImuEstimate,
        /// Rotation, lever arm, clock offset, scale.
        verdicts: &'a [Verdict; 4],
    },
}

/// What the report is made from.
#[derive(Clone, Copy, Debug)]
pub struct ImuOnlyReportInput<'a> {
    /// Page title.
    pub title: &'a str,
    /// The mode in words (as the result file's notes give it).
    pub mode: &'a str,
    /// The dataset (folder, bag or files) in words.
    pub dataset: &'a str,
    /// The calibration.
    pub kind: ImuOnlyKind<'a>,
    /// Why the calibration failed (empty when it passed its checks).
    pub failure: &'a [String],
    /// The run's warnings.
    pub warnings: &'a [String],
    /// The counts of data read and used, one line each.
    pub counts: &'a [String],
    /// The result file's name and text.
    pub result: Option<(&'a str, &'a str)>,
    /// Seconds the calibration took.
    pub elapsed_s: f64,
}

/// Renders the report as one HTML document.
pub fn render_imu_only_html(input: &ImuOnlyReportInput) -> String {
    let mut s = String::with_capacity(32 * 1024);
    page_start(&mut s, input.title);
    summary(&mut s, input);
    match input.kind {
        ImuOnlyKind::CameraImu(imu) => super::imu::imu_section(&mut s, &imu),
        ImuOnlyKind::DvlImu { estimate, verdicts } => dvl_imu_section(&mut s, estimate, verdicts),
    }
    warnings(&mut s, input.warnings);
    section(&mut s, "result-file", "Result file");
    match input.result {
        Some((name, text)) => put!(
            s,
            "<details open><summary>{}</summary><pre>{}</pre></details>",
            escape(name),
            escape(text)
        ),
        None => s.push_str("<p>No result file was written with this report.</p>"),
    }
    s.push_str("</section>\n</body></html>\n");
    s
}

/// The calibration's verdicts with the quantities' names, rotation first.
fn named_verdicts<'a>(kind: &ImuOnlyKind<'a>) -> Vec<(&'static str, &'a Verdict)> {
    match *kind {
        ImuOnlyKind::CameraImu(imu) => {
            let v = imu.verdicts;
            vec![
                ("rotation", &v.rotation),
                ("lever arm", &v.lever_arm),
                ("clock offset", &v.time_offset),
            ]
        }
        ImuOnlyKind::DvlImu { verdicts, .. } => {
            let names = ["rotation", "lever arm", "clock offset", "velocity scale"];
            names.into_iter().zip(verdicts.iter()).collect()
        }
    }
}

fn summary(s: &mut String, input: &ImuOnlyReportInput) {
    section(s, "summary", "Summary");
    let what = match input.kind {
        ImuOnlyKind::CameraImu(_) => {
            "the IMU against the camera (T_cam_imu and the IMU's clock offset)"
        }
        ImuOnlyKind::DvlImu { .. } => {
            "the DVL against the IMU (T_imu_dvl, the clock offset and the velocity scale)"
        }
    };
    put!(
        s,
        "<p>Dataset {}: {} calibrated {} in {:.2} s.</p>\n",
        escape(input.dataset),
        escape(input.mode),
        escape(what),
        input.elapsed_s
    );
    let weak: Vec<&str> = named_verdicts(&input.kind)
        .into_iter()
        .filter(|(_, v)| !v.ok)
        .map(|(n, _)| n)
        .collect();
    let verdict = if !input.failure.is_empty() {
        format!(
            "The calibration FAILED its checks and must not be used: {}.",
            input.failure.join("; ")
        )
    } else if weak.is_empty() {
        "Every estimated quantity is well determined by this recording.".to_owned()
    } else {
        format!(
            "The calibration passed its checks, but the recording determined the {} poorly: \
             see the verdicts below before using {}.",
            weak.join(", "),
            if weak.len() == 1 { "it" } else { "them" }
        )
    };
    let class = if input.failure.is_empty() && weak.is_empty() {
        "ok"
    } else {
        "weak"
    };
    put!(
        s,
        "<p id=\"verdict\" class=\"{class}\">{}</p>\n",
        escape(&verdict)
    );
    if !input.counts.is_empty() {
        s.push_str("<ul id=\"counts\">");
        for line in input.counts {
            put!(s, "<li>{}</li>", escape(line));
        }
        s.push_str("</ul>\n");
    }
    s.push_str("</section>\n");
}

fn dvl_imu_section(s: &mut String, e: &DvlImuEstimate, v: &[Verdict; 4]) {
    section(s, "dvl-imu", "The DVL in the IMU frame");
    s.push_str(
        "<p>T_imu_dvl maps DVL-frame points into the IMU frame; the DVL's clock runs \
         t_imu = t_dvl + offset; the DVL's velocities are the true ones times the scale. The \
         trajectory is the IMU's own, integrated from its samples with the gyro and \
         accelerometer biases and the direction of gravity estimated alongside.</p>\n",
    );
    let sd = e.std();
    let rot_deg = Vector3::new(sd[0], sd[1], sd[2]).map(f64::to_degrees);
    let lever = Vector3::new(sd[3], sd[4], sd[5]);
    let p = &e.params;
    let st = &e.imu;
    let bias = st.bias.values.first();
    let (gyro_factor, accel_factor, dvl_factor) = e.noise_factor;
    let rows = [
        (
            "rotation, quaternion_imu_dvl_xyzw (std about DVL x, y, z)",
            quat(&p.t_cam_dvl.quaternion_xyzw()),
            format!("{} deg", vec3(&rot_deg, 1.0, 3)),
            verdict_cell(&v[0], true),
        ),
        (
            "lever arm p_imu_dvl (m, IMU frame)",
            vec3(&p.t_cam_dvl.trans, 1.0, 4),
            format!("{} mm", vec3(&lever, 1e3, 2)),
            verdict_cell(&v[1], true),
        ),
        (
            "clock offset time_offset_s (t_imu = t_dvl + offset)",
            format!("{:.5} s", p.time_offset_s),
            format!("{:.2} ms", 1e3 * sd[7]),
            verdict_cell(&v[2], true),
        ),
        (
            "velocity scale",
            format!("{:.5}", p.velocity_scale),
            format!("{:.5}", sd[6]),
            verdict_cell(&v[3], true),
        ),
        (
            "gravity in the world frame (m/s^2; the IMU at the start)",
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
            "noise factors (gyro, accelerometer, DVL)",
            format!("{gyro_factor:.2}, {accel_factor:.2}, {dvl_factor:.2}"),
            String::new(),
            "",
        ),
    ];
    estimate_table(s, "dvl-imu-results", &rows);
    s.push_str("<ul class=\"verdicts\" id=\"dvl-imu-verdicts\">");
    for line in [
        verdict_sentence(
            "The rotation",
            &v[0],
            true,
            &format!("at most {:.3} deg about any axis", rot_deg.max()),
            None,
        ),
        verdict_sentence(
            "The lever arm",
            &v[1],
            true,
            &format!("at most {:.2} mm along any axis", 1e3 * lever.max()),
            None,
        ),
        verdict_sentence(
            "The clock offset",
            &v[2],
            true,
            &format!("{:.2} ms", 1e3 * sd[7]),
            None,
        ),
        verdict_sentence(
            "The velocity scale",
            &v[3],
            true,
            &format!("{:.5}", sd[6]),
            None,
        ),
    ] {
        put!(s, "<li>{}</li>", escape(&line));
    }
    s.push_str("</ul>\n");
    if let Some(shift) = e.prior_shift {
        let d = e.data_std();
        let v3 = |x: &[f64]| Vector3::new(x[0], x[1], x[2]);
        put!(
            s,
            "<p id=\"dvl-imu-prior\">{}</p>\n",
            escape(&format!(
                "The standard deviations include the motion prior's share: a prior ten times \
                 looser moves the rotation by {} deg, the lever arm by {} mm, the clock offset \
                 by {:.3} ms and the scale by {:.5}, against standard deviations of {} deg, {} \
                 mm, {:.3} ms and {:.5} from the sensors' noise alone.",
                vec3(&v3(&shift.as_slice()[0..3]).map(f64::to_degrees), 1.0, 4),
                vec3(&v3(&shift.as_slice()[3..6]), 1e3, 2),
                1e3 * shift[7],
                shift[6],
                vec3(&v3(&d[0..3]).map(f64::to_degrees), 1.0, 4),
                vec3(&v3(&d[3..6]), 1e3, 2),
                1e3 * d[7],
                d[6]
            ))
        );
    }
    put!(
        s,
        "<p id=\"dvl-imu-fit\">The solution took {} Gauss-Newton iterations{}; {} of {} DVL \
         reports and {} of {} IMU bins lie inside the span both sensors cover and were used.</p>\n",
        e.iterations,
        if e.converged {
            ""
        } else {
            " and did not converge"
        },
        e.dvl_used,
        e.dvl_total,
        e.bins_used,
        e.bins_total
    );
    s.push_str(&super::rotation::rotation_forms(
        "dvl-imu-rotation-forms",
        "R_imu_dvl",
        "",
        &p.t_cam_dvl.rot,
        None,
    ));
    let _ = writeln!(s, "</section>");
}
