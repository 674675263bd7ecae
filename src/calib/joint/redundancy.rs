//! How many of each group's residual dimensions are free to show its scale: the redundancy of
//! the co-sensor's and the DVL's measurements in the joint problem, for the estimate of their
//! noise scales, and of the GP prior's terms per interval, for the jerk density along the
//! recording (variance components both).
//!
//! A group of measurements with weights `W_g` and Jacobian `J_g` takes `p_g = tr(H^-1 J_g^T W_g
//! J_g)` of the problem's degrees of freedom; its cost at the estimate has the expectation
//! `s_g^2 (m_g - p_g)` with `m_g` its dimension and `s_g^2` the ratio of its true to its stated
//! variance. The trajectory's system is block tridiagonal, so the traces need only the blocks of
//! `H^-1` on and next to the diagonal ([`BandedInverse`]). The co-sensor's and the GP prior's
//! shares are summed knot by knot; the DVL's is what is left of the trajectory's `18 N` degrees
//! of freedom, plus the calibration parameters it alone determines.

use super::factors::DvlFactors;
use super::problem::JointProblem;
use crate::error::Result;
use crate::trajectory::Knot;
use crate::trajectory::blocktri::{BandedInverse, BlockTridiagonal, M18, V18};
use crate::trajectory::factors::IntervalNormal;
use crate::trajectory::gp::PriorNormal;
use crate::trajectory::solver::ASSEMBLY_CHUNK;
use crate::types::CalibrationParams;

/// Costs and redundancies of the joint problem's measurement groups at one estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Redundancy {
    /// The DVL factors' cost (at their weights).
    pub dvl_cost: f64,
    /// Their dimension less the degrees of freedom they take.
    pub dvl_redundancy: f64,
    /// The co-sensor's factors' cost.
    pub cosensor_cost: f64,
    /// Their dimension less the degrees of freedom they take.
    pub cosensor_redundancy: f64,
}

/// `sum_ij a_ij b_ij`: `tr(A B)` for symmetric `A`, `tr(A^T B)` in general.
fn frobenius(a: &M18, b: &M18) -> f64 {
    a.component_mul(b).sum()
}

/// The redundancies of `jp`'s measurement groups at the knot states `knots` and the
/// calibration `p`, of which `free_params` parameters were estimated.
pub(crate) fn redundancy(
    jp: &JointProblem,
    knots: &[Knot],
    p: &CalibrationParams,
    free_params: usize,
) -> Result<Redundancy> {
    let n = knots.len();
    let (total, inv) = banded_inverse_at(jp, knots, p)?;
    let traj = jp.trajectory_problem();
    // Per knot, in chunks summed in order: the co-sensor's cost and trace, the prior's trace
    // and cost.
    let pieces = crate::parallel::map_pieces(n, ASSEMBLY_CHUNK, |r| {
        let (mut cos_cost, mut cos_tr, mut prior_cost, mut prior_tr) = (0.0, 0.0, 0.0, 0.0);
        let (mut d, mut rhs) = (M18::zeros(), V18::zeros());
        let mut t = PriorNormal::zeros();
        let mut c = IntervalNormal::zeros();
        let mut u = M18::zeros();
        for k in r {
            cos_cost += traj.knot_terms(knots, k, &mut d, &mut rhs);
            cos_tr += frobenius(&inv.diag[k], &d);
            if k + 1 < n {
                let ls = traj.prior_terms(knots, k, &mut t, &mut u);
                prior_cost += t.cost;
                prior_tr += interval_trace(&inv, k, &t.d1, &u, &t.d2);
                if traj.cosensor_interval(knots, k, &ls, &mut c) {
                    cos_cost += c.cost;
                    cos_tr += interval_trace(&inv, k, &c.d1, &c.upper, &c.d2);
                }
            }
        }
        (cos_cost, cos_tr, prior_cost, prior_tr)
    });
    let (mut cos_cost, mut cos_tr, mut prior_cost, mut prior_tr) = (0.0, 0.0, 0.0, 0.0);
    for (a, b, c, d) in pieces {
        cos_cost += a;
        cos_tr += b;
        prior_cost += c;
        prior_tr += d;
    }
    keep_inverse(jp, inv);
    let dvl_dofs = 18.0 * n as f64 - cos_tr - prior_tr + free_params as f64;
    Ok(Redundancy {
        dvl_cost: total - cos_cost - prior_cost,
        dvl_redundancy: (3 * jp.idx.len()) as f64 - dvl_dofs,
        cosensor_cost: cos_cost,
        cosensor_redundancy: jp.cosensor.dimension() as f64 - cos_tr,
    })
}

/// `tr(Sigma H)` of an interval's terms: the blocks `d1`, `d2` on the diagonal and `upper`
/// (and its transpose) beside it.
fn interval_trace(inv: &BandedInverse, k: usize, d1: &M18, upper: &M18, d2: &M18) -> f64 {
    frobenius(&inv.diag[k], d1)
        + frobenius(&inv.diag[k + 1], d2)
        + 2.0 * frobenius(&inv.upper[k], upper)
}

/// The joint problem's trajectory system at the knots `knots` and the calibration `p` (the
/// calibration held), its total cost and the blocks of its inverse on and beside the diagonal.
fn banded_inverse_at(
    jp: &JointProblem,
    knots: &[Knot],
    p: &CalibrationParams,
) -> Result<(f64, BandedInverse)> {
    let n = knots.len();
    let factors = DvlFactors::new(jp, p)?;
    let mut sys = jp
        .take_system()
        .map(|s| s.resized(n))
        .unwrap_or_else(|| BlockTridiagonal::zeros(n));
    let total = factors.assemble(knots, &mut sys, false).cost;
    Ok((total, sys.factor()?.banded_inverse()))
}

/// Keeps the storage of `inv` for the problem's next system.
fn keep_inverse(jp: &JointProblem, inv: BandedInverse) {
    let n = inv.diag.len();
    jp.keep_system(BlockTridiagonal {
        rhs: vec![V18::zeros(); n],
        diag: inv.diag,
        upper: inv.upper,
    });
}

/// One interval's GP prior terms, each part (translational, rotational) on its own.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct PriorShare {
    /// The part's cost at the estimate (at its present weights).
    pub cost: [f64; 2],
    /// The degrees of freedom it takes, `tr(H^-1 J^T W J)` of its terms.
    pub taken: [f64; 2],
}

/// Per interval between knots, the GP prior's cost and degrees of freedom in `jp` at `knots`
/// and the calibration `p` (held), its translational and rotational parts apart: the
/// variance components of the jerk density, the way [`redundancy`] gives the sensors'.
pub(crate) fn prior_shares(
    jp: &JointProblem,
    knots: &[Knot],
    p: &CalibrationParams,
) -> Result<Vec<PriorShare>> {
    let n = knots.len();
    let (_, inv) = banded_inverse_at(jp, knots, p)?;
    let traj = jp.trajectory_problem();
    let shares = crate::parallel::map_indices(n.saturating_sub(1), ASSEMBLY_CHUNK, |k| {
        let mut t = PriorNormal::zeros();
        let mut u = M18::zeros();
        let mut share = PriorShare::default();
        let qc_inv = jp.density.qc_inv(k);
        for part in 0..2 {
            let masked =
                qc_inv.map_with_location(|i, _, q| if (i < 3) == (part == 0) { q } else { 0.0 });
            traj.prior_terms_weighted(knots, k, &masked, &mut t, &mut u);
            share.cost[part] = t.cost;
            share.taken[part] = interval_trace(&inv, k, &t.d1, &u, &t.d2);
        }
        share
    });
    keep_inverse(jp, inv);
    Ok(shares)
}
