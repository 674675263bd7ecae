//! The DVL factors of the joint problem and the assembly of its normal equations.
//!
//! A DVL sample at camera time `t_i + delta` lies between two knots; its predicted velocity
//! depends on both through the GP interpolation, so its factor adds to the two diagonal blocks
//! and the off-diagonal block between them: the normal equations stay block tridiagonal. Per
//! knot the terms are added in a fixed order: the co-sensor's factor on the knot, then for each
//! adjacent interval the GP prior, the co-sensor's factors between the knots (none for camera
//! poses) and the DVL factors.

use nalgebra::SMatrix;

use super::problem::{CrossBlock, JointProblem};
use crate::calib::model::{d_predict_d_params, d_predict_d_twist, predict};
use crate::calib::update::{ParamMat, ParamVec};
use crate::error::Result;
use crate::trajectory::blocktri::{BlockTridiagonal, M18, V18};
use crate::trajectory::factors::IntervalNormal;
use crate::trajectory::gp::{LocalState, PriorNormal};
use crate::trajectory::solver::{ASSEMBLY_CHUNK, AssemblyChunk, NormalEquations, assembly_chunks};
use crate::trajectory::{Knot, KnotView};
use crate::types::CalibrationParams;

/// The DVL factors at a fixed calibration: which samples lie in which interval between knots
/// (the clock offset fixes that), ready to be linearised at any knot states.
pub(super) struct DvlFactors<'a> {
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
pub(super) struct Assembled {
    pub(super) cost: f64,
    /// `H_x theta` per knot (empty without parameters).
    pub(super) cross: Vec<CrossBlock>,
    /// `H_theta theta` and the calibration's right-hand side.
    pub(super) theta: ParamMat,
    pub(super) gradient: ParamVec,
}

/// The clock drift's terms of the joint normal equations ([`DvlFactors::drift_terms`]).
pub(super) struct DriftTerms {
    /// `H_x d`, one column per knot.
    pub(super) cross: Vec<V18>,
    /// `H_theta d`.
    pub(super) theta: ParamVec,
    /// `H_dd`.
    pub(super) information: f64,
    /// The drift's right-hand side `J_d^T W r`.
    pub(super) gradient: f64,
}

/// One chunk of knots of the joint assembly.
pub(super) struct JointChunk<'s> {
    pub(super) sys: AssemblyChunk<'s>,
    pub(super) cross: &'s mut [CrossBlock],
    pub(super) theta: ParamMat,
    pub(super) gradient: ParamVec,
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
    pub(super) fn new(jp: &'a JointProblem<'a>, params: &CalibrationParams) -> Result<Self> {
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
    pub(super) fn theta_terms(&self, knots: &[Knot]) -> (ParamMat, ParamVec) {
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

    /// The drift's column of the joint normal equations at `knots`: with `scale(t)` the derivative
    /// of a sample's camera time with respect to the clock drift (its DVL time from the drift's
    /// reference, in the drift's unit), the drift's Jacobian of a sample is the clock offset's
    /// times `scale(t)`. Returns `H_x d` per knot, `H_theta d`, `H_dd` and the drift's
    /// right-hand side, summed in the order of the knots.
    pub(super) fn drift_terms(&self, knots: &[Knot], scale: impl Fn(f64) -> f64) -> DriftTerms {
        let p = &self.params;
        let view = self.jp.view(knots);
        let n = knots.len();
        let mut out = DriftTerms {
            cross: vec![V18::zeros(); n],
            theta: ParamVec::zeros(),
            information: 0.0,
            gradient: 0.0,
        };
        for k in (0..n.saturating_sub(1)).filter(|&k| !self.samples(k).is_empty()) {
            let ls = crate::trajectory::gp::local_state(&knots[k], &knots[k + 1]);
            for &pos in self.samples(k) {
                let i = self.jp.idx[pos];
                let (o, w) = (&self.jp.obs[i], &self.jp.dvl_info[i]);
                let t = o.t + p.time_offset_s;
                let (state, j1, j2) = view.projected_twist_jacobian_in(k, t, &ls, &self.dh);
                let r = o.v - predict(p, &state.twist);
                let jt = d_predict_d_params(p, &state.twist, &state.rate);
                let wjd = w * (jt.column(7) * scale(o.t));
                out.cross[k] += j1.transpose() * wjd;
                out.cross[k + 1] += j2.transpose() * wjd;
                out.theta += jt.transpose() * wjd;
                out.information += (jt.column(7) * scale(o.t)).dot(&wjd);
                out.gradient += wjd.dot(&r);
            }
        }
        out
    }

    /// Assembles the knots of `chunk` alone (as [`DvlFactors::assemble`] forms them).
    pub(super) fn assemble_run(&self, knots: &[Knot], mut chunk: JointChunk) {
        self.assemble_chunk(self.jp.view(knots), &mut chunk, true);
    }

    /// The joint normal equations at `knots`: the trajectory's system (poses, prior and DVL
    /// factors) into `sys` and, `with_params`, the calibration's blocks. Chunks of knots are
    /// assembled on all cores; for every knot the terms are added in a fixed order and the
    /// chunks' sums are combined in order, so the result does not depend on the thread count.
    pub(super) fn assemble(
        &self,
        knots: &[Knot],
        sys: &mut BlockTridiagonal,
        with_params: bool,
    ) -> Assembled {
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

    /// One chunk of [`DvlFactors::assemble`]. Per knot: its co-sensor term, the terms of the
    /// interval before it (prior, co-sensor, DVL), then those of the interval after it. Each
    /// interval's terms are added to both of its knots as soon as they are formed (the next
    /// knot's own term is written first). The interval before the chunk is recomputed here for
    /// its second knot's part; its cost and calibration terms belong to the previous chunk.
    fn assemble_chunk(&self, view: KnotView, chunk: &mut JointChunk, with_params: bool) {
        let traj = self.jp.trajectory_problem();
        let knots = view.knots;
        let n = knots.len();
        let c = &mut chunk.sys;
        let len = c.diag.len();
        let (first, diag, rhs, upper) = (c.first, &mut *c.diag, &mut *c.rhs, &mut *c.upper);
        // The blocks of `H_x theta` are sums from zero (their storage is reused).
        chunk.cross.fill(CrossBlock::zeros());
        let mut knot_cost = traj.knot_terms(knots, first, &mut diag[0], &mut rhs[0]);
        let mut d = IntervalTerms::zeros();
        let mut t = PriorNormal::zeros();
        let mut s = IntervalNormal::zeros();
        if first > 0 {
            // The off-diagonal block of this interval is the previous chunk's.
            let ls = traj.prior_terms(knots, first - 1, &mut t, &mut M18::zeros());
            diag[0] += t.d2;
            rhs[0] += t.r2;
            if traj.cosensor_interval(knots, first - 1, &ls, &mut s) {
                diag[0] += s.d2;
                rhs[0] += s.r2;
            }
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
            cost += knot_cost;
            let next = i + 1 < len;
            if next {
                knot_cost = traj.knot_terms(knots, k + 1, &mut diag[i + 1], &mut rhs[i + 1]);
            }
            if k + 1 < n {
                let ls = traj.prior_terms(knots, k, &mut t, &mut upper[i]);
                diag[i] += t.d1;
                rhs[i] += t.r1;
                cost += t.cost;
                if next {
                    diag[i + 1] += t.d2;
                    rhs[i + 1] += t.r2;
                }
                if traj.cosensor_interval(knots, k, &ls, &mut s) {
                    diag[i] += s.d1;
                    rhs[i] += s.r1;
                    upper[i] += s.upper;
                    cost += s.cost;
                    if next {
                        diag[i + 1] += s.d2;
                        rhs[i + 1] += s.r2;
                    }
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
    pub(super) fn cost(&self, knots: &[Knot]) -> f64 {
        let traj = self.jp.trajectory_problem();
        let view = self.jp.view(knots);
        let n = knots.len();
        let between = self.jp.cosensor.has_interval_terms();
        crate::parallel::map_pieces(n, ASSEMBLY_CHUNK, |r| {
            let mut cost = 0.0;
            for k in r {
                cost += traj.knot_cost(knots, k);
                if k + 1 < n {
                    let (c, gamma2) = traj.prior_cost(knots, k);
                    cost += c;
                    if between {
                        cost += self.jp.cosensor.interval_cost(view, k, &gamma2);
                    }
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

#[cfg(test)]
#[path = "jacobian_tests.rs"]
mod jacobian_tests;
