//! Calibrations of separate stretches of one recording combined into one estimate.
//!
//! Stretches of a recording that share no data give independent measurements of the same
//! calibration, except for the priors every one of them applied (the user's, the broad default
//! on the lever arm, and the hold of a lever-arm axis the stretch's motion could not observe).
//! Each stretch's estimate `theta_k` with covariance `Sigma_k` is read as a Gaussian posterior:
//! its data's information is `Sigma_k^-1 - P_k` (`P_k` the information of the priors it applied,
//! clamped to be positive semi-definite), and that data's information vector follows from the
//! optimum's zero gradient, `D_k delta_k - g_k` (`g_k` the priors' gradient at `theta_k`,
//! `delta_k` the estimate's coordinates about a common reference). The combination adds the
//! data of all stretches to the base priors once:
//!
//! `Lambda = P_0 + sum_k D_k`, `eta = g_0 + sum_k (D_k delta_k - g_k)`, `delta = Lambda^-1 eta`.
//!
//! Parameters held fixed (zero variance in the reference stretch) are left out and keep the
//! reference's value. The rotation's coordinates are those of [`super::model::difference`],
//! exact to first order in the stretches' disagreement (a small fraction of a degree).

use nalgebra::{DMatrix, DVector};

use super::model::{NPARAM, difference};
use super::prior::Priors;
use super::update::{ParamMat, ParamVec};
use crate::types::CalibrationParams;

/// One stretch's calibration: the estimate, its covariance in the estimator's coordinates,
/// and the priors it applied.
#[derive(Clone, Debug)]
pub struct StretchEstimate {
    /// The estimate.
    pub params: CalibrationParams,
    /// Its covariance (`[dphi; dp; dkappa; ddelta]`, zero for held parameters).
    pub covariance: ParamMat,
    /// The priors the estimate used.
    pub priors: Priors,
}

/// The stretches combined.
#[derive(Clone, Debug)]
pub struct Fused {
    /// The combined estimate.
    pub params: CalibrationParams,
    /// Its covariance (zero for the held parameters).
    pub covariance: ParamMat,
}

/// The indices of the parameters free in `cov` (a positive variance).
fn free_indices(cov: &ParamMat) -> Vec<usize> {
    (0..NPARAM).filter(|&i| cov[(i, i)] > 0.0).collect()
}

/// `m` restricted to the rows and columns `idx`.
fn restrict(m: &ParamMat, idx: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(idx.len(), idx.len(), |r, c| m[(idx[r], idx[c])])
}

/// The symmetric `m` with its negative eigenvalues set to zero (`inverse`: with its positive
/// eigenvalues inverted instead, those below `1e-12` of the largest left out).
fn spectral(m: &DMatrix<f64>, inverse: bool) -> DMatrix<f64> {
    let n = m.nrows();
    if n == 0 {
        return m.clone();
    }
    let sym = (m + m.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
    let vals = eig.eigenvalues.map(|l| {
        if inverse {
            if l > 1e-12 * top && l > 0.0 {
                1.0 / l
            } else {
                0.0
            }
        } else {
            l.max(0.0)
        }
    });
    &eig.eigenvectors * DMatrix::from_diagonal(&vals) * eig.eigenvectors.transpose()
}

/// Combines the stretches' estimates about `reference` (usually the latest stretch), with
/// `base` the priors the combination keeps once (the stretches' own holds of lever-arm axes are
/// not among them). The held parameters are those `reference` holds. `None` when a stretch's
/// covariance is not finite or the combined information cannot be inverted.
pub fn fuse(
    stretches: &[StretchEstimate],
    reference: &StretchEstimate,
    base: &Priors,
) -> Option<Fused> {
    let idx = free_indices(&reference.covariance);
    let n = idx.len();
    let theta_ref = &reference.params;
    let base_terms = base.terms(theta_ref);
    let mut lambda = restrict(&base_terms.information, &idx);
    let mut eta = DVector::from_iterator(n, idx.iter().map(|&i| base_terms.gradient[i]));
    for s in stretches {
        if s.covariance.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let info = spectral(&restrict(&s.covariance, &idx), true);
        let terms = s.priors.terms(&s.params);
        let data = spectral(&(info - restrict(&terms.information, &idx)), false);
        let delta_full: ParamVec = difference(&s.params, theta_ref);
        let delta = DVector::from_iterator(n, idx.iter().map(|&i| delta_full[i]));
        let g = DVector::from_iterator(n, idx.iter().map(|&i| terms.gradient[i]));
        eta += &data * delta - g;
        lambda += data;
    }
    let chol = lambda.clone().cholesky()?;
    let delta = chol.solve(&eta);
    let cov = chol.inverse();
    let mut step = ParamVec::zeros();
    let mut covariance = ParamMat::zeros();
    for (r, &i) in idx.iter().enumerate() {
        step[i] = delta[r];
        for (c, &j) in idx.iter().enumerate() {
            covariance[(i, j)] = cov[(r, c)];
        }
    }
    if covariance.iter().any(|x| !x.is_finite()) {
        return None;
    }
    Some(Fused {
        params: theta_ref.updated(&step),
        covariance,
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::calib::prior::LeverArmPrior;

    fn params(p: [f64; 3], kappa: f64, delta: f64) -> CalibrationParams {
        CalibrationParams::from_r_dvl_cam(
            nalgebra::Matrix3::identity(),
            Vector3::from(p),
            kappa,
            delta,
        )
    }

    fn diag(v: [f64; NPARAM]) -> ParamMat {
        ParamMat::from_diagonal(&ParamVec::from(v))
    }

    #[test]
    fn two_stretches_without_priors_average_by_their_information() {
        let a = StretchEstimate {
            params: params([0.1, 0.0, 0.0], 1.0, 0.010),
            covariance: diag([1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4, 1e-4, 1e-6]),
            priors: Priors::default(),
        };
        let b = StretchEstimate {
            params: params([0.2, 0.0, 0.0], 1.0, 0.020),
            covariance: diag([1e-6, 1e-6, 1e-6, 3e-4, 1e-4, 1e-4, 1e-4, 3e-6]),
            priors: Priors::default(),
        };
        let f = fuse(&[a.clone(), b.clone()], &b, &Priors::default()).expect("fused");
        // Inverse-variance weights: 3/4 and 1/4.
        assert!((f.params.lever_arm_cam_m().x - 0.125).abs() < 1e-12);
        assert!((f.params.time_offset_s - 0.0125).abs() < 1e-12);
        assert!((f.covariance[(3, 3)] - 0.75e-4).abs() < 1e-16);
        assert!((f.covariance[(4, 4)] - 0.5e-4).abs() < 1e-16);
    }

    #[test]
    fn a_prior_every_stretch_applied_counts_once() {
        // A stretch that saw nothing of the lever arm: its posterior is the prior (zero, 1 m).
        let prior = Priors {
            lever_arm: Some(LeverArmPrior {
                lever_arm_cam_m: Vector3::zeros(),
                sigma_m: 1.0,
            }),
            ..Priors::default()
        };
        let mut cov = diag([1e-6, 1e-6, 1e-6, 1.0, 1.0, 1.0, 1e-4, 1e-6]);
        let calm = StretchEstimate {
            params: params([0.0; 3], 1.0, 0.0),
            covariance: cov,
            priors: prior,
        };
        // A stretch that measured it: data information 1e4 plus the prior's 1.
        cov[(3, 3)] = 1.0 / (1e4 + 1.0);
        cov[(4, 4)] = cov[(3, 3)];
        cov[(5, 5)] = cov[(3, 3)];
        let turning = StretchEstimate {
            params: params([0.3 * 1e4 / (1e4 + 1.0); 3], 1.0, 0.0),
            covariance: cov,
            priors: prior,
        };
        let f = fuse(&[calm, turning.clone()], &turning, &prior).expect("fused");
        // Data 1e4 once and the prior once, not twice.
        assert!((f.covariance[(3, 3)] - cov[(3, 3)]).abs() < 1e-12);
        assert!((f.params.lever_arm_cam_m().x - turning.params.lever_arm_cam_m().x).abs() < 1e-9);
    }

    #[test]
    fn a_held_parameter_stays_held() {
        let mut cov = diag([1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4, 1e-4, 0.0]);
        cov[(0, 3)] = 1e-7;
        cov[(3, 0)] = 1e-7;
        let a = StretchEstimate {
            params: params([0.1, 0.0, 0.0], 1.0, 0.05),
            covariance: cov,
            priors: Priors::default(),
        };
        let b = StretchEstimate {
            params: params([0.1, 0.0, 0.0], 1.01, 0.05),
            covariance: cov,
            priors: Priors::default(),
        };
        let f = fuse(&[a, b.clone()], &b, &Priors::default()).expect("fused");
        assert_eq!(f.covariance[(7, 7)], 0.0);
        assert_eq!(f.params.time_offset_s, 0.05);
        assert!((f.params.velocity_scale - 1.005).abs() < 1e-12);
        assert!((f.covariance[(0, 3)] - 0.5e-7).abs() < 1e-18);
    }
}
