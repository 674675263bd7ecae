//! The knots' block of the IMU's joint problem: each knot's trajectory state (18) and, beside
//! it, the IMU's biases there (6), so that a bias that walks is followed knot by knot in the
//! block-tridiagonal system; and the helpers that move between the two parts.

use nalgebra::{SMatrix, SVector, Vector6};

use crate::trajectory::blocktri::V18;

/// The knots' block in the joint problem: the trajectory's state at the knot (18), then the
/// IMU's biases there (gyro, then accelerometer), linear between knots and tied to the next
/// knot's by their random walks.
pub const KB: usize = 24;
/// A knot's block of the joint problem.
pub type MK = SMatrix<f64, KB, KB>;
/// A knot's part of a vector of the joint problem.
pub type VK = SVector<f64, KB>;

/// `[j b]`: a factor's Jacobian on a knot's trajectory state and on its biases, as one on the
/// knot's block.
pub(super) fn widen<const M: usize>(
    j: &SMatrix<f64, M, 18>,
    b: &SMatrix<f64, M, 6>,
) -> SMatrix<f64, M, KB> {
    let mut out = SMatrix::<f64, M, KB>::zeros();
    out.fixed_columns_mut::<18>(0).copy_from(j);
    out.fixed_columns_mut::<6>(18).copy_from(b);
    out
}

/// A knot block's trajectory part.
pub(super) fn trajectory_part(x: &VK) -> V18 {
    x.fixed_rows::<18>(0).into_owned()
}

/// A knot block's bias part (gyro, then accelerometer).
pub(super) fn bias_part(x: &VK) -> Vector6<f64> {
    x.fixed_rows::<6>(18).into_owned()
}
