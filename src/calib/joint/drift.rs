//! The clock drift as a ninth parameter of the joint problem.
//!
//! With a drifting DVL clock a sample's camera time is `t + delta + 1e-6 d (t - t_ref)`: the
//! drift `d` (ppm) moves a sample as the clock offset does, scaled by its DVL time from the
//! reference. Its Jacobian is the offset's column times `1e-6 (t - t_ref)`, so its terms are
//! formed from the same factors ([`DvlFactors::drift_terms`]) and appended to the joint system
//! assembled for the covariance as a ninth column. Eliminating the trajectory as for the eight
//! parameters gives the nine-parameter reduced system: its Gauss-Newton step (the drift's
//! correction, and the other parameters' with it) and its inverse, the covariance with the
//! drift marginalised.

use std::ops::AddAssign;

use nalgebra::SMatrix;

use super::covariance::{AssembledJoint, decouple_columns};
use super::factors::DvlFactors;
use super::problem::{CrossBlock, JointProblem};
use crate::calib::model::NPARAM;
use crate::calib::update::ParamMat;
use crate::error::Result;
use crate::trajectory::Knot;
use crate::trajectory::blocktri::{
    BlockSource, BlockTridiagonal, M18, V18, streamed_quadratic_forms,
};

/// Parameters with the drift: the eight, then the drift.
pub const NDRIFT: usize = NPARAM + 1;

/// A square matrix over the eight parameters and the drift.
pub type DriftMat = SMatrix<f64, NDRIFT, NDRIFT>;
/// A vector over the eight parameters and the drift.
pub type DriftVec = SMatrix<f64, NDRIFT, 1>;

/// Where the drift stands in a run: the DVL times were mapped to `t + 1e-6 ppm (t -
/// reference_t_s)` before the run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriftAt {
    /// The drift applied, ppm.
    pub ppm: f64,
    /// The reference DVL time, s (relative to the run's epoch).
    pub reference_t_s: f64,
}

/// The nine-parameter reduced system at a result.
#[derive(Clone, Debug)]
pub struct DriftSolution {
    /// The Gauss-Newton step `[dphi; dp; dkappa; ddelta; dd]` (the drift in ppm).
    pub step: DriftVec,
    /// Covariance of the nine (the drift marginalised into the others); a held parameter has
    /// zero variance.
    pub covariance: DriftMat,
    /// The eight parameters' covariance with the drift held (the inverse of the reduced
    /// system's first eight rows and columns).
    pub covariance_drift_held: ParamMat,
}

impl DriftSolution {
    /// What marginalising the drift adds to the eight parameters' covariance.
    pub fn added_covariance(&self) -> ParamMat {
        let all = self
            .covariance
            .fixed_view::<NPARAM, NPARAM>(0, 0)
            .into_owned();
        let added = all - self.covariance_drift_held;
        (added + added.transpose()) * 0.5
    }

    /// The drift's standard deviation, ppm.
    pub fn std_ppm(&self) -> f64 {
        self.covariance[(NPARAM, NPARAM)].max(0.0).sqrt()
    }
}

/// The nine-parameter reduced system of `aj` (assembled from `jp` at `knots`, the DVL times
/// mapped by `at`): its step and covariance. The drift is free; `free` says which of the
/// eight are.
pub fn drift_solution(
    jp: &JointProblem,
    aj: &AssembledJoint,
    knots: &[Knot],
    free: &[bool; NPARAM],
    at: DriftAt,
) -> Result<DriftSolution> {
    let factors = DvlFactors::new(jp, &aj.params)?;
    // A mapped time `t'` lies `(1 + 1e-6 ppm) (t - t_ref)` from the reference.
    let stretch = 1.0 + 1e-6 * at.ppm;
    let terms = factors.drift_terms(knots, |t| 1e-6 * (t - at.reference_t_s) / stretch);
    let mut free9 = [true; NDRIFT];
    free9[..NPARAM].copy_from_slice(free);

    // The calibration's own blocks, the fixed parameters decoupled and the priors added (as
    // the covariance forms them), bordered by the drift's.
    let mut theta = DriftMat::zeros();
    let mut gradient = DriftVec::zeros();
    theta
        .fixed_view_mut::<NPARAM, NPARAM>(0, 0)
        .copy_from(&aj.a.theta);
    gradient
        .fixed_rows_mut::<NPARAM>(0)
        .copy_from(&aj.a.gradient);
    if jp.priors.any() {
        let t = jp.priors.terms(&aj.params);
        theta
            .fixed_view_mut::<NPARAM, NPARAM>(0, 0)
            .add_assign(&t.information);
        gradient.fixed_rows_mut::<NPARAM>(0).add_assign(&t.gradient);
    }
    for k in 0..NPARAM {
        theta[(k, NPARAM)] = terms.theta[k];
        theta[(NPARAM, k)] = terms.theta[k];
    }
    theta[(NPARAM, NPARAM)] = terms.information;
    gradient[NPARAM] = terms.gradient;

    let blocks = DriftBlocks {
        sys: &aj.sys,
        cross: &aj.a.cross,
        drift: &terms.cross,
        free: *free,
    };
    let (reduction, cross_g) = streamed_quadratic_forms(&blocks)?;
    let schur = theta - reduction;
    let mut schur = (schur + schur.transpose()) * 0.5;
    let mut b = gradient - cross_g;
    for k in (0..NDRIFT).filter(|&k| !free9[k]) {
        schur.row_mut(k).fill(0.0);
        schur.column_mut(k).fill(0.0);
        schur[(k, k)] = 1.0;
        b[k] = 0.0;
    }
    let unknown = || DriftSolution {
        step: DriftVec::from_element(f64::NAN),
        covariance: DriftMat::from_diagonal_element(f64::INFINITY),
        covariance_drift_held: ParamMat::from_diagonal_element(f64::INFINITY),
    };
    let Some(chol) = schur.cholesky() else {
        return Ok(unknown());
    };
    let held = schur.fixed_view::<NPARAM, NPARAM>(0, 0).into_owned();
    let Some(held_inv) = held.cholesky().map(|c| c.inverse()) else {
        return Ok(unknown());
    };
    let mut covariance = chol.inverse();
    let mut covariance_drift_held = held_inv;
    for k in (0..NPARAM).filter(|&k| !free[k]) {
        covariance[(k, k)] = 0.0;
        covariance_drift_held[(k, k)] = 0.0;
    }
    Ok(DriftSolution {
        step: chol.solve(&b),
        covariance,
        covariance_drift_held,
    })
}

/// The assembled joint system with the drift's column beside the calibration's eight (the
/// fixed parameters' columns read as zero).
struct DriftBlocks<'w> {
    sys: &'w BlockTridiagonal,
    cross: &'w [CrossBlock],
    drift: &'w [V18],
    free: [bool; NPARAM],
}

impl BlockSource<NDRIFT> for DriftBlocks<'_> {
    fn len(&self) -> usize {
        self.sys.len()
    }

    fn diag(&self, k: usize) -> M18 {
        self.sys.diag[k]
    }

    fn upper(&self, k: usize) -> M18 {
        self.sys.upper[k]
    }

    fn rhs(&self, k: usize) -> V18 {
        self.sys.rhs[k]
    }

    fn columns(&self, k: usize) -> SMatrix<f64, 18, NDRIFT> {
        let mut c = self.cross[k];
        decouple_columns(&mut c, &self.free);
        let mut out = SMatrix::<f64, 18, NDRIFT>::zeros();
        out.fixed_columns_mut::<NPARAM>(0).copy_from(&c);
        out.set_column(NPARAM, &self.drift[k]);
        out
    }
}
