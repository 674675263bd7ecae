//! Gaussian priors on the calibration: what the user knows without the data (a lever arm
//! measured with a tape, a rotation known from the mount). They enter the MAP problem as
//! factors on the parameters, in the estimator's coordinates `[dphi; dp; dkappa; ddelta]`.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::model::NPARAM;
use crate::error::{Error, Result};
use crate::lie::so3;
use crate::types::CalibrationParams;

// The parameter-space types of `refine`, spelled out so that this module does not import it.
type ParamMat = SMatrix<f64, NPARAM, NPARAM>;
type ParamVec = SVector<f64, NPARAM>;

/// A lever arm `lever_arm_cam_m` known to `sigma_m` (the same on each axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeverArmPrior {
    /// The DVL origin in the camera frame, metres.
    pub lever_arm_cam_m: Vector3<f64>,
    /// Standard deviation on each axis, metres.
    pub sigma_m: f64,
}

/// A rotation `R_cam_dvl` known to `sigma_deg` (about each axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotationPrior {
    /// `R_cam_dvl`: maps DVL-frame vectors into the camera frame.
    pub r_cam_dvl: Matrix3<f64>,
    /// Standard deviation of the rotation about each axis, degrees.
    pub sigma_deg: f64,
}

/// Directions of the lever arm held at a value: a tight prior along each, none across them. The
/// calibration sets it when the motion turned about too few axes to observe some components of
/// the lever arm (see `refinement`); a user's prior is [`LeverArmPrior`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldLeverAxes {
    /// Orthogonal projector onto the held directions (camera frame).
    pub projector: Matrix3<f64>,
    /// The value the held components are held at (camera frame, metres; only its projection
    /// counts).
    pub lever_arm_cam_m: Vector3<f64>,
    /// Standard deviation along the held directions, metres (tight: they are held).
    pub sigma_m: f64,
}

/// The priors of a calibration; none by default.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Priors {
    /// A prior on the lever arm.
    pub lever_arm: Option<LeverArmPrior>,
    /// A prior on the rotation.
    pub rotation: Option<RotationPrior>,
    /// Lever-arm directions held (set by the calibration, not by the user).
    pub held_lever_axes: Option<HeldLeverAxes>,
}

/// A prior's contribution at some parameters: cost, information and gradient (`J^T W r`).
#[derive(Clone, Debug)]
pub struct PriorTerms {
    /// Sum of the squared, whitened prior residuals.
    pub cost: f64,
    /// Information the priors add, in the estimator's coordinates.
    pub information: ParamMat,
    /// `J^T W r` with `r` the residual from the current value to the prior's.
    pub gradient: ParamVec,
}

impl Priors {
    /// Whether any prior is given.
    pub fn any(&self) -> bool {
        self.lever_arm.is_some() || self.rotation.is_some() || self.held_lever_axes.is_some()
    }

    /// Checks the priors: finite values, positive standard deviations, a proper rotation.
    pub fn validate(&self) -> Result<()> {
        if let Some(l) = &self.lever_arm
            && !(l.lever_arm_cam_m.iter().all(|v| v.is_finite())
                && l.sigma_m.is_finite()
                && l.sigma_m > 0.0)
        {
            return Err(Error::Input(format!(
                "lever-arm prior {:?} with sigma {} m: the values must be finite and the sigma \
                 positive",
                l.lever_arm_cam_m.as_slice(),
                l.sigma_m
            )));
        }
        if let Some(r) = &self.rotation {
            let orthonormal = (r.r_cam_dvl.transpose() * r.r_cam_dvl - Matrix3::identity()).norm();
            let proper = orthonormal < 1e-6 && r.r_cam_dvl.determinant() > 0.0;
            if !(r.sigma_deg.is_finite() && r.sigma_deg > 0.0 && proper) {
                return Err(Error::Input(format!(
                    "rotation prior with sigma {} deg: the sigma must be positive and the \
                     rotation a proper one",
                    r.sigma_deg
                )));
            }
        }
        Ok(())
    }

    /// The priors' cost, information and gradient at `p`. The rotation residual is
    /// `log(R0_dvl_cam R_dvl_cam^T)`, the left perturbation that takes the estimate to the
    /// prior; its Jacobian is taken as the identity (exact at the prior, and within a part in
    /// a thousand for residuals under a few degrees).
    pub fn terms(&self, p: &CalibrationParams) -> PriorTerms {
        let mut t = PriorTerms {
            cost: 0.0,
            information: ParamMat::zeros(),
            gradient: ParamVec::zeros(),
        };
        let mut add = |first: usize, r: Vector3<f64>, sigma: f64| {
            let w = 1.0 / (sigma * sigma);
            t.cost += w * r.norm_squared();
            for k in 0..3 {
                t.information[(first + k, first + k)] += w;
                t.gradient[first + k] += w * r[k];
            }
        };
        if let Some(r) = &self.rotation {
            let residual = so3::log(&(r.r_cam_dvl.transpose() * p.r_dvl_cam().transpose()));
            add(0, residual, r.sigma_deg.to_radians());
        }
        if let Some(l) = &self.lever_arm {
            add(3, l.lever_arm_cam_m - p.lever_arm_cam_m(), l.sigma_m);
        }
        if let Some(h) = &self.held_lever_axes {
            let w = 1.0 / (h.sigma_m * h.sigma_m);
            let r = h.projector * (h.lever_arm_cam_m - p.lever_arm_cam_m());
            t.cost += w * r.norm_squared();
            let mut block = t.information.fixed_view_mut::<3, 3>(3, 3);
            block += h.projector * w;
            let mut g = t.gradient.fixed_rows_mut::<3>(3);
            g += r * w;
        }
        t
    }
}

/// The text form of a prior on the command line, `a,b,c[:sigma]`: three finite numbers and an
/// optional positive standard deviation (units are the option's).
#[derive(Clone, Debug)]
pub struct VectorSigma {
    /// The three numbers.
    pub v: [f64; 3],
    /// The standard deviation after the colon, if given.
    pub sigma: Option<f64>,
}

impl std::str::FromStr for VectorSigma {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        let bad = || "three numbers and an optional positive sigma, as 0.1,-0.02,0.3:0.01".into();
        let number = |x: &str| x.trim().parse::<f64>().map_err(|_| bad());
        let (values, sigma) = match text.split_once(':') {
            Some((v, s)) => (v, Some(number(s)?)),
            None => (text, None),
        };
        let v = values
            .split(',')
            .map(number)
            .collect::<std::result::Result<Vec<f64>, String>>()?;
        match v[..] {
            [x, y, z]
                if v.iter().chain(&sigma).all(|c| c.is_finite())
                    && sigma.is_none_or(|s| s > 0.0) =>
            {
                Ok(Self {
                    v: [x, y, z],
                    sigma,
                })
            }
            _ => Err(bad()),
        }
    }
}

/// The text form of an optional standard deviation: a positive number, or `none`.
#[derive(Clone, Debug)]
pub struct SigmaOrNone(pub Option<f64>);

impl std::str::FromStr for SigmaOrNone {
    type Err = String;
    fn from_str(t: &str) -> std::result::Result<Self, String> {
        match t.trim() {
            "none" => Ok(SigmaOrNone(None)),
            t => match t.parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(SigmaOrNone(Some(v))),
                _ => Err("a positive number of metres, or `none`".into()),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(p: Vector3<f64>) -> CalibrationParams {
        CalibrationParams::from_r_dvl_cam(Matrix3::identity(), p, 1.0, 0.0)
    }

    #[test]
    fn held_lever_axes_pull_along_their_directions_only() {
        let u = Vector3::new(0.0, 0.6, 0.8);
        let held = Priors {
            held_lever_axes: Some(HeldLeverAxes {
                projector: u * u.transpose(),
                lever_arm_cam_m: Vector3::zeros(),
                sigma_m: 1e-3,
            }),
            ..Priors::default()
        };
        assert!(held.any());
        let p = Vector3::new(0.3, -0.2, 0.1);
        let t = held.terms(&at(p));
        // Cost: the component along u, whitened; information w u u^T; gradient w u (u.r).
        let along = u.dot(&p);
        assert!((t.cost - (along / 1e-3).powi(2)).abs() < 1e-9 * t.cost);
        let info = t.information.fixed_view::<3, 3>(3, 3).into_owned();
        assert!((info - u * u.transpose() * 1e6).norm() < 1e-6);
        assert!((t.gradient.fixed_rows::<3>(3) + u * along * 1e6).norm() < 1e-6);
        // Nothing on the other parameters, nothing across u.
        assert_eq!(t.information.fixed_view::<3, 3>(0, 0).norm(), 0.0);
        let across = Vector3::new(1.0, 0.8, -0.6);
        assert!(held.terms(&at(across)).cost < 1e-20);
        // With every direction held it is the isotropic prior.
        let all = Priors {
            held_lever_axes: Some(HeldLeverAxes {
                projector: Matrix3::identity(),
                lever_arm_cam_m: Vector3::new(0.1, 0.0, 0.0),
                sigma_m: 0.5,
            }),
            ..Priors::default()
        };
        let iso = Priors {
            lever_arm: Some(LeverArmPrior {
                lever_arm_cam_m: Vector3::new(0.1, 0.0, 0.0),
                sigma_m: 0.5,
            }),
            ..Priors::default()
        };
        let (a, b) = (all.terms(&at(p)), iso.terms(&at(p)));
        assert!((a.cost - b.cost).abs() < 1e-12);
        assert!((a.information - b.information).norm() < 1e-12);
        assert!((a.gradient - b.gradient).norm() < 1e-12);
    }
}
