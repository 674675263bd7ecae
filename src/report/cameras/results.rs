//! The results per camera: intrinsics and distortion with their standard deviations beside
//! OpenCV's initial values, and the transforms between consecutive cameras.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::shared::{cam_color, px};
use crate::camcal::CamCalResult;
use crate::lie::{Se3, so3};
use crate::report::html::{put, section};
use crate::report::svg::escape;
use crate::types::camera::{Camchain, Distortion};

/// Decimals that show a standard deviation with two significant digits (at most 9).
fn decimals_for(sd: f64) -> usize {
    if sd.is_finite() && sd > 0.0 {
        (1.0 - sd.log10().floor()).clamp(0.0, 9.0) as usize
    } else {
        4
    }
}

/// One row of a results table: name, final ± std, initial, change.
fn result_row(s: &mut String, name: &str, value: f64, sd: Option<f64>, initial: Option<f64>) {
    let d = sd.map_or(4, decimals_for);
    let est = match sd {
        Some(sd) if sd.is_finite() => format!("{value:.d$} ± {sd:.d$}"),
        _ => format!("{value:.d$}"),
    };
    let (init, change) = match initial {
        Some(i) => (format!("{i:.d$}"), format!("{:+.d$}", value - i)),
        None => ("–".to_owned(), String::new()),
    };
    put!(
        s,
        "<tr><td>{}</td><td class=\"pm\">{}</td><td class=\"pm\">{}</td>\
         <td class=\"pm chg\">{}</td></tr>",
        escape(name),
        escape(&est),
        escape(&init),
        escape(&change)
    );
}

/// The names of a distortion's coefficients, in Kalibr's order.
fn coeff_names(d: &Distortion) -> &'static [&'static str] {
    match d {
        Distortion::None => &[],
        Distortion::RadTan { .. } => &["k1", "k2", "p1", "p2"],
        Distortion::Equidistant { .. } => &["k1", "k2", "k3", "k4"],
    }
}

/// `T_cn_cnm1` of camera `i > 0` in a chain.
fn t_cn_cnm1(chain: &Camchain, i: usize) -> Option<Se3> {
    let n = chain.t_cn_c0.get(i)?;
    let m = chain.t_cn_c0.get(i.checked_sub(1)?)?;
    Some(*n * m.inverse())
}

pub(super) fn results(s: &mut String, r: &CamCalResult) {
    section(s, "results", "Results per camera");
    if r.chain.cams.is_empty() {
        s.push_str("<p>The result holds no camera.</p></section>\n");
        return;
    }
    s.push_str(
        "<p>The final estimate of each parameter with its standard deviation (one sigma, from the \
         bundle adjustment's covariance scaled by the estimated corner noise), the value OpenCV's \
         calibrateCamera started from, and the change. Focal lengths and principal point in \
         pixels (the centre of the top-left pixel at 0).</p>\n<div class=\"grid\">",
    );
    for (i, cam) in r.chain.cams.iter().enumerate() {
        let sd = r.std.get(i);
        let init = r.initial.cams.get(i);
        put!(
            s,
            "<div><table><tr><th colspan=\"4\" style=\"color:{}\">cam{i}: {}x{} {}</th></tr>\
             <tr><th>parameter</th><th>final ± std</th><th>initial (OpenCV)</th>\
             <th>change</th></tr>",
            cam_color(i),
            cam.width,
            cam.height,
            escape(&format!(
                "pinhole-{}",
                cam.distortion.kalibr_name().replace("equidistant", "equi")
            ))
        );
        let vals = [cam.fu, cam.fv, cam.pu, cam.pv];
        let ivals = init.map(|c| [c.fu, c.fv, c.pu, c.pv]);
        for (k, name) in ["fu", "fv", "pu", "pv"].iter().enumerate() {
            result_row(
                s,
                name,
                vals[k],
                sd.map(|x| x.intrinsics[k]),
                ivals.map(|v| v[k]),
            );
        }
        let coeffs = cam.distortion.coeffs();
        let icoeffs = init.map(|c| c.distortion.coeffs());
        for (k, name) in coeff_names(&cam.distortion).iter().enumerate() {
            let Some(&v) = coeffs.get(k) else { continue };
            result_row(
                s,
                name,
                v,
                sd.and_then(|x| x.distortion.get(k).copied()),
                icoeffs.as_ref().and_then(|c| c.get(k).copied()),
            );
        }
        put!(
            s,
            "<tr><td>reprojection RMS</td><td class=\"pm\">{}</td><td class=\"pm\">{}</td>\
             <td></td></tr>",
            escape(&px(r.rms_px_per_cam.get(i).copied().unwrap_or(f64::NAN))),
            escape(&px(r.initial_rms_px.get(i).copied().unwrap_or(f64::NAN)))
        );
        s.push_str("</table></div>");
    }
    s.push_str("</div>\n");
    extrinsics(s, r);
    s.push_str("</section>\n");
}

/// The transforms between consecutive cameras.
fn extrinsics(s: &mut String, r: &CamCalResult) {
    s.push_str("<h3>Extrinsics T_cn_cnm1</h3>");
    if r.chain.cams.len() < 2 {
        s.push_str(
            "<p>No extrinsics: the chain has a single camera, so there is no transform between \
             cameras to estimate.</p>\n",
        );
        return;
    }
    s.push_str(
        "<p><code>T_cn_cnm1</code> maps points from camera n-1 into camera n (Kalibr's \
         convention). The rotation is given as a rotation vector (axis times angle, degrees) with \
         its standard deviation about cam n's x, y and z axes; the translation and the baseline \
         (its length) in millimetres.</p>\n<table><tr><th>camera</th><th>quantity</th>\
         <th>final ± std</th><th>initial (OpenCV)</th><th>change</th></tr>",
    );
    for i in 1..r.chain.cams.len() {
        let Some(t) = t_cn_cnm1(&r.chain, i) else {
            put!(
                s,
                "<tr><td>cam{i}</td><td colspan=\"4\">no transform in the result</td></tr>"
            );
            continue;
        };
        let t0 = t_cn_cnm1(&r.initial, i);
        let sd = r.std.get(i);
        let rv: Vector3<f64> = so3::log(&t.rot).map(f64::to_degrees);
        let rv0 = t0.map(|t0| so3::log(&t0.rot).map(f64::to_degrees));
        let rot_sd = sd.and_then(|x| x.rotation_rad);
        let tr_sd = sd.and_then(|x| x.translation_m);
        let rows: Vec<(String, f64, Option<f64>, Option<f64>)> = (0..3)
            .map(|k| {
                (
                    format!("rotation vector {} (deg)", ["x", "y", "z"][k]),
                    rv[k],
                    rot_sd.map(|v| v[k].to_degrees()),
                    rv0.map(|v| v[k]),
                )
            })
            .chain((0..3).map(|k| {
                (
                    format!("translation {} (mm)", ["x", "y", "z"][k]),
                    1e3 * t.trans[k],
                    tr_sd.map(|v| 1e3 * v[k]),
                    t0.map(|t0| 1e3 * t0.trans[k]),
                )
            }))
            .chain([
                (
                    "rotation angle (deg)".to_owned(),
                    rv.norm(),
                    None,
                    rv0.map(|v| v.norm()),
                ),
                (
                    "baseline (mm)".to_owned(),
                    1e3 * t.trans.norm(),
                    sd.and_then(|x| x.baseline_m).map(|b| 1e3 * b),
                    t0.map(|t0| 1e3 * t0.trans.norm()),
                ),
            ])
            .collect();
        let n = rows.len();
        for (k, (name, v, sd, init)) in rows.into_iter().enumerate() {
            if k == 0 {
                put!(
                    s,
                    "<tr><td rowspan=\"{n}\" style=\"color:{}\">cam{i} from cam{}</td>",
                    cam_color(i),
                    i - 1
                );
                // result_row opens its own row: strip its <tr>.
                let mut row = String::new();
                result_row(&mut row, &name, v, sd, init);
                s.push_str(row.trim_start_matches("<tr>"));
            } else {
                result_row(s, &name, v, sd, init);
            }
        }
    }
    s.push_str("</table>\n");
}
