//! An image drawn as an SVG panel in pixel coordinates, and the colour scales the panels use.

use std::fmt::Write as _;

use crate::report::html::put;
use crate::report::svg::{escape, format_tick, nice_ticks};

/// A linear colour scale from blue over amber to red, `t` in [0, 1].
pub(super) fn heat(t: f64) -> String {
    const STOPS: [(f64, [f64; 3]); 3] = [
        (0.0, [43.0, 108.0, 176.0]),
        (0.5, [232.0, 161.0, 10.0]),
        (1.0, [192.0, 21.0, 27.0]),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let (a, b) = if t <= 0.5 {
        (STOPS[0], STOPS[1])
    } else {
        (STOPS[1], STOPS[2])
    };
    let f = (t - a.0) / (b.0 - a.0);
    let c: Vec<u8> = (0..3)
        .map(|k| (a.1[k] + f * (b.1[k] - a.1[k])).round() as u8)
        .collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// A shade for a cell count, from pale (few) to dark blue (the most), `t` in [0, 1].
pub(super) fn shade(t: f64) -> String {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let lo = [232.0, 240.0, 250.0];
    let hi = [20.0, 70.0, 150.0];
    let c: Vec<u8> = (0..3)
        .map(|k| (lo[k] + t * (hi[k] - lo[k])).round() as u8)
        .collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// An SVG panel that shows an image: equal scale on both axes, rows growing downward as in the
/// image, the image rectangle `[-0.5, width - 0.5] x [-0.5, height - 0.5]` framed and ticked in
/// pixels.
pub(super) struct ImagePanel {
    pub(super) id: String,
    title: String,
    pub(super) img_w: f64,
    pub(super) img_h: f64,
    pub(super) left: f64,
    top: f64,
    pub(super) scale: f64,
    width: f64,
    height: f64,
}

impl ImagePanel {
    const LEFT: f64 = 52.0;
    const RIGHT: f64 = 14.0;
    const BOTTOM: f64 = 40.0;
    const TOP: f64 = 50.0;

    /// A panel `width` pixels wide (and at most `max_h` high) for an image of the given size.
    pub(super) fn new(
        id: &str,
        title: &str,
        img_w: u32,
        img_h: u32,
        width: f64,
        max_h: f64,
    ) -> Self {
        let (iw, ih) = (img_w.max(1) as f64, img_h.max(1) as f64);
        let aw = (width - Self::LEFT - Self::RIGHT).max(40.0);
        let ah = (max_h - Self::TOP - Self::BOTTOM).max(40.0);
        let scale = (aw / iw).min(ah / ih);
        ImagePanel {
            id: id.to_owned(),
            title: title.to_owned(),
            img_w: iw,
            img_h: ih,
            left: Self::LEFT,
            top: Self::TOP,
            scale,
            width,
            height: Self::TOP + ih * scale + Self::BOTTOM,
        }
    }

    /// Panel x of image column `u`.
    pub(super) fn x(&self, u: f64) -> f64 {
        self.left + (u + 0.5) * self.scale
    }

    /// Panel y of image row `v`.
    pub(super) fn y(&self, v: f64) -> f64 {
        self.top + (v + 0.5) * self.scale
    }

    /// Opens the `<svg>` with its title; `empty` marks a panel without data.
    pub(super) fn open(&self, s: &mut String, empty: bool) {
        let id = escape(&self.id);
        put!(
            s,
            "<svg id=\"{id}\" class=\"plot\" xmlns=\"http://www.w3.org/2000/svg\" \
             viewBox=\"0 0 {W:.0} {H:.0}\" width=\"{W:.0}\" height=\"{H:.0}\" role=\"img\" \
             aria-labelledby=\"{id}-title\"{e}><title id=\"{id}-title\">{t}</title>\
             <rect width=\"{W:.0}\" height=\"{H:.0}\" fill=\"#fff\"/>\
             <text x=\"{l:.1}\" y=\"17\" class=\"t\">{t}</text>",
            W = self.width,
            H = self.height,
            e = if empty { " data-empty=\"true\"" } else { "" },
            t = escape(&self.title),
            l = self.left
        );
    }

    /// The image rectangle (filled), its pixel ticks and the axis labels.
    pub(super) fn frame(&self, s: &mut String, fill: &str) {
        let (x0, y0) = (self.x(-0.5), self.y(-0.5));
        let (w, h) = (self.img_w * self.scale, self.img_h * self.scale);
        put!(
            s,
            "<rect x=\"{x0:.1}\" y=\"{y0:.1}\" width=\"{w:.1}\" height=\"{h:.1}\" fill=\"{fill}\" \
             stroke=\"#555\"/>"
        );
        let xt = nice_ticks(0.0, self.img_w, (w / 70.0).clamp(2.0, 10.0) as usize);
        for &u in &xt {
            let x = self.x(u);
            put!(
                s,
                "<line x1=\"{x:.1}\" y1=\"{b:.1}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#555\"/>\
                 <text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"k\">{}</text>",
                y0 + h + 4.0,
                y0 + h + 16.0,
                escape(&format_tick(u, 1.0)),
                b = y0 + h
            );
        }
        let yt = nice_ticks(0.0, self.img_h, (h / 45.0).clamp(2.0, 10.0) as usize);
        for &v in &yt {
            let y = self.y(v);
            put!(
                s,
                "<line x1=\"{:.1}\" y1=\"{y:.1}\" x2=\"{x0:.1}\" y2=\"{y:.1}\" stroke=\"#555\"/>\
                 <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\" class=\"k\">{}</text>",
                x0 - 4.0,
                x0 - 6.0,
                y + 4.0,
                escape(&format_tick(v, 1.0))
            );
        }
        put!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"a\">image column u (px)\
             </text><text transform=\"translate(13 {:.1}) rotate(-90)\" text-anchor=\"middle\" \
             class=\"a\">image row v (px, down)</text>",
            x0 + w / 2.0,
            self.height - 6.0,
            y0 + h / 2.0
        );
    }

    /// A note across an empty panel.
    pub(super) fn note(&self, s: &mut String, text: &str) {
        put!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"n\">{}</text>",
            self.x(self.img_w / 2.0 - 0.5),
            self.y(self.img_h / 2.0 - 0.5),
            escape(text)
        );
    }
}
