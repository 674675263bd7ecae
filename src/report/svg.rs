//! A small plotting helper that writes inline SVG for the calibration report.
//!
//! A [`Plot`] is a single panel: axes with "nice" ticks and labels, a title, a legend, and any
//! number of [`Series`] drawn as lines, dots or bars, plus shaded x spans and labelled vertical
//! markers. Long series are thinned at render time, after the axis ranges are fixed from the
//! full data, so a plot's size depends on its pixel size and not on the number of samples:
//! monotone lines keep the first, last, lowest and highest point of every pixel column, other
//! lines drop points closer than half a pixel to the previous one, and dots keep one point per
//! 2-pixel cell. Non-finite values are skipped. Every string is escaped.

use std::fmt::Write as _;

/// Escapes text for HTML and SVG content and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if c.is_control() && c != '\n' && c != '\t' => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
    out
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mark {
    /// A polyline through the points (broken at non-finite values).
    Line,
    /// A dot per point.
    Dots,
    /// Bars from zero to `y`, `width` wide in data units, starting at `x` (histograms).
    Bars { width: f64 },
}

/// One data series.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    /// Any CSS colour.
    pub color: String,
    pub mark: Mark,
    pub points: Vec<(f64, f64)>,
    /// Line width or dot diameter, pixels.
    pub size: f64,
    pub dashed: bool,
}

impl Series {
    pub fn line(name: &str, color: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.to_owned(),
            color: color.to_owned(),
            mark: Mark::Line,
            points,
            size: 1.4,
            dashed: false,
        }
    }

    pub fn dots(name: &str, color: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            mark: Mark::Dots,
            size: 3.0,
            ..Series::line(name, color, points)
        }
    }

    pub fn bars(name: &str, color: &str, width: f64, points: Vec<(f64, f64)>) -> Series {
        Series {
            mark: Mark::Bars { width },
            ..Series::line(name, color, points)
        }
    }

    pub fn size(mut self, size: f64) -> Series {
        self.size = size;
        self
    }

    pub fn dashed(mut self) -> Series {
        self.dashed = true;
        self
    }
}

/// A vertical marker line with a label.
#[derive(Clone, Debug)]
pub struct Marker {
    pub x: f64,
    pub label: String,
    pub color: String,
}

/// One plot panel.
#[derive(Clone, Debug)]
pub struct Plot {
    /// Element id of the `<svg>` (also prefixes its internal ids).
    pub id: String,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub width: f64,
    pub height: f64,
    pub series: Vec<Series>,
    /// Shaded x intervals, drawn behind the data.
    pub spans: Vec<(f64, f64)>,
    /// Legend text of the spans (none: no legend entry).
    pub span_label: Option<String>,
    pub markers: Vec<Marker>,
    /// Logarithmic y axis (points with `y <= 0` are skipped).
    pub log_y: bool,
    /// Same scale on both axes (maps, top views).
    pub equal_aspect: bool,
    /// Ticks only at whole numbers on the x axis (counts, iterations).
    pub integer_x: bool,
    /// Fixed axis ranges instead of the data's.
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
    /// Shown in the panel when there is nothing to draw.
    pub empty_note: String,
    /// y grows downward (image rows).
    pub y_down: bool,
}

/// Margins around the plotting area, pixels.
const LEFT: f64 = 66.0;
const RIGHT: f64 = 16.0;
const TOP_TITLE: f64 = 26.0;
const LEGEND_ROW: f64 = 18.0;
const BOTTOM: f64 = 42.0;

impl Plot {
    pub fn new(id: &str, title: &str, x_label: &str, y_label: &str) -> Plot {
        Plot {
            id: id.to_owned(),
            title: title.to_owned(),
            x_label: x_label.to_owned(),
            y_label: y_label.to_owned(),
            width: 640.0,
            height: 280.0,
            series: Vec::new(),
            spans: Vec::new(),
            span_label: None,
            markers: Vec::new(),
            log_y: false,
            equal_aspect: false,
            integer_x: false,
            x_range: None,
            y_range: None,
            empty_note: "no data".to_owned(),
            y_down: false,
        }
    }

    pub fn size(mut self, width: f64, height: f64) -> Plot {
        self.width = width.max(160.0);
        self.height = height.max(120.0);
        self
    }

    pub fn series(mut self, s: Series) -> Plot {
        self.series.push(s);
        self
    }

    pub fn spans(mut self, label: &str, spans: Vec<(f64, f64)>) -> Plot {
        self.span_label = Some(label.to_owned());
        self.spans = spans;
        self
    }

    pub fn marker(mut self, x: f64, label: &str, color: &str) -> Plot {
        self.markers.push(Marker {
            x,
            label: label.to_owned(),
            color: color.to_owned(),
        });
        self
    }

    pub fn log_y(mut self) -> Plot {
        self.log_y = true;
        self
    }

    pub fn equal_aspect(mut self) -> Plot {
        self.equal_aspect = true;
        self
    }

    pub fn integer_x(mut self) -> Plot {
        self.integer_x = true;
        self
    }

    pub fn y_range(mut self, lo: f64, hi: f64) -> Plot {
        self.y_range = Some((lo, hi));
        self
    }

    pub fn x_range(mut self, lo: f64, hi: f64) -> Plot {
        self.x_range = Some((lo, hi));
        self
    }

    /// y grows downward, as the rows of an image.
    pub fn y_down(mut self) -> Plot {
        self.y_down = true;
        self
    }

    pub fn empty_note(mut self, note: &str) -> Plot {
        self.empty_note = note.to_owned();
        self
    }

    fn has_legend(&self) -> bool {
        self.series.iter().any(|s| !s.name.is_empty()) || self.span_label.is_some()
    }

    /// The plotting area for a left margin: left, top, width, height in pixels.
    fn area(&self, left: f64) -> (f64, f64, f64, f64) {
        let top = TOP_TITLE + if self.has_legend() { LEGEND_ROW } else { 0.0 } + 6.0;
        (
            left,
            top,
            (self.width - left - RIGHT).max(10.0),
            (self.height - top - BOTTOM).max(10.0),
        )
    }

    fn usable(&self, y: f64) -> bool {
        y.is_finite() && (!self.log_y || y > 0.0)
    }

    /// Data ranges of x and y (before the log transform), or `None` without drawable data.
    fn data_ranges(&self) -> Option<(Range, Range)> {
        let mut xr = Range::EMPTY;
        let mut yr = Range::EMPTY;
        for s in &self.series {
            for &(x, y) in &s.points {
                if !x.is_finite() || !self.usable(y) {
                    continue;
                }
                match s.mark {
                    Mark::Bars { width } => {
                        xr.add(x);
                        xr.add(x + width);
                        yr.add(y);
                        if !self.log_y {
                            yr.add(0.0);
                        }
                    }
                    _ => {
                        xr.add(x);
                        yr.add(y);
                    }
                }
            }
        }
        if xr.is_empty() {
            return None;
        }
        for m in &self.markers {
            if m.x.is_finite() {
                xr.add(m.x);
            }
        }
        Some((xr, yr))
    }

    /// The scale with a left margin wide enough for the widest y tick label beside the axis
    /// title.
    fn fitted_scale(&self, xr: Range, yr: Range) -> Scale {
        let scale = self.scale(xr, yr, LEFT);
        let (_, labels) = self.y_ticks(&scale);
        let widest = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0) as f64;
        let need = 30.0 + 6.4 * widest;
        if need > LEFT {
            self.scale(xr, yr, need.min(0.4 * self.width))
        } else {
            scale
        }
    }

    /// Ticks of the y axis (exponents on a log axis) and their labels.
    fn y_ticks(&self, sc: &Scale) -> (Vec<f64>, Vec<String>) {
        let ticks = if self.log_y {
            log_ticks(sc.y0, sc.y1)
        } else {
            nice_ticks(sc.y0, sc.y1, (sc.h / 36.0).clamp(3.0, 10.0) as usize)
        };
        let step = tick_step(&ticks);
        let labels = ticks
            .iter()
            .map(|&y| {
                if self.log_y {
                    format_log_tick(y)
                } else {
                    format_tick(y, step)
                }
            })
            .collect();
        (ticks, labels)
    }

    /// Renders the plot as an `<svg>` element.
    pub fn render(&self) -> String {
        let id = escape(&self.id);
        let mut s = String::new();
        let ranges = self.data_ranges();
        let _ = write!(
            s,
            "<svg id=\"{id}\" class=\"plot\" xmlns=\"http://www.w3.org/2000/svg\" \
             viewBox=\"0 0 {W} {H}\" width=\"{W}\" height=\"{H}\" role=\"img\" \
             aria-labelledby=\"{id}-title\"{empty_attr}>\
             <title id=\"{id}-title\">{title}</title>\
             <rect width=\"{W}\" height=\"{H}\" fill=\"#fff\"/>",
            W = self.width,
            H = self.height,
            title = escape(&self.title),
            empty_attr = if ranges.is_none() {
                " data-empty=\"true\""
            } else {
                ""
            }
        );
        let Some((xr, yr)) = ranges else {
            let (l, t, w, h) = self.area(LEFT);
            self.title_and_legend(&mut s, l);
            let _ = write!(
                s,
                "<rect x=\"{l:.1}\" y=\"{t:.1}\" width=\"{w:.1}\" height=\"{h:.1}\" fill=\"#f6f6f6\" \
                 stroke=\"#bbb\"/><text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" \
                 class=\"n\">{}</text></svg>",
                l + w / 2.0,
                t + h / 2.0,
                escape(&self.empty_note)
            );
            return s;
        };
        let scale = self.fitted_scale(xr, yr);
        let (yticks, ylabels) = self.y_ticks(&scale);
        let (l, t, w, h) = (scale.left, scale.top, scale.w, scale.h);
        self.title_and_legend(&mut s, l);
        // Frame, grid and ticks.
        let _ = write!(
            s,
            "<rect x=\"{l:.1}\" y=\"{t:.1}\" width=\"{w:.1}\" height=\"{h:.1}\" fill=\"#fcfcfc\" \
             stroke=\"#999\"/>"
        );
        let mut xticks = nice_ticks(scale.x0, scale.x1, (w / 70.0).clamp(3.0, 12.0) as usize);
        if self.integer_x && tick_step(&xticks) < 1.0 {
            let (a, b) = (scale.x0.ceil(), scale.x1.floor());
            xticks = if b - a <= 1000.0 {
                (0..=(b - a).max(-1.0) as i64)
                    .map(|k| a + k as f64)
                    .collect()
            } else {
                Vec::new()
            };
        }
        let xstep = tick_step(&xticks);
        for &x in &xticks {
            let px = scale.px(x);
            let _ = write!(
                s,
                "<line x1=\"{px:.1}\" y1=\"{t:.1}\" x2=\"{px:.1}\" y2=\"{:.1}\" class=\"g\"/>\
                 <text x=\"{px:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"k\">{}</text>",
                t + h,
                t + h + 14.0,
                escape(&format_tick(x, xstep))
            );
        }
        for (&y, label) in yticks.iter().zip(&ylabels) {
            // Log ticks are exponents; their labels are the values.
            let py = scale.py_t(y);
            let _ = write!(
                s,
                "<line x1=\"{l:.1}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\" class=\"g\"/>\
                 <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\" class=\"k\">{}</text>",
                l + w,
                l - 4.0,
                py + 4.0,
                escape(label)
            );
        }
        let _ = write!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"a\">{}</text>\
             <text transform=\"translate(14 {:.1}) rotate(-90)\" text-anchor=\"middle\" \
             class=\"a\">{}</text>",
            l + w / 2.0,
            self.height - 8.0,
            escape(&self.x_label),
            t + h / 2.0,
            escape(&self.y_label)
        );
        // Data, clipped to the area.
        let _ = write!(
            s,
            "<clipPath id=\"{id}-clip\"><rect x=\"{l:.1}\" y=\"{t:.1}\" width=\"{w:.1}\" \
             height=\"{h:.1}\"/></clipPath><g clip-path=\"url(#{id}-clip)\">"
        );
        self.draw_spans(&mut s, &scale);
        for series in &self.series {
            self.draw_series(&mut s, series, &scale);
        }
        for m in &self.markers {
            if !m.x.is_finite() {
                continue;
            }
            let px = scale.px(m.x);
            let _ = write!(
                s,
                "<line x1=\"{px:.1}\" y1=\"{t:.1}\" x2=\"{px:.1}\" y2=\"{:.1}\" stroke=\"{}\" \
                 stroke-width=\"1.2\" stroke-dasharray=\"5 3\"/>",
                t + h,
                escape(&m.color)
            );
        }
        s.push_str("</g>");
        // Marker labels outside the clip so they stay readable near the edges.
        for (k, m) in self.markers.iter().enumerate() {
            if !m.x.is_finite() || m.label.is_empty() {
                continue;
            }
            let px = scale.px(m.x);
            let anchor = if px > l + w * 0.7 { "end" } else { "start" };
            let dx = if anchor == "end" { -4.0 } else { 4.0 };
            let _ = write!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"{anchor}\" class=\"m\" fill=\"{}\">{}</text>",
                px + dx,
                t + 13.0 + 13.0 * k as f64,
                escape(&m.color),
                escape(&m.label)
            );
        }
        s.push_str("</svg>");
        s
    }

    fn title_and_legend(&self, s: &mut String, left: f64) {
        let _ = write!(
            s,
            "<text x=\"{left:.1}\" y=\"17\" class=\"t\">{}</text>",
            escape(&self.title)
        );
        if !self.has_legend() {
            return;
        }
        let y = TOP_TITLE + 10.0;
        let mut x = left;
        if let Some(label) = &self.span_label {
            let _ = write!(
                s,
                "<rect x=\"{x:.1}\" y=\"{:.1}\" width=\"16\" height=\"10\" class=\"sp\"/>\
                 <text x=\"{:.1}\" y=\"{:.1}\" class=\"l\">{}</text>",
                y - 8.0,
                x + 20.0,
                y + 1.0,
                escape(label)
            );
            x += 28.0 + 6.5 * label.chars().count() as f64;
        }
        for se in self.series.iter().filter(|se| !se.name.is_empty()) {
            let c = escape(&se.color);
            match se.mark {
                Mark::Line => {
                    let dash = if se.dashed {
                        " stroke-dasharray=\"5 3\""
                    } else {
                        ""
                    };
                    let _ = write!(
                        s,
                        "<line x1=\"{x:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"{c}\" \
                         stroke-width=\"2\"{dash}/>",
                        y - 3.0,
                        x + 16.0,
                        y - 3.0
                    );
                }
                Mark::Dots => {
                    let _ = write!(
                        s,
                        "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{c}\"/>",
                        x + 8.0,
                        y - 3.0
                    );
                }
                Mark::Bars { .. } => {
                    let _ = write!(
                        s,
                        "<rect x=\"{x:.1}\" y=\"{:.1}\" width=\"16\" height=\"10\" fill=\"{c}\" \
                         fill-opacity=\"0.6\"/>",
                        y - 8.0
                    );
                }
            }
            let _ = write!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" class=\"l\">{}</text>",
                x + 20.0,
                y + 1.0,
                escape(&se.name)
            );
            x += 30.0 + 6.5 * se.name.chars().count() as f64;
        }
    }

    fn draw_spans(&self, s: &mut String, sc: &Scale) {
        let mut px: Vec<(f64, f64)> = self
            .spans
            .iter()
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|&(a, b)| {
                let (a, b) = (sc.px(a.min(b)), sc.px(a.max(b)));
                (
                    a.clamp(sc.left - 1.0, sc.left + sc.w + 1.0),
                    b.clamp(sc.left - 1.0, sc.left + sc.w + 1.0),
                )
            })
            .collect();
        px.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Spans closer than a pixel merge: thousands of short calm stretches stay a few rects.
        let mut merged: Vec<(f64, f64)> = Vec::new();
        for (a, b) in px {
            match merged.last_mut() {
                Some(last) if a <= last.1 + 1.0 => last.1 = last.1.max(b),
                _ => merged.push((a, b)),
            }
        }
        for (a, b) in merged {
            let _ = write!(
                s,
                "<rect x=\"{a:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\" class=\"sp\"/>",
                sc.top,
                (b - a).max(1.0),
                sc.h
            );
        }
    }

    fn draw_series(&self, s: &mut String, se: &Series, sc: &Scale) {
        let c = escape(&se.color);
        let pts: Vec<(f64, f64)> = se
            .points
            .iter()
            .map(|&(x, y)| {
                if x.is_finite() && self.usable(y) {
                    (sc.px(x), sc.py(y))
                } else {
                    (f64::NAN, f64::NAN)
                }
            })
            .collect();
        match se.mark {
            Mark::Line => {
                let mut d = String::new();
                for run in pts.split(|p| !p.0.is_finite()) {
                    let kept = thin_line(run, sc.left, sc.w);
                    for (k, (x, y)) in kept.iter().enumerate() {
                        let _ = write!(d, "{}{:.1} {:.1}", if k == 0 { 'M' } else { 'L' }, x, y);
                    }
                }
                if d.is_empty() {
                    return;
                }
                let dash = if se.dashed {
                    " stroke-dasharray=\"5 3\""
                } else {
                    ""
                };
                let _ = write!(
                    s,
                    "<path d=\"{d}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{}\" \
                     stroke-linejoin=\"round\"{dash}/>",
                    se.size
                );
            }
            Mark::Dots => {
                let kept = thin_dots(&pts, 2.0);
                if kept.is_empty() {
                    return;
                }
                // Zero-length subpaths with round caps draw as dots: one element for all.
                let mut d = String::with_capacity(kept.len() * 14);
                for (x, y) in kept {
                    let _ = write!(d, "M{x:.1} {y:.1}h0");
                }
                let _ = write!(
                    s,
                    "<path d=\"{d}\" stroke=\"{c}\" stroke-width=\"{}\" stroke-linecap=\"round\" \
                     stroke-opacity=\"0.75\"/>",
                    se.size
                );
            }
            Mark::Bars { width } => {
                let base = if self.log_y {
                    sc.top + sc.h
                } else {
                    sc.py(0.0)
                };
                for (&(x, y), &(px, py)) in se.points.iter().zip(&pts) {
                    if !px.is_finite() {
                        continue;
                    }
                    let x2 = sc.px(x + width);
                    let (top, bottom) = (py.min(base), py.max(base));
                    let _ = write!(
                        s,
                        "<rect x=\"{:.1}\" y=\"{top:.1}\" width=\"{:.1}\" height=\"{:.1}\" \
                         fill=\"{c}\" fill-opacity=\"0.6\" stroke=\"{c}\" stroke-width=\"0.6\"/>",
                        px.min(x2),
                        (x2 - px).abs().max(0.5),
                        (bottom - top).max(if y != 0.0 { 0.5 } else { 0.0 })
                    );
                }
            }
        }
    }

    /// The mapping from data to pixels.
    fn scale(&self, xr: Range, yr: Range, left: f64) -> Scale {
        let (l, t, w, h) = self.area(left);
        let (mut x0, mut x1) = self.x_range.unwrap_or((xr.lo, xr.hi));
        let (mut y0, mut y1) = self.y_range.unwrap_or((yr.lo, yr.hi));
        if self.log_y {
            y0 = y0.max(f64::MIN_POSITIVE).log10();
            y1 = y1.max(f64::MIN_POSITIVE).log10();
        }
        (x0, x1) = widen(x0, x1);
        (y0, y1) = widen(y0, y1);
        if self.y_range.is_none() {
            let pad = 0.05 * (y1 - y0);
            // Bars and non-negative data keep their zero on the axis.
            if y0 != 0.0 || self.log_y {
                y0 -= pad;
            }
            y1 += pad;
        }
        let has_dots = self
            .series
            .iter()
            .any(|s| matches!(s.mark, Mark::Dots) && !s.points.is_empty());
        if self.x_range.is_none() && (has_dots || self.equal_aspect) {
            let pad = 0.03 * (x1 - x0);
            x0 -= pad;
            x1 += pad;
        }
        if self.equal_aspect {
            // Units per pixel equal on both axes: widen the axis that has room to spare.
            let ux = (x1 - x0) / w;
            let uy = (y1 - y0) / h;
            if ux > uy {
                let c = 0.5 * (y0 + y1);
                y0 = c - 0.5 * ux * h;
                y1 = c + 0.5 * ux * h;
            } else {
                let c = 0.5 * (x0 + x1);
                x0 = c - 0.5 * uy * w;
                x1 = c + 0.5 * uy * w;
            }
        }
        Scale {
            left: l,
            top: t,
            w,
            h,
            x0,
            x1,
            y0,
            y1,
            log_y: self.log_y,
            y_down: self.y_down,
        }
    }
}

/// A running minimum and maximum.
#[derive(Clone, Copy, Debug)]
struct Range {
    lo: f64,
    hi: f64,
}

impl Range {
    const EMPTY: Range = Range {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
    };

    fn add(&mut self, v: f64) {
        self.lo = self.lo.min(v);
        self.hi = self.hi.max(v);
    }

    fn is_empty(&self) -> bool {
        self.lo > self.hi
    }
}

/// A range with some width: a single value gets a margin around it.
fn widen(lo: f64, hi: f64) -> (f64, f64) {
    if hi > lo {
        return (lo, hi);
    }
    let m = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
    (lo - m, hi + m)
}

/// Data to pixel coordinates of a plot. With a log y axis `y0`, `y1` are decimal exponents.
#[derive(Clone, Copy, Debug)]
pub struct Scale {
    pub left: f64,
    pub top: f64,
    pub w: f64,
    pub h: f64,
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
    pub log_y: bool,
    /// y grows downward.
    pub y_down: bool,
}

impl Scale {
    pub fn px(&self, x: f64) -> f64 {
        self.left + (x - self.x0) / (self.x1 - self.x0) * self.w
    }

    /// Pixel row of the data value `y`.
    pub fn py(&self, y: f64) -> f64 {
        let v = if self.log_y { y.log10() } else { y };
        self.py_t(v)
    }

    /// Pixel row of a value on the axis's own (possibly logarithmic) coordinate.
    fn py_t(&self, v: f64) -> f64 {
        let f = (v - self.y0) / (self.y1 - self.y0) * self.h;
        if self.y_down {
            self.top + f
        } else {
            self.top + self.h - f
        }
    }
}

/// The `q` quantile of `|v|` over the finite values (0 without any).
pub(super) fn abs_quantile(v: &[f64], q: f64) -> f64 {
    let mut a: Vec<f64> = v
        .iter()
        .filter(|x| x.is_finite())
        .map(|x| x.abs())
        .collect();
    if a.is_empty() {
        return 0.0;
    }
    a.sort_by(f64::total_cmp);
    let k = ((a.len() as f64 * q).ceil() as usize).clamp(1, a.len()) - 1;
    a[k]
}

#[cfg(test)]
impl Plot {
    /// The pixel mapping this plot would use (for the tests).
    pub fn pixel_scale(&self) -> Option<Scale> {
        let (xr, yr) = self.data_ranges()?;
        Some(self.fitted_scale(xr, yr))
    }
}

/// Thins a polyline in pixel coordinates. When x never decreases, each pixel column keeps its
/// first, lowest, highest and last point (in their original order), so every peak survives;
/// otherwise points within half a pixel of the previous kept point are dropped.
pub fn thin_line(pts: &[(f64, f64)], left: f64, width: f64) -> Vec<(f64, f64)> {
    if pts.len() <= 2 {
        return pts.to_vec();
    }
    let monotone = pts.windows(2).all(|w| w[1].0 >= w[0].0);
    let mut out = Vec::new();
    if monotone {
        let column = |x: f64| ((x - left).floor().clamp(-1.0, width + 1.0)) as i64;
        let mut start = 0;
        while start < pts.len() {
            let col = column(pts[start].0);
            let mut end = start + 1;
            while end < pts.len() && column(pts[end].0) == col {
                end += 1;
            }
            let bucket = &pts[start..end];
            let (mut lo, mut hi) = (0, 0);
            for (k, p) in bucket.iter().enumerate() {
                if p.1 < bucket[lo].1 {
                    lo = k;
                }
                if p.1 > bucket[hi].1 {
                    hi = k;
                }
            }
            let mut keep = [0, lo, hi, bucket.len() - 1];
            keep.sort_unstable();
            let mut last = usize::MAX;
            for k in keep {
                if k != last {
                    out.push(bucket[k]);
                    last = k;
                }
            }
            start = end;
        }
    } else {
        let mut last = pts[0];
        out.push(last);
        for (k, &p) in pts.iter().enumerate().skip(1) {
            let far = (p.0 - last.0).abs() >= 0.5 || (p.1 - last.1).abs() >= 0.5;
            if far || k + 1 == pts.len() {
                out.push(p);
                last = p;
            }
        }
    }
    out
}

/// Keeps the first point of every `cell`-pixel square, in order of first appearance.
pub fn thin_dots(pts: &[(f64, f64)], cell: f64) -> Vec<(f64, f64)> {
    let mut seen = std::collections::HashSet::new();
    pts.iter()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .filter(|p| seen.insert(((p.0 / cell).floor() as i64, (p.1 / cell).floor() as i64)))
        .copied()
        .collect()
}

/// About `target` evenly spaced round values (steps of 1, 2 or 5 times a power of ten) inside
/// `[lo, hi]`.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return Vec::new();
    }
    let target = target.max(2) as f64;
    let raw = (hi - lo) / target;
    let mag = 10f64.powf(raw.log10().floor());
    let count = |step: f64| ((hi / step).floor() - (lo / step).ceil() + 1.0).max(0.0);
    // The round step whose tick count is closest to the target, preferring at least two ticks
    // and, on a tie, the finer step.
    let mut best = (f64::INFINITY, 10.0 * mag);
    for m in [0.5, 1.0, 2.0, 5.0, 10.0] {
        let step = m * mag;
        let n = count(step);
        let penalty = (n - target).abs() + if n < 2.0 { 100.0 } else { 0.0 };
        if penalty < best.0 {
            best = (penalty, step);
        }
    }
    let step = best.1;
    let first = (lo / step).ceil();
    let last = (hi / step).floor();
    if !(last - first).is_finite() || last < first || last - first > 1000.0 {
        return Vec::new();
    }
    (0..=(last - first) as i64)
        .map(|k| {
            let v = (first + k as f64) * step;
            // Exact zero rather than -0 or 1e-17.
            if v.abs() < step * 1e-9 { 0.0 } else { v }
        })
        .collect()
}

/// Ticks of a logarithmic axis whose range `[lo, hi]` is given in decimal exponents: the
/// decades, with 2 and 5 between them when fewer than three decades are visible. Returned as
/// exponents.
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return Vec::new();
    }
    let (a, b) = (lo.floor() as i64, hi.ceil() as i64);
    let fine = b - a < 3;
    let step = ((b - a) / 8).max(1);
    let mut out = Vec::new();
    let mut e = a;
    while e <= b {
        let mults: &[f64] = if fine { &[1.0, 2.0, 5.0] } else { &[1.0] };
        for m in mults {
            let v = e as f64 + m.log10();
            if v >= lo - 1e-12 && v <= hi + 1e-12 {
                out.push(v);
            }
        }
        e += step;
    }
    out
}

fn tick_step(ticks: &[f64]) -> f64 {
    match ticks {
        [a, b, ..] => (b - a).abs(),
        _ => 1.0,
    }
}

/// A tick label with as many decimals as the step needs.
pub fn format_tick(v: f64, step: f64) -> String {
    let a = v.abs();
    if a != 0.0 && (!(1e-4..1e6).contains(&a) || step < 1e-5) {
        return format!("{v:.1e}");
    }
    let decimals = if step > 0.0 {
        (-step.log10().floor()).clamp(0.0, 8.0) as usize
    } else {
        2
    };
    format!("{v:.decimals$}")
}

fn format_log_tick(e: f64) -> String {
    let v = 10f64.powf(e);
    if (1e-3..1e5).contains(&v) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        format!("{v:.0e}")
    }
}

/// A histogram: left edge of the first bin, bin width, counts, and how many values fell
/// outside `[lo, hi]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Histogram {
    pub lo: f64,
    pub width: f64,
    pub counts: Vec<usize>,
    pub outside: usize,
}

impl Histogram {
    /// `bins` equal bins over `[lo, hi]`; non-finite values are ignored.
    pub fn new(values: &[f64], lo: f64, hi: f64, bins: usize) -> Histogram {
        let bins = bins.max(1);
        let (lo, hi) = widen(lo, hi);
        let width = (hi - lo) / bins as f64;
        let mut counts = vec![0; bins];
        let mut outside = 0;
        for &v in values.iter().filter(|v| v.is_finite()) {
            if v < lo || v > hi {
                outside += 1;
                continue;
            }
            let k = (((v - lo) / width) as usize).min(bins - 1);
            counts[k] += 1;
        }
        Histogram {
            lo,
            width,
            counts,
            outside,
        }
    }

    /// Bars for [`Series::bars`].
    pub fn points(&self) -> Vec<(f64, f64)> {
        self.counts
            .iter()
            .enumerate()
            .map(|(k, &c)| (self.lo + k as f64 * self.width, c as f64))
            .collect()
    }

    /// Total count inside the range.
    pub fn total(&self) -> usize {
        self.counts.iter().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_covers_markup_characters() {
        assert_eq!(
            escape("a<b & c>\"d\" 'e'"),
            "a&lt;b &amp; c&gt;&quot;d&quot; &#39;e&#39;"
        );
        assert_eq!(escape("x\u{1}y"), "x\u{fffd}y");
    }

    #[test]
    fn coordinates_map_the_data_range_onto_the_area() {
        let p = Plot::new("p", "t", "x", "y")
            .size(400.0, 300.0)
            .series(Series::line("", "#000", vec![(0.0, 0.0), (10.0, 5.0)]))
            .y_range(0.0, 5.0);
        let sc = p.pixel_scale().expect("data");
        let (l, t, w, h) = p.area(sc.left);
        assert!((sc.px(0.0) - l).abs() < 1e-9);
        assert!((sc.px(10.0) - (l + w)).abs() < 1e-9);
        assert!((sc.py(0.0) - (t + h)).abs() < 1e-9, "y grows upward");
        assert!((sc.py(5.0) - t).abs() < 1e-9);
        assert!((sc.px(5.0) - (l + w / 2.0)).abs() < 1e-9);
        // Image rows: y grows downward.
        let sc = p.clone().y_down().pixel_scale().expect("data");
        assert!((sc.py(0.0) - t).abs() < 1e-9, "row 0 at the top");
        assert!((sc.py(5.0) - (t + h)).abs() < 1e-9);
    }

    #[test]
    fn log_axis_maps_decades_evenly() {
        let p = Plot::new("p", "t", "x", "y")
            .series(Series::line("", "#000", vec![(0.0, 1.0), (1.0, 100.0)]))
            .y_range(1.0, 100.0)
            .log_y();
        let sc = p.pixel_scale().expect("data");
        let mid = sc.py(10.0);
        assert!((mid - 0.5 * (sc.py(1.0) + sc.py(100.0))).abs() < 1e-9);
    }

    #[test]
    fn equal_aspect_gives_equal_units_per_pixel() {
        let p = Plot::new("p", "t", "x", "y")
            .size(600.0, 300.0)
            .series(Series::line("", "#000", vec![(0.0, 0.0), (1.0, 3.0)]))
            .equal_aspect();
        let sc = p.pixel_scale().expect("data");
        let ux = (sc.x1 - sc.x0) / sc.w;
        let uy = (sc.y1 - sc.y0) / sc.h;
        assert!((ux - uy).abs() < 1e-12 * ux.abs().max(1.0));
        assert!(sc.y0 <= 0.0 && sc.y1 >= 3.0 && sc.x0 <= 0.0 && sc.x1 >= 1.0);
    }

    #[test]
    fn thinning_a_dense_line_keeps_its_extremes() {
        // 100k samples of a sine with two spikes, over 500 pixels.
        let n = 100_000;
        let mut pts: Vec<(f64, f64)> = (0..n)
            .map(|k| {
                let x = k as f64 * 500.0 / n as f64;
                (x, 100.0 + 50.0 * (x * 0.05).sin())
            })
            .collect();
        pts[31_337].1 = -400.0;
        pts[77_777].1 = 900.0;
        let kept = thin_line(&pts, 0.0, 500.0);
        assert!(kept.len() <= 4 * 502, "{} points kept", kept.len());
        assert!(kept.contains(&pts[31_337]) && kept.contains(&pts[77_777]));
        assert_eq!(kept.first(), pts.first());
        assert_eq!(kept.last(), pts.last());
        assert!(kept.windows(2).all(|w| w[1].0 >= w[0].0), "order kept");
        // Deterministic.
        assert_eq!(kept, thin_line(&pts, 0.0, 500.0));
    }

    #[test]
    fn thinning_a_path_drops_only_subpixel_steps() {
        let pts: Vec<(f64, f64)> = (0..1000)
            .map(|k| {
                let a = k as f64 * 0.0063;
                (100.0 + 50.0 * a.cos(), 100.0 + 50.0 * a.sin())
            })
            .collect();
        let kept = thin_line(&pts, 0.0, 200.0);
        assert!(kept.len() < pts.len() && kept.len() > 300);
        for w in kept.windows(2) {
            assert!(((w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)) < 2.0);
        }
        assert_eq!(kept.last(), pts.last());
    }

    #[test]
    fn dots_keep_one_per_cell() {
        let pts = vec![(0.1, 0.1), (0.5, 0.5), (3.0, 0.2), (f64::NAN, 1.0)];
        assert_eq!(thin_dots(&pts, 2.0), vec![(0.1, 0.1), (3.0, 0.2)]);
    }

    #[test]
    fn ticks_are_round_and_inside() {
        let t = nice_ticks(0.13, 9.7, 5);
        assert_eq!(t, vec![2.0, 4.0, 6.0, 8.0]);
        let t = nice_ticks(-0.031, 0.029, 6);
        assert!(t.contains(&0.0) && t.iter().all(|v| (-0.031..=0.029).contains(v)));
        assert_eq!(format_tick(0.01, 0.01), "0.01");
        assert_eq!(format_tick(1500.0, 500.0), "1500");
        assert_eq!(log_ticks(0.0, 2.0).len(), 7);
        assert_eq!(format_log_tick(2.0), "100");
        assert!(nice_ticks(1.0, 1.0, 5).is_empty());
    }

    #[test]
    fn histogram_counts_and_outliers() {
        let h = Histogram::new(&[0.0, 0.1, 0.9, 1.0, 2.0, f64::NAN], 0.0, 1.0, 2);
        assert_eq!(h.counts, vec![2, 2]);
        assert_eq!(h.outside, 1);
        assert_eq!(h.points(), vec![(0.0, 2.0), (0.5, 2.0)]);
    }

    #[test]
    fn rendered_plot_is_escaped_and_carries_its_id() {
        let svg = Plot::new("cost", "a <b> & c", "x & y", "y")
            .series(Series::dots("<m>", "#123", vec![(0.0, 1.0), (1.0, 2.0)]))
            .spans("calm & quiet", vec![(0.2, 0.4), (0.41, 0.5)])
            .marker(0.5, "opt<", "#f00")
            .render();
        assert!(svg.starts_with("<svg id=\"cost\""));
        assert!(svg.ends_with("</svg>"));
        assert!(!svg.contains("<b>") && !svg.contains("<m>") && !svg.contains("opt<"));
        assert!(svg.contains("a &lt;b&gt; &amp; c") && svg.contains("calm &amp; quiet"));
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
    }

    #[test]
    fn empty_plot_says_so() {
        let svg = Plot::new("e", "t", "x", "y")
            .series(Series::line("s", "#000", vec![(f64::NAN, 1.0)]))
            .empty_note("nothing here")
            .render();
        assert!(svg.contains("data-empty=\"true\"") && svg.contains("nothing here"));
    }
}
