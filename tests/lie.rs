//! Property tests for the SO(3)/SE(3) module `dvlcal::lie`.
//!
//! Every formula is checked against an independent reference: numeric central differences for
//! the Jacobians, a scaling-and-squaring matrix exponential and power series in `curly(xi)` for
//! `exp`, `J_l`, `J_r` and `Ad(exp(xi))`, and nalgebra's quaternions for the quaternion
//! conversions. The per-group properties are written once against the small [`Group`] trait and
//! instantiated for SO(3) and SE(3) by the `group_tests!` macro. Tolerances are tight enough
//! that a wrong sign or coefficient in any term fails; they are looser than machine precision
//! only by the conditioning of the reference (e.g. `eps / h` for central differences).

use dvlcal::lie::{self, Se3, so3};
use nalgebra::{
    DMatrix, DVector, Matrix3, Matrix4, Quaternion, SMatrix, SVector, UnitQuaternion, Vector3,
    Vector4,
};
use proptest::prelude::*;
use std::f64::consts::PI;

/// Cases per property.
const CASES: u32 = 256;

/// `CASES` cases; failures are reported with their minimal input rather than persisted to disk.
fn config() -> ProptestConfig {
    ProptestConfig {
        cases: CASES,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}
/// Central-difference step.
const H: f64 = 1e-6;
/// The module's switch-over angles between Taylor series and closed forms: for the SO(3)
/// coefficients (`SMALL_ANGLE`) and for the SE(3) `Q` block (`Q_SMALL_ANGLE`).
const SMALL_ANGLE: f64 = 1e-4;
const Q_SMALL_ANGLE: f64 = 0.1;

// ---------------------------------------------------------------------------------------------
// Reference implementations
// ---------------------------------------------------------------------------------------------

/// Matrix exponential by scaling and squaring with a degree-24 Taylor polynomial.
fn expm(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let norm = a.amax() * n as f64;
    let mut squarings = 0;
    let mut scale = 1.0;
    while norm * scale > 0.25 {
        scale *= 0.5;
        squarings += 1;
    }
    let b = a * scale;
    let mut sum = DMatrix::identity(n, n);
    let mut term = DMatrix::identity(n, n);
    for k in 1..=24 {
        term = &term * &b / k as f64;
        sum += &term;
    }
    for _ in 0..squarings {
        sum = &sum * &sum;
    }
    sum
}

/// `sum_{k>=0} m^k / (k+1)!`, the series of the left Jacobian in `m = curly(xi)`.
fn jacobian_series<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let mut sum = SMatrix::<f64, N, N>::identity();
    let mut term = SMatrix::<f64, N, N>::identity();
    for k in 1..80 {
        term = term * m / (k + 1) as f64;
        sum += term;
    }
    sum
}

/// Central-difference Jacobian of `f` at 0.
fn numeric_jacobian<const N: usize>(
    f: impl Fn(&SVector<f64, N>) -> SVector<f64, N>,
) -> SMatrix<f64, N, N> {
    let mut j = SMatrix::<f64, N, N>::zeros();
    for i in 0..N {
        let mut d = SVector::<f64, N>::zeros();
        d[i] = H;
        j.set_column(i, &((f(&d) - f(&-d)) / (2.0 * H)));
    }
    j
}

/// Max-abs-error comparison of two matrices of the same shape (static or dynamic).
fn close<R1, C1, R2, C2, S1, S2>(
    what: &str,
    a: &nalgebra::Matrix<f64, R1, C1, S1>,
    b: &nalgebra::Matrix<f64, R2, C2, S2>,
    tol: f64,
) -> Result<(), TestCaseError>
where
    R1: nalgebra::Dim,
    C1: nalgebra::Dim,
    R2: nalgebra::Dim,
    C2: nalgebra::Dim,
    S1: nalgebra::RawStorage<f64, R1, C1>,
    S2: nalgebra::RawStorage<f64, R2, C2>,
{
    prop_assert_eq!(a.shape(), b.shape(), "{}: shape mismatch", what);
    let mut err = 0.0f64;
    for (x, y) in a.iter().zip(b.iter()) {
        err = err.max((x - y).abs());
    }
    prop_assert!(
        err <= tol && err.is_finite(),
        "{what}: max abs error {err:e} > {tol:e}\n  got {a}\n  expected {b}"
    );
    Ok(())
}

fn rotation_from_quaternion_ref(q: &[f64; 4]) -> Matrix3<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
        .to_rotation_matrix()
        .into_inner()
}

// ---------------------------------------------------------------------------------------------
// The two groups behind one interface
// ---------------------------------------------------------------------------------------------

/// A matrix Lie group with an `N`-dimensional tangent space.
trait Group<const N: usize>: Copy + std::fmt::Debug {
    /// Tangent vector from a translation part (ignored by SO(3)) and a rotation vector.
    fn tangent(rho: &Vector3<f64>, phi: &Vector3<f64>) -> SVector<f64, N>;
    /// Group element from a rotation and a translation (ignored by SO(3)).
    fn element(rot: &Matrix3<f64>, trans: &Vector3<f64>) -> Self;
    fn exp(x: &SVector<f64, N>) -> Self;
    fn log(&self) -> SVector<f64, N>;
    fn mul(&self, other: &Self) -> Self;
    fn inv(&self) -> Self;
    fn identity() -> Self;
    /// Homogeneous matrix of the element.
    fn matrix(&self) -> DMatrix<f64>;
    fn hat(x: &SVector<f64, N>) -> DMatrix<f64>;
    fn vee(m: &DMatrix<f64>) -> SVector<f64, N>;
    /// Lie-algebra adjoint (`phi^` for SO(3), `curly` for SE(3)).
    fn ad(x: &SVector<f64, N>) -> SMatrix<f64, N, N>;
    /// Group adjoint.
    fn adjoint(&self) -> SMatrix<f64, N, N>;
    fn jl(x: &SVector<f64, N>) -> SMatrix<f64, N, N>;
    fn jr(x: &SVector<f64, N>) -> SMatrix<f64, N, N>;
    fn jl_inv(x: &SVector<f64, N>) -> SMatrix<f64, N, N>;
    fn jr_inv(x: &SVector<f64, N>) -> SMatrix<f64, N, N>;
}

/// SO(3) as a rotation matrix.
#[derive(Clone, Copy, Debug)]
struct Rot(Matrix3<f64>);

impl Group<3> for Rot {
    fn tangent(_rho: &Vector3<f64>, phi: &Vector3<f64>) -> Vector3<f64> {
        *phi
    }
    fn element(rot: &Matrix3<f64>, _trans: &Vector3<f64>) -> Self {
        Rot(*rot)
    }
    fn exp(x: &Vector3<f64>) -> Self {
        Rot(so3::exp(x))
    }
    fn log(&self) -> Vector3<f64> {
        so3::log(&self.0)
    }
    fn mul(&self, other: &Self) -> Self {
        Rot(self.0 * other.0)
    }
    fn inv(&self) -> Self {
        Rot(self.0.transpose())
    }
    fn identity() -> Self {
        Rot(Matrix3::identity())
    }
    fn matrix(&self) -> DMatrix<f64> {
        DMatrix::from_column_slice(3, 3, self.0.as_slice())
    }
    fn hat(x: &Vector3<f64>) -> DMatrix<f64> {
        DMatrix::from_column_slice(3, 3, lie::hat(x).as_slice())
    }
    fn vee(m: &DMatrix<f64>) -> Vector3<f64> {
        lie::vee(&m.fixed_view::<3, 3>(0, 0).into_owned())
    }
    fn ad(x: &Vector3<f64>) -> Matrix3<f64> {
        lie::hat(x)
    }
    fn adjoint(&self) -> Matrix3<f64> {
        self.0
    }
    fn jl(x: &Vector3<f64>) -> Matrix3<f64> {
        so3::left_jacobian(x)
    }
    fn jr(x: &Vector3<f64>) -> Matrix3<f64> {
        so3::right_jacobian(x)
    }
    fn jl_inv(x: &Vector3<f64>) -> Matrix3<f64> {
        so3::left_jacobian_inv(x)
    }
    fn jr_inv(x: &Vector3<f64>) -> Matrix3<f64> {
        so3::right_jacobian_inv(x)
    }
}

impl Group<6> for Se3 {
    fn tangent(rho: &Vector3<f64>, phi: &Vector3<f64>) -> SVector<f64, 6> {
        SVector::<f64, 6>::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
    }
    fn element(rot: &Matrix3<f64>, trans: &Vector3<f64>) -> Self {
        Se3::new(*rot, *trans)
    }
    fn exp(x: &SVector<f64, 6>) -> Self {
        Se3::exp(x)
    }
    fn log(&self) -> SVector<f64, 6> {
        Se3::log(self)
    }
    fn mul(&self, other: &Self) -> Self {
        self * other
    }
    fn inv(&self) -> Self {
        self.inverse()
    }
    fn identity() -> Self {
        Se3::identity()
    }
    fn matrix(&self) -> DMatrix<f64> {
        DMatrix::from_column_slice(4, 4, self.to_matrix().as_slice())
    }
    fn hat(x: &SVector<f64, 6>) -> DMatrix<f64> {
        DMatrix::from_column_slice(4, 4, lie::se3_hat(x).as_slice())
    }
    fn vee(m: &DMatrix<f64>) -> SVector<f64, 6> {
        lie::se3_vee(&m.fixed_view::<4, 4>(0, 0).into_owned())
    }
    fn ad(x: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        lie::curly(x)
    }
    fn adjoint(&self) -> SMatrix<f64, 6, 6> {
        Se3::adjoint(self)
    }
    fn jl(x: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        lie::se3_left_jacobian(x)
    }
    fn jr(x: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        lie::se3_right_jacobian(x)
    }
    fn jl_inv(x: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        lie::se3_left_jacobian_inv(x)
    }
    fn jr_inv(x: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        lie::se3_right_jacobian_inv(x)
    }
}

// ---------------------------------------------------------------------------------------------
// Strategies
// ---------------------------------------------------------------------------------------------

fn unit_axis() -> impl Strategy<Value = Vector3<f64>> {
    prop::array::uniform3(-1.0f64..1.0)
        .prop_map(Vector3::from)
        .prop_filter("axis too short", |v| v.norm() > 0.1)
        .prop_map(|v| v.normalize())
}

fn vec3(r: f64) -> impl Strategy<Value = Vector3<f64>> {
    prop::array::uniform3(-r..r).prop_map(Vector3::from)
}

/// Tangent vectors with rotation angle drawn from `angle` and translation part in [-2, 2]^3.
fn tangent<G: Group<N>, const N: usize>(
    angle: impl Strategy<Value = f64>,
) -> impl Strategy<Value = SVector<f64, N>> {
    (unit_axis(), angle, vec3(2.0)).prop_map(|(u, th, rho)| G::tangent(&rho, &(u * th)))
}

/// Tangent vectors of norm 10^e, e in [lo, hi] (rotation and translation equally small).
fn tiny_tangent<G: Group<N>, const N: usize>(
    lo: f64,
    hi: f64,
) -> impl Strategy<Value = SVector<f64, N>> {
    (unit_axis(), unit_axis(), lo..hi).prop_map(|(u, v, e)| {
        let x = G::tangent(&v, &u);
        x.normalize() * 10f64.powf(e)
    })
}

/// Random unit quaternion `[x, y, z, w]` (any sign of w).
fn quaternion() -> impl Strategy<Value = [f64; 4]> {
    prop::array::uniform4(-1.0f64..1.0)
        .prop_filter("quaternion too short", |q| Vector4::from(*q).norm() > 0.1)
        .prop_map(|q| {
            let n = Vector4::from(q).norm();
            [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
        })
}

/// Uniformly oriented group elements with translation in [-5, 5]^3.
fn element<G: Group<N>, const N: usize>() -> impl Strategy<Value = G> {
    (quaternion(), vec3(5.0)).prop_map(|(q, t)| G::element(&rotation_from_quaternion_ref(&q), &t))
}

// ---------------------------------------------------------------------------------------------
// Generic properties
// ---------------------------------------------------------------------------------------------

fn check_hat_vee<G: Group<N>, const N: usize>(x: &SVector<f64, N>) -> Result<(), TestCaseError> {
    let m = G::hat(x);
    close("vee(hat(x))", &G::vee(&m), x, 1e-15)?;
    // The rotation block is skew-symmetric.
    let r = m.view((0, 0), (3, 3));
    close("hat skew", &r, &(-r.transpose()), 0.0)?;
    Ok(())
}

/// `log(exp(x)) == x` to `tol` (absolute).
fn check_log_exp<G: Group<N>, const N: usize>(
    x: &SVector<f64, N>,
    tol: f64,
) -> Result<(), TestCaseError> {
    close("log(exp(x))", &G::exp(x).log(), x, tol)
}

/// `exp(x)` equals the matrix exponential of `hat(x)`, to `tol` (absolute).
fn check_exp_expm<G: Group<N>, const N: usize>(
    x: &SVector<f64, N>,
    tol: f64,
) -> Result<(), TestCaseError> {
    close(
        "exp(x) vs expm(hat(x))",
        &G::exp(x).matrix(),
        &expm(&G::hat(x)),
        tol,
    )
}

/// `exp(log(T)) == T`, and the logarithm has rotation angle at most pi.
fn check_exp_log<G: Group<N>, const N: usize>(t: &G, tol: f64) -> Result<(), TestCaseError> {
    let x = t.log();
    let phi = x.fixed_rows::<3>(N - 3).into_owned();
    prop_assert!(phi.norm() <= PI + 1e-12, "angle {} > pi", phi.norm());
    close("exp(log(T))", &G::exp(&x).matrix(), &t.matrix(), tol)
}

/// Defining relations of the four Jacobians, by central differences.
fn check_jacobians_numeric<G: Group<N>, const N: usize>(
    x: &SVector<f64, N>,
    tol: f64,
) -> Result<(), TestCaseError> {
    let t = G::exp(x);
    let ti = t.inv();
    // exp(x + d) ~= exp(x) exp(J_r d)
    let jr = numeric_jacobian(|d| ti.mul(&G::exp(&(x + d))).log());
    close("J_r", &G::jr(x), &jr, tol)?;
    // exp(x + d) ~= exp(J_l d) exp(x)
    let jl = numeric_jacobian(|d| G::exp(&(x + d)).mul(&ti).log());
    close("J_l", &G::jl(x), &jl, tol)?;
    // log(exp(x) exp(d)) ~= x + J_r^-1 d
    let jri = numeric_jacobian(|d| t.mul(&G::exp(d)).log());
    close("J_r^-1", &G::jr_inv(x), &jri, tol)?;
    // log(exp(d) exp(x)) ~= x + J_l^-1 d
    let jli = numeric_jacobian(|d| G::exp(d).mul(&t).log());
    close("J_l^-1", &G::jl_inv(x), &jli, tol)?;
    Ok(())
}

/// `J J^-1 == J^-1 J == I`, `J_r(x) == J_l(-x)`, `J_l(x) == Ad(exp(x)) J_r(x)`.
fn check_jacobian_identities<G: Group<N>, const N: usize>(
    x: &SVector<f64, N>,
    tol: f64,
) -> Result<(), TestCaseError> {
    let id = SMatrix::<f64, N, N>::identity();
    let (jl, jr, jli, jri) = (G::jl(x), G::jr(x), G::jl_inv(x), G::jr_inv(x));
    close("J_l J_l^-1", &(jl * jli), &id, tol)?;
    close("J_l^-1 J_l", &(jli * jl), &id, tol)?;
    close("J_r J_r^-1", &(jr * jri), &id, tol)?;
    close("J_r^-1 J_r", &(jri * jr), &id, tol)?;
    close("J_r(x) vs J_l(-x)", &jr, &G::jl(&-x), 0.0)?;
    close(
        "J_l(x) vs Ad(exp(x)) J_r(x)",
        &jl,
        &(G::exp(x).adjoint() * jr),
        tol,
    )?;
    Ok(())
}

/// `J_l`, `J_r` and `Ad(exp(x))` against their power series in `ad(x)`, to `tol` (absolute).
fn check_series<G: Group<N>, const N: usize>(
    x: &SVector<f64, N>,
    tol: f64,
) -> Result<(), TestCaseError> {
    let ad = G::ad(x);
    close("J_l vs series", &G::jl(x), &jacobian_series(&ad), tol)?;
    close("J_r vs series", &G::jr(x), &jacobian_series(&-ad), tol)?;
    let ad_d = DMatrix::from_column_slice(N, N, ad.as_slice());
    let e = expm(&ad_d);
    close("Ad(exp(x)) vs expm(ad(x))", &G::exp(x).adjoint(), &e, tol)?;
    // ad(x) x == 0, so every term past the first of the series vanishes on x itself.
    close("J_l(x) x", &(G::jl(x) * x), x, tol * (1.0 + x.norm()))?;
    Ok(())
}

/// Derivatives of `log(T1^-1 T2)` with respect to right perturbations of `T2` and `T1`.
fn check_log_difference<G: Group<N>, const N: usize>(
    t1: &G,
    x: &SVector<f64, N>,
    tol: f64,
) -> Result<(), TestCaseError> {
    let t2 = t1.mul(&G::exp(x));
    let f = t1.inv().mul(&t2).log();
    close("log(T1^-1 T2)", &f, x, 1e-9)?;
    let d2 = numeric_jacobian(|d| t1.inv().mul(&t2.mul(&G::exp(d))).log());
    close("d/dT2", &d2, &G::jr_inv(&f), tol)?;
    let d1 = numeric_jacobian(|d| t1.mul(&G::exp(d)).inv().mul(&t2).log());
    close("d/dT1", &d1, &(-G::jl_inv(&f)), tol)?;
    Ok(())
}

/// `T exp(x) T^-1 == exp(Ad(T) x)`, `Ad(A B) == Ad(A) Ad(B)`, `Ad(T^-1) == Ad(T)^-1`.
fn check_adjoint<G: Group<N>, const N: usize>(
    a: &G,
    b: &G,
    x: &SVector<f64, N>,
) -> Result<(), TestCaseError> {
    let lhs = a.mul(&G::exp(x)).mul(&a.inv());
    close(
        "T exp(x) T^-1",
        &lhs.matrix(),
        &G::exp(&(a.adjoint() * x)).matrix(),
        1e-12,
    )?;
    close(
        "Ad(AB)",
        &a.mul(b).adjoint(),
        &(a.adjoint() * b.adjoint()),
        1e-12,
    )?;
    close(
        "Ad(T^-1) Ad(T)",
        &(a.inv().adjoint() * a.adjoint()),
        &SMatrix::<f64, N, N>::identity(),
        1e-12,
    )?;
    close(
        "Ad(I)",
        &G::identity().adjoint(),
        &SMatrix::<f64, N, N>::identity(),
        0.0,
    )?;
    // Ad(T) hat-conjugation: T x^ T^-1 == (Ad(T) x)^
    let conj = a.matrix() * G::hat(x) * a.inv().matrix();
    close("T x^ T^-1", &conj, &G::hat(&(a.adjoint() * x)), 1e-12)?;
    Ok(())
}

/// `ad(a) b == vee([a^, b^])`, and antisymmetry / Jacobi identity of the bracket.
fn check_bracket<G: Group<N>, const N: usize>(
    a: &SVector<f64, N>,
    b: &SVector<f64, N>,
    c: &SVector<f64, N>,
) -> Result<(), TestCaseError> {
    let (ha, hb) = (G::hat(a), G::hat(b));
    let br = G::vee(&(&ha * &hb - &hb * &ha));
    close("ad(a) b vs [a^, b^]", &(G::ad(a) * b), &br, 1e-13)?;
    close(
        "ad(a) b == -ad(b) a",
        &(G::ad(a) * b),
        &(-(G::ad(b) * a)),
        1e-13,
    )?;
    let jacobi = G::ad(a) * (G::ad(b) * c) + G::ad(b) * (G::ad(c) * a) + G::ad(c) * (G::ad(a) * b);
    close(
        "Jacobi identity",
        &jacobi,
        &SVector::<f64, N>::zeros(),
        1e-12,
    )?;
    Ok(())
}

/// Group axioms and exp/log symmetries.
fn check_group<G: Group<N>, const N: usize>(
    a: &G,
    b: &G,
    c: &G,
    x: &SVector<f64, N>,
) -> Result<(), TestCaseError> {
    let n = a.matrix().nrows();
    let id = DMatrix::<f64>::identity(n, n);
    close("A A^-1", &a.mul(&a.inv()).matrix(), &id, 1e-13)?;
    close("A^-1 A", &a.inv().mul(a).matrix(), &id, 1e-13)?;
    close("A I", &a.mul(&G::identity()).matrix(), &a.matrix(), 0.0)?;
    close(
        "A matrix",
        &a.mul(b).matrix(),
        &(a.matrix() * b.matrix()),
        1e-13,
    )?;
    close(
        "(AB)^-1",
        &a.mul(b).inv().matrix(),
        &b.inv().mul(&a.inv()).matrix(),
        1e-12,
    )?;
    close(
        "(AB)C",
        &a.mul(b).mul(c).matrix(),
        &a.mul(&b.mul(c)).matrix(),
        1e-12,
    )?;
    close(
        "A^-1 matrix",
        &a.inv().matrix(),
        &a.matrix().try_inverse().unwrap(),
        1e-12,
    )?;
    close(
        "exp(-x)",
        &G::exp(&-x).matrix(),
        &G::exp(x).inv().matrix(),
        1e-13,
    )?;
    close("log(exp(x)^-1)", &G::exp(x).inv().log(), &(-x), 1e-9)?;
    let (s1, s2) = (0.3, 0.45);
    close(
        "exp(s1 x) exp(s2 x)",
        &G::exp(&(x * s1)).mul(&G::exp(&(x * s2))).matrix(),
        &G::exp(&(x * (s1 + s2))).matrix(),
        1e-13,
    )?;
    close("exp(0)", &G::exp(&SVector::zeros()).matrix(), &id, 0.0)?;
    close(
        "log(I)",
        &G::identity().log(),
        &SVector::<f64, N>::zeros(),
        0.0,
    )?;
    Ok(())
}

/// Values just below and just above a Taylor switch-over angle `th0` agree, and both match the
/// power series. The two angles `th0 (1 -+ 1e-13)` differ by `2e-13 th0`, so the true values
/// differ by at most a few times that; the rest of the tolerance is the closed forms' rounding
/// (~1e-15 per unit of translation at the `Q` switch-over).
fn check_switch_over<G: Group<N>, const N: usize>(
    th0: f64,
    u: &Vector3<f64>,
    rho: &Vector3<f64>,
) -> Result<(), TestCaseError> {
    let (th_lo, th_hi) = (th0 * (1.0 - 1e-13), th0 * (1.0 + 1e-13));
    // Translation part scaled with the angle, and of order one.
    for r in [rho * th0, *rho] {
        let tol = (2e-15 + 1e-12 * th0) * (1.0 + r.norm());
        let below = G::tangent(&r, &(u * th_lo));
        let above = G::tangent(&r, &(u * th_hi));
        let (tb, ta) = (G::exp(&below), G::exp(&above));
        close("exp continuity", &tb.matrix(), &ta.matrix(), tol)?;
        close("log continuity", &tb.log(), &ta.log(), tol)?;
        close("J_l continuity", &G::jl(&below), &G::jl(&above), tol)?;
        close("J_r continuity", &G::jr(&below), &G::jr(&above), tol)?;
        close(
            "J_l^-1 continuity",
            &G::jl_inv(&below),
            &G::jl_inv(&above),
            tol,
        )?;
        close(
            "J_r^-1 continuity",
            &G::jr_inv(&below),
            &G::jr_inv(&above),
            tol,
        )?;
        let round_off = 1e-14 * (1.0 + r.norm());
        for x in [&below, &above] {
            check_series::<G, N>(x, round_off)?;
            check_jacobian_identities::<G, N>(x, round_off)?;
            close(
                "exp(x) vs expm(hat(x))",
                &G::exp(x).matrix(),
                &expm(&G::hat(x)),
                round_off,
            )?;
        }
    }
    Ok(())
}

macro_rules! group_tests {
    ($name:ident, $G:ty, $N:literal) => {
        mod $name {
            use super::*;
            type G = $G;
            const N: usize = $N;

            proptest! {
                #![proptest_config(config())]

                #[test]
                fn hat_vee_round_trip(x in tangent::<G, N>(0.0..10.0)) {
                    check_hat_vee::<G, N>(&x)?;
                }

                #[test]
                fn log_exp_generic(x in tangent::<G, N>(0.0..PI - 1e-3)) {
                    check_log_exp::<G, N>(&x, 1e-11)?;
                    check_exp_expm::<G, N>(&x, 1e-13)?;
                }

                #[test]
                fn log_exp_tiny(x in tiny_tangent::<G, N>(-12.0, -3.0)) {
                    let tol = 1e-12 * x.norm();
                    check_log_exp::<G, N>(&x, tol)?;
                    // Plus the rounding of the diagonal entries near 1.
                    let tol = tol + 2.3e-16;
                    // Relative accuracy of exp(x) - I.
                    let n = G::hat(&x).nrows();
                    let id = DMatrix::<f64>::identity(n, n);
                    close(
                        "exp(x) - I",
                        &(G::exp(&x).matrix() - &id),
                        &(expm(&G::hat(&x)) - &id),
                        tol,
                    )?;
                }

                #[test]
                fn log_exp_near_pi(x in tangent::<G, N>(PI - 1e-3..PI - 1e-7)) {
                    check_log_exp::<G, N>(&x, 1e-9)?;
                    check_exp_expm::<G, N>(&x, 1e-13)?;
                }

                #[test]
                fn exp_log_any_element(t in element::<G, N>()) {
                    check_exp_log::<G, N>(&t, 1e-12)?;
                }

                #[test]
                fn exp_log_exactly_pi(u in unit_axis(), tr in vec3(5.0)) {
                    // Rotation by exactly pi: R = 2 u u^T - I.
                    let r = u * u.transpose() * 2.0 - Matrix3::identity();
                    let t = G::element(&r, &tr);
                    check_exp_log::<G, N>(&t, 1e-9)?;
                    let phi = t.log().fixed_rows::<3>(N - 3).into_owned();
                    prop_assert!((phi.norm() - PI).abs() < 1e-9, "angle {}", phi.norm());
                    prop_assert!((phi.normalize().dot(&u).abs() - 1.0).abs() < 1e-9);
                    // Also through exp of an exact-pi rotation vector.
                    let t = G::exp(&G::tangent(&tr, &(u * PI)));
                    check_exp_log::<G, N>(&t, 1e-9)?;
                }

                #[test]
                fn jacobians_numeric(x in tangent::<G, N>(0.0..3.0)) {
                    check_jacobians_numeric::<G, N>(&x, 1e-7)?;
                }

                #[test]
                fn jacobians_numeric_small(x in tiny_tangent::<G, N>(-5.0, -2.0)) {
                    check_jacobians_numeric::<G, N>(&x, 1e-8)?;
                }

                #[test]
                fn jacobian_identities_generic(x in tangent::<G, N>(0.0..PI)) {
                    check_jacobian_identities::<G, N>(&x, 1e-12)?;
                }

                #[test]
                fn jacobian_identities_tiny(x in tiny_tangent::<G, N>(-12.0, -3.0)) {
                    check_jacobian_identities::<G, N>(&x, 1e-14)?;
                }

                #[test]
                fn jacobian_identities_near_pi(x in tangent::<G, N>(PI - 1e-3..PI - 1e-7)) {
                    check_jacobian_identities::<G, N>(&x, 1e-11)?;
                }

                #[test]
                fn jacobian_identities_exactly_pi(u in unit_axis(), rho in vec3(2.0)) {
                    check_jacobian_identities::<G, N>(&G::tangent(&rho, &(u * PI)), 1e-11)?;
                }

                #[test]
                fn series_generic(x in tangent::<G, N>(0.0..PI)) {
                    check_series::<G, N>(&x, 1e-12)?;
                }

                #[test]
                fn series_small(x in tiny_tangent::<G, N>(-7.0, -1.0)) {
                    check_series::<G, N>(&x, 1e-14)?;
                }

                #[test]
                fn taylor_switch_over_continuity(u in unit_axis(), rho in vec3(2.0)) {
                    check_switch_over::<G, N>(SMALL_ANGLE, &u, &rho)?;
                    check_switch_over::<G, N>(Q_SMALL_ANGLE, &u, &rho)?;
                }

                #[test]
                fn log_difference_jacobians(t1 in element::<G, N>(), x in tangent::<G, N>(0.0..3.0)) {
                    check_log_difference::<G, N>(&t1, &x, 1e-7)?;
                }

                #[test]
                fn adjoint(
                    a in element::<G, N>(),
                    b in element::<G, N>(),
                    x in tangent::<G, N>(0.0..PI),
                ) {
                    check_adjoint::<G, N>(&a, &b, &x)?;
                }

                #[test]
                fn bracket(
                    a in tangent::<G, N>(0.0..PI),
                    b in tangent::<G, N>(0.0..PI),
                    c in tangent::<G, N>(0.0..PI),
                ) {
                    check_bracket::<G, N>(&a, &b, &c)?;
                }

                #[test]
                fn group_axioms(
                    a in element::<G, N>(),
                    b in element::<G, N>(),
                    c in element::<G, N>(),
                    x in tangent::<G, N>(0.0..PI - 1e-3),
                ) {
                    check_group::<G, N>(&a, &b, &c, &x)?;
                }
            }
        }
    };
}

group_tests!(so3_group, Rot, 3);
group_tests!(se3_group, Se3, 6);

// ---------------------------------------------------------------------------------------------
// Group-specific properties
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(config())]

    #[test]
    fn hat_is_cross_product(w in vec3(3.0), v in vec3(3.0)) {
        close("hat(w) v", &(lie::hat(&w) * v), &w.cross(&v), 1e-14)?;
    }

    #[test]
    fn quaternion_round_trip(q in quaternion()) {
        let r = so3::matrix_from_quaternion(&q);
        close("matrix_from_quaternion", &r, &rotation_from_quaternion_ref(&q), 1e-14)?;
        close("R^T R", &(r.transpose() * r), &Matrix3::identity(), 4e-15)?;
        prop_assert!((r.determinant() - 1.0).abs() < 1e-14);
        let back = so3::quaternion_from_matrix(&r);
        prop_assert!(back[3] >= 0.0);
        let s = if q[3] < 0.0 { -1.0 } else { 1.0 };
        close("quaternion_from_matrix", &Vector4::from(back), &(Vector4::from(q) * s), 1e-14)?;
        close("log_quaternion", &so3::log_quaternion(&q), &so3::log(&r), 1e-14)?;
        // Unnormalised input is normalised first.
        let q3 = [3.0 * q[0], 3.0 * q[1], 3.0 * q[2], 3.0 * q[3]];
        close("unnormalised", &so3::matrix_from_quaternion(&q3), &r, 4e-15)?;
    }

    #[test]
    fn quaternion_round_trip_w_near_zero(
        u in unit_axis(),
        w in prop_oneof![Just(0.0), 0.0f64..1e-6, 1e-6f64..1e-3],
    ) {
        let s = (1.0 - w * w).sqrt();
        let q = [u.x * s, u.y * s, u.z * s, w];
        let r = so3::matrix_from_quaternion(&q);
        close("matrix_from_quaternion", &r, &rotation_from_quaternion_ref(&q), 1e-14)?;
        let back = so3::quaternion_from_matrix(&r);
        prop_assert!(back[3] >= 0.0);
        // With w ~ 0, q and -q may both be returned.
        let (b, q) = (Vector4::from(back), Vector4::from(q));
        let err = (b - q).amax().min((b + q).amax());
        prop_assert!(err < 1e-14, "quaternion error {err:e}");
        if w > 1e-12 {
            close("sign", &b, &q, 1e-14)?;
        }
        close("matrix round trip", &so3::matrix_from_quaternion(&back), &r, 1e-14)?;
        // The angle 2 atan2(|v|, w) is near pi.
        let phi = so3::log_quaternion(&back);
        prop_assert!((phi.norm() - (PI - 2.0 * w.asin())).abs() < 1e-14);
    }

    #[test]
    fn quaternion_w_tiny_is_accurate(u in unit_axis(), e in -12.0f64..-3.0) {
        // Small rotation: quaternion (u sin(th/2), cos(th/2)); relative accuracy of the vector part.
        let th = 10f64.powf(e);
        let q = [u.x * (th / 2.0).sin(), u.y * (th / 2.0).sin(), u.z * (th / 2.0).sin(), (th / 2.0).cos()];
        let r = so3::matrix_from_quaternion(&q);
        let back = so3::quaternion_from_matrix(&r);
        close("vector part", &Vector3::new(back[0], back[1], back[2]), &Vector3::new(q[0], q[1], q[2]), 1e-12 * th)?;
        close("log_quaternion", &so3::log_quaternion(&q), &(u * th), 1e-12 * th)?;
    }

    #[test]
    fn se3_matrix_round_trip(q in quaternion(), t in vec3(10.0)) {
        let r = rotation_from_quaternion_ref(&q);
        let m = Se3::new(r, t).to_matrix();
        let mut expected = Matrix4::identity();
        expected.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        expected.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
        close("to_matrix", &m, &expected, 0.0)?;
        let back = Se3::from_matrix(&m);
        close("from_matrix rot", &back.rot, &r, 1e-14)?;
        close("from_matrix trans", &back.trans, &t, 0.0)?;
        let s = Se3::from_quaternion_xyzw(&q, t);
        close("from_quaternion_xyzw", &s.rot, &r, 1e-14)?;
        let qb = s.quaternion_xyzw();
        let sign = if q[3] < 0.0 { -1.0 } else { 1.0 };
        close("quaternion_xyzw", &Vector4::from(qb), &(Vector4::from(q) * sign), 1e-14)?;
    }

    #[test]
    fn se3_from_matrix_projects_rotation(q in quaternion(), t in vec3(10.0), noise in prop::array::uniform9(-1e-9f64..1e-9)) {
        let r = rotation_from_quaternion_ref(&q);
        let mut m = Se3::new(r, t).to_matrix();
        for (k, n) in noise.iter().enumerate() {
            m[(k % 3, k / 3)] += n;
        }
        let back = Se3::from_matrix(&m);
        close("orthonormal", &(back.rot.transpose() * back.rot), &Matrix3::identity(), 4e-15)?;
        close("close to input", &back.rot, &r, 1e-8)?;
        let drifted = Se3::new(m.fixed_view::<3, 3>(0, 0).into_owned(), t).renormalized();
        close("renormalized", &(drifted.rot.transpose() * drifted.rot), &Matrix3::identity(), 4e-15)?;
    }

    #[test]
    fn se3_exp_structure(rho in vec3(2.0), u in unit_axis(), th in 0.0..PI) {
        // exp(xi) has rotation exp(phi) and translation J_l(phi) rho; log splits the same way.
        let phi = u * th;
        let xi = <Se3 as Group<6>>::tangent(&rho, &phi);
        let t = Se3::exp(&xi);
        close("rotation", &t.rot, &so3::exp(&phi), 0.0)?;
        close("translation", &t.trans, &(so3::left_jacobian(&phi) * rho), 1e-14)?;
        // The SE(3) Jacobians have J_l(phi) on the diagonal blocks and zero lower-left block.
        let jl = lie::se3_left_jacobian(&xi);
        close("J_l block 00", &jl.fixed_view::<3, 3>(0, 0), &so3::left_jacobian(&phi), 0.0)?;
        close("J_l block 11", &jl.fixed_view::<3, 3>(3, 3), &so3::left_jacobian(&phi), 0.0)?;
        close("J_l block 10", &jl.fixed_view::<3, 3>(3, 0), &Matrix3::zeros(), 0.0)?;
        // curly has the documented block structure.
        let c = lie::curly(&xi);
        close("curly 00", &c.fixed_view::<3, 3>(0, 0), &lie::hat(&phi), 0.0)?;
        close("curly 01", &c.fixed_view::<3, 3>(0, 3), &lie::hat(&rho), 0.0)?;
        close("curly 11", &c.fixed_view::<3, 3>(3, 3), &lie::hat(&phi), 0.0)?;
        close("curly 10", &c.fixed_view::<3, 3>(3, 0), &Matrix3::zeros(), 0.0)?;
    }

    #[test]
    fn se3_adjoint_structure(q in quaternion(), t in vec3(5.0)) {
        let r = rotation_from_quaternion_ref(&q);
        let ad = Se3::new(r, t).adjoint();
        close("Ad 00", &ad.fixed_view::<3, 3>(0, 0), &r, 0.0)?;
        close("Ad 01", &ad.fixed_view::<3, 3>(0, 3), &(lie::hat(&t) * r), 0.0)?;
        close("Ad 10", &ad.fixed_view::<3, 3>(3, 0), &Matrix3::zeros(), 0.0)?;
        close("Ad 11", &ad.fixed_view::<3, 3>(3, 3), &r, 0.0)?;
    }

    #[test]
    fn transform_point(
        qa in quaternion(), ta in vec3(5.0),
        qb in quaternion(), tb in vec3(5.0),
        p in vec3(10.0),
        xi in tangent::<Se3, 6>(0.0..PI),
    ) {
        let a = Se3::new(rotation_from_quaternion_ref(&qa), ta);
        let b = Se3::new(rotation_from_quaternion_ref(&qb), tb);
        let ph = Vector4::new(p.x, p.y, p.z, 1.0);
        close("T p", &a.transform_point(&p), &(a.to_matrix() * ph).xyz(), 1e-14)?;
        close("(AB) p", &(a * b).transform_point(&p), &a.transform_point(&b.transform_point(&p)), 1e-13)?;
        close("T^-1 T p", &a.inverse().transform_point(&a.transform_point(&p)), &p, 1e-13)?;
        close("I p", &Se3::identity().transform_point(&p), &p, 0.0)?;
        let e = expm(&DMatrix::from_column_slice(4, 4, lie::se3_hat(&xi).as_slice()));
        let ep = &e * DVector::from_column_slice(ph.as_slice());
        close("exp(xi) p", &Se3::exp(&xi).transform_point(&p), &ep.rows(0, 3), 1e-12)?;
        // Rigid: distances are preserved.
        let p2 = p * 0.5 + Vector3::new(1.0, -2.0, 0.5);
        let d0 = (p - p2).norm();
        let d1 = (a.transform_point(&p) - a.transform_point(&p2)).norm();
        prop_assert!((d0 - d1).abs() < 1e-13);
    }

    #[test]
    fn retract_is_right_perturbation(q in quaternion(), t in vec3(5.0), xi in tangent::<Se3, 6>(0.0..PI)) {
        let a = Se3::new(rotation_from_quaternion_ref(&q), t);
        let r = a.retract(&xi);
        close("retract rot", &r.rot, &(a * Se3::exp(&xi)).rot, 1e-14)?;
        close("retract trans", &r.trans, &(a * Se3::exp(&xi)).trans, 1e-13)?;
        close("retract orthonormal", &(r.rot.transpose() * r.rot), &Matrix3::identity(), 4e-15)?;
    }
}

#[test]
fn quaternion_from_matrix_every_branch() {
    // Rotations whose largest quaternion component is w, x, y and z in turn, at and near pi.
    for axis in [
        Vector3::x(),
        Vector3::y(),
        Vector3::z(),
        Vector3::new(1.0, -1.0, 1.0).normalize(),
    ] {
        for th in [0.0, 0.3, 2.0, PI - 1e-6, PI] {
            let r = so3::exp(&(axis * th));
            let q = so3::quaternion_from_matrix(&r);
            let expected = [
                axis.x * (th / 2.0).sin(),
                axis.y * (th / 2.0).sin(),
                axis.z * (th / 2.0).sin(),
                (th / 2.0).cos(),
            ];
            let (q, e) = (Vector4::from(q), Vector4::from(expected));
            // At exactly pi, w == 0 and q, -q are the same rotation.
            let err = if th == PI {
                (q - e).amax().min((q + e).amax())
            } else {
                (q - e).amax()
            };
            assert!(
                err < 1e-15,
                "axis {axis:?} angle {th}: {q:?} vs {expected:?}"
            );
            let phi = so3::log(&r);
            let err = if th == PI {
                (phi - axis * th).amax().min((phi + axis * th).amax())
            } else {
                (phi - axis * th).amax()
            };
            assert!(err < 1e-14, "log {phi:?}");
        }
    }
}

#[test]
fn exp_log_identity_and_zero() {
    assert_eq!(so3::exp(&Vector3::zeros()), Matrix3::identity());
    assert_eq!(so3::log(&Matrix3::identity()), Vector3::zeros());
    assert_eq!(so3::left_jacobian(&Vector3::zeros()), Matrix3::identity());
    assert_eq!(
        so3::left_jacobian_inv(&Vector3::zeros()),
        Matrix3::identity()
    );
    let z = SVector::<f64, 6>::zeros();
    assert_eq!(Se3::exp(&z), Se3::identity());
    assert_eq!(Se3::identity().log(), z);
    assert_eq!(lie::se3_left_jacobian(&z), SMatrix::<f64, 6, 6>::identity());
    assert_eq!(
        lie::se3_left_jacobian_inv(&z),
        SMatrix::<f64, 6, 6>::identity()
    );
    assert_eq!(Se3::default(), Se3::identity());
}

#[test]
fn taylor_switch_over_sweep() {
    // Deterministic sweep across both Taylor switch-overs: the Jacobians against the series.
    let u = Vector3::new(0.48, -0.6, 0.64);
    let rho = Vector3::new(1.5, -0.7, 1.9);
    let mut th = 1e-6;
    while th < 1.0 {
        for x in [
            <Se3 as Group<6>>::tangent(&rho, &(u * th)),
            <Se3 as Group<6>>::tangent(&(rho * th), &(u * th)),
        ] {
            let jl = lie::se3_left_jacobian(&x);
            let series = jacobian_series(&lie::curly(&x));
            let err = (jl - series).amax();
            assert!(err < 1e-13, "angle {th:e}: SE(3) J_l error {err:e}");
            let err =
                (lie::se3_left_jacobian_inv(&x) * series - SMatrix::<f64, 6, 6>::identity()).amax();
            assert!(err < 1e-13, "angle {th:e}: SE(3) J_l^-1 error {err:e}");
        }
        let phi = u * th;
        let err = (so3::left_jacobian(&phi) - jacobian_series(&lie::hat(&phi))).amax();
        assert!(err < 1e-15, "angle {th:e}: SO(3) J_l error {err:e}");
        th *= 1.07;
    }
}

#[test]
fn both_inverse_jacobians_at_once_equal_two_separate_calls() {
    // `se3_left_jacobian_inv_both` shares the trigonometry and the Q block's products between
    // `xi` and `-xi`: its values are those of the two separate calls (compared with `==`, which
    // also equates the two signs of an exact zero), across both Taylor switch-overs, with zero
    // components, and up to near pi.
    let u = Vector3::new(0.48, -0.6, 0.64);
    let rho = Vector3::new(1.5, -0.7, 1.9);
    let mut th = 1e-7;
    while th < 3.1 {
        for x in [
            <Se3 as Group<6>>::tangent(&rho, &(u * th)),
            <Se3 as Group<6>>::tangent(&(rho * th), &(u * th)),
            <Se3 as Group<6>>::tangent(&Vector3::new(0.3, 0.0, 0.0), &Vector3::new(0.0, 0.0, th)),
        ] {
            let (jl, jr) = lie::se3_left_jacobian_inv_both(&x);
            assert_eq!(jl, lie::se3_left_jacobian_inv(&x), "J_l^-1 at {x:?}");
            assert_eq!(jr, lie::se3_right_jacobian_inv(&x), "J_r^-1 at {x:?}");
            let phi = x.fixed_rows::<3>(3).into_owned();
            let (sl, sr) = so3::left_jacobian_inv_both(&phi);
            assert_eq!(sl, so3::left_jacobian_inv(&phi));
            assert_eq!(sr, so3::right_jacobian_inv(&phi));
        }
        th *= 1.09;
    }
}
