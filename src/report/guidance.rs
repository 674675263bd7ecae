//! What to do next about a run: concrete steps derived from its verdicts, its checks and the
//! frames the image pipeline could not use, most important first; and the specific cause of a
//! weak parameter when the recording's frames explain it.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::html::put;
use super::input::{FrameDrop, FrameStat, ReportInput, posed_edge_width_px};
use super::svg::escape;
use super::words::estimated;
use crate::calib::{DeterminedBy, Verdict, WeakCause};

/// A share of unposed frames from which they are named as the cause of weak parameters.
const LOSS_SHARE: f64 = 0.2;

/// A share of the valid DVL reports outside the camera's time span (or in its gaps) from which
/// recording the camera longer is a step.
const OUTSIDE_SHARE: f64 = 0.25;

/// The DVL axis least rotated about counts as the one to rotate about when its RMS rate is
/// below this fraction of the most rotated axis's; otherwise all three are named.
const AXIS_CONTRAST: f64 = 0.5;

/// The kind of a next step, in the order the box lists them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum StepKind {
    /// The result failed its sanity checks.
    ResultFailed,
    /// Frames were dropped as blurred.
    SharperImages,
    /// Frames were dropped for missing tags or corners: the board was out of view or too far.
    BoardInView,
    /// The clock offset drifts over the recording.
    ClockDrift,
    /// The lever arm is held at the broad default prior: measure it.
    MeasureLeverArm,
    /// The motion rotated too little about some DVL axis.
    RotateMore,
    /// The motion moved along too few directions for the rotation.
    MoreDirections,
    /// The speed changed too little for the clock offset.
    VarySpeed,
    /// The motion was too small for the velocity scale.
    MoreMotion,
    /// Many DVL reports fall outside the camera's time span or in its gaps.
    LongerCameraRecording,
}

/// One step to take, with the problem it answers.
#[derive(Clone, Debug, PartialEq)]
pub struct NextStep {
    /// What kind of step it is.
    pub kind: StepKind,
    /// What is wrong, in words.
    pub problem: String,
    /// What to do, in words.
    pub action: String,
}

/// The frames the image pipeline could not pose, by cause.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct FrameLoss {
    pub frames: usize,
    pub posed: usize,
    pub blurred: usize,
    pub no_tags: usize,
    pub too_few_corners: usize,
    pub no_solution: usize,
    pub unreadable: usize,
    /// Median edge width of the posed frames and of the blurred ones, px.
    pub posed_edge_px: Option<f64>,
    pub blurred_edge_px: Option<f64>,
    /// Frames and poses per second over the frames' span.
    pub frame_rate_hz: Option<f64>,
    pub pose_rate_hz: Option<f64>,
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.retain(|x| x.is_finite());
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

impl FrameLoss {
    /// `None` for a run without image frames.
    pub fn of(frames: Option<&[FrameStat]>) -> Option<FrameLoss> {
        let frames = frames.filter(|f| !f.is_empty())?;
        let mut l = FrameLoss {
            frames: frames.len(),
            posed_edge_px: posed_edge_width_px(frames),
            ..FrameLoss::default()
        };
        for f in frames {
            match f.dropped {
                None if f.posed => l.posed += 1,
                None | Some(FrameDrop::TooFewCorners) => l.too_few_corners += 1,
                Some(FrameDrop::Blurred) => l.blurred += 1,
                Some(FrameDrop::NoTags) => l.no_tags += 1,
                Some(FrameDrop::NoSolution) => l.no_solution += 1,
                Some(FrameDrop::Unreadable) => l.unreadable += 1,
            }
        }
        l.blurred_edge_px = median(
            frames
                .iter()
                .filter(|f| f.dropped == Some(FrameDrop::Blurred))
                .filter_map(|f| f.edge_width_px)
                .collect(),
        );
        let (lo, hi) = frames
            .iter()
            .map(|f| f.t)
            .filter(|t| t.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
                (a.min(t), b.max(t))
            });
        if hi > lo {
            l.frame_rate_hz = Some((l.frames - 1) as f64 / (hi - lo));
            l.pose_rate_hz = Some(l.posed as f64 / (hi - lo));
        }
        Some(l)
    }

    pub fn dropped(&self) -> usize {
        self.frames - self.posed
    }

    /// Enough frames lost to explain weak parameters.
    pub fn significant(&self) -> bool {
        self.dropped() > 0 && self.dropped() as f64 >= LOSS_SHARE * self.frames as f64
    }

    /// What became of the unposed frames, in words: "209 of 251 frames got no pose (209
    /// blurred: ...), leaving poses at 1.7 Hz of 10.0 Hz".
    pub fn words(&self) -> String {
        let mut parts = Vec::new();
        if self.blurred > 0 {
            let mut w = format!("{} blurred", self.blurred);
            if let Some(b) = self.blurred_edge_px {
                let _ = write!(w, ": their sharpest edges are {b:.1} px wide");
                if let Some(p) = self.posed_edge_px {
                    let _ = write!(w, " against {p:.1} px in the posed frames");
                }
            }
            parts.push(w);
        }
        for (n, what) in [
            (self.no_tags, "without any tag found"),
            (self.too_few_corners, "with too few of the board's corners"),
            (self.no_solution, "without a pose solution"),
            (self.unreadable, "without a usable image"),
        ] {
            if n > 0 {
                parts.push(format!("{n} {what}"));
            }
        }
        let mut s = format!(
            "{} of {} frames got no pose ({})",
            self.dropped(),
            self.frames,
            parts.join("; ")
        );
        if let (Some(p), Some(f)) = (self.pose_rate_hz, self.frame_rate_hz) {
            let _ = write!(s, ", leaving poses at {p:.1} Hz of {f:.1} Hz");
        }
        s
    }
}

/// Whether a weakness of the data can come from too few or too sparse poses.
fn explained_by_frames(cause: Option<WeakCause>) -> bool {
    matches!(
        cause,
        Some(
            WeakCause::RotationRateNoise
                | WeakCause::LittleRotation
                | WeakCause::FewRotationAxes
                | WeakCause::FewDirections
                | WeakCause::LittleSpeedChange
                | WeakCause::LittleMotion
        )
    )
}

/// The reason of a weak verdict, led by the frames the image pipeline lost when they explain
/// it.
pub(super) fn specific_reason(v: &Verdict, loss: Option<&FrameLoss>) -> String {
    match loss {
        Some(l) if l.significant() && explained_by_frames(v.cause) => {
            format!("{}, so {}", l.words(), v.reason)
        }
        _ => v.reason.clone(),
    }
}

/// Whether the lever arm sits at the broad default prior (not a prior the user gave).
fn lever_at_default_prior(v: &Verdict) -> bool {
    v.by == DeterminedBy::Prior && v.cause != Some(WeakCause::UserPrior)
}

/// The DVL's axis names.
const AXES: [&str; 3] = ["x", "y", "z"];

/// RMS angular rate of the fitted trajectory about each DVL axis, rad/s.
fn rates_about_dvl_axes(input: &ReportInput) -> Option<Vector3<f64>> {
    let o = input.outcome;
    let (a, b) = o.fitted.span();
    let n = 400usize;
    let r = o.params.r_dvl_cam();
    let mut sum = Vector3::zeros();
    let mut k = 0usize;
    for i in 0..n {
        let t = a + (b - a) * i as f64 / (n - 1) as f64;
        if let Ok(q) = o.fitted.state(t) {
            let w = r * q.twist.fixed_rows::<3>(3).into_owned();
            sum += w.component_mul(&w);
            k += 1;
        }
    }
    (k > 0).then(|| (sum / k as f64).map(f64::sqrt))
}

/// The rotation step: about the least rotated DVL axis, or all three when none stands out.
fn rotate_more(input: &ReportInput, problem: String) -> NextStep {
    let action = match rates_about_dvl_axes(input) {
        Some(w) => {
            let (lo, hi) = (w.imin(), w.imax());
            if w[lo] < AXIS_CONTRAST * w[hi] {
                format!(
                    "Rotate more about the DVL's {} axis: {:.3} rad/s RMS about it, against {:.3} \
                     rad/s about its {} axis (rotations about several axes separate the lever arm \
                     from the velocity).",
                    AXES[lo], w[lo], w[hi], AXES[hi]
                )
            } else {
                format!(
                    "Rotate more strongly about all three of the DVL's axes (RMS rates about x, \
                     y, z: {:.3}, {:.3}, {:.3} rad/s).",
                    w.x, w.y, w.z
                )
            }
        }
        None => "Rotate more strongly about several axes.".to_owned(),
    };
    NextStep {
        kind: StepKind::RotateMore,
        problem,
        action,
    }
}

/// The steps for a run, most important first; empty when all is well.
pub fn next_steps(input: &ReportInput) -> Vec<NextStep> {
    let o = input.outcome;
    let v = &o.verdicts;
    let ext = estimated(&o.method, true);
    let tim = estimated(&o.method, false);
    let loss = FrameLoss::of(input.frames);
    let mut steps = Vec::new();
    if let crate::calib::Status::Failed(reasons) = &o.status {
        steps.push(NextStep {
            kind: StepKind::ResultFailed,
            problem: format!(
                "the result failed its checks: {}",
                reasons.first().map_or("", String::as_str)
            ),
            action: match loss.as_ref().filter(|l| l.significant()) {
                Some(l) => format!(
                    "Do not use this result. The likely cause is the frames the image pipeline \
                     lost ({}): poses this sparse cannot follow the motion; remove that cause \
                     (the next steps), then calibrate again.",
                    l.words()
                ),
                None => "Do not use this result: remove the cause named in the red box above, \
                         then calibrate again."
                    .to_owned(),
            },
        });
    }
    if let Some(l) = loss.as_ref().filter(|l| l.dropped() > 0) {
        if l.blurred > 0 && l.blurred as f64 >= 0.5 * LOSS_SHARE * l.frames as f64 {
            steps.push(NextStep {
                kind: StepKind::SharperImages,
                problem: format!(
                    "frames were dropped as blurred: {} of {} frames got no pose for blur",
                    l.blurred, l.frames
                ),
                action: format!(
                    "Record with slower motion or more light (a shorter exposure) so that the \
                     board stays sharp: {}.",
                    l.words()
                ),
            });
        }
        let unseen = l.no_tags + l.too_few_corners;
        if unseen > 0 && unseen as f64 >= LOSS_SHARE * l.frames as f64 {
            steps.push(NextStep {
                kind: StepKind::BoardInView,
                problem: format!(
                    "{unseen} of {} frames showed too little of the board for a pose",
                    l.frames
                ),
                action: format!(
                    "Keep the whole board in view and near enough for its tags to be found: {}.",
                    l.words()
                ),
            });
        }
    }
    let lever_reason = specific_reason(&v.lever_arm, loss.as_ref());
    if ext && lever_at_default_prior(&v.lever_arm) {
        let mut problem =
            "the lever arm is held at its prior (zero): this recording does not measure it"
                .to_owned();
        if let Some(l) = loss.as_ref().filter(|l| l.significant()) {
            let _ = write!(problem, " ({})", l.words());
        }
        steps.push(NextStep {
            kind: StepKind::MeasureLeverArm,
            problem,
            action: "Re-measure the lever arm on the vehicle and give it with --lever-arm-prior \
                     (x,y,z in metres in the camera frame, with its uncertainty)."
                .to_owned(),
        });
    }
    let lever_motion = matches!(
        v.lever_arm.cause,
        Some(WeakCause::RotationRateNoise | WeakCause::LittleRotation | WeakCause::FewRotationAxes)
    );
    if ext && !v.lever_arm.ok && lever_motion {
        steps.push(rotate_more(
            input,
            if lever_at_default_prior(&v.lever_arm) {
                "the motion does not observe the lever arm".to_owned()
            } else {
                format!("the lever arm is weakly observable: {lever_reason}")
            },
        ));
    }
    if ext && !v.rotation.ok && v.rotation.cause == Some(WeakCause::FewDirections) {
        let k = o.std.rotation_deg.imax();
        let others: Vec<&str> = (0..3).filter(|&j| j != k).map(|j| AXES[j]).collect();
        steps.push(NextStep {
            kind: StepKind::MoreDirections,
            problem: format!(
                "the rotation is weakly observable: {}",
                specific_reason(&v.rotation, loss.as_ref())
            ),
            action: format!(
                "Move along more directions: the rotation about the DVL's {} axis is the least \
                 determined ({:.3} deg); move more along its {} and {} axes.",
                AXES[k], o.std.rotation_deg[k], others[0], others[1]
            ),
        });
    }
    let drifts = o.drift.as_ref().is_some_and(|d| d.significant);
    // A drifting clock is what leaves the offset weak then, not the speed.
    if tim && !v.time_offset.ok && !drifts && explained_by_frames(v.time_offset.cause) {
        steps.push(NextStep {
            kind: StepKind::VarySpeed,
            problem: format!(
                "the clock offset is weakly observable: {}",
                specific_reason(&v.time_offset, loss.as_ref())
            ),
            action: "Vary the speed: speed up, slow down and reverse during the recording, and \
                     start it with a calm stretch."
                .to_owned(),
        });
    }
    if tim && !v.velocity_scale.ok && explained_by_frames(v.velocity_scale.cause) {
        steps.push(NextStep {
            kind: StepKind::MoreMotion,
            problem: format!(
                "the velocity scale is weakly observable: {}",
                specific_reason(&v.velocity_scale, loss.as_ref())
            ),
            action: "Move faster and for longer: the scale is measured against the speed."
                .to_owned(),
        });
    }
    if let Some(d) = o.drift.as_ref().filter(|d| d.significant) {
        let problem = format!(
            "the clock drifts: the clock offset is {:.4} s in the first third of the recording \
             and {:.4} s in the last (about {:+.0} ppm)",
            d.first_third_s, d.last_third_s, d.drift_ppm
        );
        let action = if o.clock_drift.is_some() {
            "The drift is not constant even with --clock-drift: synchronise the clocks (NTP or \
             PTP), or calibrate shorter recordings."
        } else {
            "The clock drifts: calibrate again with --clock-drift (or synchronise the clocks)."
        };
        steps.push(NextStep {
            kind: StepKind::ClockDrift,
            problem,
            action: action.to_owned(),
        });
    }
    let c = &o.counts;
    let valid = c.dvl_samples.saturating_sub(c.dvl_invalid);
    let outside = c.dvl_outside_span + c.dvl_in_pose_gaps;
    if valid > 0 && outside as f64 >= OUTSIDE_SHARE * valid as f64 {
        steps.push(NextStep {
            kind: StepKind::LongerCameraRecording,
            problem: format!(
                "{outside} of {valid} valid DVL reports fall outside the camera poses' time span \
                 ({}) or in gaps between poses ({})",
                c.dvl_outside_span, c.dvl_in_pose_gaps
            ),
            action: "Record the camera for the whole DVL log without gaps (or give the matching \
                     stretch of the DVL log): the reports outside were not used."
                .to_owned(),
        });
    }
    steps.sort_by_key(|s| s.kind);
    steps
}

/// The box at the top of the report; `warnings` is the number of warnings the page lists.
pub(super) fn next_steps_section(s: &mut String, steps: &[NextStep], warnings: usize) {
    s.push_str("<section id=\"next-steps\" class=\"next\"><h2>What to do next</h2>");
    if steps.is_empty() && warnings == 0 {
        s.push_str(
            "<p id=\"nothing-to-do\">Nothing to do: every check passed and every estimated \
             quantity is well determined.</p>",
        );
    } else if steps.is_empty() {
        put!(
            s,
            "<p id=\"nothing-to-do\">No step is needed for the estimates; read the {warnings} \
             warning{} below.</p>",
            if warnings == 1 { "" } else { "s" }
        );
    } else {
        s.push_str("<ol id=\"next-steps-list\">");
        for st in steps {
            put!(
                s,
                "<li data-step=\"{:?}\"><strong>{}</strong> <span class=\"why\">({})</span></li>",
                st.kind,
                escape(&st.action),
                escape(&st.problem)
            );
        }
        s.push_str("</ol>");
    }
    s.push_str("</section>\n");
}
