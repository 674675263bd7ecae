//! The joint problem of the trajectory and the IMU's calibration: camera poses on some knots,
//! the motion prior between knots, the IMU's bins (or preintegrated windows) between them, and
//! the biases' random walks from knot to knot; Gauss-Newton on knots and calibration together,
//! the calibration eliminated through its Schur complement. Each knot carries its biases beside
//! its trajectory state (a block of [`KB`] = 24), so the knots' system stays block tridiagonal
//! however fast the biases walk, and the calibration is the 9 fixed parameters (17 with a DVL).
//!
//! The same problem serves the DVL + IMU mode: no camera (a prior on the first knot fixes the
//! gauge), the IMU's own frame and clock as the trajectory's (those columns held), and the
//! DVL's velocities as a third kind of factor with the DVL's parameters at the end of `theta`.

use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, SVector, Vector6};
use rayon::prelude::*;

use super::bins::ImuBin;
use super::block::{KB, MK, VK, bias_part, trajectory_part, widen};
use super::coupling::{Coupling, schur_forms};
use super::factors::{SparsePoseFactors, bin_residual, bin_terms};
use super::preint::{WindowTerms, Windows, residual as window_residual, window_terms};
use super::state::{ImuState, NFIXED};
use crate::calib::model::{DvlObs, NPARAM};
use crate::error::{Error, Result};
use crate::trajectory::JerkDensity;
use crate::trajectory::blocktri::{BandedInverse, BlockTridiagonal, Factored, V18};
use crate::trajectory::gp::{Knot, LocalState, local_gamma, local_state};
use crate::trajectory::solver::{Problem, step};
use crate::types::imu::ImuNoise;

/// The problem: knot times, the poses on them, the motion prior, the IMU's bins and noise.
pub struct ImuJoint<'a> {
    pub times: Vec<f64>,
    pub poses: SparsePoseFactors,
    pub density: JerkDensity,
    pub bins: &'a [ImuBin],
    pub info: Vec<Vector6<f64>>,
    pub noise: ImuNoise,
    /// Columns of `theta` held at their value (zero step, no information of their own).
    pub held: Vec<usize>,
    /// DVL velocities (with a DVL in the state), and their information.
    pub dvl: &'a [DvlObs],
    pub dvl_info: Vec<Matrix3<f64>>,
    /// The IMU preintegrated between consecutive knots: when given, its windows replace the
    /// bins as the IMU's factors (the bins then only count what the windows cover).
    pub windows: Option<Windows>,
}

/// Each sensor's chi-square and its share of the redundancy at a solution (see
/// [`ImuJoint::redundancy`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Redundancy {
    /// The gyro's chi-square and redundancy.
    pub gyro: (f64, f64),
    /// The accelerometer's.
    pub accel: (f64, f64),
    /// The DVL's (zero without one).
    pub dvl: (f64, f64),
}

impl Redundancy {
    /// The factor a sensor's std are off by: `sqrt(chi2 / redundancy)`.
    pub fn factor(part: (f64, f64)) -> f64 {
        (part.0 / part.1.max(1.0)).sqrt()
    }
}

/// The calibration's part of the normal equations at one linearisation point.
struct Linear {
    cost: f64,
    /// `H_x theta`, per knot on the columns its factors touch.
    cross: Coupling,
    hth: DMatrix<f64>,
    /// `-J_theta^T W e`.
    gth: DVector<f64>,
}

/// Gauss-Newton stops when the step's predicted decrease of the cost is below this: no linear
/// function of the variables would move by more than a tenth of its standard deviation.
const STOP_DECREMENT: f64 = 1e-2;

/// Gauss-Newton also stops when the calibration's step is below [`STOP_DECREMENT`] in its own
/// metric (no linear function of `theta` would move by more than a tenth of its marginal
/// standard deviation) and the whole step's decrement is below this fraction of the cost: what
/// the knots have left to move changes the chi-square the noise factors are estimated from by
/// less than a millionth. On long recordings the knots' hundreds of thousands of variables keep
/// the whole decrement above the absolute bound for an iteration or two after the calibration
/// has settled.
const STOP_RELATIVE: f64 = 1e-6;

/// A step is only taken as the last one (without linearising after it) when the calibration's
/// share of its decrement is below this: it moves no linear function of `theta` by more than
/// its marginal std. Further away the ratio of two decrements says nothing of the next: from
/// the first estimate at 1 h, a step of 18 after one of 1e5 was followed by one of 0.25.
const LAST_STEP_BELOW: f64 = 1.0;

/// The calibration's Schur complement `S` (symmetrised), the reduced right-hand side `s` and
/// the knots' `A^-1 r`, from the linearisation `lin` and the knots' factor.
fn schur_of(lin: &Linear, factor: &Factored<KB>) -> (DMatrix<f64>, DVector<f64>, Vec<VK>) {
    let (hah, har, xr) = schur_forms(factor, &lin.cross);
    let schur = &lin.hth - hah;
    let schur = (&schur + schur.transpose()) * 0.5;
    (schur, &lin.gth - har, xr)
}

/// One Gauss-Newton step.
struct Step {
    dx: Vec<VK>,
    dth: DVector<f64>,
    schur: DMatrix<f64>,
    decrement: f64,
    /// The calibration's share of `decrement`: `dth^T S dth`.
    theta_decrement: f64,
    factor: Factored<KB>,
}

/// The linearisation at a solution, the knots' factor and the calibration's Schur complement
/// there, kept for [`ImuJoint::redundancy_of`].
struct Last {
    lin: Linear,
    factor: Factored<KB>,
    schur: DMatrix<f64>,
    /// Whether `lin` was taken at the point before the solution's last step (a fraction of a
    /// standard deviation away) rather than at the solution (read by the tests).
    #[cfg_attr(not(test), allow(dead_code))]
    behind: bool,
}

/// The columns of `theta` the redundancy's solves take at once: one pass covers the camera
/// modes' 9 and, with a DVL, its 17.
const CHUNK: usize = 17;

/// The error of a calibration whose information is singular.
fn singular() -> Error {
    Error::Numerical("the IMU calibration's information is singular".into())
}

/// `J Sigma J^T` of a residual block with Jacobians `j1`, `j2` on knots `k`, `k + 1`, for the
/// knots' covariance blocks `band` (the trajectory's own, the calibration held).
fn local_projection<const M: usize>(
    band: &BandedInverse<KB>,
    k: usize,
    j1: &SMatrix<f64, M, KB>,
    j2: &SMatrix<f64, M, KB>,
) -> SMatrix<f64, M, M> {
    let (d1, d2, u): (&MK, &MK, &MK) = (&band.diag[k], &band.diag[k + 1], &band.upper[k]);
    let a = j1 * u * j2.transpose();
    j1 * d1 * j1.transpose() + a + a.transpose() + j2 * d2 * j2.transpose()
}

/// `S^-1 s`, or an error saying the calibration is not determined.
fn solve_schur(schur: &DMatrix<f64>, s: &DVector<f64>) -> Result<DVector<f64>> {
    let chol = schur.clone().cholesky().ok_or_else(|| {
        Error::Numerical(
            "the IMU's calibration is not determined by this motion (its information matrix \
             is singular): rotate the rig about more than one axis"
                .into(),
        )
    })?;
    Ok(chol.solve(s))
}

/// The solution.
pub struct Solution {
    pub knots: Vec<Knot>,
    pub state: ImuState,
    /// Covariance of `theta` (the knots marginalised).
    pub covariance: DMatrix<f64>,
    pub iterations: usize,
    pub converged: bool,
    pub cost: f64,
    /// Bins inside the trajectory's span at the solution (with windows: inside one).
    pub bins_used: usize,
    /// The last linearisation (at `knots` and `state`, or at the point a last small step
    /// before them) and its factor.
    last: Option<Box<Last>>,
}

impl Solution {
    /// Whether the kept linearisation was taken a step before the solution.
    #[cfg(test)]
    pub(crate) fn kept_behind(&self) -> Option<bool> {
        self.last.as_ref().map(|l| l.behind)
    }
}

/// Bins whose terms are computed at once (in parallel) before they are summed in order.
const BLOCK: usize = 256;
/// Bins one task computes in turn, sharing their intervals' local states.
const TASK: usize = 32;

/// A bin's or window's share of the normal equations, computed apart from the sums it goes
/// into: on knots `k` and `k + 1` (their trajectory states and biases) and on the fixed
/// parameters.
#[derive(Clone, Default)]
struct BinNormal {
    k: usize,
    cost: f64,
    d1: MK,
    d2: MK,
    up: MK,
    r1: VK,
    r2: VK,
    c1: SMatrix<f64, KB, NFIXED>,
    c2: SMatrix<f64, KB, NFIXED>,
    hl: SMatrix<f64, NFIXED, NFIXED>,
    gl: SMatrix<f64, NFIXED, 1>,
}

/// Knots per run of [`ImuJoint::linearise_windows`].
const RUN: usize = 256;

/// A run's cost, what its last window adds to the next run's first knot (the knot's diagonal
/// block, right-hand side and coupling), and its sums on the fixed parameters.
struct RunTail {
    cost: f64,
    next: Option<(MK, VK, SMatrix<f64, KB, NFIXED>)>,
    hl: SMatrix<f64, NFIXED, NFIXED>,
    gl: SMatrix<f64, NFIXED, 1>,
}

/// Adds a block on the fixed parameters to the calibration's normal equations.
fn add_theta(
    hth: &mut DMatrix<f64>,
    gth: &mut DVector<f64>,
    (hl, gl): (&SMatrix<f64, NFIXED, NFIXED>, &SMatrix<f64, NFIXED, 1>),
) {
    let mut h = hth.fixed_view_mut::<NFIXED, NFIXED>(0, 0);
    h += hl;
    let mut g = gth.fixed_rows_mut::<NFIXED>(0);
    g -= gl;
}

impl BinNormal {
    /// The share of a whitened residual `e` with Jacobians `j1`, `j2` on knots `k`, `k + 1`
    /// and `jth` on the fixed parameters.
    fn of<const M: usize>(
        k: usize,
        e: &SVector<f64, M>,
        j1: &SMatrix<f64, M, KB>,
        j2: &SMatrix<f64, M, KB>,
        jth: &SMatrix<f64, M, NFIXED>,
    ) -> BinNormal {
        BinNormal {
            k,
            cost: e.norm_squared(),
            d1: j1.tr_mul(j1),
            d2: j2.tr_mul(j2),
            up: j1.tr_mul(j2),
            r1: j1.tr_mul(e),
            r2: j2.tr_mul(e),
            c1: j1.tr_mul(jth),
            c2: j2.tr_mul(jth),
            hl: jth.tr_mul(jth),
            gl: jth.tr_mul(e),
        }
    }

    /// Adds the blocks into the knots' system `sys`, the coupling `cross` and the calibration's
    /// `hth` and `gth`; returns the cost.
    fn add_into(
        &self,
        sys: &mut BlockTridiagonal<KB>,
        cross: &mut Coupling,
        (hth, gth): (&mut DMatrix<f64>, &mut DVector<f64>),
    ) -> f64 {
        let k = self.k;
        sys.diag[k] += self.d1;
        sys.diag[k + 1] += self.d2;
        sys.upper[k] += self.up;
        sys.rhs[k] -= self.r1;
        sys.rhs[k + 1] -= self.r2;
        cross.add_bin(k, &self.c1);
        cross.add_bin(k + 1, &self.c2);
        add_theta(hth, gth, (&self.hl, &self.gl));
        self.cost
    }
}

/// A window's Jacobians on its two knots' blocks: each knot's biases carry half of the
/// window's (whose biases are the two knots' mean).
fn window_jacobians(t: &WindowTerms) -> (SMatrix<f64, 9, KB>, SMatrix<f64, 9, KB>) {
    let half = t.jb * 0.5;
    (widen(&t.j1, &half), widen(&t.j2, &half))
}

/// A window's share of the normal equations (its terms already whitened).
fn window_normal(k: usize, t: &WindowTerms) -> BinNormal {
    let (j1, j2) = window_jacobians(t);
    BinNormal::of(k, &t.e, &j1, &j2, &t.jl)
}

/// A bin's Jacobians on its two knots' blocks, whitened by the square roots of its
/// information `w`, with its residual and its Jacobian on the fixed parameters.
fn bin_whitened(
    t: &super::factors::BinTerms,
    w: &Vector6<f64>,
) -> (
    Vector6<f64>,
    SMatrix<f64, 6, KB>,
    SMatrix<f64, 6, KB>,
    SMatrix<f64, 6, NFIXED>,
) {
    let sw = w.map(f64::sqrt);
    let eye = SMatrix::<f64, 6, 6>::identity();
    let j1 = widen(&t.j1, &(eye * (1.0 - t.u)));
    let j2 = widen(&t.j2, &(eye * t.u));
    (
        t.e.component_mul(&sw),
        SMatrix::from_fn(|r, c| sw[r] * j1[(r, c)]),
        SMatrix::from_fn(|r, c| sw[r] * j2[(r, c)]),
        SMatrix::from_fn(|r, c| sw[r] * t.jth[(r, c)]),
    )
}

impl ImuJoint<'_> {
    fn problem(&self) -> Problem<'_> {
        Problem {
            times: &self.times,
            cosensor: &self.poses,
            density: &self.density,
        }
    }

    /// For each bin inside the span at `offset`: the interval and the time into it.
    fn placed(&self, offset: f64) -> Vec<(usize, usize, f64)> {
        let n = self.times.len();
        let (a, b) = (self.times[0], self.times[n - 1]);
        let mut k = 0;
        let mut out = Vec::with_capacity(self.bins.len());
        for (j, bin) in self.bins.iter().enumerate() {
            let tau = bin.t + offset;
            if tau < a || tau > b {
                continue;
            }
            while k + 2 < n && self.times[k + 1] <= tau {
                k += 1;
            }
            out.push((j, k, tau - self.times[k]));
        }
        out
    }

    /// The bins the IMU's factors use: those inside the span at the state's clock offset, or
    /// with windows, those inside a window.
    fn bins_used(&self, st: &ImuState) -> usize {
        let Some(w) = &self.windows else {
            return self.placed(st.time_offset_s).len();
        };
        let mut spans = w
            .list
            .iter()
            .flatten()
            .map(|(p, _)| (p.t0, p.t0 + p.dt))
            .peekable();
        let mut used = 0;
        for b in self.bins {
            while spans.peek().is_some_and(|s| s.1 < b.t) {
                spans.next();
            }
            if spans.peek().is_some_and(|s| s.0 <= b.t) {
                used += 1;
            }
        }
        used
    }

    /// `f` of every factor of `placed` (bins, windows or DVL velocities: its index, interval and
    /// time), with what `interval` gives for its interval (computed once for the factors of one
    /// interval), handed to `sink` in the factors' order. The terms are
    /// computed in parallel a block at a time, into one buffer (`zero` fills it), and summed by
    /// the caller in order, so the sums are those of a plain loop on any number of cores.
    pub(super) fn map_factors<C, T: Send + Sync + Clone>(
        &self,
        placed: &[(usize, usize, f64)],
        zero: T,
        interval: impl Fn(usize) -> C + Sync,
        f: impl Fn(&C, usize, usize, f64) -> T + Sync,
        mut sink: impl FnMut(&T),
    ) {
        let mut buf = vec![zero; BLOCK.min(placed.len())];
        for block in placed.chunks(BLOCK) {
            let out = &mut buf[..block.len()];
            out.par_chunks_mut(TASK)
                .zip(block.par_chunks(TASK))
                .for_each(|(out, task)| {
                    let mut at: Option<(usize, C)> = None;
                    for (o, &(j, k, s)) in out.iter_mut().zip(task) {
                        if at.as_ref().is_none_or(|(kk, _)| *kk != k) {
                            at = Some((k, interval(k)));
                        }
                        if let Some((_, c)) = &at {
                            *o = f(c, j, k, s);
                        }
                    }
                });
            out.iter().for_each(&mut sink);
        }
    }

    /// The IMU's factors weighed by its stated noise times `f` (gyro, accelerometer): the
    /// bins' information from `stated` (theirs at the stated noise), or the windows' sample
    /// variances.
    pub fn weigh_imu(&mut self, stated: &[Vector6<f64>], f: (f64, f64)) {
        let (g2, a2) = (f.0 * f.0, f.1 * f.1);
        self.info = stated
            .iter()
            .map(|w| {
                let mut w = *w;
                for r in 0..3 {
                    w[r] /= g2;
                    w[r + 3] /= a2;
                }
                w
            })
            .collect();
        if let Some(w) = &mut self.windows {
            let (vg, va) = Windows::stated_variances(&self.noise);
            w.reweigh((vg * g2, va * a2));
        }
    }

    /// Window `k`'s whitened terms at `knots` and `st`, held columns zeroed (`None`: no
    /// window there, or one whose covariance is not positive definite).
    fn window_at(
        &self,
        w: &Windows,
        knots: &[Knot],
        k: usize,
        st: &ImuState,
    ) -> Option<WindowTerms> {
        let (pre, white) = w.list.get(k)?.as_ref()?;
        let mut t = window_terms((k, &knots[k]), &knots[k + 1], pre, w.offset0, st, white);
        for &c in self.held.iter().filter(|&&c| c < NFIXED) {
            t.jl.column_mut(c).fill(0.0);
        }
        Some(t)
    }

    /// Zeroes the columns of a bin's calibration Jacobian that are held.
    fn hold_bin(&self, jl: &mut SMatrix<f64, 6, NFIXED>) {
        for &c in self.held.iter().filter(|&&c| c < NFIXED) {
            jl.column_mut(c).fill(0.0);
        }
    }

    /// The whole cost at `knots` and `st`.
    pub fn cost(&self, knots: &[Knot], st: &ImuState) -> f64 {
        let mut cost = self.problem().cost(knots) + self.walk_cost(st) + self.dvl_cost(knots, st);
        if let Some(w) = &self.windows {
            let term = |_: &(), _: usize, k: usize, _: f64| {
                w.list[k].as_ref().map_or(0.0, |(pre, white)| {
                    let e = window_residual((k, &knots[k]), &knots[k + 1], pre, w.offset0, st);
                    (white * e).norm_squared()
                })
            };
            self.map_factors(&w.placed(), 0.0, |_| (), term, |c| cost += c);
            return cost;
        }
        let placed = self.placed(st.time_offset_s);
        let gamma2 = |k: usize| local_gamma(&knots[k], &knots[k + 1]);
        let term = |g2: &V18, j: usize, k: usize, s: f64| {
            let dt = self.times[k + 1] - self.times[k];
            let e = bin_residual((k, &knots[k]), g2, s, dt, &self.bins[j], st);
            e.dot(&self.info[j].component_mul(&e))
        };
        self.map_factors(&placed, 0.0, gamma2, term, |c| cost += c);
        cost
    }

    /// The normal equations at `knots` and `st`: the knots' blocks into `sys`, the rest returned.
    fn linearise(&self, knots: &[Knot], st: &ImuState, sys: &mut BlockTridiagonal<KB>) -> Linear {
        let mut own = BlockTridiagonal::<18>::zeros(knots.len());
        self.linearise_into(knots, st, sys, &mut own)
    }

    /// [`ImuJoint::linearise`] with `own` the storage the trajectory's terms are assembled in
    /// first (its contents meaningless), kept by a caller that linearises again and again.
    fn linearise_into(
        &self,
        knots: &[Knot],
        st: &ImuState,
        sys: &mut BlockTridiagonal<KB>,
        own: &mut BlockTridiagonal<18>,
    ) -> Linear {
        let n = knots.len();
        debug_assert_eq!(st.bias.values.len(), n, "one bias per knot");
        let p = st.dim();
        let mut cost = self.assemble_trajectory(knots, sys, own);
        let mut cross = Coupling::zeros(n, p, st.dvl.map(|_| st.dvl_start()));
        let mut hth = DMatrix::<f64>::zeros(p, p);
        let mut gth = DVector::<f64>::zeros(p);
        let normal = |l: &LocalState, j: usize, k: usize, s: f64| {
            let dt = self.times[k + 1] - self.times[k];
            let mut t = bin_terms((k, &knots[k]), l, s, dt, &self.bins[j], st);
            self.hold_bin(&mut t.jth);
            let (e, j1, j2, jth) = bin_whitened(&t, &self.info[j]);
            BinNormal::of(k, &e, &j1, &j2, &jth)
        };
        let local = |k: usize| local_state(&knots[k], &knots[k + 1]);
        let add = |b: &BinNormal| cost += b.add_into(sys, &mut cross, (&mut hth, &mut gth));
        match &self.windows {
            Some(w) => {
                cost += self.linearise_windows(w, knots, st, sys, &mut cross, (&mut hth, &mut gth));
            }
            None => {
                let placed = self.placed(st.time_offset_s);
                self.map_factors(&placed, BinNormal::default(), local, normal, add)
            }
        }
        cost += self.linearise_walks(st, sys);
        // The DVL's velocities.
        if let Some(p) = &st.dvl {
            cost += self.linearise_dvl(knots, st, p, sys, &mut cross, (&mut hth, &mut gth));
        }
        for &c in &self.held {
            cross.hold(c);
            hth.row_mut(c).fill(0.0);
            hth.column_mut(c).fill(0.0);
            hth[(c, c)] = 1.0;
            gth[c] = 0.0;
        }
        Linear {
            cost,
            cross,
            hth,
            gth,
        }
    }

    /// The trajectory's own terms (poses and motion prior) on the knots' trajectory rows of
    /// `sys`, every other entry of its blocks zeroed, assembled in `own` first; returns their
    /// cost.
    fn assemble_trajectory(
        &self,
        knots: &[Knot],
        sys: &mut BlockTridiagonal<KB>,
        own: &mut BlockTridiagonal<18>,
    ) -> f64 {
        let cost = self.problem().assemble_into(knots, own);
        sys.diag
            .par_iter_mut()
            .zip(own.diag.par_iter())
            .zip(sys.rhs.par_iter_mut().zip(own.rhs.par_iter()))
            .for_each(|((d, od), (r, or))| {
                d.fill(0.0);
                d.fixed_view_mut::<18, 18>(0, 0).copy_from(od);
                r.fill(0.0);
                r.fixed_rows_mut::<18>(0).copy_from(or);
            });
        sys.upper
            .par_iter_mut()
            .zip(own.upper.par_iter())
            .for_each(|(u, ou)| {
                u.fill(0.0);
                u.fixed_view_mut::<18, 18>(0, 0).copy_from(ou);
            });
        cost
    }

    /// The windows' share of [`ImuJoint::linearise`]: their blocks on the knots into `sys` and
    /// `cross`, on `theta` into `hth` and `gth`; returns their cost. Runs of [`RUN`] knots are
    /// filled in parallel, each by its own windows (window `k` lies between knots `k` and
    /// `k + 1`); what a run's last window adds to the next run's first knot, and each run's sums
    /// on `theta`, are added after, in the runs' order. The order of every sum is fixed by the
    /// recording, so the result is the same on any number of cores.
    fn linearise_windows(
        &self,
        w: &Windows,
        knots: &[Knot],
        st: &ImuState,
        sys: &mut BlockTridiagonal<KB>,
        cross: &mut Coupling,
        (hth, gth): (&mut DMatrix<f64>, &mut DVector<f64>),
    ) -> f64 {
        // Knot `n - 1` has no window of its own: a run made of it alone (cut off by the zip
        // with the `n - 1` upper blocks) would add nothing; the window before it hands it
        // its share as any run's last window does.
        let runs: Vec<RunTail> = sys
            .diag
            .par_chunks_mut(RUN)
            .zip(sys.upper.par_chunks_mut(RUN))
            .zip(sys.rhs.par_chunks_mut(RUN))
            .zip(cross.runs_mut(RUN))
            .enumerate()
            .map(|(run, (((diag, upper), rhs), rows))| {
                let mut tail = RunTail {
                    cost: 0.0,
                    next: None,
                    hl: SMatrix::zeros(),
                    gl: SMatrix::zeros(),
                };
                for i in 0..upper.len() {
                    let k = run * RUN + i;
                    let Some(t) = self.window_at(w, knots, k, st) else {
                        continue;
                    };
                    let b = window_normal(k, &t);
                    tail.cost += b.cost;
                    diag[i] += b.d1;
                    upper[i] += b.up;
                    rhs[i] -= b.r1;
                    rows[i] += b.c1;
                    if i + 1 < diag.len() {
                        diag[i + 1] += b.d2;
                        rhs[i + 1] -= b.r2;
                        rows[i + 1] += b.c2;
                    } else {
                        tail.next = Some((b.d2, b.r2, b.c2));
                    }
                    tail.hl += b.hl;
                    tail.gl += b.gl;
                }
                tail
            })
            .collect();
        let mut cost = 0.0;
        for (run, tail) in runs.into_iter().enumerate() {
            cost += tail.cost;
            if let Some((d2, r2, c2)) = tail.next {
                let k = (run + 1) * RUN;
                sys.diag[k] += d2;
                sys.rhs[k] -= r2;
                cross.add_bin(k, &c2);
            }
            add_theta(hth, gth, (&tail.hl, &tail.gl));
        }
        cost
    }

    /// The Gauss-Newton step at one linearisation: the knots' and the calibration's, the
    /// Schur complement of the calibration, and the predicted decrease of the cost. The Schur
    /// complement `S = H_theta - H_x theta^T A^-1 H_x theta` and the reduced right-hand side
    /// `s = g_theta - H_x theta^T A^-1 r` come from the knots' factor ([`schur_forms`]); the
    /// knots' step is `A^-1 (r - H_x theta d_theta)`.
    fn step(&self, lin: &Linear, sys: BlockTridiagonal<KB>) -> Result<Step> {
        let factor = sys.factor()?;
        let (schur, s, xr) = schur_of(lin, &factor);
        let dth = solve_schur(&schur, &s)?;
        let hd: Vec<VK> = (0..xr.len()).map(|k| lin.cross.times(k, &dth)).collect();
        let xd = factor.solve_many::<1>(&hd);
        let dx = xr.iter().zip(&xd).map(|(a, b)| a - b).collect();
        let theta_decrement = s.dot(&dth);
        let decrement = factor.decrement() + theta_decrement;
        Ok(Step {
            dx,
            dth,
            schur,
            decrement,
            theta_decrement,
            factor,
        })
    }

    /// The calibration's Gauss-Newton step at `knots` and `st` with the motion prior's density
    /// multiplied by `factor` (the knots' step discarded; the density restored after): from a
    /// solution at the present density, the linear response of `theta` to the other one.
    pub fn theta_step_at_density(
        &mut self,
        knots: &[Knot],
        st: &ImuState,
        factor: f64,
    ) -> Result<DVector<f64>> {
        let kept = self.density.clone();
        self.density = kept.scaled(factor);
        let mut sys = BlockTridiagonal::<KB>::zeros(knots.len());
        let lin = self.linearise(knots, st, &mut sys);
        self.density = kept;
        Ok(self.step(&lin, sys)?.dth)
    }

    /// Each sensor's share of the measurements' redundancy at the solution, and its chi-square.
    /// The redundancy of a residual block is its dimension less `tr(W J Sigma J^T)`, with
    /// `Sigma` the joint covariance of the two knots and the calibration it touches; the
    /// chi-square over it estimates the factor by which the stated variances are off.
    ///
    /// With `X = A^-1 H_x theta` and `S^-1 = G G^T` (`G = L^-T` of the Schur complement's
    /// Cholesky factor), `J Sigma J^T = J_x A^-1 J_x^T + U U^T` with `U = J_x X G - J_theta G`:
    /// the first term needs the knots' banded covariance, the second splits by the columns of
    /// `G`, so `X G` is solved for a few columns at a time and never stored whole.
    pub fn redundancy(&self, knots: &[Knot], st: &ImuState) -> Result<Redundancy> {
        let mut sys = BlockTridiagonal::<KB>::zeros(knots.len());
        let lin = self.linearise(knots, st, &mut sys);
        let factor = sys.factor()?;
        let schur = schur_of(&lin, &factor).0;
        self.redundancy_at(knots, st, lin, factor, &schur)
    }

    /// [`ImuJoint::redundancy`] at a solution of [`ImuJoint::solve`] (with the same weights),
    /// from the linearisation and factor it ended with. When the solve stopped a last small
    /// step past them, the chi-squares are still the solution's and only the traces come from
    /// the point before it.
    pub fn redundancy_of(&self, sol: &mut Solution) -> Result<Redundancy> {
        match sol.last.take() {
            Some(last) => {
                let Last {
                    lin, factor, schur, ..
                } = *last;
                self.redundancy_at(&sol.knots, &sol.state, lin, factor, &schur)
            }
            None => self.redundancy(&sol.knots, &sol.state),
        }
    }

    /// [`ImuJoint::redundancy`] from the linearisation `lin` at `knots` and `st` and the
    /// knots' factor there.
    fn redundancy_at(
        &self,
        knots: &[Knot],
        st: &ImuState,
        lin: Linear,
        factor: Factored<KB>,
        schur: &DMatrix<f64>,
    ) -> Result<Redundancy> {
        let n = knots.len();
        let p = schur.nrows();
        let l = schur.clone().cholesky().ok_or_else(singular)?.unpack();
        let g = l
            .transpose()
            .solve_upper_triangular(&DMatrix::identity(p, p))
            .ok_or_else(singular)?;
        let solved = |c0: usize| {
            let mut x: Vec<SMatrix<f64, KB, CHUNK>> = (0..n)
                .map(|k| lin.cross.times_matrix::<CHUNK>(k, &g, c0))
                .collect();
            factor.solve_many_in_place::<CHUNK>(&mut x);
            x
        };
        let starts: Vec<usize> = (0..p).step_by(CHUNK).collect();
        let mut out = Redundancy::default();
        let Some((&last, rest)) = starts.split_last() else {
            return Ok(out);
        };
        for &c0 in rest {
            let x = solved(c0);
            self.redundancy_pass(knots, st, (&x, &g, c0), None, &mut out);
        }
        let x = solved(last);
        let band = factor.banded_inverse();
        self.redundancy_pass(knots, st, (&x, &g, last), Some(&band), &mut out);
        Ok(out)
    }

    /// One pass of [`ImuJoint::redundancy`] over the residual blocks: subtracts `tr(W U U^T)`
    /// on the columns `c0..c0 + CHUNK` of `G` (`xg` holds those of `X G`, knot by knot) from
    /// each sensor's redundancy; with the knots' banded covariance, also adds each block's
    /// dimension less `tr(W J_x A^-1 J_x^T)` and its chi-square.
    fn redundancy_pass(
        &self,
        knots: &[Knot],
        st: &ImuState,
        (xg, g, c0): (&[SMatrix<f64, KB, CHUNK>], &DMatrix<f64>, usize),
        band: Option<&BandedInverse<KB>>,
        out: &mut Redundancy,
    ) {
        let width = CHUNK.min(g.ncols() - c0);
        let g_rows = |cols: &[usize]| -> DMatrix<f64> {
            DMatrix::from_fn(cols.len(), CHUNK, |a, c| {
                if c < width { g[(cols[a], c0 + c)] } else { 0.0 }
            })
        };
        let fixed: Vec<usize> = (0..NFIXED).collect();
        let g_fixed = SMatrix::<f64, NFIXED, CHUNK>::from_iterator(g_rows(&fixed).iter().copied());
        let local = |k: usize| local_state(&knots[k], &knots[k + 1]);
        // Per row: `|u|^2`, and with the band `e^2` and `1 - J_x A^-1 J_x^T` (whitened rows).
        let terms = |l: &LocalState, j: usize, k: usize, s: f64| {
            let dt = self.times[k + 1] - self.times[k];
            let mut t = bin_terms((k, &knots[k]), l, s, dt, &self.bins[j], st);
            self.hold_bin(&mut t.jth);
            let (e, j1, j2, jth) = bin_whitened(&t, &self.info[j]);
            let u = j1 * xg[k] + j2 * xg[k + 1] - jth * g_fixed;
            let proj = band.map(|b| local_projection(b, k, &j1, &j2));
            std::array::from_fn::<_, 6, _>(|r| {
                let own = proj.map(|pr| (e[r] * e[r], 1.0 - pr[(r, r)]));
                (u.row(r).norm_squared(), own)
            })
        };
        let mut sink = |rows: &[(f64, Option<(f64, f64)>)]| {
            for (r, &(projected, own)) in rows.iter().enumerate() {
                let part = if r < 3 { &mut out.gyro } else { &mut out.accel };
                part.1 -= projected;
                if let Some((chi, red)) = own {
                    part.0 += chi;
                    part.1 += red;
                }
            }
        };
        match &self.windows {
            // Whitened rows: the first three the gyro's, the rest the accelerometer's.
            Some(w) => {
                let terms = |_: &(), _: usize, k: usize, _: f64| {
                    let Some(t) = self.window_at(w, knots, k, st) else {
                        return [(0.0, None); 9];
                    };
                    let (j1, j2) = window_jacobians(&t);
                    let u = j1 * xg[k] + j2 * xg[k + 1] - t.jl * g_fixed;
                    let proj = band.map(|b| local_projection(b, k, &j1, &j2));
                    std::array::from_fn::<_, 9, _>(|r| {
                        let own = proj.map(|pr| (t.e[r] * t.e[r], 1.0 - pr[(r, r)]));
                        (u.row(r).norm_squared(), own)
                    })
                };
                self.map_factors(&w.placed(), [(0.0, None); 9], |_| (), terms, |r| sink(r));
            }
            None => {
                let placed = self.placed(st.time_offset_s);
                self.map_factors(&placed, [(0.0, None); 6], local, terms, |r| sink(r))
            }
        }
        if let Some(pd) = &st.dvl {
            let c = st.dvl_start();
            let cols: Vec<usize> = (c..c + NPARAM).collect();
            let gl = SMatrix::<f64, NPARAM, CHUNK>::from_iterator(g_rows(&cols).iter().copied());
            // Per velocity: `tr(W U U^T)`, and with the band its chi-square and its dimension
            // less `tr(W J_x A^-1 J_x^T)`.
            let local = |k: usize| local_state(&knots[k], &knots[k + 1]);
            let terms = |l: &LocalState, i: usize, k: usize, tau: f64| {
                let t = self.dvl_terms(knots, k, tau, l, i, pd);
                let none = SMatrix::<f64, 3, 6>::zeros();
                let (j1, j2) = (widen(&t.j1, &none), widen(&t.j2, &none));
                let u = j1 * xg[k] + j2 * xg[k + 1] - t.jth * gl;
                let w = &self.dvl_info[i];
                // tr(W P) for symmetric P.
                let trace = |p: &Matrix3<f64>| w.component_mul(p).sum();
                let own = band.map(|b| {
                    (
                        (t.e.transpose() * w * t.e)[0],
                        3.0 - trace(&local_projection(b, k, &j1, &j2)),
                    )
                });
                (trace(&(u * u.transpose())), own)
            };
            let sink = |&(projected, own): &(f64, Option<(f64, f64)>)| {
                out.dvl.1 -= projected;
                if let Some((chi, red)) = own {
                    out.dvl.0 += chi;
                    out.dvl.1 += red;
                }
            };
            self.map_factors(&self.placed_dvl(st), (0.0, None), local, terms, sink);
        }
    }

    /// Gauss-Newton from `knots` and `st`.
    pub fn solve(
        &self,
        mut knots: Vec<Knot>,
        mut st: ImuState,
        max_iterations: usize,
    ) -> Result<Solution> {
        let n = knots.len();
        let mut sys = BlockTridiagonal::<KB>::zeros(n);
        let mut own = BlockTridiagonal::<18>::zeros(n);
        let mut lin = self.linearise_into(&knots, &st, &mut sys, &mut own);
        let mut cost = lin.cost;
        let mut iterations = 0;
        let mut converged = false;
        let mut previous: Option<(f64, f64)> = None;
        loop {
            let Step {
                dx,
                dth,
                schur,
                decrement,
                theta_decrement,
                factor,
            } = self.step(&lin, sys)?;
            let settles = |d: f64, td: f64| {
                d < STOP_DECREMENT || (td < STOP_DECREMENT && d < STOP_RELATIVE * cost)
            };
            let settled = settles(decrement, theta_decrement);
            if converged || settled || iterations >= max_iterations {
                converged = converged || settled;
                let covariance = schur.clone().try_inverse().ok_or_else(singular)?;
                let bins_used = self.bins_used(&st);
                return Ok(Solution {
                    knots,
                    state: st,
                    covariance,
                    iterations,
                    converged,
                    cost,
                    bins_used,
                    last: Some(Box::new(Last {
                        lin,
                        factor,
                        schur,
                        behind: false,
                    })),
                });
            }
            // Within a standard deviation of the minimum the decrements shrink at least by the
            // ratio of this step's to the last's (Gauss-Newton converges linearly at worst
            // there): when that says the next step would settle, this one is the last.
            let last_step = previous.is_some_and(|(d0, td0)| {
                theta_decrement < LAST_STEP_BELOW
                    && decrement < d0
                    && theta_decrement < td0
                    && settles(
                        decrement * decrement / d0,
                        theta_decrement * theta_decrement / td0,
                    )
            });
            previous = Some((decrement, theta_decrement));
            let dx18: Vec<V18> = dx.iter().map(trajectory_part).collect();
            let db: Vec<Vector6<f64>> = dx.iter().map(bias_part).collect();
            let mut scale = 1.0;
            let mut accepted = None;
            for _ in 0..10 {
                let trial = step(&knots, &dx18, scale);
                let tst = st.retract(&(&dth * scale)).with_bias_step(&db, scale);
                let tcost = self.cost(&trial, &tst);
                if tcost.is_finite() && tcost <= cost {
                    accepted = Some((trial, tst, tcost));
                    break;
                }
                scale *= 0.5;
            }
            iterations += 1;
            match accepted {
                // The full step lowered the cost as its linearisation predicted (so the
                // linearisation holds that far): stop at it, with the covariance and the kept
                // linearisation of the point it was taken from, a fraction of a standard
                // deviation away.
                Some((k, s, c)) if last_step && scale == 1.0 && cost - c >= 0.5 * decrement => {
                    let covariance = schur.clone().try_inverse().ok_or_else(singular)?;
                    let bins_used = self.bins_used(&s);
                    return Ok(Solution {
                        knots: k,
                        state: s,
                        covariance,
                        iterations,
                        converged: true,
                        cost: c,
                        bins_used,
                        last: Some(Box::new(Last {
                            lin,
                            factor,
                            schur,
                            behind: true,
                        })),
                    });
                }
                Some((k, s, c)) => {
                    // A full step that lowers the cost by less than the stopping decrement has
                    // nothing left to gain (the clock offset's steps alternate in sign near the
                    // minimum and shrink slowly: they are far below its std by then).
                    converged = scale == 1.0 && cost - c < STOP_DECREMENT;
                    knots = k;
                    st = s;
                }
                None => converged = true,
            }
            sys = factor.into_system();
            lin = self.linearise_into(&knots, &st, &mut sys, &mut own);
            cost = lin.cost;
        }
    }
}

#[cfg(test)]
#[path = "solve_tests.rs"]
mod tests;
