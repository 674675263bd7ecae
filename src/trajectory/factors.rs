//! What drives a trajectory: the co-sensor's measurements, as factors on the knot states.
//!
//! The trajectory's problem is the GP prior between consecutive knots plus the factors of the
//! co-sensor, the sensor whose motion the DVL is calibrated against. [`CoSensorFactors`] is the
//! seam: a kind of co-sensor measurement says what it adds to the block-tridiagonal normal
//! equations, at one knot (a factor on a single state) or on the interval between two knots (a
//! factor that interpolates between them). The solver, the fit and the calibration's joint
//! problem take any kind through it.
//!
//! - [`PoseFactors`]: camera poses (or motion capture, VIO), one per knot (the knots sit at the
//!   pose times), each a factor on its knot's pose.
//! - A kind measured between knots (an IMU's angular rate and specific force) implements
//!   [`CoSensorFactors::interval_terms`] instead, as the DVL's velocity factors do in the
//!   calibration: its terms couple the interval's two knots and keep the system block
//!   tridiagonal.

use std::ops::Range;

use nalgebra::Matrix6;

use super::blocktri::{M18, V18};
use super::gp::{Knot, LocalState};
use super::view::KnotView;
use crate::lie::{Se3, se3_right_jacobian_inv};

/// The normal-equation blocks of the factors on one interval between knots `k` and `k + 1`.
#[derive(Clone, Debug)]
pub struct IntervalNormal {
    /// The first knot's diagonal block.
    pub d1: M18,
    /// The coupling block `A[k, k + 1]`.
    pub upper: M18,
    /// The second knot's diagonal block.
    pub d2: M18,
    /// The first knot's right-hand side.
    pub r1: V18,
    /// The second knot's right-hand side.
    pub r2: V18,
    /// The factors' cost.
    pub cost: f64,
}

impl IntervalNormal {
    /// All blocks zero.
    pub fn zeros() -> IntervalNormal {
        IntervalNormal {
            d1: M18::zeros(),
            upper: M18::zeros(),
            d2: M18::zeros(),
            r1: V18::zeros(),
            r2: V18::zeros(),
            cost: 0.0,
        }
    }
}

/// One kind of co-sensor measurement, as factors on the trajectory's knot states.
///
/// Every sum is formed knot by knot in a fixed order (the solver's chunks), so a kind's terms
/// must depend only on the knots they are given, never on the thread that asks.
pub trait CoSensorFactors: Sync {
    /// Overwrites `diag` and `rhs` with the terms of the factors on knot `k` alone (zero when
    /// the kind has none there); returns their cost.
    fn knot_terms(&self, knots: &[Knot], k: usize, diag: &mut M18, rhs: &mut V18) -> f64;

    /// The cost of the factors on knot `k` alone, as [`CoSensorFactors::knot_terms`] returns it.
    fn knot_cost(&self, knots: &[Knot], k: usize) -> f64;

    /// Whether the kind has factors between knots at all (the solver skips asking otherwise).
    fn has_interval_terms(&self) -> bool {
        false
    }

    /// Writes into `out` the terms of the factors on the interval between knots `k` and
    /// `k + 1` of `view`, with `ls` the local state of knot `k + 1` relative to knot `k`;
    /// `false` (and `out` as it was) when the kind has none there. Camera poses have none.
    fn interval_terms(
        &self,
        _view: KnotView,
        _k: usize,
        _ls: &LocalState,
        _out: &mut IntervalNormal,
    ) -> bool {
        false
    }

    /// The cost of the interval's factors, as [`CoSensorFactors::interval_terms`] forms it,
    /// with `gamma2` the local state of knot `k + 1`.
    fn interval_cost(&self, _view: KnotView, _k: usize, _gamma2: &V18) -> f64 {
        0.0
    }

    /// The number of scalar measurements the factors hold (their residuals' dimension).
    fn dimension(&self) -> usize;

    /// The factors of the knots `range` alone, renumbered from zero (for a problem on part of
    /// the recording).
    fn restricted(&self, range: Range<usize>) -> Box<dyn CoSensorFactors + '_>;
}

/// Camera poses `T_world_cam` as factors: one per knot, the error `log(T_meas^-1 T_knot)`
/// weighted by the pose's information matrix.
#[derive(Clone, Debug)]
pub struct PoseFactors {
    meas: Vec<Se3>,
    info: Vec<Matrix6<f64>>,
}

impl PoseFactors {
    /// The factors of the poses `meas` with their information matrices `info` (one per pose,
    /// one pose per knot).
    pub fn new(meas: Vec<Se3>, info: Vec<Matrix6<f64>>) -> PoseFactors {
        PoseFactors { meas, info }
    }

    /// The measured poses, one per knot.
    pub fn measurements(&self) -> &[Se3] {
        &self.meas
    }

    /// The information matrices, one per pose.
    pub fn information(&self) -> &[Matrix6<f64>] {
        &self.info
    }

    /// Replaces the information matrices (the same poses weighed anew).
    pub fn set_information(&mut self, info: Vec<Matrix6<f64>>) {
        self.info = info;
    }
}

impl CoSensorFactors for PoseFactors {
    fn knot_terms(&self, knots: &[Knot], k: usize, diag: &mut M18, rhs: &mut V18) -> f64 {
        *diag = M18::zeros();
        *rhs = V18::zeros();
        let e = (self.meas[k].inverse() * knots[k].pose).log();
        let j = se3_right_jacobian_inv(&e);
        let wj = self.info[k] * j;
        diag.fixed_view_mut::<6, 6>(0, 0)
            .copy_from(&(j.transpose() * wj));
        rhs.fixed_rows_mut::<6>(0).copy_from(&-(wj.transpose() * e));
        (e.transpose() * self.info[k] * e)[0]
    }

    fn knot_cost(&self, knots: &[Knot], k: usize) -> f64 {
        let e = (self.meas[k].inverse() * knots[k].pose).log();
        (e.transpose() * self.info[k] * e)[0]
    }

    fn dimension(&self) -> usize {
        6 * self.meas.len()
    }

    fn restricted(&self, range: Range<usize>) -> Box<dyn CoSensorFactors + '_> {
        Box::new(PoseFactors {
            meas: self.meas[range.clone()].to_vec(),
            info: self.info[range].to_vec(),
        })
    }
}

#[cfg(test)]
#[path = "factors_tests.rs"]
pub(crate) mod tests;
