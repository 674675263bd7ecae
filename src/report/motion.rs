//! The motion section of the DVL report: the camera's angular velocity with the calm samples of
//! the clock-offset search, and the lever-arm term against the speed.

use super::data::Derived;
use super::guidance::{FrameLoss, specific_reason};
use super::html::{AFTER, AXES, AXIS_COLORS, LEVER, WIDE, figure, percent, section};
use super::svg::{Plot, Series};
use super::words::estimated;
use crate::calib::offset::OffsetMethod;
use crate::calib::{CalibrationOutcome, DeterminedBy};

pub(super) fn motion(
    s: &mut String,
    o: &CalibrationOutcome,
    d: &Derived,
    loss: Option<&FrameLoss>,
) {
    section(s, "motion", "Motion: rotation and lever-arm excitation");
    let norm: Vec<(f64, f64)> = d.angular.iter().map(|(t, w)| (*t, w.norm())).collect();
    let mut plot = Plot::new(
        "angular-velocity",
        "Angular velocity of the camera (fitted trajectory)",
        "camera time (s)",
        "rad/s",
    )
    .size(WIDE, 280.0);
    if !d.calm_spans.is_empty() {
        plot = plot.spans("calm samples (clock offset)", d.calm_spans.clone());
    }
    for (k, axis) in AXES.iter().enumerate() {
        let comp: Vec<(f64, f64)> = d.angular.iter().map(|(t, w)| (*t, w[k])).collect();
        plot = plot.series(Series::line(&format!("w_{axis}"), AXIS_COLORS[k], comp).size(1.0));
    }
    plot = plot.series(Series::line("|w|", "#111", norm).size(1.6));
    let calm_words = match &o.init {
        Some(i) => format!(
            "Shaded: the {} DVL samples slow enough in rotation to be used for the clock-offset \
             search ({}).",
            i.offset.calm.len(),
            match i.offset.method {
                OffsetMethod::CalmSubset => "they were used",
                OffsetMethod::SpeedCorrelation =>
                    "too few; the search used the speed of all samples instead",
            }
        ),
        None => "No clock-offset search was run with this method, so no calm subset is shaded."
            .to_owned(),
    };
    figure(
        s,
        &plot,
        &format!(
            "Body angular velocity of the camera per axis and its norm. RMS angular speed over the \
             DVL samples used: {:.3} rad/s. {calm_words}",
            o.excitation.rms_angular_speed
        ),
    );

    let speed: Vec<(f64, f64)> = d.samples.iter().map(|x| (x.t_cam, x.speed)).collect();
    let lever: Vec<(f64, f64)> = d.samples.iter().map(|x| (x.t_cam, x.lever)).collect();
    let plot = Plot::new(
        "lever-arm",
        "Lever-arm velocity |w × p| against camera speed |v|",
        "camera time (s)",
        "m/s",
    )
    .size(WIDE, 260.0)
    .series(Series::line("|v| camera speed", AFTER, speed).size(1.2))
    .series(
        Series::line(
            if o.verdicts.lever_arm.by == DeterminedBy::Prior {
                "|w × p| lever-arm term (p: its prior)"
            } else {
                "|w × p| lever-arm term"
            },
            LEVER,
            lever,
        )
        .size(1.4),
    );
    let ratio = o.excitation.lever_arm_ratio;
    let lever_std_mm = 1e3 * o.std.lever_arm_m.max();
    let ext = estimated(&o.method, true);
    let judgement = if !ext {
        "The lever arm was held fixed in this run.".to_owned()
    } else if o.verdicts.lever_arm.by == DeterminedBy::Prior {
        format!(
            "The lever arm comes from its prior, not from this motion: {}",
            specific_reason(&o.verdicts.lever_arm, loss)
        )
    } else if o.verdicts.lever_arm.ok {
        format!(
            "This motion makes the lever arm observable: it shows in the DVL velocities strongly \
             enough to fix it to {lever_std_mm:.2} mm (largest standard deviation)."
        )
    } else {
        format!(
            "With this motion the lever arm is weakly observable ({lever_std_mm:.2} mm largest \
             standard deviation): {}",
            specific_reason(&o.verdicts.lever_arm, loss)
        )
    };
    figure(
        s,
        &plot,
        &format!(
            "The DVL sees the camera speed plus the lever-arm term w × p; only that term carries \
             information about the lever arm. Over the samples used it is {} of the speed (RMS \
             ratio). {judgement}",
            percent(ratio)
        ),
    );
    s.push_str("</section>\n");
}
