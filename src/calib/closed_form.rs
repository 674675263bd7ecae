//! Closed-form initial extrinsics (the paper's Sec. IV-C-2).
//!
//! Stacking `v_dvl_i^T = [v_i^T, -w_i^T] Z` with `Z = [(kappa R)^T; (kappa R p^)^T]` (6x3) gives a
//! linear least-squares problem in `Z`. The camera twists are estimates with covariance
//! `Sigma_i`, so `sum h_i h_i^T` overestimates `sum h_i^o h_i^o^T` by `G = sum S Sigma_i S`
//! (`S = diag(I, -I)`); subtracting `G` removes that bias (errors-in-variables correction).
//! Then `kappa = |det Z1|^(1/3)`, `R` is the nearest rotation to `Z1^T / kappa` and the lever arm
//! is the skew part of `R^T Z2^T / kappa`.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

use crate::error::{Error, Result};
use crate::lie::vee;
use crate::types::CalibrationParams;

/// One row of the stacked problem.
#[derive(Clone, Debug)]
pub struct ClosedFormRow {
    /// Measured DVL velocity.
    pub v_dvl: Vector3<f64>,
    /// Estimated camera twist `[v; w]` at the sample's camera time.
    pub twist: Vector6<f64>,
    /// Covariance of that twist estimate.
    pub twist_cov: Matrix6<f64>,
}

/// Result of the closed form.
#[derive(Clone, Debug)]
pub struct ClosedForm {
    /// Rotation, lever arm and scale; the time offset is left at zero (set by the caller).
    pub params: CalibrationParams,
    /// Whether the angular-velocity part of the normal matrix was too weak to solve for the lever
    /// arm (it is then zero and must not be trusted).
    pub lever_arm_solved: bool,
    /// Smallest eigenvalue of the angular-velocity block of the (corrected) normal matrix divided
    /// by the number of rows: the mean squared angular rate along the least excited axis.
    pub min_rotation_excitation: f64,
    /// Mean variance of one component of the camera's angular velocity as the trajectory
    /// estimates it, (rad/s)^2: the noise that excitation has to stand out from.
    pub angular_noise_variance: f64,
}

impl ClosedForm {
    /// The least excited axis's mean squared angular rate over the angular velocity's noise
    /// variance: below a few, the angular velocity is mostly noise and the lever arm, seen only
    /// through `w x p`, is not observed.
    pub fn rotation_snr(&self) -> f64 {
        self.min_rotation_excitation / self.angular_noise_variance.max(1e-300)
    }
}

/// Nearest rotation matrix to `m` (SVD projection with the determinant forced to +1).
pub fn project_to_rotation(m: &Matrix3<f64>) -> Result<Matrix3<f64>> {
    let svd = m.svd(true, true);
    let (u, vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Err(Error::Numerical("SVD failed in rotation projection".into())),
    };
    let d = (u * vt).determinant().signum();
    Ok(u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt)
}

/// Solves the stacked problem; `bias_corrected` subtracts the twist-covariance bias.
pub fn closed_form(rows: &[ClosedFormRow], bias_corrected: bool) -> Result<ClosedForm> {
    if rows.len() < 4 {
        return Err(Error::TooFewSamples {
            what: "DVL samples inside the camera span for the closed-form extrinsics".into(),
            found: rows.len(),
            needed: 4,
        });
    }
    let s = Matrix6::from_diagonal(&Vector6::new(1.0, 1.0, 1.0, -1.0, -1.0, -1.0));
    let mut a = Matrix6::zeros();
    let mut b = SMatrix::<f64, 6, 3>::zeros();
    for r in rows {
        let h = s * r.twist;
        a += h * h.transpose();
        if bias_corrected {
            a -= s * r.twist_cov * s;
        }
        b += h * r.v_dvl.transpose();
    }
    let n = rows.len() as f64;
    a /= n;
    b /= n;
    let a = (a + a.transpose()) * 0.5;
    let avv: Matrix3<f64> = a.fixed_view::<3, 3>(0, 0).into_owned();
    let aww: Matrix3<f64> = a.fixed_view::<3, 3>(3, 3).into_owned();
    let excitation = aww.symmetric_eigenvalues().min();
    let vmax = avv.symmetric_eigenvalues().max();
    if !(vmax.is_finite() && vmax > 0.0) {
        return Err(Error::Input(
            "the camera did not move while the DVL was logging: no velocity to calibrate against"
                .into(),
        ));
    }
    // The lever arm needs rotation about at least two axes; a numerically singular angular block
    // leaves it undetermined.
    let lever_arm_solved = excitation > 1e-10 * vmax.max(1e-12) && {
        let ev = a.symmetric_eigenvalues();
        ev.min() > 1e-12 * ev.max()
    };
    let z: SMatrix<f64, 6, 3> = if lever_arm_solved {
        a.cholesky()
            .map(|c| c.solve(&b))
            .or_else(|| a.lu().solve(&b))
            .ok_or_else(|| {
                Error::Numerical("normal matrix of the closed form is singular".into())
            })?
    } else {
        let bv: SMatrix<f64, 3, 3> = b.fixed_view::<3, 3>(0, 0).into_owned();
        let z1 = avv
            .lu()
            .solve(&bv)
            .ok_or_else(|| Error::Input("camera velocity spans fewer than three axes".into()))?;
        let mut z = SMatrix::<f64, 6, 3>::zeros();
        z.fixed_view_mut::<3, 3>(0, 0).copy_from(&z1);
        z
    };
    let kr: Matrix3<f64> = z.fixed_view::<3, 3>(0, 0).transpose();
    let det = kr.determinant();
    if !(det.is_finite() && det.abs() > 1e-12) {
        // Whose velocities are degenerate: the DVL's (a constant or replayed value), or the
        // camera's (motion along a line or in a plane).
        let dvl: Matrix3<f64> = rows.iter().map(|r| r.v_dvl * r.v_dvl.transpose()).sum();
        let ev = dvl.symmetric_eigenvalues();
        let dvl_degenerate = ev.min() <= 1e-10 * ev.max() || !ev.min().is_finite();
        let msg = if dvl_degenerate {
            "the DVL velocities span fewer than three directions (they are constant, or lie \
             along one line or in one plane, exactly): the DVL rotation is undetermined; check \
             the DVL log"
        } else {
            "the camera velocity does not excite all three axes: the DVL rotation is undetermined"
        };
        return Err(Error::Input(msg.into()));
    }
    let scale = det.abs().cbrt();
    let r = project_to_rotation(&(kr / scale))?;
    let lever_arm = if lever_arm_solved {
        let m = r.transpose() * z.fixed_view::<3, 3>(3, 0).transpose() / scale;
        vee(&((m - m.transpose()) * 0.5))
    } else {
        Vector3::zeros()
    };
    Ok(ClosedForm {
        params: CalibrationParams::from_r_dvl_cam(r, lever_arm, scale, 0.0),
        lever_arm_solved,
        min_rotation_excitation: excitation.max(0.0),
        angular_noise_variance: rows
            .iter()
            .map(|r| (r.twist_cov[(3, 3)] + r.twist_cov[(4, 4)] + r.twist_cov[(5, 5)]) / 3.0)
            .sum::<f64>()
            / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::model::predict;
    use crate::lie::so3;
    use crate::rng::Rng;

    #[test]
    fn exact_data_gives_exact_parameters() {
        let truth = CalibrationParams::from_r_dvl_cam(
            so3::exp(&Vector3::new(-1.5, 0.05, 0.02)),
            Vector3::new(0.05, 0.25, -0.1),
            1.01,
            0.0,
        );
        let mut rng = Rng::new(3);
        let rows: Vec<ClosedFormRow> = (0..50)
            .map(|_| {
                let tw = rng.normal_vec6() * 0.5;
                ClosedFormRow {
                    v_dvl: predict(&truth, &tw),
                    twist: tw,
                    twist_cov: Matrix6::zeros(),
                }
            })
            .collect();
        let cf = closed_form(&rows, true).unwrap();
        assert!(cf.lever_arm_solved);
        assert!((cf.params.r_dvl_cam() - truth.r_dvl_cam()).abs().max() < 1e-12);
        assert!((cf.params.lever_arm_cam_m() - truth.lever_arm_cam_m()).norm() < 1e-12);
        assert!((cf.params.velocity_scale - truth.velocity_scale).abs() < 1e-12);
    }

    #[test]
    fn bias_correction_removes_attenuation() {
        // Noisy regressors shrink an uncorrected least-squares estimate towards zero; with the
        // covariance subtracted the scale is recovered on average.
        let truth = CalibrationParams::from_r_dvl_cam(
            Matrix3::identity(),
            Vector3::new(0.1, -0.2, 0.3),
            1.0,
            0.0,
        );
        let mut rng = Rng::new(11);
        let sd = 0.1;
        let cov = Matrix6::identity() * sd * sd;
        let rows: Vec<ClosedFormRow> = (0..20000)
            .map(|_| {
                let tw = rng.normal_vec6() * 0.3;
                ClosedFormRow {
                    v_dvl: predict(&truth, &tw),
                    twist: tw + rng.normal_vec6() * sd,
                    twist_cov: cov,
                }
            })
            .collect();
        let biased = closed_form(&rows, false).unwrap();
        let fixed = closed_form(&rows, true).unwrap();
        // Attenuation factor 0.09 / (0.09 + 0.01) = 0.9 without the correction.
        assert!(
            (biased.params.velocity_scale - 0.9).abs() < 0.02,
            "{}",
            biased.params.velocity_scale
        );
        assert!(
            (fixed.params.velocity_scale - 1.0).abs() < 0.02,
            "{}",
            fixed.params.velocity_scale
        );
        assert!((fixed.params.lever_arm_cam_m() - truth.lever_arm_cam_m()).norm() < 0.03);
    }

    #[test]
    fn no_rotation_leaves_lever_arm_unsolved() {
        let truth = CalibrationParams::from_r_dvl_cam(
            so3::exp(&Vector3::new(0.3, 0.2, 0.1)),
            Vector3::new(0.1, 0.0, 0.0),
            1.0,
            0.0,
        );
        let mut rng = Rng::new(5);
        let rows: Vec<ClosedFormRow> = (0..30)
            .map(|_| {
                let v = rng.normal_vec3();
                let tw = Vector6::new(v.x, v.y, v.z, 0.0, 0.0, 0.0);
                ClosedFormRow {
                    v_dvl: predict(&truth, &tw),
                    twist: tw,
                    twist_cov: Matrix6::zeros(),
                }
            })
            .collect();
        let cf = closed_form(&rows, true).unwrap();
        assert!(!cf.lever_arm_solved);
        assert!((cf.params.r_dvl_cam() - truth.r_dvl_cam()).abs().max() < 1e-10);
    }
}
