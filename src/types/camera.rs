//! Pinhole cameras with Kalibr's distortion models, and chains of them: the camera model every
//! stage shares (the camchain reader in `io::camchain`, a bag's `CameraInfo`, detection, PnP,
//! camera calibration, rendering). Pure math: reading and writing the files is `io`'s.
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

use nalgebra::{Matrix2, Matrix2x3, Matrix2x4, Vector2, Vector3};

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

impl Camchain {
    /// A chain of one camera.
    pub fn mono(cam: Camera) -> Camchain {
        Camchain {
            cams: vec![cam],
            t_cn_c0: vec![Se3::identity()],
            topics: vec![None],
        }
    }
}
