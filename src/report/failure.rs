//! The report of a calibration that stopped with an error: what was found (the inputs, the
//! counts, the time spans of the camera and the DVL logs and their overlap, the detection
//! summary) and why it stopped, in words, so that a failed run leaves something to read.

use std::fmt::Write as _;

use super::guidance::FrameLoss;
use super::html::STYLE;
use super::input::FrameStat;
use super::svg::{Plot, Series, escape};
use crate::error::Error;
use crate::io::dvl::DvlLogStats;
use crate::types::{DvlSample, PoseMeasurement};

/// The id of every section of the failure report, in page order.
pub const FAILURE_SECTION_IDS: &[&str] = &[
    "failure",
    "inputs",
    "counts",
    "time-spans",
    "detection",
    "dvl-log",
];

/// The id of every plot of the failure report.
pub const FAILURE_PLOT_IDS: &[&str] = &["time-spans"];

/// What a failure report is made from.
#[derive(Clone, Debug)]
pub struct FailureReportInput<'a> {
    /// Page title.
    pub title: &'a str,
    /// What was being done when the error came ("calibrating dvl.jsonl against images/").
    pub context: &'a str,
    /// The error.
    pub error: &'a Error,
    /// The inputs found: what each is and its path.
    pub inputs: &'a [(String, String)],
    /// The camera poses that were read.
    pub poses: &'a [PoseMeasurement],
    /// The DVL samples that were read (DVL clock, on the poses' epoch).
    pub dvl: &'a [DvlSample],
    /// The DVL log's counts, when read from a file.
    pub dvl_stats: Option<&'a DvlLogStats>,
    /// Per-frame detection statistics, for runs from images.
    pub frames: Option<&'a [FrameStat]>,
    /// The detection's summary in words, for runs from images.
    pub detection: Option<&'a str>,
    /// Notes on the camera data.
    pub notes: &'a [String],
}

/// The error's messages, outermost first (a step's context, then what went wrong in it).
fn chain(e: &Error) -> Vec<String> {
    let mut out = Vec::new();
    let mut e = e;
    while let Error::During { context, inner } = e {
        out.push(context.clone());
        e = inner;
    }
    out.push(e.to_string());
    out
}

/// What the innermost error usually means and what to try.
fn advice(e: &Error) -> &'static str {
    match e {
        Error::During { inner, .. } => advice(inner),
        Error::NoTimeOverlap(_) => {
            "The camera poses and the DVL reports cover no common stretch of time at the clock \
             offsets the search may try. Check that both logs are of the same recording, and \
             compare their time spans below: clocks that differ by more than the recordings' \
             length need --offset-range, or --dvl-time host for a DVL log with the computer's \
             receive time."
        }
        Error::TooFewSamples { .. } => {
            "A stage had too few usable samples: the recording is too short, the DVL lost bottom \
             lock for most of it, or the logs overlap for only a short time (see the spans and \
             counts below)."
        }
        Error::Numerical(_) => {
            "A numerical step failed: usually motion that excites nothing (standing still, or \
             translation without any rotation) or data that do not fit the model at all. The \
             counts and spans below show what the calibration had to work with."
        }
        Error::InvalidOption { .. } | Error::UnusedOption(_) => {
            "An option value cannot be used; see its message."
        }
        Error::Parse { .. } | Error::Io { .. } => {
            "An input file could not be read or has a line that cannot be used; the message \
             names it."
        }
        Error::Dataset { .. } => "The dataset lacks a part, or holds two candidates for one.",
        Error::Input(_) => {
            "The input as a whole cannot be used; the message says why and the counts below \
             show what was read."
        }
    }
}

/// First and last finite time.
fn span(t: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    t.filter(|x| x.is_finite()).fold(None, |acc, x| match acc {
        None => Some((x, x)),
        Some((a, b)) => Some((f64::min(a, x), f64::max(b, x))),
    })
}

/// The spans of the camera poses and the valid DVL samples and their overlap (clocks as
/// recorded, no offset applied).
pub(super) struct Spans {
    pub camera: Option<(f64, f64)>,
    pub dvl: Option<(f64, f64)>,
}

impl Spans {
    pub fn of(poses: &[PoseMeasurement], dvl: &[DvlSample]) -> Spans {
        Spans {
            camera: span(poses.iter().map(|p| p.t)),
            dvl: span(dvl.iter().filter(|s| s.valid).map(|s| s.t)),
        }
    }

    /// The common stretch at a clock offset of zero; `Err(gap)` with the time between them
    /// when they do not meet.
    pub fn overlap(&self) -> Option<Result<(f64, f64), f64>> {
        let ((a0, a1), (b0, b1)) = (self.camera?, self.dvl?);
        let (lo, hi) = (a0.max(b0), a1.min(b1));
        Some(if hi >= lo { Ok((lo, hi)) } else { Err(lo - hi) })
    }
}

fn row(s: &mut String, k: &str, v: &str) {
    let _ = write!(s, "<tr><th>{}</th><td>{}</td></tr>", escape(k), escape(v));
}

fn span_words(sp: Option<(f64, f64)>) -> String {
    match sp {
        Some((a, b)) => format!("{a:.3} s to {b:.3} s ({:.1} s)", b - a),
        None => "none".into(),
    }
}

/// Renders the failure report as one HTML document.
pub fn render_failure_html(input: &FailureReportInput) -> String {
    let mut s = String::with_capacity(64 * 1024);
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body data-report=\"failure\">\n",
        escape(input.title)
    );
    let _ = write!(
        s,
        "<section id=\"failure\"><h1>{}</h1><p class=\"meta\">dvlcal {}</p>\
         <div id=\"failed\" class=\"failed\"><p><strong>The calibration stopped with an error: \
         no result was computed.</strong></p><ul>",
        escape(input.title),
        env!("CARGO_PKG_VERSION")
    );
    let mut msgs = vec![input.context.to_owned()];
    msgs.extend(chain(input.error));
    for m in msgs.iter().filter(|m| !m.is_empty()) {
        let _ = write!(s, "<li>{}</li>", escape(m));
    }
    let _ = write!(
        s,
        "</ul><p id=\"advice\">{}</p>",
        escape(advice(input.error))
    );
    // The frames the image pipeline lost are what happened, whatever the error's usual causes.
    if let Some(l) = FrameLoss::of(input.frames).filter(FrameLoss::significant) {
        let _ = write!(
            s,
            "<p id=\"frame-cause\">In this run {}: the camera poses are too few or too sparse \
             to follow the motion.</p>",
            escape(&l.words())
        );
    }
    s.push_str("</div></section>\n");

    s.push_str("<section id=\"inputs\"><h2>Inputs found</h2><table>");
    for (k, v) in input.inputs {
        row(&mut s, k, v);
    }
    s.push_str("</table>");
    if !input.notes.is_empty() {
        s.push_str("<ul>");
        for n in input.notes {
            let _ = write!(s, "<li>{}</li>", escape(n));
        }
        s.push_str("</ul>");
    }
    s.push_str("</section>\n");

    s.push_str("<section id=\"counts\"><h2>What was read</h2><table>");
    row(&mut s, "camera poses", &input.poses.len().to_string());
    let valid = input.dvl.iter().filter(|x| x.valid).count();
    row(
        &mut s,
        "DVL samples read (valid / flagged invalid by the DVL)",
        &format!(
            "{} ({valid} / {})",
            input.dvl.len(),
            input.dvl.len() - valid
        ),
    );
    if let Some(st) = input.dvl_stats {
        row(
            &mut s,
            "DVL bottom-track velocity reports",
            &st.velocity_reports.to_string(),
        );
        row(
            &mut s,
            "skipped: duplicates / rejected lines / times going backwards",
            &format!(
                "{} / {} / {}",
                st.duplicates, st.rejected_lines, st.time_backwards
            ),
        );
    }
    if let Some(fr) = input.frames {
        let posed = fr.iter().filter(|f| f.posed).count();
        row(
            &mut s,
            "image frames (with a pose / skipped)",
            &format!("{} ({posed} / {})", fr.len(), fr.len() - posed),
        );
    }
    s.push_str("</table></section>\n");

    let sp = Spans::of(input.poses, input.dvl);
    s.push_str("<section id=\"time-spans\"><h2>Time spans</h2><table>");
    row(
        &mut s,
        "camera poses (camera clock)",
        &span_words(sp.camera),
    );
    row(&mut s, "valid DVL samples (DVL clock)", &span_words(sp.dvl));
    let overlap = match sp.overlap() {
        Some(Ok((a, b))) => format!(
            "{a:.3} s to {b:.3} s ({:.1} s) with the clocks as recorded",
            b - a
        ),
        Some(Err(gap)) => format!(
            "none with the clocks as recorded: {gap:.3} s lie between the end of one and the \
             start of the other"
        ),
        None => "none: one of the logs has no usable time".into(),
    };
    row(&mut s, "overlap", &overlap);
    s.push_str("</table>");
    let mut plot = Plot::new(
        "time-spans",
        "Time spans of the logs (times relative to the dataset epoch)",
        "time (s)",
        "",
    )
    .size(940.0, 170.0)
    .y_range(-0.5, 1.5)
    .empty_note("no times in either log");
    if let Some((a, b)) = sp.camera {
        plot = plot
            .series(Series::line("camera poses", "#1a63c2", vec![(a, 1.0), (b, 1.0)]).size(8.0));
    }
    if let Some((a, b)) = sp.dvl {
        plot =
            plot.series(Series::line("DVL samples", "#e8710a", vec![(a, 0.0), (b, 0.0)]).size(8.0));
    }
    let _ = writeln!(
        s,
        "<figure>{}<figcaption>Upper bar: camera poses; lower bar: valid DVL samples. The \
         calibration searches the clock offset among those at which the bars overlap once \
         shifted.</figcaption></figure></section>",
        plot.render()
    );

    s.push_str("<section id=\"detection\"><h2>Detection</h2>");
    match input.detection {
        Some(d) => {
            let _ = write!(s, "<pre>{}</pre>", escape(d));
        }
        None => {
            s.push_str("<p>No image detection in this run: the poses were read from a file.</p>")
        }
    }
    s.push_str("</section>\n");

    s.push_str("<section id=\"dvl-log\"><h2>DVL log</h2>");
    match input.dvl_stats {
        Some(st) => {
            s.push_str("<table>");
            row(&mut s, "file", &st.path.display().to_string());
            row(
                &mut s,
                "format",
                &st.format.map_or("unknown".into(), |f| f.to_string()),
            );
            row(&mut s, "time stamps", &st.time_source_used);
            row(
                &mut s,
                "valid / invalid",
                &format!("{} / {}", st.valid, st.invalid),
            );
            s.push_str("</table>");
            if !st.warnings.is_empty() {
                s.push_str("<ul class=\"warn\">");
                for w in &st.warnings {
                    let _ = write!(s, "<li>{}</li>", escape(w));
                }
                s.push_str("</ul>");
            }
        }
        None => s.push_str("<p>The DVL log's own counts were not given to the report.</p>"),
    }
    s.push_str("</section>\n</body></html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::PoseMeasurement;
    use nalgebra::Vector3;

    fn poses(a: f64, b: f64) -> Vec<PoseMeasurement> {
        (0..=10)
            .map(|k| PoseMeasurement {
                t: a + (b - a) * k as f64 / 10.0,
                pose: crate::lie::Se3::identity(),
                cov: None,
            })
            .collect()
    }

    fn dvl(a: f64, b: f64) -> Vec<DvlSample> {
        (0..=20)
            .map(|k| DvlSample {
                t: a + (b - a) * k as f64 / 20.0,
                v: Vector3::zeros(),
                cov: None,
                valid: k != 20,
            })
            .collect()
    }

    #[test]
    fn spans_and_overlap() {
        let sp = Spans::of(&poses(0.0, 10.0), &dvl(4.0, 24.0));
        assert_eq!(sp.camera, Some((0.0, 10.0)));
        // The last DVL sample is invalid: the span ends at the one before.
        assert_eq!(sp.dvl, Some((4.0, 23.0)));
        assert_eq!(sp.overlap(), Some(Ok((4.0, 10.0))));
        let sp = Spans::of(&poses(0.0, 10.0), &dvl(30.0, 50.0));
        assert_eq!(sp.overlap(), Some(Err(20.0)));
        assert_eq!(Spans::of(&[], &dvl(0.0, 1.0)).overlap(), None);
    }

    #[test]
    fn the_error_chain_and_its_meaning_are_on_the_page() {
        let e = Error::NoTimeOverlap("the DVL log <ends> before the poses".into())
            .during("UIC on runs/dive2");
        let p = poses(0.0, 10.0);
        let d = dvl(100.0, 120.0);
        let inputs = vec![("DVL log".to_owned(), "runs/dive2/dvl.jsonl".to_owned())];
        let html = render_failure_html(&FailureReportInput {
            title: "DVL calibration report",
            context: "calibrating dvl.jsonl against poses.txt",
            error: &e,
            inputs: &inputs,
            poses: &p,
            dvl: &d,
            dvl_stats: None,
            frames: None,
            detection: None,
            notes: &[],
        });
        for id in FAILURE_SECTION_IDS {
            assert!(html.contains(&format!("<section id=\"{id}\"")), "{id}");
        }
        assert!(html.contains("<svg id=\"time-spans\""));
        assert!(html.contains("UIC on runs/dive2"));
        assert!(html.contains("the DVL log &lt;ends&gt; before the poses"));
        assert!(html.contains("cover no common stretch of time"));
        assert!(html.contains("90.000 s lie between"), "gap of 100 - 10 s");
        assert!(html.contains("0.000 s to 10.000 s (10.0 s)"));
        assert!(html.contains("runs/dive2/dvl.jsonl"));
        // The reason comes before everything else.
        assert!(html.find("stopped with an error").unwrap() < html.find("Inputs found").unwrap());
    }
}
