//! The joint problem over trajectory and calibration: state update (trajectory refitted with the
//! DVL velocities as factors, calibration fixed) and the marginal covariance of the calibration.
//!
//! A DVL sample at camera time `t_i + delta` lies between two knots; its predicted velocity
//! depends on both through the GP interpolation, so its factor adds to the two diagonal blocks
//! and the off-diagonal block between them: the normal equations stay block tridiagonal.

use std::sync::Mutex;

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector6};

use super::model::{NPARAM, d_predict_d_params, d_predict_d_twist, predict};
use super::offset::DvlObs;
use super::prior::Priors;
use super::refine::{ParamMat, ParamVec, pin_fixed};
use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::trajectory::blocktri::{
    BlockSource, BlockTridiagonal, M18, V18, streamed_quadratic_forms,
};
use crate::trajectory::gp::{LocalState, PriorNormal};
use crate::trajectory::solver::{
    ASSEMBLY_CHUNK, AssemblyChunk, GaussNewtonOptions, NormalEquations, Problem, STEP_DECREMENT,
    assembly_chunks, gauss_newton, measurement_information, step,
};
use crate::trajectory::{Knot, KnotView, Trajectory};
use crate::types::CalibrationParams;
use crate::types::PoseMeasurement;

/// What the joint problem needs besides the knot states, set up once per calibration: the pose
/// terms (with the weights and Qc of the trajectory's fit) and the DVL terms.
pub struct JointProblem<'a> {
    pub obs: &'a [DvlObs],
    /// DVL samples used.
    pub idx: &'a [usize],
    /// DVL information matrices, one per observation.
    pub dvl_info: Vec<Matrix3<f64>>,
    /// Priors on the calibration, factors of the joint problem beside the DVL's.
    pub priors: Priors,
    times: Vec<f64>,
    meas: Vec<Se3>,
    pose_info: Vec<Matrix6<f64>>,
    qc_inv: Vector6<f64>,
    /// Storage kept from one system to the next.
    storage: Mutex<JointStorage>,
}

/// What a joint problem keeps from one system to the next: the storage of the trajectory's
/// system (a system of 100k knots takes half a gigabyte, which is slow to allocate, and whose
/// pages are slow to fault in, every time) and of the calibration's coupling blocks `H_x theta`
/// (an eighth of a gigabyte more).
#[derive(Default)]
pub(crate) struct JointStorage {
    system: Option<BlockTridiagonal>,
    cross: Vec<CrossBlock>,
}

impl<'a> JointProblem<'a> {
    /// The joint problem of `traj` (fitted to `poses`) and the DVL samples `idx` of `obs`.
    pub fn new(
        poses: &[PoseMeasurement],
        traj: &Trajectory,
        obs: &'a [DvlObs],
        idx: &'a [usize],
    ) -> Result<Self> {
        let dvl_info = obs.iter().map(DvlObs::information).collect::<Result<_>>()?;
        Ok(JointProblem {
            obs,
            idx,
            dvl_info,
            priors: Priors::default(),
            times: traj.times().to_vec(),
            meas: poses.iter().map(|m| m.pose).collect(),
            pose_info: measurement_information(poses, traj.report().pose_sigma)?,
            qc_inv: traj.qc().map(|q| 1.0 / q),
            storage: Mutex::new(JointStorage::default()),
        })
    }

    /// The problem of the samples `idx` (a subset of this one's) on the knots `range` alone:
    /// this problem's pose terms, weights and DVL information restricted to them, without
    /// computing any of them again.
    pub fn part<'p>(&'p self, idx: &'p [usize], range: std::ops::Range<usize>) -> JointProblem<'p> {
        JointProblem {
            obs: self.obs,
            idx,
            dvl_info: self.dvl_info.clone(),
            priors: self.priors,
            times: self.times[range.clone()].to_vec(),
            meas: self.meas[range.clone()].to_vec(),
            pose_info: self.pose_info[range].to_vec(),
            qc_inv: self.qc_inv,
            storage: Mutex::new(JointStorage::default()),
        }
    }

    /// All the kept storage, to hand to another problem of the same knots.
    pub(crate) fn take_storage(&self) -> JointStorage {
        self.storage
            .lock()
            .map(|mut s| std::mem::take(&mut *s))
            .unwrap_or_default()
    }

    /// Keeps `storage` (from [`JointProblem::take_storage`]) for the next systems.
    pub(crate) fn keep_storage(&self, storage: JointStorage) {
        if let Ok(mut s) = self.storage.lock() {
            *s = storage;
        }
    }

    /// The kept system storage, if any.
    pub(crate) fn take_system(&self) -> Option<BlockTridiagonal> {
        self.storage.lock().ok().and_then(|mut s| s.system.take())
    }

    /// Keeps `sys` for the next update.
    pub(crate) fn keep_system(&self, sys: BlockTridiagonal) {
        if let Ok(mut s) = self.storage.lock() {
            s.system = Some(sys);
        }
    }

    /// The kept storage of `H_x theta` (empty when there is none).
    fn take_cross(&self) -> Vec<CrossBlock> {
        self.storage
            .lock()
            .map(|mut s| std::mem::take(&mut s.cross))
            .unwrap_or_default()
    }

    /// Keeps the system and the coupling blocks of a finished joint system.
    fn keep_joint(&self, js: JointSystem) {
        if let Ok(mut s) = self.storage.lock() {
            s.system = Some(js.factor.into_system());
            s.cross = js.cross;
        }
    }

    /// The pose and GP-prior terms (the trajectory fit's own problem).
    fn pose_problem(&self) -> Problem<'_> {
        Problem {
            times: &self.times,
            meas: &self.meas,
            info: &self.pose_info,
            qc_inv: self.qc_inv,
        }
    }

    fn view<'k>(&'k self, knots: &'k [Knot]) -> KnotView<'k> {
        KnotView {
            times: &self.times,
            knots,
        }
    }
}

/// The 18 x 8 block `H_x theta` of one knot: how the knot's variables and the calibration
/// parameters are coupled through the DVL factors.
type CrossBlock = SMatrix<f64, 18, NPARAM>;

/// The DVL factors at a fixed calibration: which samples lie in which interval between knots
/// (the clock offset fixes that), ready to be linearised at any knot states.
struct DvlFactors<'a> {
    jp: &'a JointProblem<'a>,
    params: CalibrationParams,
    /// Derivative of the prediction with respect to the twist.
    dh: SMatrix<f64, 3, 6>,
    /// Samples of interval `k`: `order[start[k]..start[k + 1]]` (positions in `jp.idx`, in
    /// their order there).
    start: Vec<usize>,
    order: Vec<usize>,
}

/// What the DVL factors of one interval add to the joint normal equations.
struct IntervalTerms {
    /// Blocks of the interval's first knot, the coupling block, and the second knot's blocks.
    d1: M18,
    upper: M18,
    d2: M18,
    r1: V18,
    r2: V18,
    /// `H_x theta` of the two knots, and the calibration's own blocks (with parameters only).
    c1: CrossBlock,
    c2: CrossBlock,
    theta: ParamMat,
    gradient: ParamVec,
    cost: f64,
}

impl IntervalTerms {
    fn zeros() -> IntervalTerms {
        IntervalTerms {
            d1: M18::zeros(),
            upper: M18::zeros(),
            d2: M18::zeros(),
            r1: V18::zeros(),
            r2: V18::zeros(),
            c1: CrossBlock::zeros(),
            c2: CrossBlock::zeros(),
            theta: ParamMat::zeros(),
            gradient: ParamVec::zeros(),
            cost: 0.0,
        }
    }

    /// Every sum the next interval forms back to zero, in place (the calibration's blocks
    /// only `with_params`, the only time they are formed and read).
    fn clear(&mut self, with_params: bool) {
        self.d1 = M18::zeros();
        self.upper = M18::zeros();
        self.d2 = M18::zeros();
        self.r1 = V18::zeros();
        self.r2 = V18::zeros();
        self.cost = 0.0;
        if with_params {
            self.c1 = CrossBlock::zeros();
            self.c2 = CrossBlock::zeros();
            self.theta = ParamMat::zeros();
            self.gradient = ParamVec::zeros();
        }
    }
}

/// The joint normal equations' parts beyond the trajectory's system.
struct Assembled {
    cost: f64,
    /// `H_x theta` per knot (empty without parameters).
    cross: Vec<CrossBlock>,
    /// `H_theta theta` and the calibration's right-hand side.
    theta: ParamMat,
    gradient: ParamVec,
}

/// One chunk of knots of the joint assembly.
struct JointChunk<'s> {
    sys: AssemblyChunk<'s>,
    cross: &'s mut [CrossBlock],
    theta: ParamMat,
    gradient: ParamVec,
}

/// `out += a^T b` on the lower triangle of `out` alone, for the symmetric `a^T W a` of a
/// factor with three rows (`b = W a`): half the products of the full sum. Each element is
/// summed as nalgebra's product sums it (the three rows in order, the first product alone),
/// so it equals `out += a.transpose() * b` there to the bit.
#[inline]
fn add_lower_atb(out: &mut M18, a: &SMatrix<f64, 3, 18>, b: &SMatrix<f64, 3, 18>) {
    for j in 0..18 {
        let bj = b.column(j);
        for i in j..18 {
            let ai = a.column(i);
            let s = ai[0] * bj[0] + ai[1] * bj[1] + ai[2] * bj[2];
            out[(i, j)] += s;
        }
    }
}

/// Copies the lower triangle of `m` onto its upper triangle.
fn mirror_lower(m: &mut M18) {
    for j in 0..18 {
        for i in j + 1..18 {
            m[(j, i)] = m[(i, j)];
        }
    }
}

impl<'a> DvlFactors<'a> {
    /// The DVL factors of `jp` at the calibration `params`; fails when a sample's camera time
    /// falls outside the trajectory.
    fn new(jp: &'a JointProblem<'a>, params: &CalibrationParams) -> Result<Self> {
        let view = KnotView {
            times: &jp.times,
            knots: &[],
        };
        let n = jp.times.len();
        let interval: Vec<usize> = jp
            .idx
            .iter()
            .map(|&i| view.locate(jp.obs[i].t + params.time_offset_s))
            .collect::<Result<_>>()?;
        // Counting sort by interval, stable in the order of `idx`.
        let mut start = vec![0usize; n + 1];
        for &k in &interval {
            start[k + 1] += 1;
        }
        for k in 0..n {
            start[k + 1] += start[k];
        }
        let mut fill = start.clone();
        let mut order = vec![0usize; interval.len()];
        for (pos, &k) in interval.iter().enumerate() {
            order[fill[k]] = pos;
            fill[k] += 1;
        }
        Ok(DvlFactors {
            jp,
            params: *params,
            dh: d_predict_d_twist(params),
            start,
            order,
        })
    }

    /// Positions (in `jp.idx`) of the samples in interval `k`.
    fn samples(&self, k: usize) -> &[usize] {
        &self.order[self.start[k]..self.start[k + 1]]
    }

    /// The DVL terms of interval `k`, linearised at the knots of `view`, with `ls` the local
    /// state of its second knot, written into `out` (a chunk's scratch, so that eleven
    /// kilobytes are not returned through a copy for every interval); `false`, with `out` left
    /// as it was, when no sample lies in the interval.
    fn interval_terms(
        &self,
        view: KnotView,
        k: usize,
        ls: &LocalState,
        with_params: bool,
        out: &mut IntervalTerms,
    ) -> bool {
        let samples = self.samples(k);
        if samples.is_empty() {
            return false;
        }
        let p = &self.params;
        out.clear(with_params);
        for &pos in samples {
            let i = self.jp.idx[pos];
            let (o, w) = (&self.jp.obs[i], &self.jp.dvl_info[i]);
            let (state, j1, j2) =
                view.projected_twist_jacobian_in(k, o.t + p.time_offset_s, ls, &self.dh);
            let r = o.v - predict(p, &state.twist);
            let (wj1, wj2) = (w * j1, w * j2);
            add_lower_atb(&mut out.d1, &j1, &wj1);
            add_lower_atb(&mut out.d2, &j2, &wj2);
            out.upper += j1.transpose() * wj2;
            out.r1 += wj1.transpose() * r;
            out.r2 += wj2.transpose() * r;
            out.cost += (r.transpose() * w * r)[0];
            if with_params {
                let jt = d_predict_d_params(p, &state.twist, &state.rate);
                let wjt = w * jt;
                out.c1 += j1.transpose() * wjt;
                out.c2 += j2.transpose() * wjt;
                out.theta += jt.transpose() * wjt;
                out.gradient += wjt.transpose() * r;
            }
        }
        mirror_lower(&mut out.d1);
        mirror_lower(&mut out.d2);
        true
    }

    /// The cost of the DVL factors of interval `k` at the knots of `view`, with `gamma2` the
    /// local state of its second knot (the same sum as [`DvlFactors::interval_terms`] forms).
    fn interval_cost(&self, view: KnotView, k: usize, gamma2: &V18) -> f64 {
        let p = &self.params;
        let mut cost = 0.0;
        for &pos in self.samples(k) {
            let i = self.jp.idx[pos];
            let (o, w) = (&self.jp.obs[i], &self.jp.dvl_info[i]);
            let twist = view.twist_in(k, o.t + p.time_offset_s, gamma2);
            let r = o.v - predict(p, &twist);
            cost += (r.transpose() * w * r)[0];
        }
        cost
    }

    /// The calibration's own blocks `H_theta theta` and right-hand side of the DVL factors at
    /// `knots`, without the trajectory's: the same sums, in the same order, as
    /// [`DvlFactors::assemble`] forms with parameters.
    fn theta_terms(&self, knots: &[Knot]) -> (ParamMat, ParamVec) {
        let p = &self.params;
        let view = self.jp.view(knots);
        let n = knots.len();
        let pieces = crate::parallel::map_pieces(n, ASSEMBLY_CHUNK, |r| {
            let (mut theta, mut gradient) = (ParamMat::zeros(), ParamVec::zeros());
            for k in r.filter(|&k| k + 1 < n && !self.samples(k).is_empty()) {
                let gamma2 = crate::trajectory::gp::local_gamma(&knots[k], &knots[k + 1]);
                let (mut t, mut g) = (ParamMat::zeros(), ParamVec::zeros());
                for &pos in self.samples(k) {
                    let i = self.jp.idx[pos];
                    let (o, w) = (&self.jp.obs[i], &self.jp.dvl_info[i]);
                    let state = view.motion_in(k, o.t + p.time_offset_s, &gamma2);
                    let r = o.v - predict(p, &state.twist);
                    let jt = d_predict_d_params(p, &state.twist, &state.rate);
                    let wjt = w * jt;
                    t += jt.transpose() * wjt;
                    g += wjt.transpose() * r;
                }
                theta += t;
                gradient += g;
            }
            (theta, gradient)
        });
        let (mut theta, mut gradient) = (ParamMat::zeros(), ParamVec::zeros());
        for (t, g) in pieces {
            theta += t;
            gradient += g;
        }
        (theta, gradient)
    }

    /// Assembles the knots of `chunk` alone (as [`DvlFactors::assemble`] forms them).
    fn assemble_run(&self, knots: &[Knot], mut chunk: JointChunk) {
        self.assemble_chunk(self.jp.view(knots), &mut chunk, true);
    }

    /// The joint normal equations at `knots`: the trajectory's system (poses, prior and DVL
    /// factors) into `sys` and, `with_params`, the calibration's blocks. Chunks of knots are
    /// assembled on all cores; for every knot the terms are added in a fixed order and the
    /// chunks' sums are combined in order, so the result does not depend on the thread count.
    fn assemble(&self, knots: &[Knot], sys: &mut BlockTridiagonal, with_params: bool) -> Assembled {
        let n = knots.len();
        assert_eq!(sys.len(), n, "system size does not match the knots");
        // Each chunk clears its own blocks of `H_x theta` before it adds to them.
        let mut cross = if with_params {
            let mut c = self.jp.take_cross();
            c.resize(n, CrossBlock::zeros());
            c
        } else {
            Vec::new()
        };
        let mut cross_chunks = cross.chunks_mut(ASSEMBLY_CHUNK);
        let mut chunks: Vec<JointChunk> = assembly_chunks(sys)
            .into_iter()
            .map(|c| JointChunk {
                sys: c,
                cross: cross_chunks.next().unwrap_or_default(),
                theta: ParamMat::zeros(),
                gradient: ParamVec::zeros(),
            })
            .collect();
        let view = self.jp.view(knots);
        crate::parallel::for_each(&mut chunks, |c| self.assemble_chunk(view, c, with_params));
        let mut out = Assembled {
            cost: 0.0,
            cross: Vec::new(),
            theta: ParamMat::zeros(),
            gradient: ParamVec::zeros(),
        };
        for c in &chunks {
            out.cost += c.sys.cost;
            out.theta += c.theta;
            out.gradient += c.gradient;
        }
        drop(chunks);
        out.cross = cross;
        out
    }

    /// One chunk of [`DvlFactors::assemble`]. Per knot: its pose term, the prior and DVL terms
    /// of the interval before it, then those of the interval after it. Each interval's terms
    /// are added to both of its knots as soon as they are formed (the next knot's pose term is
    /// written first). The interval before the chunk is recomputed here for its second knot's
    /// part; its cost and calibration terms belong to the previous chunk.
    fn assemble_chunk(&self, view: KnotView, chunk: &mut JointChunk, with_params: bool) {
        let pose = self.jp.pose_problem();
        let knots = view.knots;
        let n = knots.len();
        let c = &mut chunk.sys;
        let len = c.diag.len();
        let (first, diag, rhs, upper) = (c.first, &mut *c.diag, &mut *c.rhs, &mut *c.upper);
        // The blocks of `H_x theta` are sums from zero (their storage is reused).
        chunk.cross.fill(CrossBlock::zeros());
        let mut pose_cost = pose.pose_terms(knots, first, &mut diag[0], &mut rhs[0]);
        let mut d = IntervalTerms::zeros();
        let mut t = PriorNormal::zeros();
        if first > 0 {
            // The off-diagonal block of this interval is the previous chunk's.
            let ls = pose.prior_terms(knots, first - 1, &mut t, &mut M18::zeros());
            diag[0] += t.d2;
            rhs[0] += t.r2;
            if self.interval_terms(view, first - 1, &ls, with_params, &mut d) {
                diag[0] += d.d2;
                rhs[0] += d.r2;
                if with_params {
                    chunk.cross[0] += d.c2;
                }
            }
        }
        let mut cost = 0.0;
        for i in 0..len {
            let k = first + i;
            cost += pose_cost;
            let next = i + 1 < len;
            if next {
                pose_cost = pose.pose_terms(knots, k + 1, &mut diag[i + 1], &mut rhs[i + 1]);
            }
            if k + 1 < n {
                let ls = pose.prior_terms(knots, k, &mut t, &mut upper[i]);
                diag[i] += t.d1;
                rhs[i] += t.r1;
                cost += t.cost;
                if next {
                    diag[i + 1] += t.d2;
                    rhs[i + 1] += t.r2;
                }
                if self.interval_terms(view, k, &ls, with_params, &mut d) {
                    diag[i] += d.d1;
                    rhs[i] += d.r1;
                    upper[i] += d.upper;
                    cost += d.cost;
                    if next {
                        diag[i + 1] += d.d2;
                        rhs[i + 1] += d.r2;
                    }
                    if with_params {
                        chunk.cross[i] += d.c1;
                        if next {
                            chunk.cross[i + 1] += d.c2;
                        }
                        chunk.theta += d.theta;
                        chunk.gradient += d.gradient;
                    }
                }
            }
        }
        c.cost = cost;
    }

    /// The joint cost at `knots` alone (the same terms in the same order as
    /// [`DvlFactors::assemble`], so the two agree to the last bit).
    fn cost(&self, knots: &[Knot]) -> f64 {
        let pose = self.jp.pose_problem();
        let view = self.jp.view(knots);
        let n = knots.len();
        crate::parallel::map_pieces(n, ASSEMBLY_CHUNK, |r| {
            let mut cost = 0.0;
            for k in r {
                cost += pose.pose_cost(knots, k);
                if k + 1 < n {
                    let (c, gamma2) = pose.prior_cost(knots, k);
                    cost += c;
                    if !self.samples(k).is_empty() {
                        cost += self.interval_cost(view, k, &gamma2);
                    }
                }
            }
            cost
        })
        .into_iter()
        .sum()
    }
}

impl NormalEquations for DvlFactors<'_> {
    fn normal_equations(&self, knots: &[Knot], sys: &mut BlockTridiagonal) -> Result<f64> {
        Ok(self.assemble(knots, sys, false).cost)
    }

    fn cost(&self, knots: &[Knot]) -> Result<f64> {
        Ok(DvlFactors::cost(self, knots))
    }
}

/// State update: the trajectory refitted with the DVL factors at fixed calibration `p`.
/// Returns the new trajectory (without posterior covariance: the refinement only interpolates
/// it, and the calibration's covariance comes from [`joint_covariance`]) and the total cost.
pub fn state_update(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    max_iterations: usize,
) -> Result<(Trajectory, f64)> {
    let problem = DvlFactors::new(jp, p)?;
    let opts = GaussNewtonOptions {
        max_iterations,
        stop_decrement: STEP_DECREMENT,
        factor: false,
        storage: jp.take_system(),
    };
    let solved = gauss_newton(&problem, traj.knots().to_vec(), opts)?;
    if let Some(s) = solved.spare {
        jp.keep_system(s);
    }
    let prior_cost = if jp.priors.any() {
        jp.priors.terms(p).cost
    } else {
        0.0
    };
    Ok((
        traj.with_knots(solved.knots, None),
        solved.cost + prior_cost,
    ))
}

/// The joint cost at the trajectory `traj` and the calibration `p`: pose, GP prior, DVL and
/// calibration prior terms (what [`state_update`] returns for its own result).
pub fn joint_cost(jp: &JointProblem, traj: &Trajectory, p: &CalibrationParams) -> Result<f64> {
    let prior_cost = if jp.priors.any() {
        jp.priors.terms(p).cost
    } else {
        0.0
    };
    Ok(DvlFactors::new(jp, p)?.cost(traj.knots()) + prior_cost)
}

/// The joint system at `(traj, p)` with the fixed parameters decoupled, factorised: the
/// factor of `H_xx`, `H_x theta` per knot, `H_theta theta` and the calibration's right-hand side.
struct JointSystem {
    factor: crate::trajectory::blocktri::Factored,
    cross: Vec<CrossBlock>,
    theta: ParamMat,
    gradient: ParamVec,
    cost: f64,
}

/// The joint system at `(traj, p)` as assembled, before the fixed parameters are decoupled
/// and before the factorisation: what the covariance and the halves check share.
pub struct AssembledJoint {
    sys: BlockTridiagonal,
    a: Assembled,
    /// The calibration the system was linearised at.
    params: CalibrationParams,
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

fn joint_system(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    free: &[bool; NPARAM],
) -> Result<JointSystem> {
    finish(jp, assemble_joint(jp, traj.knots(), p)?, free)
}

/// An assembled joint system with the fixed parameters decoupled and the priors added,
/// factorised.
fn finish(jp: &JointProblem, aj: AssembledJoint, free: &[bool; NPARAM]) -> Result<JointSystem> {
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
fn decouple_columns(m: &mut CrossBlock, free: &[bool; NPARAM]) {
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
fn reduced(js: &JointSystem, free: &[bool; NPARAM]) -> (ParamMat, ParamVec) {
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
fn linear_estimate_of(
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
fn estimate_from(
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

/// Outcome of a joint step.
pub struct JointStep {
    pub trajectory: Trajectory,
    pub params: CalibrationParams,
}

/// One Gauss-Newton step on the joint problem (trajectory and free calibration parameters
/// together, the calibration eliminated by its Schur complement), with step halving. `None`
/// when no step along the Gauss-Newton direction lowers the joint cost.
///
/// Block-coordinate descent converges linearly when the trajectory and the calibration (above
/// all the clock offset) are coupled; a joint step moves both towards their common fixed
/// point at once.
pub fn joint_step(
    jp: &JointProblem,
    traj: &Trajectory,
    p: &CalibrationParams,
    free: &[bool; NPARAM],
) -> Result<Option<JointStep>> {
    let js = joint_system(jp, traj, p, free)?;
    // Calibration step from the Schur complement, then the trajectory's step for it:
    // `H_xx dx = g_x - H_x theta dtheta`.
    let (schur, b) = reduced(&js, free);
    let Some(dtheta) = schur.cholesky().map(|c| c.solve(&b)) else {
        jp.keep_joint(js);
        return Ok(None);
    };
    let u = js.factor.solve();
    let correction = js
        .factor
        .solve_many(&js.cross.iter().map(|c| c * dtheta).collect::<Vec<V18>>());
    let start_cost = js.cost;
    jp.keep_joint(js);
    let dx: Vec<V18> = u.iter().zip(&correction).map(|(u, c)| u - c).collect();
    let mut scale = 1.0;
    for _ in 0..8 {
        let params = p.updated(&(dtheta * scale));
        // A step that moves a sample outside the trajectory is too long.
        if let Ok(f) = DvlFactors::new(jp, &params) {
            let knots = step(traj.knots(), &dx, scale);
            let mut cost = f.cost(&knots);
            if jp.priors.any() {
                cost += jp.priors.terms(&params).cost;
            }
            if cost.is_finite() && cost <= start_cost {
                return Ok(Some(JointStep {
                    trajectory: traj.with_knots(knots, None),
                    params,
                }));
            }
        }
        scale *= 0.5;
    }
    Ok(None)
}
#[cfg(test)]
#[path = "state_jacobian_tests.rs"]
mod jacobian_tests;

/// Laplace approximation of the log marginal likelihood of the poses and the DVL reports (up to
/// a constant that does not depend on `qc_factor`) when the jerk density is `qc_factor` times the
/// trajectory's: the trajectory is refitted with the DVL factors at the calibration `p`, and
/// `-1/2 [cost + log det H + (N - 1) * 18 log qc_factor]` is evaluated there (`H` the joint
/// information of trajectory and free parameters, `N` the knots; the `Q_k` of the prior scale
/// with `Qc`, and `log det (Q(dt) (x) Qc)` has `3 log` of each of Qc's six values).
pub fn joint_log_evidence(
    poses: &[PoseMeasurement],
    traj: &Trajectory,
    obs: &[DvlObs],
    idx: &[usize],
    p: &CalibrationParams,
    free: &[bool; NPARAM],
    qc_factor: f64,
) -> Result<f64> {
    let mut jp = JointProblem::new(poses, traj, obs, idx)?;
    jp.qc_inv /= qc_factor;
    let (fitted, _) = state_update(&jp, traj, p, 20)?;
    let js = joint_system(&jp, &fitted, p, free)?;
    let (schur, _) = reduced(&js, free);
    let log_det_theta = schur.cholesky().map_or(f64::INFINITY, |c| {
        2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>()
    });
    let n = fitted.knots().len() as f64;
    Ok(-0.5 * (js.cost + js.factor.log_det() + log_det_theta + (n - 1.0) * 18.0 * qc_factor.ln()))
}
