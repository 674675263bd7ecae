//! The DVL residuals over time, per DVL axis, after the calibration, with the band of three
//! times the noise the calibration stated for each sample: drift, steps and bursts show here,
//! where a histogram would hide them.
//!
//! Long recordings are decimated for drawing, and the page says so: the samples are split into
//! time columns of about a pixel, each column keeps its lowest and highest residual, and every
//! sample outside the band or down-weighted by the robust loss is drawn whatever the count.

use std::fmt::Write as _;

use super::data::Sample;
use super::svg::{Plot, Series, abs_quantile, escape};

/// Time columns of the decimated drawing (about the plotting width of a full-width plot).
pub(super) const COLUMNS: usize = 860;

/// Down-weighted samples: weight below this.
const DOWNWEIGHTED: f64 = 0.5;

/// One axis of the residual timeline, in m/s.
#[derive(Clone, Debug)]
pub(super) struct AxisTimeline {
    /// The residuals drawn (DVL time, measured minus predicted).
    pub drawn: Vec<(f64, f64)>,
    /// Three times the stated standard deviation: per sample, or the largest of each column
    /// when decimated.
    pub band: Vec<(f64, f64)>,
    /// Every sample outside its own band.
    pub outside: Vec<(f64, f64)>,
    /// Every sample the robust loss down-weighted.
    pub downweighted: Vec<(f64, f64)>,
    /// Samples of the axis.
    pub n: usize,
    /// Whether the residuals were decimated (`drawn` holds the extremes of each column).
    pub decimated: bool,
    /// Half height of the plot's y range.
    pub half_range: f64,
    /// Drawn points beyond the range, put on its edge.
    pub clamped: usize,
}

/// The timeline of axis `k` of `samples`, decimated to `columns` when there are more than
/// twice as many samples.
pub(super) fn axis_timeline(samples: &[Sample], k: usize, columns: usize) -> AxisTimeline {
    let mut order: Vec<usize> = (0..samples.len()).collect();
    order.sort_by(|&a, &b| samples[a].t_dvl.total_cmp(&samples[b].t_dvl));
    let res = |i: usize| samples[i].measured[k] - samples[i].after[k];
    let band_of = |i: usize| 3.0 * samples[i].sigma[k];
    let n = order.len();
    let decimated = n > 2 * columns.max(1);
    let (mut drawn, mut band) = (Vec::new(), Vec::new());
    if !decimated {
        for &i in &order {
            drawn.push((samples[i].t_dvl, res(i)));
            band.push((samples[i].t_dvl, band_of(i)));
        }
    } else {
        let t0 = samples[order[0]].t_dvl;
        let t1 = samples[order[n - 1]].t_dvl;
        let span = (t1 - t0).max(f64::MIN_POSITIVE);
        let column = |t: f64| (((t - t0) / span * columns as f64) as usize).min(columns - 1);
        let mut start = 0;
        while start < n {
            let col = column(samples[order[start]].t_dvl);
            let mut end = start + 1;
            while end < n && column(samples[order[end]].t_dvl) == col {
                end += 1;
            }
            let bucket = &order[start..end];
            let lo = bucket
                .iter()
                .copied()
                .min_by(|&a, &b| res(a).total_cmp(&res(b)))
                .unwrap_or(bucket[0]);
            let hi = bucket
                .iter()
                .copied()
                .max_by(|&a, &b| res(a).total_cmp(&res(b)))
                .unwrap_or(bucket[0]);
            let (a, b) = if samples[lo].t_dvl <= samples[hi].t_dvl {
                (lo, hi)
            } else {
                (hi, lo)
            };
            drawn.push((samples[a].t_dvl, res(a)));
            if b != a {
                drawn.push((samples[b].t_dvl, res(b)));
            }
            let widest = bucket
                .iter()
                .map(|&i| band_of(i))
                .fold(f64::NEG_INFINITY, f64::max);
            let mid = 0.5 * (samples[bucket[0]].t_dvl + samples[bucket[bucket.len() - 1]].t_dvl);
            band.push((mid, widest));
            start = end;
        }
    }
    let outside: Vec<(f64, f64)> = order
        .iter()
        .filter(|&&i| res(i).abs() > band_of(i))
        .map(|&i| (samples[i].t_dvl, res(i)))
        .collect();
    let downweighted: Vec<(f64, f64)> = order
        .iter()
        .filter(|&&i| samples[i].weight < DOWNWEIGHTED)
        .map(|&i| (samples[i].t_dvl, res(i)))
        .collect();
    let all: Vec<f64> = order.iter().map(|&i| res(i)).collect();
    let widest_band = band.iter().map(|b| b.1).fold(0.0, f64::max);
    let half_range = (1.1 * abs_quantile(&all, 0.999)).max(1.5 * widest_band);
    let mut clamped = 0;
    let mut clamp = |pts: &mut Vec<(f64, f64)>| {
        for p in pts.iter_mut() {
            if p.1.abs() > half_range {
                p.1 = p.1.signum() * half_range;
                clamped += 1;
            }
        }
    };
    let (mut drawn, mut outside, mut downweighted) = (drawn, outside, downweighted);
    clamp(&mut drawn);
    clamp(&mut outside);
    clamp(&mut downweighted);
    AxisTimeline {
        drawn,
        band,
        outside,
        downweighted,
        n,
        decimated,
        half_range,
        clamped,
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];
const RESIDUAL: &str = "#1a63c2";
const BAND: &str = "#2a9d3a";
const OUTSIDE: &str = "#d62728";
const DOWN: &str = "#8e24aa";

/// The section: one full-width plot per DVL axis and what was drawn, in words.
pub(super) fn residual_time_section(samples: &[Sample], dvl_gaps: &[(f64, f64)]) -> String {
    let mut s = String::from(
        "<section id=\"residual-time\"><h2>DVL residuals over time</h2>\n<p>Measured minus \
         predicted DVL velocity per axis of the DVL frame with the final parameters, against the \
         DVL clock, and the band of three times the noise the calibration stated for each \
         sample (the reports' covariance, or --dvl-sigma). A good calibration leaves noise \
         inside the band without drift, steps or bursts; with the stated noise right, about \
         0.3 % of the samples fall outside it. Red: outside the band; large purple dots: \
         down-weighted by the robust loss (less than half their weight); shaded: no valid DVL \
         report. Dots that would cover the same 2-pixel cell are drawn once.</p>\n",
    );
    let mut words = Vec::new();
    for (k, axis) in AXES.iter().enumerate() {
        let tl = axis_timeline(samples, k, COLUMNS);
        let mm = |v: &[(f64, f64)]| -> Vec<(f64, f64)> {
            v.iter().map(|&(t, r)| (t, 1e3 * r)).collect()
        };
        let upper = mm(&tl.band);
        let lower: Vec<(f64, f64)> = upper.iter().map(|&(t, b)| (t, -b)).collect();
        let h = 1e3 * tl.half_range;
        let mut plot = Plot::new(
            &format!("residual-time-{axis}"),
            &format!("DVL {axis} residual after calibration"),
            "DVL time (s)",
            &format!("residual {axis} (mm/s)"),
        )
        .size(940.0, 250.0)
        .y_range(-h, h)
        .empty_note("no samples")
        .series(Series::dots("residual", RESIDUAL, mm(&tl.drawn)).size(2.5))
        .series(
            Series::line("±3σ stated noise", BAND, upper)
                .size(1.3)
                .dashed(),
        )
        .series(Series::line("", BAND, lower).size(1.3).dashed());
        if !tl.downweighted.is_empty() {
            plot = plot.series(Series::dots("down-weighted", DOWN, mm(&tl.downweighted)).size(8.0));
        }
        if !tl.outside.is_empty() {
            plot = plot.series(Series::dots("outside ±3σ", OUTSIDE, mm(&tl.outside)).size(4.0));
        }
        if !dvl_gaps.is_empty() {
            plot = plot.spans("no valid DVL report", dvl_gaps.to_vec());
        }
        s.push_str("<figure>");
        s.push_str(&plot.render());
        s.push_str("</figure>\n");
        let pct = if tl.n > 0 {
            100.0 * tl.outside.len() as f64 / tl.n as f64
        } else {
            0.0
        };
        let mut w = format!(
            "{axis}: {} samples, {} ({pct:.2} %) outside ±3σ, {} down-weighted",
            tl.n,
            tl.outside.len(),
            tl.downweighted.len()
        );
        if tl.decimated {
            let _ = write!(
                w,
                "; drawn decimated: the lowest and highest residual of each of {} time columns \
                 ({} points), plus every sample outside the band and every down-weighted one",
                tl.band.len(),
                tl.drawn.len()
            );
        } else {
            w.push_str("; every sample drawn");
        }
        if tl.clamped > 0 {
            let _ = write!(
                w,
                "; {} points beyond ±{:.0} mm/s drawn on the edge",
                tl.clamped, h
            );
        }
        words.push(w);
    }
    let _ = writeln!(
        s,
        "<p class=\"meta\" id=\"residual-time-words\">{}.</p></section>",
        escape(&words.join(". "))
    );
    s
}
