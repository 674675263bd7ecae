//! The correlation matrix of the eight calibration parameters, from the covariance the
//! calibration reports ([`CalibrationOutcome::covariance`], after its inflations), as a
//! colour-coded table with the strongly correlated pairs named in words.

use std::fmt::Write as _;

use super::svg::escape;
use crate::calib::model::NPARAM;
use crate::calib::{CalibrationOutcome, Method, PARAM_NAMES};

/// Pairs correlated more strongly than this are named under the table.
pub(super) const STRONG: f64 = 0.9;

/// The correlation matrix: `None` in the rows and columns of parameters that were not
/// estimated (held by the method, or without a positive finite variance).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Correlation {
    pub r: [[Option<f64>; NPARAM]; NPARAM],
    /// Whether each parameter was estimated.
    pub estimated: [bool; NPARAM],
    /// Whether the lever arm was held at the broad default prior (the motion did not observe
    /// it): its variance is the prior's, with no covariance with anything else.
    pub lever_arm_held: bool,
}

impl Correlation {
    pub fn of(o: &CalibrationOutcome) -> Correlation {
        let mut held = match o.method {
            Method::Fixed {
                estimate_offset, ..
            } => [
                true,
                true,
                true,
                true,
                true,
                true,
                !estimate_offset,
                !estimate_offset,
            ],
            _ => [false; NPARAM],
        };
        let c = &o.covariance;
        let lever = 3..6;
        let lever_arm_held = o.lever_arm_from_default_prior
            && lever.clone().all(|k| {
                (0..NPARAM)
                    .filter(|j| !lever.contains(j))
                    .all(|j| c[(k, j)] == 0.0 && c[(j, k)] == 0.0)
            });
        if lever_arm_held {
            for h in &mut held[lever] {
                *h = true;
            }
        }
        let mut estimated = [false; NPARAM];
        for k in 0..NPARAM {
            let v = c[(k, k)];
            estimated[k] = !held[k] && v.is_finite() && v > 0.0;
        }
        let mut r = [[None; NPARAM]; NPARAM];
        for i in 0..NPARAM {
            for j in 0..NPARAM {
                if estimated[i] && estimated[j] {
                    let x = if i == j {
                        1.0
                    } else {
                        // The average of both triangles keeps the matrix exactly symmetric.
                        0.5 * (c[(i, j)] + c[(j, i)]) / (c[(i, i)] * c[(j, j)]).sqrt()
                    };
                    r[i][j] = Some(x.clamp(-1.0, 1.0));
                }
            }
        }
        Correlation {
            r,
            estimated,
            lever_arm_held,
        }
    }

    /// The pairs `(i, j, r)`, `i < j`, with `|r| > STRONG`, strongest first.
    pub fn strong_pairs(&self) -> Vec<(usize, usize, f64)> {
        let mut out = Vec::new();
        for i in 0..NPARAM {
            for j in i + 1..NPARAM {
                if let Some(x) = self.r[i][j].filter(|x| x.abs() > STRONG) {
                    out.push((i, j, x));
                }
            }
        }
        out.sort_by(|a, b| b.2.abs().total_cmp(&a.2.abs()));
        out
    }
}

/// Short column labels, in the order of [`PARAM_NAMES`].
const SHORT: [&str; NPARAM] = [
    "rot x", "rot y", "rot z", "p x", "p y", "p z", "scale", "offset",
];

/// Background of a cell: blue for positive, red for negative, stronger with `|r|`.
fn cell_colour(r: f64) -> String {
    let a = r.abs().clamp(0.0, 1.0);
    let (cr, cg, cb) = if r >= 0.0 {
        (33.0, 102.0, 172.0)
    } else {
        (178.0, 24.0, 43.0)
    };
    let mix = |c: f64| (255.0 + (c - 255.0) * a).round() as u8;
    format!("#{:02x}{:02x}{:02x}", mix(cr), mix(cg), mix(cb))
}

/// The section: the table and the strongly correlated pairs in words.
pub(super) fn correlation_section(o: &CalibrationOutcome) -> String {
    let c = Correlation::of(o);
    let mut s = String::from(
        "<section id=\"correlation\"><h2>Correlation of the estimates</h2>\n<p>The correlation \
         of each pair of parameters in the covariance the standard deviations come from (rotation \
         about the DVL axes, lever arm along the camera axes, velocity scale, clock offset). \
         Near +1 or -1 the data cannot tell the two apart: an error in one is made up by the \
         other, and their standard deviations are large together. Blue is positive, red \
         negative.</p>\n<table id=\"correlation-matrix\" class=\"corr\"><tr><th></th>",
    );
    for name in SHORT {
        let _ = write!(s, "<th>{}</th>", escape(name));
    }
    s.push_str("</tr>");
    for i in 0..NPARAM {
        let _ = write!(
            s,
            "<tr><th title=\"{}\">{}</th>",
            escape(PARAM_NAMES[i].0),
            escape(SHORT[i])
        );
        for j in 0..NPARAM {
            match c.r[i][j] {
                Some(x) => {
                    let fg = if x.abs() > 0.6 { "#fff" } else { "#111" };
                    let bold = if i != j && x.abs() > STRONG {
                        ";font-weight:700"
                    } else {
                        ""
                    };
                    let _ = write!(
                        s,
                        "<td class=\"num\" style=\"background:{};color:{fg}{bold}\">{x:+.2}</td>",
                        cell_colour(x)
                    );
                }
                // The lever arm held at its prior was given its value by the prior, not fixed.
                None if c.lever_arm_held && (3..6).any(|k| k == i || k == j) => {
                    s.push_str("<td class=\"fixed-cell\">prior</td>")
                }
                None => s.push_str("<td class=\"fixed-cell\">fixed</td>"),
            }
        }
        s.push_str("</tr>");
    }
    s.push_str("</table>\n");
    let at_prior = |k: usize| c.lever_arm_held && (3..6).contains(&k);
    let held: Vec<&str> = (0..NPARAM)
        .filter(|&k| !c.estimated[k] && !at_prior(k))
        .map(|k| PARAM_NAMES[k].0)
        .collect();
    if !held.is_empty() {
        let _ = writeln!(
            s,
            "<p>Fixed in this run, so without a correlation: {}.</p>",
            escape(&held.join(", "))
        );
    }
    if c.lever_arm_held {
        s.push_str(
            "<p id=\"correlation-prior\">The lever arm is held at its prior (the broad default \
             prior: the motion did not observe it), so it has no correlation with the others \
             (cells marked prior).</p>\n",
        );
    }
    let strong = c.strong_pairs();
    if strong.is_empty() {
        let _ = writeln!(
            s,
            "<p id=\"correlation-words\">No pair of estimated parameters is correlated beyond \
             {STRONG}: the recording separates them.</p>"
        );
    } else {
        s.push_str("<ul id=\"correlation-words\" class=\"warn\">");
        for (i, j, x) in strong {
            let _ = write!(
                s,
                "<li>{}</li>",
                escape(&format!(
                    "The {} and the {} are strongly correlated ({x:+.3}): this recording hardly \
                     tells them apart{}.",
                    PARAM_NAMES[i].0,
                    PARAM_NAMES[j].0,
                    pair_advice(i, j)
                ))
            );
        }
        s.push_str("</ul>\n");
    }
    s.push_str("</section>\n");
    s
}

/// What usually separates a pair, in words.
fn pair_advice(i: usize, j: usize) -> &'static str {
    match (i, j) {
        (3..=5, 3..=5) | (0..=2, 3..=5) => {
            "; rotating more strongly and about more axes separates the lever arm"
        }
        (6, 7) => "; changes of speed (speeding up, slowing down, reversing) separate them",
        (0..=2, 6 | 7) | (3..=5, 6 | 7) => "; more varied motion separates them",
        _ => "",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_run_from_white_to_the_sign_colour() {
        assert_eq!(cell_colour(0.0), "#ffffff");
        assert_eq!(cell_colour(1.0), "#2166ac");
        assert_eq!(cell_colour(-1.0), "#b2182b");
    }

    #[test]
    fn advice_covers_the_usual_pairs() {
        assert!(pair_advice(3, 5).contains("rotating"));
        assert!(pair_advice(6, 7).contains("speed"));
        assert_eq!(pair_advice(0, 1), "");
    }
}
