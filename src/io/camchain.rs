//! Kalibr camchain files (`camchain.yaml`): the cameras of a [`Camchain`] with their
//! intrinsics, distortion and `T_cn_cnm1`, read with every value checked and written in a form
//! Kalibr's own YAML reader takes back.

use nalgebra::Matrix4;
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::types::camera::{Camchain, Camera, Distortion};

#[derive(Deserialize)]
struct CamEntry {
    camera_model: String,
    intrinsics: Vec<f64>,
    distortion_model: String,
    #[serde(default)]
    distortion_coeffs: Vec<f64>,
    resolution: Vec<u32>,
    #[serde(default)]
    rostopic: Option<String>,
    #[serde(default, rename = "T_cn_cnm1")]
    t_cn_cnm1: Option<Vec<Vec<f64>>>,
}

fn yaml_err(path: &Path, e: serde_yaml::Error) -> Error {
    let line = e.location().map(|l| l.line()).unwrap_or(0);
    Error::parse(path, line, e.to_string())
}

/// Reads a Kalibr camchain YAML (`cam0`, `cam1`, ...; other keys such as `T_cam_imu` and
/// `cam_overlaps` are ignored).
pub fn read_camchain(path: &Path) -> Result<Camchain> {
    let text = crate::files::read_text(path)?;
    parse_camchain(&text, path)
}

/// Parses camchain YAML text; `path` names the source in errors.
pub fn parse_camchain(text: &str, path: &Path) -> Result<Camchain> {
    let entries: BTreeMap<String, serde_yaml::Value> =
        serde_yaml::from_str(text).map_err(|e| yaml_err(path, e))?;
    let mut chain = Camchain {
        cams: vec![],
        t_cn_c0: vec![],
        topics: vec![],
    };
    // The line of each `camN:` key (its first line starting so), found in one pass: a
    // search per camera would take time quadratic in the file.
    let mut key_lines: HashMap<&str, usize> = HashMap::new();
    for (i, l) in text.lines().enumerate() {
        if let Some((key, _)) = l.split_once(':')
            && key.starts_with("cam")
        {
            key_lines.entry(key).or_insert(i + 1);
        }
    }
    let mut n = 0usize;
    loop {
        let key = format!("cam{n}");
        let Some(v) = entries.get(&key) else { break };
        // Re-serialise the entry to check it with field-level messages; the line of the
        // camera's key locates it in the file.
        let line = key_lines.get(key.as_str()).copied().unwrap_or(0);
        let e: CamEntry = serde_yaml::from_value(v.clone())
            .map_err(|err| Error::parse(path, line, format!("{key}: {}", explain(&err))))?;
        let bad = |msg: String| Error::parse(path, line, format!("{key}: {msg}"));
        if e.camera_model != "pinhole" {
            return Err(bad(format!(
                "camera_model '{}' is not supported (only pinhole)",
                e.camera_model
            )));
        }
        if e.intrinsics.len() != 4 {
            return Err(bad(format!(
                "intrinsics must be [fu, fv, pu, pv], got {} values",
                e.intrinsics.len()
            )));
        }
        if !e.intrinsics.iter().all(|v| v.is_finite()) {
            return Err(bad(format!(
                "intrinsics {:?} are not all finite numbers",
                e.intrinsics
            )));
        }
        if e.intrinsics[0] <= 0.0 || e.intrinsics[1] <= 0.0 {
            return Err(bad("focal lengths must be positive".into()));
        }
        if e.resolution.len() != 2 || e.resolution[0] == 0 || e.resolution[1] == 0 {
            return Err(bad("resolution must be [width, height]".into()));
        }
        // The principal point lies inside the image for every real camera; outside it, the
        // intrinsics belong to another resolution or are in the wrong order.
        let (w, h) = (f64::from(e.resolution[0]), f64::from(e.resolution[1]));
        let inside = (0.0..w).contains(&e.intrinsics[2]) && (0.0..h).contains(&e.intrinsics[3]);
        if !inside || e.intrinsics[2] == 0.0 || e.intrinsics[3] == 0.0 {
            return Err(bad(format!(
                "the principal point ({}, {}) is outside the {}x{} image: intrinsics of \
                 another resolution, or not in the order [fu, fv, pu, pv]",
                e.intrinsics[2], e.intrinsics[3], e.resolution[0], e.resolution[1]
            )));
        }
        let c = &e.distortion_coeffs;
        let distortion = match e.distortion_model.as_str() {
            "none" if c.iter().all(|v| *v == 0.0) => Distortion::None,
            "radtan" if c.len() == 4 => Distortion::RadTan {
                k1: c[0],
                k2: c[1],
                p1: c[2],
                p2: c[3],
            },
            "equidistant" if c.len() == 4 => Distortion::Equidistant {
                k1: c[0],
                k2: c[1],
                k3: c[2],
                k4: c[3],
            },
            "none" | "radtan" | "equidistant" => {
                return Err(bad(format!(
                    "distortion_model {} needs {} distortion_coeffs, got {}",
                    e.distortion_model,
                    if e.distortion_model == "none" {
                        "no"
                    } else {
                        "4"
                    },
                    c.len()
                )));
            }
            other => {
                return Err(bad(format!(
                    "distortion_model '{other}' is not supported (radtan, equidistant, none)"
                )));
            }
        };
        let corner_radius = {
            let (fu, fv, pu, pv) = (
                e.intrinsics[0],
                e.intrinsics[1],
                e.intrinsics[2],
                e.intrinsics[3],
            );
            let du = pu.max(w - pu) / fu;
            let dv = pv.max(h - pv) / fv;
            du.hypot(dv)
        };
        if let Some(fold) = fold_radius(&distortion, corner_radius) {
            return Err(bad(format!(
                "the distortion coefficients {c:?} fold the image over itself {:.0} px from \
                 the principal point, inside the image: coefficients of another model or \
                 camera, or in another order",
                fold * e.intrinsics[0]
            )));
        }
        let t_prev = if n == 0 {
            Se3::identity()
        } else {
            let m = e
                .t_cn_cnm1
                .as_ref()
                .ok_or_else(|| bad("T_cn_cnm1 is missing".into()))?;
            if m.len() != 4 || m.iter().any(|r| r.len() != 4) {
                return Err(bad("T_cn_cnm1 must be a 4x4 matrix".into()));
            }
            let mut mm = Matrix4::zeros();
            for (r, row) in m.iter().enumerate() {
                for (cc, v) in row.iter().enumerate() {
                    mm[(r, cc)] = *v;
                }
            }
            if !mm.iter().all(|v| v.is_finite()) {
                return Err(bad("T_cn_cnm1 is not finite".into()));
            }
            let r = mm.fixed_view::<3, 3>(0, 0).into_owned();
            if (r.transpose() * r - nalgebra::Matrix3::identity()).norm() > 1e-3 {
                return Err(bad("T_cn_cnm1's rotation block is not a rotation".into()));
            }
            if r.determinant() < 0.0 {
                return Err(bad(
                    "T_cn_cnm1's rotation block is a reflection (determinant -1): an axis \
                     is flipped"
                        .into(),
                ));
            }
            let baseline = mm.fixed_view::<3, 1>(0, 3).norm();
            if baseline > 2.0 {
                return Err(bad(format!(
                    "T_cn_cnm1 puts the cameras {baseline:.1} m apart: translations are in \
                     metres (millimetres given?)"
                )));
            }
            Se3::from_matrix(&mm)
        };
        let t_cn_c0 = match chain.t_cn_c0.last() {
            None => Se3::identity(),
            Some(prev) => t_prev * *prev,
        };
        chain.cams.push(Camera {
            fu: e.intrinsics[0],
            fv: e.intrinsics[1],
            pu: e.intrinsics[2],
            pv: e.intrinsics[3],
            distortion,
            width: e.resolution[0],
            height: e.resolution[1],
        });
        chain.t_cn_c0.push(t_cn_c0);
        chain.topics.push(e.rostopic);
        n += 1;
    }
    if chain.cams.is_empty() {
        return Err(Error::parse(path, 1, "no cam0 in the camchain"));
    }
    if let Some(k) = entries
        .keys()
        .filter(|k| k.starts_with("cam") && k[3..].parse::<usize>().is_ok())
        .find(|k| k[3..].parse::<usize>().map(|i| i >= n).unwrap_or(false))
    {
        return Err(Error::parse(
            path,
            0,
            format!("{k} present but cam{n} missing (cameras must be numbered from cam0)"),
        ));
    }
    Ok(chain)
}

/// The chain as a Kalibr camchain YAML ([`read_camchain`] reads it back; `T_cn_cnm1` from
/// `t_cn_c0`).
pub fn camchain_yaml(chain: &Camchain) -> String {
    let mut s = String::new();
    for i in 0..chain.cams.len() {
        s.push_str(&format!("cam{i}:\n"));
        s.push_str(&kalibr_entry(chain, i));
    }
    s
}

/// The keys of camera `i` in Kalibr's camchain (`T_cn_cnm1` for all but cam0,
/// `camera_model`, `distortion_coeffs`, `distortion_model`, `intrinsics`, `resolution`,
/// `rostopic` when known), one per line, indented by two spaces; empty for a camera the
/// chain does not have.
pub fn kalibr_entry(chain: &Camchain, i: usize) -> String {
    let mut s = String::new();
    if let Some(c) = chain.cams.get(i) {
        if i > 0 {
            let t = chain.t_cn_c0[i] * chain.t_cn_c0[i - 1].inverse();
            let m = t.to_matrix();
            s.push_str("  T_cn_cnm1:\n");
            for r in 0..4 {
                s.push_str(&format!(
                    "  - [{}, {}, {}, {}]\n",
                    yaml_float(m[(r, 0)]),
                    yaml_float(m[(r, 1)]),
                    yaml_float(m[(r, 2)]),
                    yaml_float(m[(r, 3)])
                ));
            }
        }
        s.push_str("  camera_model: pinhole\n");
        s.push_str(&format!(
            "  distortion_coeffs: [{}]\n",
            c.distortion
                .coeffs()
                .iter()
                .map(|&v| yaml_float(v))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        s.push_str(&format!(
            "  distortion_model: {}\n",
            c.distortion.kalibr_name()
        ));
        s.push_str(&format!(
            "  intrinsics: [{}, {}, {}, {}]\n",
            yaml_float(c.fu),
            yaml_float(c.fv),
            yaml_float(c.pu),
            yaml_float(c.pv)
        ));
        s.push_str(&format!("  resolution: [{}, {}]\n", c.width, c.height));
        if let Some(Some(t)) = chain.topics.get(i) {
            s.push_str(&format!("  rostopic: {t}\n"));
        }
    }
    s
}

/// A number as YAML 1.1 readers (PyYAML, hence Kalibr) read a float: the shortest digits that
/// read back exactly, with a decimal point and a signed exponent (`1e-20` would be a string to
/// them; `1.0e-20` is a float).
pub fn yaml_float(x: f64) -> String {
    let s = format!("{x:?}");
    match s.split_once('e') {
        Some((m, e)) => {
            let m = if m.contains('.') {
                m.to_owned()
            } else {
                format!("{m}.0")
            };
            let e = if e.starts_with('-') {
                e.to_owned()
            } else {
                format!("+{e}")
            };
            format!("{m}e{e}")
        }
        None => s,
    }
}

/// A YAML type error in words a user can act on: a word where a number belongs (`nan`, `inf`,
/// `1,5`) is named as not a number.
fn explain(err: &serde_yaml::Error) -> String {
    let msg = err.to_string();
    match msg
        .strip_prefix("invalid type: string \"")
        .and_then(|rest| rest.split_once("\", expected f64"))
    {
        Some((word, _)) => {
            format!("\"{word}\" is not a number (camera parameters are finite decimal numbers)")
        }
        None => msg,
    }
}

/// The distorted radius (normalised image coordinates) at which the radial distortion stops
/// growing with the angle off axis, when that happens within `corner` (the farthest image
/// corner from the principal point): there the image would fold over itself, which no real lens
/// does. `None` for a lens that stays monotone over the whole image.
fn fold_radius(d: &Distortion, corner: f64) -> Option<f64> {
    // (distorted radius, its derivative) at undistorted radius r (radtan) or angle theta
    // (equidistant); tangential terms are small and left out.
    let radial = |x: f64| -> (f64, f64) {
        match *d {
            Distortion::None => (x, 1.0),
            Distortion::RadTan { k1, k2, .. } => {
                let x2 = x * x;
                (
                    x * (1.0 + k1 * x2 + k2 * x2 * x2),
                    1.0 + 3.0 * k1 * x2 + 5.0 * k2 * x2 * x2,
                )
            }
            Distortion::Equidistant { k1, k2, k3, k4 } => {
                let t2 = x * x;
                let poly = 1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)));
                let dpoly =
                    1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
                (x * poly, dpoly)
            }
        }
    };
    // Walk outwards until the distorted radius passes the corner: radtan up to a radius far
    // beyond any lens, equidistant up to 90 degrees off axis.
    let limit = match d {
        Distortion::Equidistant { .. } => std::f64::consts::FRAC_PI_2,
        _ => 20.0 * corner.max(1e-3),
    };
    let steps = 4000;
    for k in 1..=steps {
        let x = limit * k as f64 / steps as f64;
        let (rd, slope) = radial(x);
        if slope <= 0.0 || slope.is_nan() || !rd.is_finite() {
            let (rd_prev, _) = radial(limit * (k - 1) as f64 / steps as f64);
            return (rd_prev <= corner).then_some(rd_prev.max(0.0));
        }
        if rd > corner {
            return None;
        }
    }
    None
}
