//! The rotation group SO(3) and the rigid-motion group SE(3).
//!
//! Conventions:
//! - A tangent vector of SE(3) is `xi = [rho; phi]`: translation part first, rotation part last.
//! - `exp(xi)` has rotation `exp(phi)` and translation `J_l(phi) rho`.
//! - Right Jacobian: `exp(xi + d) ~= exp(xi) exp(J_r(xi) d)`; left Jacobian:
//!   `exp(xi + d) ~= exp(J_l(xi) d) exp(xi)`. `J_r(xi) = J_l(-xi)`.
//! - `curly(xi)` is the adjoint of the Lie algebra: `curly(a) b = [a, b]` (the Lie bracket of
//!   the hats), `[[phi^, rho^], [0, phi^]]`.
//! - `Se3::adjoint()` is `Ad(T) = [[R, t^ R], [0, R]]`, so that `T exp(xi) = exp(Ad(T) xi) T`.
//!
//! Every function is written to stay accurate near zero (Taylor series below a small angle) and
//! near pi (the logarithm goes through a quaternion, not through `acos` of the trace).

use nalgebra::{Matrix3, Matrix4, Matrix6, Vector3, Vector6};

/// Below this angle (rad) the Taylor series of the Jacobian coefficients is used.
const SMALL_ANGLE: f64 = 1e-4;

/// Below this angle (rad) the Taylor series of the coefficients of the SE(3) `Q` block is used.
/// Their closed forms lose about `eps / th` (absolute, times `|rho|`) to cancellation, so they
/// take over only where that is ~1e-15; the series (to th^8) is exact to ~1e-20 there.
const Q_SMALL_ANGLE: f64 = 0.1;

/// `(1 - cos th) / th^2`, computed as `2 sin^2(th/2) / th^2` so that it keeps full relative
/// precision for small `th` (the direct form loses `eps / th^2`).
#[inline]
fn half_versine_over_th2(th: f64) -> f64 {
    let s = (0.5 * th).sin() / th;
    2.0 * s * s
}

/// `hat(w) v = w x v`.
#[inline]
pub fn hat(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// Inverse of [`hat`] (the skew part of `m` if `m` is not exactly skew).
#[inline]
pub fn vee(m: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(
        0.5 * (m[(2, 1)] - m[(1, 2)]),
        0.5 * (m[(0, 2)] - m[(2, 0)]),
        0.5 * (m[(1, 0)] - m[(0, 1)]),
    )
}

/// SO(3) functions on rotation matrices and rotation vectors.
pub mod so3 {
    use super::*;

    /// Rotation matrix of the rotation vector `phi` (Rodrigues).
    pub fn exp(phi: &Vector3<f64>) -> Matrix3<f64> {
        let th2 = phi.norm_squared();
        let th = th2.sqrt();
        let (a, b) = if th < SMALL_ANGLE {
            (
                1.0 - th2 / 6.0 + th2 * th2 / 120.0,
                0.5 - th2 / 24.0 + th2 * th2 / 720.0,
            )
        } else {
            (th.sin() / th, half_versine_over_th2(th))
        };
        let k = hat(phi);
        Matrix3::identity() + k * a + k * k * b
    }

    /// Rotation vector of `r`, with angle in [0, pi]. Accurate near 0 and near pi.
    pub fn log(r: &Matrix3<f64>) -> Vector3<f64> {
        let q = quaternion_from_matrix(r);
        log_quaternion(&q)
    }

    /// Rotation vector of the unit quaternion `[x, y, z, w]`.
    pub fn log_quaternion(q: &[f64; 4]) -> Vector3<f64> {
        let (mut v, mut w) = (Vector3::new(q[0], q[1], q[2]), q[3]);
        if w < 0.0 {
            v = -v;
            w = -w;
        }
        let n = v.norm();
        if n < 1e-9 {
            // atan2(n, w) / n ~= 1/w (1 - n^2 / (3 w^2))
            v * (2.0 / w) * (1.0 - n * n / (3.0 * w * w))
        } else {
            v * (2.0 * n.atan2(w) / n)
        }
    }

    /// Unit quaternion `[x, y, z, w]` of a rotation matrix (Shepperd's method, `w >= 0`).
    pub fn quaternion_from_matrix(r: &Matrix3<f64>) -> [f64; 4] {
        let tr = r.trace();
        let (r00, r11, r22) = (r[(0, 0)], r[(1, 1)], r[(2, 2)]);
        let mut q = if tr >= r00 && tr >= r11 && tr >= r22 {
            let s = 2.0 * (1.0 + tr).max(0.0).sqrt();
            [
                (r[(2, 1)] - r[(1, 2)]) / s,
                (r[(0, 2)] - r[(2, 0)]) / s,
                (r[(1, 0)] - r[(0, 1)]) / s,
                0.25 * s,
            ]
        } else if r00 >= r11 && r00 >= r22 {
            let s = 2.0 * (1.0 + r00 - r11 - r22).max(0.0).sqrt();
            [
                0.25 * s,
                (r[(0, 1)] + r[(1, 0)]) / s,
                (r[(0, 2)] + r[(2, 0)]) / s,
                (r[(2, 1)] - r[(1, 2)]) / s,
            ]
        } else if r11 >= r22 {
            let s = 2.0 * (1.0 - r00 + r11 - r22).max(0.0).sqrt();
            [
                (r[(0, 1)] + r[(1, 0)]) / s,
                0.25 * s,
                (r[(1, 2)] + r[(2, 1)]) / s,
                (r[(0, 2)] - r[(2, 0)]) / s,
            ]
        } else {
            let s = 2.0 * (1.0 - r00 - r11 + r22).max(0.0).sqrt();
            [
                (r[(0, 2)] + r[(2, 0)]) / s,
                (r[(1, 2)] + r[(2, 1)]) / s,
                0.25 * s,
                (r[(1, 0)] - r[(0, 1)]) / s,
            ]
        };
        if q[3] < 0.0 {
            q.iter_mut().for_each(|c| *c = -*c);
        }
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        q.iter_mut().for_each(|c| *c /= n);
        q
    }

    /// Rotation matrix of the unit quaternion `[x, y, z, w]` (normalised first).
    pub fn matrix_from_quaternion(q: &[f64; 4]) -> Matrix3<f64> {
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        let (x, y, z, w) = (q[0] / n, q[1] / n, q[2] / n, q[3] / n);
        Matrix3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        )
    }

    /// Left Jacobian of SO(3).
    pub fn left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
        let th2 = phi.norm_squared();
        let th = th2.sqrt();
        let (a, b) = if th < SMALL_ANGLE {
            (
                0.5 - th2 / 24.0 + th2 * th2 / 720.0,
                1.0 / 6.0 - th2 / 120.0 + th2 * th2 / 5040.0,
            )
        } else {
            (half_versine_over_th2(th), (th - th.sin()) / (th2 * th))
        };
        let k = hat(phi);
        Matrix3::identity() + k * a + k * k * b
    }

    /// Inverse of the left Jacobian of SO(3) (singular at angles 2 pi k, k != 0).
    pub fn left_jacobian_inv(phi: &Vector3<f64>) -> Matrix3<f64> {
        let c = inv_square_coefficient(phi.norm_squared());
        let k = hat(phi);
        Matrix3::identity() - k * 0.5 + k * k * c
    }

    /// The coefficient of `hat(phi)^2` in `J_l^-1(phi)`, for `th2 = |phi|^2`.
    fn inv_square_coefficient(th2: f64) -> f64 {
        let th = th2.sqrt();
        if th < SMALL_ANGLE {
            1.0 / 12.0 + th2 / 720.0 + th2 * th2 / 30240.0
        } else {
            // 1/th^2 - (1 + cos th) / (2 th sin th) == 1/th^2 - cot(th/2) / (2 th)
            1.0 / th2 - (0.5 * th).cos() / ((0.5 * th).sin() * 2.0 * th)
        }
    }

    /// `J_l^-1(phi)` and `J_l^-1(-phi)` (= `J_r^-1(phi)`) with one evaluation of the shared
    /// coefficient and square: the values [`left_jacobian_inv`] gives for each.
    pub fn left_jacobian_inv_both(phi: &Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
        let c = inv_square_coefficient(phi.norm_squared());
        let (k, km) = (hat(phi), hat(&-phi));
        // hat(-phi)^2 has the same products as hat(phi)^2, term by term.
        let kkc = k * k * c;
        (
            Matrix3::identity() - k * 0.5 + kkc,
            Matrix3::identity() - km * 0.5 + kkc,
        )
    }

    /// Right Jacobian of SO(3): `J_r(phi) = J_l(-phi)`.
    pub fn right_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
        left_jacobian(&-phi)
    }

    /// Inverse of the right Jacobian of SO(3).
    pub fn right_jacobian_inv(phi: &Vector3<f64>) -> Matrix3<f64> {
        left_jacobian_inv(&-phi)
    }
}

/// Lie-algebra adjoint of se(3): `curly(xi) = [[phi^, rho^], [0, phi^]]`.
pub fn curly(xi: &Vector6<f64>) -> Matrix6<f64> {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    let mut m = Matrix6::zeros();
    let ph = hat(&phi);
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&ph);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&hat(&rho));
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&ph);
    m
}

/// 4x4 matrix of the tangent vector `xi = [rho; phi]`.
pub fn se3_hat(xi: &Vector6<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::zeros();
    m.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&hat(&xi.fixed_rows::<3>(3).into_owned()));
    m.fixed_view_mut::<3, 1>(0, 3)
        .copy_from(&xi.fixed_rows::<3>(0));
    m
}

/// Inverse of [`se3_hat`].
pub fn se3_vee(m: &Matrix4<f64>) -> Vector6<f64> {
    let w = vee(&m.fixed_view::<3, 3>(0, 0).into_owned());
    Vector6::new(m[(0, 3)], m[(1, 3)], m[(2, 3)], w.x, w.y, w.z)
}

/// The coefficients of the Q block's three groups of products, for `th2 = |phi|^2`.
fn q_coefficients(th2: f64) -> (f64, f64, f64) {
    let th = th2.sqrt();
    if th < Q_SMALL_ANGLE {
        // c1 = sum (-th^2)^k / (2k+3)!, c2 = sum (-th^2)^k / (2k+4)!,
        // c3 = sum (-th^2)^k (k+1) / (2k+5)!.
        let x = th2;
        (
            1.0 / 6.0
                - x * (1.0 / 120.0 - x * (1.0 / 5040.0 - x * (1.0 / 362880.0 - x / 39916800.0))),
            1.0 / 24.0
                - x * (1.0 / 720.0 - x * (1.0 / 40320.0 - x * (1.0 / 3628800.0 - x / 479001600.0))),
            1.0 / 120.0
                - x * (1.0 / 2520.0
                    - x * (1.0 / 120960.0 - x * (1.0 / 9979200.0 - x / 1245404160.0))),
        )
    } else {
        let (s, c) = th.sin_cos();
        let th4 = th2 * th2;
        // th^2 + 2 cos th - 2 == th^2 - 4 sin^2(th/2): without the rounding of 2 cos th near 2.
        let sh = (0.5 * th).sin();
        (
            (th - s) / (th2 * th),
            (th2 - 4.0 * sh * sh) / (2.0 * th4),
            (2.0 * th - 3.0 * s + th * c) / (2.0 * th4 * th),
        )
    }
}

/// The products of `p = hat(phi)` and `r = hat(rho)` in the Q block.
struct QProducts {
    pr: Matrix3<f64>,
    rp: Matrix3<f64>,
    prp: Matrix3<f64>,
    ppr: Matrix3<f64>,
    rpp: Matrix3<f64>,
    prpp: Matrix3<f64>,
    pprp: Matrix3<f64>,
}

impl QProducts {
    #[inline(always)]
    fn of(p: &Matrix3<f64>, r: &Matrix3<f64>) -> QProducts {
        let pr = p * r;
        let rp = r * p;
        let prp = pr * p;
        let ppr = p * p * r;
        QProducts {
            pr,
            rp,
            prp,
            rpp: rp * p,
            prpp: prp * p,
            pprp: ppr * p,
            ppr,
        }
    }

    /// `r/2 + (pr + rp + prp) c1 + (ppr + rpp - 3 prp) c2 + (prpp + pprp) c3`.
    #[inline(always)]
    fn sum(&self, r: &Matrix3<f64>, (c1, c2, c3): (f64, f64, f64)) -> Matrix3<f64> {
        r * 0.5
            + (self.pr + self.rp + self.prp) * c1
            + (self.ppr + self.rpp - self.prp * 3.0) * c2
            + (self.prpp + self.pprp) * c3
    }
}

/// The Q block of the SE(3) left Jacobian (Barfoot, State Estimation for Robotics, eq. 7.86).
fn q_block(rho: &Vector3<f64>, phi: &Vector3<f64>) -> Matrix3<f64> {
    let r = hat(rho);
    QProducts::of(&hat(phi), &r).sum(&r, q_coefficients(phi.norm_squared()))
}

/// [`q_block`] at `(rho, phi)` and at `(-rho, -phi)`, from one set of products: those of
/// `Q(-rho, -phi)` are the products of `Q(rho, phi)` or their negatives (negation is exact), so
/// the values are those of two calls of [`q_block`] (up to the sign of an exact zero).
fn q_block_both(rho: &Vector3<f64>, phi: &Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let c = q_coefficients(phi.norm_squared());
    let r = hat(rho);
    let q = QProducts::of(&hat(phi), &r);
    let plus = q.sum(&r, c);
    let negated = QProducts {
        prp: -q.prp,
        ppr: -q.ppr,
        rpp: -q.rpp,
        ..q
    };
    (plus, negated.sum(&hat(&-rho), c))
}

/// `J_l^-1(xi)` and `J_l^-1(-xi)` (= `J_r^-1(xi)`), with the trigonometry and the products of
/// the Q blocks shared: the values [`se3_left_jacobian_inv`] gives for each.
pub fn se3_left_jacobian_inv_both(xi: &Vector6<f64>) -> (Matrix6<f64>, Matrix6<f64>) {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    let (ji, jim) = so3::left_jacobian_inv_both(&phi);
    let (q, qm) = q_block_both(&rho, &phi);
    (se3_jacobian_inv_of(&ji, &q), se3_jacobian_inv_of(&jim, &qm))
}

/// `[[J^-1, -J^-1 Q J^-1], [0, J^-1]]` from the SO(3) inverse Jacobian and the Q block.
fn se3_jacobian_inv_of(ji: &Matrix3<f64>, q: &Matrix3<f64>) -> Matrix6<f64> {
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(ji);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(ji);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-ji * q * ji));
    m
}

/// Left Jacobian of SE(3): `[[J_l(phi), Q], [0, J_l(phi)]]`.
pub fn se3_left_jacobian(xi: &Vector6<f64>) -> Matrix6<f64> {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    let j = so3::left_jacobian(&phi);
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&j);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&j);
    m.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&q_block(&rho, &phi));
    m
}

/// Inverse of the left Jacobian of SE(3): `[[J^-1, -J^-1 Q J^-1], [0, J^-1]]`.
pub fn se3_left_jacobian_inv(xi: &Vector6<f64>) -> Matrix6<f64> {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    se3_jacobian_inv_of(&so3::left_jacobian_inv(&phi), &q_block(&rho, &phi))
}

/// Right Jacobian of SE(3): `J_r(xi) = J_l(-xi)`.
pub fn se3_right_jacobian(xi: &Vector6<f64>) -> Matrix6<f64> {
    se3_left_jacobian(&-xi)
}

/// Inverse of the right Jacobian of SE(3).
pub fn se3_right_jacobian_inv(xi: &Vector6<f64>) -> Matrix6<f64> {
    se3_left_jacobian_inv(&-xi)
}

/// A rigid transform. `T_a_b` maps b-frame points into frame a: `p_a = R p_b + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Se3 {
    /// Rotation `R_a_b`.
    pub rot: Matrix3<f64>,
    /// Translation: the origin of frame b expressed in frame a.
    pub trans: Vector3<f64>,
}

impl Default for Se3 {
    fn default() -> Self {
        Se3::identity()
    }
}

impl Se3 {
    /// The identity transform.
    pub fn identity() -> Se3 {
        Se3 {
            rot: Matrix3::identity(),
            trans: Vector3::zeros(),
        }
    }

    /// The transform with rotation `rot` (`R_a_b`) and translation `trans` (the origin of b in
    /// frame a), taken as given.
    pub fn new(rot: Matrix3<f64>, trans: Vector3<f64>) -> Se3 {
        Se3 { rot, trans }
    }

    /// From a unit quaternion `[x, y, z, w]` (normalised here) and a translation.
    pub fn from_quaternion_xyzw(q: &[f64; 4], trans: Vector3<f64>) -> Se3 {
        Se3 {
            rot: so3::matrix_from_quaternion(q),
            trans,
        }
    }

    /// The rotation as a unit quaternion `[x, y, z, w]` with `w >= 0`.
    pub fn quaternion_xyzw(&self) -> [f64; 4] {
        so3::quaternion_from_matrix(&self.rot)
    }

    /// Exponential map of `xi = [rho; phi]`.
    pub fn exp(xi: &Vector6<f64>) -> Se3 {
        let rho = xi.fixed_rows::<3>(0).into_owned();
        let phi = xi.fixed_rows::<3>(3).into_owned();
        Se3 {
            rot: so3::exp(&phi),
            trans: so3::left_jacobian(&phi) * rho,
        }
    }

    /// Logarithm: the `xi = [rho; phi]` with rotation angle in [0, pi] and `exp(xi) == self`.
    pub fn log(&self) -> Vector6<f64> {
        let phi = so3::log(&self.rot);
        let rho = so3::left_jacobian_inv(&phi) * self.trans;
        Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
    }

    /// The inverse transform: `T_b_a` from `T_a_b`.
    pub fn inverse(&self) -> Se3 {
        let rt = self.rot.transpose();
        Se3 {
            rot: rt,
            trans: -(rt * self.trans),
        }
    }

    /// `self * p`.
    pub fn transform_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rot * p + self.trans
    }

    /// `Ad(T) = [[R, t^ R], [0, R]]`.
    pub fn adjoint(&self) -> Matrix6<f64> {
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rot);
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.rot);
        m.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(hat(&self.trans) * self.rot));
        m
    }

    /// The 4x4 homogeneous matrix `[[R, t], [0, 1]]`.
    pub fn to_matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rot);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.trans);
        m
    }

    /// From a 4x4 homogeneous matrix; the rotation block is projected onto SO(3).
    pub fn from_matrix(m: &Matrix4<f64>) -> Se3 {
        let r = m.fixed_view::<3, 3>(0, 0).into_owned();
        Se3 {
            rot: so3::matrix_from_quaternion(&so3::quaternion_from_matrix(&r)),
            trans: m.fixed_view::<3, 1>(0, 3).into_owned(),
        }
    }

    /// Removes round-off drift from the rotation matrix.
    pub fn renormalized(&self) -> Se3 {
        Se3 {
            rot: so3::matrix_from_quaternion(&so3::quaternion_from_matrix(&self.rot)),
            trans: self.trans,
        }
    }

    /// `self * exp(xi)`: right perturbation (in the frame of the transform's source).
    pub fn retract(&self, xi: &Vector6<f64>) -> Se3 {
        (*self * Se3::exp(xi)).renormalized()
    }
}

impl std::ops::Mul for Se3 {
    type Output = Se3;
    fn mul(self, rhs: Se3) -> Se3 {
        Se3 {
            rot: self.rot * rhs.rot,
            trans: self.rot * rhs.trans + self.trans,
        }
    }
}

impl std::ops::Mul<&Se3> for &Se3 {
    type Output = Se3;
    fn mul(self, rhs: &Se3) -> Se3 {
        *self * *rhs
    }
}
