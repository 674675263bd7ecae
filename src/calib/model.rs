//! The DVL measurement model and its derivatives.
//!
//! `v_dvl = kappa * R_dvl_cam * (v_cam + w_cam x p_cam_dvl) + n`, evaluated with the camera twist at
//! the camera-clock time `t_dvl + time_offset_s`.

use nalgebra::{Matrix3, SMatrix, Vector3, Vector6};

use crate::error::{Error, Result};
use crate::lie::{hat, so3};
use crate::types::CalibrationParams;

/// A DVL velocity on the DVL clock (seconds relative to the camera epoch).
#[derive(Clone, Debug)]
pub struct DvlObs {
    /// DVL-clock time of validity, seconds (`t_cam = t + time_offset_s`).
    pub t: f64,
    /// Measured velocity of the DVL origin in the DVL frame, m/s.
    pub v: Vector3<f64>,
    /// Noise covariance `Q_d`.
    pub cov: Matrix3<f64>,
}

impl DvlObs {
    /// The information matrix `Q_d^-1`; an error naming the report's time when `Q_d` is
    /// singular.
    pub fn information(&self) -> Result<Matrix3<f64>> {
        self.cov.try_inverse().ok_or_else(|| {
            Error::Input(format!("DVL sample at t = {}: singular covariance", self.t))
        })
    }
}

/// Number of estimated parameters: rotation (3), lever arm (3), scale, time offset.
pub const NPARAM: usize = 8;

impl CalibrationParams {
    /// Applies an update `[dphi; dp; dkappa; ddelta]` in the estimator's coordinates (those of
    /// [`difference`] and of the covariance); the rotation is perturbed on the left,
    /// `R_dvl_cam <- exp(dphi) R_dvl_cam` (a rotation of the DVL frame).
    pub fn updated(&self, d: &SMatrix<f64, NPARAM, 1>) -> CalibrationParams {
        let dphi = Vector3::new(d[0], d[1], d[2]);
        let r = so3::exp(&dphi) * self.r_dvl_cam();
        CalibrationParams::from_r_dvl_cam(
            so3::matrix_from_quaternion(&so3::quaternion_from_matrix(&r)),
            self.lever_arm_cam_m() + Vector3::new(d[3], d[4], d[5]),
            self.velocity_scale + d[6],
            self.time_offset_s + d[7],
        )
    }
}

/// `self - other` in the coordinates of [`CalibrationParams::updated`] and of the covariance:
/// `[log(R_self R_other^T); p_self - p_other; kappa_self - kappa_other; delta_self - delta_other]`.
pub fn difference(a: &CalibrationParams, b: &CalibrationParams) -> SMatrix<f64, NPARAM, 1> {
    let r = so3::log(&(a.r_dvl_cam() * b.r_dvl_cam().transpose()));
    let p = a.lever_arm_cam_m() - b.lever_arm_cam_m();
    SMatrix::<f64, NPARAM, 1>::from_column_slice(&[
        r.x,
        r.y,
        r.z,
        p.x,
        p.y,
        p.z,
        a.velocity_scale - b.velocity_scale,
        a.time_offset_s - b.time_offset_s,
    ])
}

/// Predicted DVL velocity from the camera twist `[v; w]`.
pub fn predict(p: &CalibrationParams, twist: &Vector6<f64>) -> Vector3<f64> {
    let v = twist.fixed_rows::<3>(0).into_owned();
    let w = twist.fixed_rows::<3>(3).into_owned();
    p.r_dvl_cam() * (v + w.cross(&p.lever_arm_cam_m())) * p.velocity_scale
}

/// Derivative of the prediction with respect to the twist `[v; w]` (3x6):
/// `kappa R [I, -p^]`.
pub fn d_predict_d_twist(p: &CalibrationParams) -> SMatrix<f64, 3, 6> {
    let kr = p.r_dvl_cam() * p.velocity_scale;
    let mut j = SMatrix::<f64, 3, 6>::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&kr);
    j.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-(kr * hat(&p.lever_arm_cam_m()))));
    j
}

/// Derivative of the prediction with respect to the parameters `[dphi; dp; dkappa; ddelta]`
/// (3x8), given the twist and its rate at the sample's camera time.
pub fn d_predict_d_params(
    p: &CalibrationParams,
    twist: &Vector6<f64>,
    rate: &Vector6<f64>,
) -> SMatrix<f64, 3, NPARAM> {
    let v = twist.fixed_rows::<3>(0).into_owned();
    let w = twist.fixed_rows::<3>(3).into_owned();
    let u = v + w.cross(&p.lever_arm_cam_m());
    let ru = p.r_dvl_cam() * u;
    let mut j = SMatrix::<f64, 3, NPARAM>::zeros();
    // exp(dphi) R u ~= R u + dphi x (R u) = R u - (R u)^ dphi
    j.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-hat(&ru) * p.velocity_scale));
    j.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(p.r_dvl_cam() * hat(&w) * p.velocity_scale));
    j.set_column(6, &ru);
    let dv = rate.fixed_rows::<3>(0).into_owned();
    let dw = rate.fixed_rows::<3>(3).into_owned();
    j.set_column(
        7,
        &(p.r_dvl_cam() * (dv + dw.cross(&p.lever_arm_cam_m())) * p.velocity_scale),
    );
    j
}

/// Names of the parameters in the covariance's order, with the factor to their display unit
/// and the unit (empty for the scale).
pub const PARAM_NAMES: [(&str, f64, &str); NPARAM] = [
    ("rotation about x", 57.295_779_513_082_32, "deg"),
    ("rotation about y", 57.295_779_513_082_32, "deg"),
    ("rotation about z", 57.295_779_513_082_32, "deg"),
    ("lever arm x", 1e3, "mm"),
    ("lever arm y", 1e3, "mm"),
    ("lever arm z", 1e3, "mm"),
    ("velocity scale", 1.0, ""),
    ("clock offset", 1e3, "ms"),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_singular_dvl_covariance_is_an_error_naming_the_report() {
        let mut o = DvlObs {
            t: 12.5,
            v: Vector3::new(0.1, 0.0, 0.0),
            cov: Matrix3::from_diagonal_element(4e-4),
        };
        assert_eq!(
            o.information().unwrap(),
            Matrix3::from_diagonal_element(2500.0)
        );
        o.cov[(2, 2)] = 0.0;
        let e = o.information().unwrap_err().to_string();
        assert!(
            e.contains("t = 12.5") && e.contains("singular covariance"),
            "{e}"
        );
    }

    #[test]
    fn parameter_jacobian_matches_numeric_differentiation() {
        let p = CalibrationParams::from_r_dvl_cam(
            so3::exp(&Vector3::new(1.2, -0.3, 0.4)),
            Vector3::new(0.05, 0.25, -0.1),
            1.02,
            0.07,
        );
        // A twist that varies linearly in time: twist(t) = t0 + rate * t.
        let tw = Vector6::new(0.3, -0.2, 0.1, 0.5, -0.8, 0.3);
        let rate = Vector6::new(0.1, 0.05, -0.2, 0.3, 0.2, -0.1);
        let f =
            |q: &CalibrationParams| predict(q, &(tw + rate * (q.time_offset_s - p.time_offset_s)));
        let j = d_predict_d_params(&p, &tw, &rate);
        let h = 1e-6;
        for i in 0..NPARAM {
            let mut d = SMatrix::<f64, NPARAM, 1>::zeros();
            d[i] = h;
            let num = (f(&p.updated(&d)) - f(&p.updated(&-d))) / (2.0 * h);
            assert!(
                (num - j.column(i)).norm() < 1e-8,
                "column {i}: {num} vs {}",
                j.column(i)
            );
        }
        let jt = d_predict_d_twist(&p);
        for i in 0..6 {
            let mut d = Vector6::zeros();
            d[i] = h;
            let num = (predict(&p, &(tw + d)) - predict(&p, &(tw - d))) / (2.0 * h);
            assert!((num - jt.column(i)).norm() < 1e-8);
        }
    }
}
