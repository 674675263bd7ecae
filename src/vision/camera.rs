//! Pinhole cameras with Kalibr's distortion models, and Kalibr camchain files.
//!
//! Pixel convention: OpenCV's and Kalibr's, the centre of the top-left pixel is at (0, 0).
//! Camera frame: x right, y down, z forward.
//!
//! Distortion of the normalised point `(x, y) = (X/Z, Y/Z)`:
//! - `radtan` (Kalibr's name; OpenCV's plumb-bob with k3 = 0), coefficients `[k1, k2, p1, p2]`:
//!   `x' = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)`,
//!   `y' = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y`;
//! - `equidistant` (OpenCV's fisheye), `[k1, k2, k3, k4]`: `theta = atan(r)`,
//!   `theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`,
//!   `(x', y') = (theta_d / r) (x, y)`;
//! - `none`.
//!
//! Pixel: `u = fu x' + pu`, `v = fv y' + pv`.

use nalgebra::{Matrix2, Matrix2x3, Matrix2x4, Matrix4, Vector2, Vector3};
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use crate::error::{Error, Result};
use crate::lie::Se3;

/// Lens distortion model and coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distortion {
    /// No distortion (Kalibr's `none`).
    None,
    /// Radial-tangential distortion (Kalibr's `radtan`, OpenCV's plumb-bob with k3 = 0).
    RadTan {
        /// Second-order radial coefficient (multiplies r^2).
        k1: f64,
        /// Fourth-order radial coefficient (multiplies r^4).
        k2: f64,
        /// First tangential coefficient.
        p1: f64,
        /// Second tangential coefficient.
        p2: f64,
    },
    /// Equidistant fisheye distortion (Kalibr's `equidistant`, OpenCV's fisheye).
    Equidistant {
        /// Coefficient of theta^3 in the distorted angle theta_d.
        k1: f64,
        /// Coefficient of theta^5 in the distorted angle theta_d.
        k2: f64,
        /// Coefficient of theta^7 in the distorted angle theta_d.
        k3: f64,
        /// Coefficient of theta^9 in the distorted angle theta_d.
        k4: f64,
    },
}

impl Distortion {
    /// Kalibr's name of the model.
    pub fn kalibr_name(&self) -> &'static str {
        match self {
            Distortion::None => "none",
            Distortion::RadTan { .. } => "radtan",
            Distortion::Equidistant { .. } => "equidistant",
        }
    }

    /// The coefficients in Kalibr's order.
    pub fn coeffs(&self) -> Vec<f64> {
        match *self {
            Distortion::None => vec![],
            Distortion::RadTan { k1, k2, p1, p2 } => vec![k1, k2, p1, p2],
            Distortion::Equidistant { k1, k2, k3, k4 } => vec![k1, k2, k3, k4],
        }
    }

    /// Distorted normalised point and its 2x2 Jacobian with respect to the undistorted point.
    pub fn distort(&self, p: &Vector2<f64>) -> (Vector2<f64>, Matrix2<f64>) {
        let (x, y) = (p.x, p.y);
        match *self {
            Distortion::None => (*p, Matrix2::identity()),
            Distortion::RadTan { k1, k2, p1, p2 } => {
                let r2 = x * x + y * y;
                let radial = 1.0 + k1 * r2 + k2 * r2 * r2;
                let d_radial = k1 + 2.0 * k2 * r2; // d radial / d r2
                let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
                let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
                // d r2/dx = 2x, d r2/dy = 2y
                let dxd_dx = radial + x * d_radial * 2.0 * x + 2.0 * p1 * y + p2 * 6.0 * x;
                let dxd_dy = x * d_radial * 2.0 * y + 2.0 * p1 * x + p2 * 2.0 * y;
                let dyd_dx = y * d_radial * 2.0 * x + p1 * 2.0 * x + 2.0 * p2 * y;
                let dyd_dy = radial + y * d_radial * 2.0 * y + p1 * 6.0 * y + 2.0 * p2 * x;
                (
                    Vector2::new(xd, yd),
                    Matrix2::new(dxd_dx, dxd_dy, dyd_dx, dyd_dy),
                )
            }
            Distortion::Equidistant { k1, k2, k3, k4 } => {
                let r2 = x * x + y * y;
                let r = r2.sqrt();
                if r < 1e-12 {
                    // theta_d / r -> 1 as r -> 0.
                    return (*p, Matrix2::identity());
                }
                let th = r.atan();
                let t2 = th * th;
                let poly = 1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)));
                let thd = th * poly;
                // d thd / d th
                let dthd_dth =
                    1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
                let dth_dr = 1.0 / (1.0 + r2);
                let s = thd / r; // scale
                let ds_dr = (dthd_dth * dth_dr * r - thd) / r2;
                // d(s x)/dx = s + x ds/dr * x/r
                let j = Matrix2::new(
                    s + ds_dr * x * x / r,
                    ds_dr * x * y / r,
                    ds_dr * x * y / r,
                    s + ds_dr * y * y / r,
                );
                (Vector2::new(s * x, s * y), j)
            }
        }
    }

    /// The 2x4 Jacobian of the distorted normalised point with respect to the four coefficients,
    /// in Kalibr's order (zero for [`Distortion::None`]).
    pub fn coeff_jacobian(&self, p: &Vector2<f64>) -> Matrix2x4<f64> {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        match self {
            Distortion::None => Matrix2x4::zeros(),
            Distortion::RadTan { .. } => Matrix2x4::new(
                x * r2,
                x * r2 * r2,
                2.0 * x * y,
                r2 + 2.0 * x * x,
                y * r2,
                y * r2 * r2,
                r2 + 2.0 * y * y,
                2.0 * x * y,
            ),
            Distortion::Equidistant { .. } => {
                let r = r2.sqrt();
                if r < 1e-12 {
                    return Matrix2x4::zeros();
                }
                // d theta_d / d k_i = theta^(2i+1); the point scales by theta_d / r.
                let th = r.atan();
                let t2 = th * th;
                let mut m = Matrix2x4::zeros();
                let mut pow = th * t2;
                for i in 0..4 {
                    m[(0, i)] = pow * x / r;
                    m[(1, i)] = pow * y / r;
                    pow *= t2;
                }
                m
            }
        }
    }

    /// Undistorts a distorted normalised point by Gauss-Newton iteration; `None` when the
    /// iteration does not converge (outside the region where the model is invertible).
    pub fn undistort(&self, pd: &Vector2<f64>) -> Option<Vector2<f64>> {
        let start = match self {
            Distortion::None => return Some(*pd),
            // Start at the point with the same distorted angle, ignoring the polynomial.
            Distortion::Equidistant { .. } => {
                let rd = pd.norm();
                if rd > 1e-12 && rd < std::f64::consts::FRAC_PI_2 {
                    pd * (rd.tan() / rd)
                } else {
                    *pd
                }
            }
            Distortion::RadTan { .. } => *pd,
        };
        let mut p = start;
        for _ in 0..30 {
            let (f, j) = self.distort(&p);
            let step = j.try_inverse()? * (f - pd);
            p -= step;
            if !p.iter().all(|v| v.is_finite()) {
                return None;
            }
            if step.norm_squared() < 1e-26 {
                break;
            }
        }
        ((self.distort(&p).0 - pd).norm() < 1e-9).then_some(p)
    }
}

/// A pinhole camera with distortion.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Horizontal focal length (px).
    pub fu: f64,
    /// Vertical focal length (px).
    pub fv: f64,
    /// Horizontal coordinate of the principal point (px, centre of the top-left pixel at 0).
    pub pu: f64,
    /// Vertical coordinate of the principal point (px, centre of the top-left pixel at 0).
    pub pv: f64,
    /// Lens distortion of the normalised image point.
    pub distortion: Distortion,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
}

impl Camera {
    /// Pixel of a camera-frame point, OpenCV/Kalibr convention (centre of the top-left pixel at
    /// (0,0)); `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<Vector2<f64>> {
        // Behind or on the camera plane (NaN included).
        if p.z.is_nan() || p.z <= 1e-12 {
            return None;
        }
        let n = Vector2::new(p.x / p.z, p.y / p.z);
        let (d, _) = self.distortion.distort(&n);
        Some(Vector2::new(
            self.fu * d.x + self.pu,
            self.fv * d.y + self.pv,
        ))
    }

    /// Pixel and its Jacobian with respect to the camera-frame point.
    pub fn project_jacobian(&self, p: &Vector3<f64>) -> Option<(Vector2<f64>, Matrix2x3<f64>)> {
        // Behind or on the camera plane (NaN included).
        if p.z.is_nan() || p.z <= 1e-12 {
            return None;
        }
        let iz = 1.0 / p.z;
        let n = Vector2::new(p.x * iz, p.y * iz);
        let (d, jd) = self.distortion.distort(&n);
        let jn = Matrix2x3::new(iz, 0.0, -n.x * iz, 0.0, iz, -n.y * iz);
        let jf = Matrix2::new(self.fu, 0.0, 0.0, self.fv);
        Some((
            Vector2::new(self.fu * d.x + self.pu, self.fv * d.y + self.pv),
            jf * jd * jn,
        ))
    }

    /// Unit-depth ray (z = 1) of a pixel, undistorting iteratively; `None` where the distortion
    /// model cannot be inverted.
    pub fn unproject(&self, px: &Vector2<f64>) -> Option<Vector3<f64>> {
        let pd = Vector2::new((px.x - self.pu) / self.fu, (px.y - self.pv) / self.fv);
        let n = self.distortion.undistort(&pd)?;
        Some(Vector3::new(n.x, n.y, 1.0))
    }

    /// Whether a pixel lies on the image (between the outer pixel edges).
    pub fn in_image(&self, px: &Vector2<f64>) -> bool {
        px.x >= -0.5
            && px.y >= -0.5
            && px.x <= self.width as f64 - 0.5
            && px.y <= self.height as f64 - 0.5
    }
}

/// A chain of cameras (Kalibr's camchain).
#[derive(Clone, Debug, PartialEq)]
pub struct Camchain {
    /// The cameras, cam0 first.
    pub cams: Vec<Camera>,
    /// `T_cn_c0` (maps cam0 points into cam n), identity for cam0, composed from Kalibr's
    /// `T_cn_cnm1`.
    pub t_cn_c0: Vec<Se3>,
    /// Each camera's `rostopic`, when given.
    pub topics: Vec<Option<String>>,
}

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

impl Camchain {
    /// A chain of one camera.
    pub fn mono(cam: Camera) -> Camchain {
        Camchain {
            cams: vec![cam],
            t_cn_c0: vec![Se3::identity()],
            topics: vec![None],
        }
    }

    /// Reads a Kalibr camchain YAML (`cam0`, `cam1`, ...; other keys such as `T_cam_imu` and
    /// `cam_overlaps` are ignored).
    pub fn load(path: &Path) -> Result<Camchain> {
        let text = crate::files::read_text(path)?;
        Camchain::parse(&text, path)
    }

    /// Parses camchain YAML text; `path` names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Camchain> {
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

    /// The chain as a Kalibr camchain YAML (`load` reads it back; `T_cn_cnm1` from `t_cn_c0`).
    pub fn to_kalibr_yaml(&self) -> String {
        let mut s = String::new();
        for i in 0..self.cams.len() {
            s.push_str(&format!("cam{i}:\n"));
            s.push_str(&self.kalibr_entry(i));
        }
        s
    }

    /// The keys of camera `i` in Kalibr's camchain (`T_cn_cnm1` for all but cam0,
    /// `camera_model`, `distortion_coeffs`, `distortion_model`, `intrinsics`, `resolution`,
    /// `rostopic` when known), one per line, indented by two spaces; empty for a camera the
    /// chain does not have.
    pub fn kalibr_entry(&self, i: usize) -> String {
        let mut s = String::new();
        if let Some(c) = self.cams.get(i) {
            if i > 0 {
                let t = self.t_cn_c0[i] * self.t_cn_c0[i - 1].inverse();
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
            if let Some(Some(t)) = self.topics.get(i) {
                s.push_str(&format!("  rostopic: {t}\n"));
            }
        }
        s
    }
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
