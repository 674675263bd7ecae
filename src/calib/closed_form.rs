//! Closed-form initial extrinsics (the paper's Sec. IV-C-2).
//!
//! Stacking `v_dvl_i^T = [v_i^T, -w_i^T] Z` with `Z = [(kappa R)^T; (kappa R p^)^T]` (6x3) gives a
//! linear least-squares problem in `Z`. The camera twists are estimates with covariance
//! `Sigma_i`, so `sum h_i h_i^T` overestimates `sum h_i^o h_i^o^T` by `G = sum S Sigma_i S`
//! (`S = diag(I, -I)`); subtracting `G` removes that bias (errors-in-variables correction).
//! Then `kappa = |det Z1|^(1/3)`, `R` is the nearest rotation to `Z1^T / kappa` and the lever arm
//! is the skew part of `R^T Z2^T / kappa`.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

use super::model::predict;
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
    /// The angular-velocity block of the (corrected) normal matrix over the number of rows: the
    /// mean of `w w^T` in the camera frame, (rad/s)^2.
    pub rotation_excitation: Matrix3<f64>,
}

impl ClosedForm {
    /// The least excited axis's mean squared angular rate over the angular velocity's noise
    /// variance: below a few, the angular velocity is mostly noise and the lever arm, seen only
    /// through `w x p`, is not observed.
    pub fn rotation_snr(&self) -> f64 {
        self.min_rotation_excitation / self.angular_noise_variance.max(1e-300)
    }

    /// The directions of the lever arm (unit vectors in the camera frame) that the rotation
    /// rates leave in noise. The lever arm is seen through `w x p`, whose information on `p` is
    /// `tr(S) I - S` for `S` the mean of `w w^T`: along an eigenvector of `S` it is the sum of
    /// the other two eigenvalues, the excitation about the axes across it. A direction is
    /// unobserved when that sum is below `2 snr` times the angular velocity's noise variance
    /// (each of the two axes below `snr`, on average). Rotation about one axis only leaves the
    /// lever arm along that axis unobserved; about none, all of it; about two or more, none.
    pub fn unobserved_lever_directions(&self, snr: f64) -> Vec<Vector3<f64>> {
        let eig = self.rotation_excitation.symmetric_eigen();
        let total = eig.eigenvalues.sum();
        let floor = 2.0 * snr * self.angular_noise_variance.max(1e-300);
        (0..3)
            .filter(|&i| total - eig.eigenvalues[i] < floor)
            .map(|i| eig.eigenvectors.column(i).normalize())
            .collect()
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
        rotation_excitation: aww,
        angular_noise_variance: rows
            .iter()
            .map(|r| (r.twist_cov[(3, 3)] + r.twist_cov[(4, 4)] + r.twist_cov[(5, 5)]) / 3.0)
            .sum::<f64>()
            / n,
    })
}

/// A rotation the closed form's linear solution missed: the minimum of the DVL residuals over
/// rotations, far from the closed form's rotation (see [`search_rotation`]).
#[derive(Clone, Debug)]
pub struct RotationSearch {
    /// Rotation, scale and lever arm at that minimum (the lever arm only when the closed form
    /// solved it, otherwise the closed form's zero); the time offset is zero.
    pub params: CalibrationParams,
    /// Angle between its rotation and the closed form's, degrees.
    pub angle_deg: f64,
    /// RMS DVL residual there, m/s.
    pub rms: f64,
    /// RMS DVL residual at the closed form's own parameters, m/s.
    pub closed_form_rms: f64,
}

/// Angle beyond which the minimum over rotations replaces the closed form's rotation, degrees:
/// far more than noise moves a closed form that the velocities determine, well within what the
/// refinement corrects.
pub const ROTATION_SEARCH_ANGLE_DEG: f64 = 10.0;

/// Most rows the rotation search uses (spread evenly).
const SEARCH_ROWS: usize = 2000;

/// The closed form's rotation checked against the minimum of the DVL residuals
/// `sum |v_dvl - kappa R (v + w x p)|^2` over the rotation and the scale (and the lever arm when
/// the closed form solved it), searched by Levenberg-Marquardt from the closed form's rotation
/// turned by each of the 24 rotations of a cube (one of them lies within 63 deg of any
/// rotation, so the global minimum's basin is always entered).
///
/// The closed form solves for a free 3x3 matrix `kappa R` and projects it onto the rotations.
/// When the camera's velocity stays along nearly one direction of its own frame (a trolley or
/// a vehicle that only moves forward), two of that matrix's columns rest on the small sideways
/// velocities and their noise, and the projection can land anywhere, a half turn off included;
/// the refinement started there can collapse the scale towards zero instead of turning back.
/// The minimum over rotations only ever weighs the velocities by their size. It is returned
/// when its rotation is more than [`ROTATION_SEARCH_ANGLE_DEG`] from the closed form's with a
/// positive scale; `None` when the closed form already sits in the best basin (then nothing
/// changes).
pub fn search_rotation(rows: &[ClosedFormRow], cf: &ClosedForm) -> Option<RotationSearch> {
    if rows.len() < 8 {
        return None;
    }
    // A start needs no more than a few thousand rows, spread evenly over the recording.
    let stride = rows.len().div_ceil(SEARCH_ROWS);
    let thinned: Vec<ClosedFormRow> = rows.iter().step_by(stride).cloned().collect();
    let rows = &thinned[..];
    let p0 = &cf.params;
    let r_cf = p0.r_dvl_cam();
    let lever_free = cf.lever_arm_solved;
    let start_cost = residual_cost(rows, &r_cf, p0.velocity_scale, &p0.lever_arm_cam_m());
    let best = cube_rotations()
        .iter()
        .filter_map(|g| {
            polish(
                rows,
                r_cf * g,
                p0.velocity_scale.abs().max(0.1),
                p0.lever_arm_cam_m(),
                lever_free,
            )
        })
        .filter(|m| m.kappa > 0.0 && m.cost.is_finite())
        .min_by(|a, b| a.cost.total_cmp(&b.cost))?;
    let angle = crate::lie::so3::log(&(best.r * r_cf.transpose()))
        .norm()
        .to_degrees();
    if !(angle > ROTATION_SEARCH_ANGLE_DEG && best.cost < start_cost) {
        return None;
    }
    let n = rows.len() as f64;
    Some(RotationSearch {
        params: CalibrationParams::from_r_dvl_cam(best.r, best.p, best.kappa, 0.0),
        angle_deg: angle,
        rms: (best.cost / n).sqrt(),
        closed_form_rms: (start_cost / n).sqrt(),
    })
}

/// A local minimum of the DVL residuals over the rotation, the scale and the lever arm.
struct Minimum {
    r: Matrix3<f64>,
    kappa: f64,
    p: Vector3<f64>,
    cost: f64,
}

/// `sum |v_dvl - kappa R (v + w x p)|^2` over the rows (the measurement model's residuals).
fn residual_cost(rows: &[ClosedFormRow], r: &Matrix3<f64>, kappa: f64, p: &Vector3<f64>) -> f64 {
    let params = CalibrationParams::from_r_dvl_cam(*r, *p, kappa, 0.0);
    rows.iter()
        .map(|row| (row.v_dvl - predict(&params, &row.twist)).norm_squared())
        .sum()
}

/// Levenberg-Marquardt on the DVL residuals from `(r, kappa, p)`: the rotation (left
/// perturbation), the scale, and the lever arm when `lever_free`.
fn polish(
    rows: &[ClosedFormRow],
    mut r: Matrix3<f64>,
    mut kappa: f64,
    mut p: Vector3<f64>,
    lever_free: bool,
) -> Option<Minimum> {
    let np = if lever_free { 7 } else { 4 };
    let mut cost = residual_cost(rows, &r, kappa, &p);
    let mut lambda = 1e-4;
    for _ in 0..100 {
        let mut h = SMatrix::<f64, 7, 7>::zeros();
        let mut g = SMatrix::<f64, 7, 1>::zeros();
        for row in rows {
            let v = row.twist.fixed_rows::<3>(0).into_owned();
            let w = row.twist.fixed_rows::<3>(3).into_owned();
            let ru = r * (v + w.cross(&p));
            let e = row.v_dvl - ru * kappa;
            let mut j = SMatrix::<f64, 3, 7>::zeros();
            j.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&(crate::lie::hat(&ru) * kappa));
            j.fixed_view_mut::<3, 1>(0, 3).copy_from(&(-ru));
            if lever_free {
                j.fixed_view_mut::<3, 3>(0, 4)
                    .copy_from(&(-(r * crate::lie::hat(&w)) * kappa));
            }
            h += j.transpose() * j;
            g += j.transpose() * e;
        }
        let mut improved = false;
        while lambda < 1e12 {
            let mut a = h;
            for k in 0..np {
                a[(k, k)] += lambda * h[(k, k)].max(1e-12);
            }
            for k in np..7 {
                a[(k, k)] = 1.0;
            }
            let step = a.cholesky()?.solve(&(-g));
            let r1 = crate::lie::so3::exp(&step.fixed_rows::<3>(0).into_owned()) * r;
            let k1 = kappa + step[3];
            let p1 = p + step.fixed_rows::<3>(4).into_owned();
            let c1 = residual_cost(rows, &r1, k1, &p1);
            if c1.is_finite() && c1 < cost {
                let gain = cost - c1;
                (r, kappa, p, cost) = (r1, k1, p1, c1);
                lambda = (lambda * 0.3).max(1e-9);
                improved = gain > 1e-12 * cost;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Some(Minimum { r, kappa, p, cost })
}

/// The 24 rotations of a cube: the signed permutation matrices of determinant +1.
fn cube_rotations() -> Vec<Matrix3<f64>> {
    const PERMS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = Vec::with_capacity(24);
    for perm in PERMS {
        for signs in 0..8u32 {
            let mut m = Matrix3::zeros();
            for (row, &col) in perm.iter().enumerate() {
                m[(row, col)] = if signs & (1 << row) != 0 { -1.0 } else { 1.0 };
            }
            if m.determinant() > 0.0 {
                out.push(m);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::lie::so3;
    use crate::rng::Rng;

    /// A closed form whose rotation rates have mean `w w^T` = `s` and noise variance 1e-4.
    fn excited(s: Matrix3<f64>) -> ClosedForm {
        ClosedForm {
            params: CalibrationParams::from_r_dvl_cam(
                Matrix3::identity(),
                Vector3::zeros(),
                1.0,
                0.0,
            ),
            lever_arm_solved: true,
            min_rotation_excitation: s.symmetric_eigenvalues().min(),
            angular_noise_variance: 1e-4,
            rotation_excitation: s,
        }
    }

    #[test]
    fn the_lever_arm_along_the_only_rotation_axis_is_the_unobserved_one() {
        let (big, noise) = (0.05, 1e-4);
        // Yaw about a tilted axis only: the lever arm along that axis is unobserved.
        let a = Vector3::new(0.1, 0.2, 1.0).normalize();
        let one = excited(a * a.transpose() * big + Matrix3::identity() * noise);
        let dirs = one.unobserved_lever_directions(4.0);
        assert_eq!(dirs.len(), 1);
        assert!(dirs[0].dot(&a).abs() > 1.0 - 1e-9, "{:?}", dirs[0]);
        // Two axes turning: every direction is observed (each has a turning axis across it),
        // though the least excited axis is noise.
        let two = excited(Matrix3::from_diagonal(&Vector3::new(big, big, noise)));
        assert!(two.rotation_snr() < 4.0);
        assert!(two.unobserved_lever_directions(4.0).is_empty());
        // No turning: all three.
        let none = excited(Matrix3::identity() * noise * 2.0);
        assert_eq!(none.unobserved_lever_directions(4.0).len(), 3);
        // The second axis at the threshold's edge: its pair sum decides.
        let edge = |second: f64| {
            excited(Matrix3::from_diagonal(&Vector3::new(big, second, 0.0)))
                .unobserved_lever_directions(4.0)
                .len()
        };
        assert_eq!(edge(7.9 * noise), 1);
        assert_eq!(edge(8.1 * noise), 0);
    }

    #[test]
    fn the_cube_has_24_distinct_rotations() {
        let g = cube_rotations();
        assert_eq!(g.len(), 24);
        for (i, a) in g.iter().enumerate() {
            assert!(((a * a.transpose()) - Matrix3::identity()).norm() < 1e-15);
            assert!(g[..i].iter().all(|b| (a - b).norm() > 1.0));
        }
    }

    #[test]
    fn the_search_leaves_a_determined_closed_form_alone() {
        let truth = CalibrationParams::from_r_dvl_cam(
            so3::exp(&Vector3::new(-1.5, 0.05, 0.02)),
            Vector3::new(0.05, 0.25, -0.1),
            1.01,
            0.0,
        );
        let mut rng = Rng::new(4);
        let rows: Vec<ClosedFormRow> = (0..500)
            .map(|_| {
                let tw = rng.normal_vec6() * 0.3;
                ClosedFormRow {
                    v_dvl: predict(&truth, &tw) + rng.normal_vec3() * 0.01,
                    twist: tw,
                    twist_cov: Matrix6::zeros(),
                }
            })
            .collect();
        let cf = closed_form(&rows, true).unwrap();
        assert!(search_rotation(&rows, &cf).is_none());
        // Started half a turn off, the search finds the truth again.
        let mut off = cf.clone();
        off.params = CalibrationParams::from_r_dvl_cam(
            so3::exp(&Vector3::new(0.0, 0.0, 3.0)) * cf.params.r_dvl_cam(),
            Vector3::zeros(),
            1.0,
            0.0,
        );
        let s = search_rotation(&rows, &off).expect("a better rotation");
        let err = so3::log(&(s.params.r_dvl_cam() * truth.r_dvl_cam().transpose())).norm();
        assert!(err.to_degrees() < 0.5, "{}", err.to_degrees());
        assert!((s.params.velocity_scale - 1.01).abs() < 0.01);
    }

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
