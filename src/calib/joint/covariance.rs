//! The calibration's covariance from the joint system: the Schur complement of the
//! trajectory in the joint information, the linearised estimate of a part of the recording
//! (the halves check) taken from the whole's assembled system, and the reduced system a joint
//! step solves.

use super::factors::{Assembled, DvlFactors, JointChunk};
use super::problem::{CrossBlock, JointProblem, JointStorage};
use crate::calib::model::NPARAM;
use crate::calib::update::{ParamMat, ParamVec, pin_fixed};
use crate::error::{Error, Result};
use crate::trajectory::blocktri::{
    BlockSource, BlockTridiagonal, M18, V18, streamed_quadratic_forms,
};
use crate::trajectory::solver::AssemblyChunk;
use crate::trajectory::{Knot, KnotView, Trajectory};
use crate::types::CalibrationParams;

/// The joint system at `(traj, p)` with the fixed parameters decoupled, factorised: the
/// factor of `H_xx`, `H_x theta` per knot, `H_theta theta` and the calibration's right-hand side.
pub(super) struct JointSystem {
    pub(super) factor: crate::trajectory::blocktri::Factored,
    pub(super) cross: Vec<CrossBlock>,
    pub(super) theta: ParamMat,
    pub(super) gradient: ParamVec,
    pub(super) cost: f64,
}

/// The joint system at `(traj, p)` as assembled, before the fixed parameters are decoupled
/// and before the factorisation: what the covariance and the halves check share.
pub struct AssembledJoint {
    pub(super) sys: BlockTridiagonal,
    pub(super) a: Assembled,
    /// The calibration the system was linearised at.
    pub(super) params: CalibrationParams,
}

impl AssembledJoint {
    /// The calibration the system was linearised at.
    pub fn params(&self) -> CalibrationParams {
        self.params
    }
}

/// Assembles the joint system of `jp` at the knot states `knots` (one per knot time of `jp`)
/// and the calibration `p`, in `jp`'s kept storage.
pub fn assemble_joint(
    jp: &JointProblem,
    knots: &[Knot],
    p: &CalibrationParams,
) -> Result<AssembledJoint> {
    let n = knots.len();
    let mut sys = jp
        .take_system()
        .map(|s| s.resized(n))
        .unwrap_or_else(|| BlockTridiagonal::zeros(n));
    let a = DvlFactors::new(jp, p)?.assemble(knots, &mut sys, true);
    Ok(AssembledJoint { sys, a, params: *p })
}

pub(super) fn joint_system(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    free: &[bool; NPARAM],
) -> Result<JointSystem> {
    finish(jp, assemble_joint(jp, traj.knots(), p)?, free)
}

/// An assembled joint system with the fixed parameters decoupled and the priors added,
/// factorised.
pub(super) fn finish(
    jp: &JointProblem,
    aj: AssembledJoint,
    free: &[bool; NPARAM],
) -> Result<JointSystem> {
    let AssembledJoint { sys, mut a, params } = aj;
    a.cross.iter_mut().for_each(|m| decouple_columns(m, free));
    decouple(jp, &mut a, &params, free);
    Ok(JointSystem {
        factor: sys.factor()?,
        cross: a.cross,
        theta: a.theta,
        gradient: a.gradient,
        cost: a.cost,
    })
}

/// A block of `H_x theta` with the fixed parameters' columns zero: the trajectory does not
/// couple to a parameter that is held.
pub(super) fn decouple_columns(m: &mut CrossBlock, free: &[bool; NPARAM]) {
    for (c, _) in free.iter().enumerate().filter(|(_, f)| !**f) {
        m.column_mut(c).fill(0.0);
    }
}

/// The calibration's own blocks of `a` with the fixed parameters decoupled (their gradient
/// zero, their rows and columns of `H_theta theta` pinned) and the priors at `p` added. The
/// fixed columns of `H_x theta` are left to the caller.
fn decouple(jp: &JointProblem, a: &mut Assembled, p: &CalibrationParams, free: &[bool; NPARAM]) {
    for (c, _) in free.iter().enumerate().filter(|(_, f)| !**f) {
        a.gradient[c] = 0.0;
    }
    if jp.priors.any() {
        let t = jp.priors.terms(p);
        a.theta += t.information;
        a.cost += t.cost;
        for (c, f) in free.iter().enumerate() {
            if *f {
                a.gradient[c] += t.gradient[c];
            }
        }
    }
    pin_fixed(&mut a.theta, free);
}

/// The calibration's reduced normal equations of a factorised joint system: the Schur complement
/// `S = H_tt - H_tx H_xx^-1 H_xt` (symmetrised, fixed parameters pinned) and the reduced
/// gradient `b = g_t - H_tx H_xx^-1 g_x` (zero for fixed parameters).
pub(super) fn reduced(js: &JointSystem, free: &[bool; NPARAM]) -> (ParamMat, ParamVec) {
    reduced_from(
        &js.theta,
        &js.gradient,
        js.factor.quadratic_forms(&js.cross),
        free,
    )
}

/// [`reduced`] from the calibration's blocks and the quadratic forms `(H_tx H_xx^-1 H_xt,
/// H_tx H_xx^-1 g_x)`.
fn reduced_from(
    theta: &ParamMat,
    gradient: &ParamVec,
    (reduction, cross_g): (ParamMat, ParamVec),
    free: &[bool; NPARAM],
) -> (ParamMat, ParamVec) {
    let schur = theta - reduction;
    let mut schur = (schur + schur.transpose()) * 0.5;
    pin_fixed(&mut schur, free);
    let mut b = gradient - cross_g;
    for c in 0..NPARAM {
        if !free[c] {
            b[c] = 0.0;
        }
    }
    (schur, b)
}

/// `cov` with the variances of the fixed parameters set to zero (they were pinned, not estimated).
fn held_at_zero(mut cov: ParamMat, free: &[bool; NPARAM]) -> ParamMat {
    for k in 0..NPARAM {
        if !free[k] {
            cov[(k, k)] = 0.0;
        }
    }
    cov
}

/// Marginal covariance of the calibration parameters in the joint problem (trajectory and
/// calibration), at the current estimate: the inverse of the Schur complement
/// `H_tt - H_tx H_xx^-1 H_xt`. Also returns the total cost.
pub fn joint_covariance(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    free: &[bool; NPARAM],
) -> Result<(ParamMat, f64)> {
    joint_covariance_of(jp, assemble_joint(jp, traj.knots(), p)?, free)
}

/// [`joint_covariance`] of a system already assembled by [`assemble_joint`]. The Schur
/// complement is summed as the system is eliminated ([`streamed_quadratic_forms`]): the
/// factor is not stored, and the system's storage is kept unchanged for the next problem.
pub fn joint_covariance_of(
    jp: &JointProblem,
    mut aj: AssembledJoint,
    free: &[bool; NPARAM],
) -> Result<(ParamMat, f64)> {
    decouple(jp, &mut aj.a, &aj.params, free);
    let forms = streamed_quadratic_forms(&SystemBlocks::whole(&aj, free));
    let (schur, _) = reduced_from(&aj.a.theta, &aj.a.gradient, forms?, free);
    let cost = aj.a.cost;
    jp.keep_storage(JointStorage {
        system: Some(aj.sys),
        cross: aj.a.cross,
    });
    let cov = schur
        .try_inverse()
        .unwrap_or_else(|| ParamMat::from_diagonal_element(f64::INFINITY));
    Ok((held_at_zero(cov, free), cost))
}

/// The linearised estimate of the calibration at `p` and its marginal covariance from the
/// factorised joint system `js` (linearised at `p`), as [`estimate_from`] forms it: the
/// reference that [`part_linear_estimate`] is tested against.
#[cfg(test)]
pub(super) fn linear_estimate_of(
    jp: &JointProblem,
    js: JointSystem,
    p: &CalibrationParams,
    free: &[bool; NPARAM],
) -> Result<(CalibrationParams, ParamMat)> {
    let (schur, b) = reduced(&js, free);
    jp.keep_joint(js);
    Ok(estimate_from(p, &schur, &b, free))
}

/// The linearised estimate of the calibration at `p` and its marginal covariance, from the
/// reduced normal equations `(S, b)` of a joint system linearised at `p`: `p` moved by the
/// calibration part of a Gauss-Newton step (`dtheta = S^-1 b` with `S` the Schur complement and
/// `b` the reduced gradient), and `S^-1`. The trajectory's part of the step is not formed. For
/// a problem whose solution lies near `p` (a part of the data, starting from the whole's
/// estimate) this is its estimate to first order.
pub(super) fn estimate_from(
    p: &CalibrationParams,
    schur: &ParamMat,
    b: &ParamVec,
    free: &[bool; NPARAM],
) -> (CalibrationParams, ParamMat) {
    let Some(chol) = schur.cholesky() else {
        return (*p, ParamMat::from_diagonal_element(f64::INFINITY));
    };
    (
        p.updated(&chol.solve(b)),
        held_at_zero(chol.inverse(), free),
    )
}

/// The linearised estimate and covariance (see [`estimate_from`]) of the problem `part` at
/// the calibration the whole was assembled at (`part` holds a subset of the whole's samples, on the
/// knots `range` of the whole's trajectory; `knots` are their states), taken from the whole's
/// assembled system `whole` rather than assembled afresh. Knot by knot the part's normal
/// equations are the whole's wherever no sample of the whole outside the part lies in the
/// intervals next to the knot, and the knot is not at either end of the slice (where the whole
/// has prior terms across the cut); those knots are read from the whole's system, the others
/// assembled anew, and the calibration's own blocks formed from the part's samples alone. The
/// part's system is eliminated as it is read ([`streamed_quadratic_forms`]), so nothing of its
/// length is copied or stored. The result is the one the part's own assembly and factorisation
/// give, to the bit.
pub fn part_linear_estimate(
    whole_jp: &JointProblem,
    whole: &AssembledJoint,
    part: &JointProblem,
    knots: &[Knot],
    range: std::ops::Range<usize>,
    free: &[bool; NPARAM],
) -> Result<(CalibrationParams, ParamMat)> {
    let p = whole.params;
    let n = range.len();
    if n < 2 || range.end > whole.sys.len() || knots.len() != n || part.times.len() != n {
        return Err(Error::Numerical(format!(
            "part of {n} knots at {}..{} does not fit a system of {} knots",
            range.start,
            range.end,
            whole.sys.len()
        )));
    }
    // Knots whose blocks differ: both ends, and the knots of every interval holding a sample of
    // the whole that the part leaves out.
    let mut redo = vec![false; n];
    redo[0] = true;
    redo[n - 1] = true;
    let mut in_part = vec![false; whole_jp.obs.len()];
    for &i in part.idx {
        if let Some(f) = in_part.get_mut(i) {
            *f = true;
        }
    }
    let view = KnotView {
        times: &part.times,
        knots: &[],
    };
    for &i in whole_jp.idx.iter().filter(|&&i| !in_part[i]) {
        // The interval the sample would take in the part (none outside its span).
        if let Some(k) = view.interval(whole_jp.obs[i].t + p.time_offset_s) {
            redo[k] = true;
            redo[k + 1] = true;
        }
    }
    let factors = DvlFactors::new(part, &p)?;
    let mut own = SystemBlocks::part(whole, range.start, &redo, free);
    let mut k = 0;
    while k < n {
        if !redo[k] {
            k += 1;
            continue;
        }
        let start = k;
        while k < n && redo[k] {
            k += 1;
        }
        own.assemble(&factors, knots, start..k);
    }
    let (theta, gradient) = factors.theta_terms(knots);
    let mut a = Assembled {
        cost: 0.0,
        cross: Vec::new(),
        theta,
        gradient,
    };
    decouple(part, &mut a, &p, free);
    let forms = streamed_quadratic_forms(&own)?;
    let (schur, b) = reduced_from(&a.theta, &a.gradient, forms, free);
    Ok(estimate_from(&p, &schur, &b, free))
}

/// A joint system as the streamed elimination reads it ([`streamed_quadratic_forms`]): an
/// assembled system's blocks from `first` on, except at the knots assembled anew (for a part of
/// the data), whose blocks it holds in the order of the knots; the fixed parameters' columns of
/// `H_x theta` read as zero.
struct SystemBlocks<'w> {
    sys: &'w BlockTridiagonal,
    cross: &'w [CrossBlock],
    /// The first knot read, and the number of knots.
    first: usize,
    len: usize,
    /// Per knot, the position of its own blocks (`usize::MAX`: the assembled system's); empty
    /// when no knot has its own.
    slot: Vec<usize>,
    diag: Vec<M18>,
    /// `A[k, k + 1]` of the knot in the slot (none for the last knot).
    upper: Vec<M18>,
    rhs: Vec<V18>,
    own_cross: Vec<CrossBlock>,
    free: [bool; NPARAM],
}

impl<'w> SystemBlocks<'w> {
    /// The whole of an assembled system.
    fn whole(a: &'w AssembledJoint, free: &[bool; NPARAM]) -> Self {
        Self::with_slots(a, 0, a.sys.len(), Vec::new(), 0, free)
    }

    /// The knots of an assembled system from `first` on, one per flag of `redo`, with room for
    /// the knots flagged to be assembled anew.
    fn part(a: &'w AssembledJoint, first: usize, redo: &[bool], free: &[bool; NPARAM]) -> Self {
        let mut count = 0;
        let slot = redo
            .iter()
            .map(|&r| {
                if r {
                    count += 1;
                    count - 1
                } else {
                    usize::MAX
                }
            })
            .collect();
        Self::with_slots(a, first, redo.len(), slot, count, free)
    }

    fn with_slots(
        a: &'w AssembledJoint,
        first: usize,
        len: usize,
        slot: Vec<usize>,
        count: usize,
        free: &[bool; NPARAM],
    ) -> Self {
        SystemBlocks {
            sys: &a.sys,
            cross: &a.a.cross,
            first,
            len,
            slot,
            diag: vec![M18::zeros(); count],
            upper: vec![M18::zeros(); count],
            rhs: vec![V18::zeros(); count],
            own_cross: vec![CrossBlock::zeros(); count],
            free: *free,
        }
    }

    /// The position of knot `k`'s own blocks, if it has them.
    fn own(&self, k: usize) -> Option<usize> {
        self.slot.get(k).copied().filter(|&s| s != usize::MAX)
    }

    /// Assembles the knots `range` (all marked) into their slots.
    fn assemble(&mut self, factors: &DvlFactors, knots: &[Knot], range: std::ops::Range<usize>) {
        let n = self.len;
        let s = self.slot[range.start];
        let len = range.len();
        // Knot `k` owns the coupling to `k + 1`; the last knot has none.
        let uppers = range.end.min(n - 1) - range.start.min(n - 1);
        let chunk = JointChunk {
            sys: AssemblyChunk {
                first: range.start,
                diag: &mut self.diag[s..s + len],
                upper: &mut self.upper[s..s + uppers],
                rhs: &mut self.rhs[s..s + len],
                cost: 0.0,
            },
            cross: &mut self.own_cross[s..s + len],
            theta: ParamMat::zeros(),
            gradient: ParamVec::zeros(),
        };
        factors.assemble_run(knots, chunk);
    }
}

impl BlockSource<NPARAM> for SystemBlocks<'_> {
    fn len(&self) -> usize {
        self.len
    }

    fn diag(&self, k: usize) -> M18 {
        match self.own(k) {
            None => self.sys.diag[self.first + k],
            Some(s) => self.diag[s],
        }
    }

    fn upper(&self, k: usize) -> M18 {
        match self.own(k) {
            None => self.sys.upper[self.first + k],
            Some(s) => self.upper[s],
        }
    }

    fn rhs(&self, k: usize) -> V18 {
        match self.own(k) {
            None => self.sys.rhs[self.first + k],
            Some(s) => self.rhs[s],
        }
    }

    fn columns(&self, k: usize) -> CrossBlock {
        let mut c = match self.own(k) {
            None => self.cross[self.first + k],
            Some(s) => self.own_cross[s],
        };
        decouple_columns(&mut c, &self.free);
        c
    }
}
impl JointProblem<'_> {
    /// Keeps the system and the coupling blocks of a finished joint system.
    pub(super) fn keep_joint(&self, js: JointSystem) {
        self.keep_storage(JointStorage {
            system: Some(js.factor.into_system()),
            cross: js.cross,
        });
    }
}
