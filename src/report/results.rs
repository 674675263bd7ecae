//! The results table of the DVL report: each estimate with its start, standard deviation and
//! verdict, the verdicts in sentences, the scale as a speed of sound, and the rotation in its
//! other forms.

use std::fmt::Write as _;

use super::guidance::{FrameLoss, specific_reason};
use super::html::{put, quat, section, vec3};
use super::input::ReportInput;
use super::svg::escape;
use super::words::estimated;
use crate::calib::{DeterminedBy, Verdict, WeakCause};

/// The verdict cell of the results table.
pub(super) fn verdict_cell(v: &Verdict, free: bool) -> &'static str {
    if !free {
        "<span class=\"fixed\">fixed (from --init)</span>"
    } else if v.by == DeterminedBy::Prior && v.cause == Some(WeakCause::UserPrior) {
        "<span class=\"weak\">prior (mainly the one given)</span>"
    } else if v.by == DeterminedBy::Prior {
        "<span class=\"weak\">prior (not measured)</span>"
    } else if v.ok {
        "<span class=\"ok\">well determined</span>"
    } else {
        "<span class=\"weak\">weakly observable</span>"
    }
}

/// One sentence on one parameter; `spread` describes its standard deviation (weak verdicts
/// already quote it in their reason), `loss` the frames the image pipeline lost.
pub(super) fn verdict_sentence(
    name: &str,
    v: &Verdict,
    free: bool,
    spread: &str,
    loss: Option<&FrameLoss>,
) -> String {
    let reason = specific_reason(v, loss);
    if !free {
        format!(
            "{name} was not estimated: it stays at the value given with --init and has no \
             standard deviation."
        )
    } else if v.by == DeterminedBy::Prior {
        format!(
            "{name} comes from its prior rather than the data: {}.",
            reason.trim_end_matches('.')
        )
    } else if v.ok {
        format!("{name} is well determined: its standard deviation is {spread}.")
    } else {
        format!(
            "{name} is weakly observable: {}. Do not rely on this value without a recording that \
             excites it better.",
            reason.trim_end_matches('.')
        )
    }
}

pub(super) fn results(s: &mut String, input: &ReportInput) {
    let o = input.outcome;
    let sound_speed = input.dvl_stats.and_then(|st| st.sound_speed_mps);
    let loss = FrameLoss::of(input.frames);
    let loss = loss.as_ref();
    section(s, "results", "Results");
    let c = o.params;
    let c0 = o.start;
    let st = &o.std;
    let ext = estimated(&o.method, true);
    let tim = estimated(&o.method, false);
    s.push_str(
        "<table><tr><th>quantity</th><th>estimate <span class=\"start\">(refinement start)</span>\
         </th><th>standard deviation</th><th>verdict</th></tr>\n",
    );
    let rows = [
        (
            "rotation, quaternion_cam_dvl_xyzw (std about DVL x, y, z)",
            quat(&c.t_cam_dvl.quaternion_xyzw()),
            format!("{} deg", vec3(&st.rotation_deg, 1.0, 3)),
            quat(&c0.t_cam_dvl.quaternion_xyzw()),
            verdict_cell(&o.verdicts.rotation, ext),
        ),
        (
            "lever arm p_cam_dvl (m, camera frame)",
            vec3(&o.params.lever_arm_cam_m(), 1.0, 4),
            format!(
                "{} mm{}",
                vec3(&st.lever_arm_m, 1e3, 2),
                if o.verdicts.lever_arm.by == DeterminedBy::Prior && ext {
                    " (the prior's)"
                } else {
                    ""
                }
            ),
            vec3(&o.start.lever_arm_cam_m(), 1.0, 4),
            verdict_cell(&o.verdicts.lever_arm, ext),
        ),
        (
            "clock offset time_offset_s (t_cam = t_dvl + offset)",
            format!("{:.5} s", o.params.time_offset_s),
            format!("{:.2} ms", 1e3 * st.time_offset_s),
            format!("{:.5} s", o.start.time_offset_s),
            verdict_cell(&o.verdicts.time_offset, tim),
        ),
        (
            "velocity scale",
            format!("{:.5}", o.params.velocity_scale),
            format!("{:.5}", st.velocity_scale),
            format!("{:.5}", o.start.velocity_scale),
            verdict_cell(&o.verdicts.velocity_scale, tim),
        ),
    ];
    for (name, est, sd, start, verdict) in rows {
        // A parameter the method held has no standard deviation.
        let sd = if verdict.contains("class=\"fixed\"") {
            "none (held)".to_owned()
        } else {
            sd
        };
        put!(
            s,
            "<tr><td>{}</td><td class=\"num\">{}<br><span class=\"start\">({})</span></td>\
             <td class=\"num\">{}</td><td>{verdict}</td></tr>\n",
            escape(name),
            escape(&est),
            escape(&start),
            escape(&sd)
        );
    }
    s.push_str("</table>\n<ul class=\"verdicts\">");
    let sentences = [
        verdict_sentence(
            "The rotation",
            &o.verdicts.rotation,
            ext,
            &format!("at most {:.3} deg about any axis", st.rotation_deg.max()),
            loss,
        ),
        verdict_sentence(
            "The lever arm",
            &o.verdicts.lever_arm,
            ext,
            &format!(
                "at most {:.2} mm along any axis",
                1e3 * st.lever_arm_m.max()
            ),
            loss,
        ),
        verdict_sentence(
            "The clock offset",
            &o.verdicts.time_offset,
            tim,
            &format!("{:.2} ms", 1e3 * st.time_offset_s),
            loss,
        ),
        verdict_sentence(
            "The velocity scale",
            &o.verdicts.velocity_scale,
            tim,
            &format!(
                "{:.5} ({:.2}%)",
                st.velocity_scale,
                100.0 * st.velocity_scale
            ),
            loss,
        ),
    ];
    for line in sentences {
        put!(s, "<li>{}</li>", escape(&line));
    }
    s.push_str("</ul>\n");
    if tim {
        put!(
            s,
            "<p id=\"sound-speed\">Velocity scale as a speed of sound: {}.</p>\n",
            escape(&super::words::sound_speed_words(
                c.velocity_scale,
                st.velocity_scale,
                sound_speed
            ))
        );
    }
    s.push_str(&super::rotation::rotation_table(
        &c.t_cam_dvl.rot,
        &c0.t_cam_dvl.rot,
    ));
    let r = c.t_cam_dvl.rot;
    put!(
        s,
        "<p>R_cam_dvl (rotates DVL-frame vectors into the camera frame):</p><pre>",
    );
    for i in 0..3 {
        put!(
            s,
            "[{:+.6}, {:+.6}, {:+.6}]\n",
            r[(i, 0)],
            r[(i, 1)],
            r[(i, 2)]
        );
    }
    s.push_str("</pre></section>\n");
}
