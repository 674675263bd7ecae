//! A first estimate of a DVL's calibration against an IMU, without a camera: dead reckoning
//! over short windows, where everything unknown enters linearly.
//!
//! Over a window of a couple of seconds the gyro's integrated attitude is good (its bias turns
//! it by a fraction of a degree). Take the body frame at the window's first DVL report as the
//! reference. The velocity of the IMU in its own frame at report `i` is
//! `v_i = M u_i - w_i x p` with `u_i` the DVL's velocity, `M = R_imu_dvl / kappa` and `p` the
//! lever arm `p_imu_dvl`. The accelerometer integrated between the reports gives the change of
//! the velocity in the reference frame:
//!
//! `dR_i v_i - v_0 = dv_i - B_i b_a + g_0 dt_i`
//!
//! with `dR_i` the attitude relative to the reference, `dv_i` the integral of `dR f`, `B_i` the
//! integral of `dR` (the accelerometer bias `b_a` enters through it) and `g_0` gravity in the
//! reference frame, one per window. All of `M` (9), `p`, `b_a` and the `g_0` are linear
//! unknowns; the windows' `g_0` are eliminated window by window. The clock offset is the grid
//! point (then a parabola) whose least-squares cost is smallest; `M` is then split into a
//! rotation and a scale and the rest solved again with the rotation held.

use std::ops::AddAssign;

use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, Vector3};
use rayon::prelude::*;

use super::bins::ImuBin;
use super::state::BiasNodes;
use crate::calib::model::DvlObs;
use crate::error::{Error, Result};
use crate::lie::{hat, so3};

/// The IMU's attitude and integrals at its bins' times, the gyro's bias removed.
pub(crate) struct DeadReckoning<'a> {
    bins: &'a [ImuBin],
    gyro_bias: Vector3<f64>,
    /// `R_ref_body` at each bin time (the reference: the body at the first bin).
    rot: Vec<Matrix3<f64>>,
    /// Integral of `R f` from the first bin.
    sf: Vec<Vector3<f64>>,
    /// Integral of `R`.
    sr: Vec<Matrix3<f64>>,
}

/// What the dead reckoning gives at one time.
pub(crate) struct Reckoned {
    pub rot: Matrix3<f64>,
    pub sf: Vector3<f64>,
    pub sr: Matrix3<f64>,
    /// The gyro's rate there (bias removed), interpolated between bins.
    pub w: Vector3<f64>,
    /// The accelerometer's reading there, interpolated between bins.
    pub f: Vector3<f64>,
}

impl<'a> DeadReckoning<'a> {
    /// Integrates `bins` (each held over the time to the next) with the gyro bias removed.
    pub fn new(bins: &'a [ImuBin], gyro_bias: Vector3<f64>) -> DeadReckoning<'a> {
        let n = bins.len();
        let mut rot = Vec::with_capacity(n);
        let mut sf = Vec::with_capacity(n);
        let mut sr = Vec::with_capacity(n);
        let (mut r, mut f, mut s) = (Matrix3::identity(), Vector3::zeros(), Matrix3::zeros());
        for (j, b) in bins.iter().enumerate() {
            rot.push(r);
            sf.push(f);
            sr.push(s);
            if let Some(next) = bins.get(j + 1) {
                let dt = next.t - b.t;
                let w = b.gyro - gyro_bias;
                let mid = r * so3::exp(&(w * (0.5 * dt)));
                f += mid * b.accel * dt;
                s += mid * dt;
                r = so3::matrix_from_quaternion(&so3::quaternion_from_matrix(
                    &(r * so3::exp(&(w * dt))),
                ));
            }
        }
        DeadReckoning {
            bins,
            gyro_bias,
            rot,
            sf,
            sr,
        }
    }

    /// The span of the bins.
    pub fn span(&self) -> (f64, f64) {
        (
            self.bins.first().map_or(0.0, |b| b.t),
            self.bins.last().map_or(0.0, |b| b.t),
        )
    }

    /// The state at `t` inside the span.
    pub fn at(&self, t: f64) -> Option<Reckoned> {
        let (a, b) = self.span();
        if !(t >= a && t <= b) || self.bins.len() < 2 {
            return None;
        }
        let j = self
            .bins
            .partition_point(|x| x.t <= t)
            .saturating_sub(1)
            .min(self.bins.len() - 2);
        let (b0, b1) = (&self.bins[j], &self.bins[j + 1]);
        let s = t - b0.t;
        let u = (s / (b1.t - b0.t)).clamp(0.0, 1.0);
        let w0 = b0.gyro - self.gyro_bias;
        let mid = self.rot[j] * so3::exp(&(w0 * (0.5 * s)));
        Some(Reckoned {
            rot: self.rot[j] * so3::exp(&(w0 * s)),
            sf: self.sf[j] + mid * b0.accel * s,
            sr: self.sr[j] + mid * s,
            w: b0.gyro * (1.0 - u) + b1.gyro * u - self.gyro_bias,
            f: b0.accel * (1.0 - u) + b1.accel * u,
        })
    }
}

/// The windows' normal equations with their gravities eliminated: `N x = r`, and the constant
/// `c` of the cost `c - 2 r^T x + x^T N x`; per window what recovers its gravity.
struct Normal {
    n: SMatrix<f64, 15, 15>,
    r: SMatrix<f64, 15, 1>,
    c: f64,
    rows: usize,
    /// Per window: what recovers its gravity.
    windows: Vec<Window>,
}

/// What recovers a window's gravity: `g_0 = ci (ctb - cta x)` in the body frame at its start.
struct Window {
    /// The window's start, IMU clock, s.
    t: f64,
    /// `C^T C` inverse, `C^T A` and `C^T b`.
    ci: Matrix3<f64>,
    cta: SMatrix<f64, 3, 15>,
    ctb: Vector3<f64>,
}

/// One window's gravity: its time and its direction in the body frame at the window's start.
#[derive(Clone, Debug)]
pub(crate) struct WindowGravity {
    pub t: f64,
    pub body: Vector3<f64>,
}

/// The first estimate.
#[derive(Clone, Debug)]
pub(crate) struct DvlImuStart {
    /// `t_imu = t_dvl + offset`.
    pub offset: f64,
    pub r_imu_dvl: Matrix3<f64>,
    pub scale: f64,
    pub lever: Vector3<f64>,
    pub accel_bias: Vector3<f64>,
    /// Gravity in the dead reckoning's reference frame (the body at the first bin).
    pub gravity: Vector3<f64>,
    /// Each window's gravity (unit), from which the gyro's bias is estimated
    /// ([`gyro_bias_from_gravity`]).
    pub windows: Vec<WindowGravity>,
}

/// Longest window, s, and the longest pause between reports inside one.
const WINDOW_S: f64 = 2.0;
const PAUSE_S: f64 = 0.5;

fn normal(dr: &DeadReckoning, obs: &[DvlObs], offset: f64) -> Normal {
    let mut out = Normal {
        n: SMatrix::zeros(),
        r: SMatrix::zeros(),
        c: 0.0,
        rows: 0,
        windows: Vec::new(),
    };
    let mut window: Vec<(f64, Reckoned, Vector3<f64>)> = Vec::new();
    let flush = |w: &mut Vec<(f64, Reckoned, Vector3<f64>)>, out: &mut Normal| {
        if w.len() >= 3 {
            add_window(w, out);
        }
        w.clear();
    };
    for o in obs {
        let tau = o.t + offset;
        let Some(s) = dr.at(tau) else { continue };
        if let (Some(first), Some(last)) = (window.first(), window.last())
            && (tau - first.0 > WINDOW_S || tau - last.0 > PAUSE_S)
        {
            flush(&mut window, &mut out);
        }
        window.push((tau, s, o.v));
    }
    flush(&mut window, &mut out);
    out
}

/// Adds one window's rows, its gravity eliminated.
fn add_window(w: &[(f64, Reckoned, Vector3<f64>)], out: &mut Normal) {
    let (t0, s0, u0) = &w[0];
    let r0t = s0.rot.transpose();
    let mut ata = SMatrix::<f64, 15, 15>::zeros();
    let mut atc = SMatrix::<f64, 15, 3>::zeros();
    let mut ctc = Matrix3::zeros();
    let mut atb = SMatrix::<f64, 15, 1>::zeros();
    let mut ctb = Vector3::zeros();
    let mut btb = 0.0;
    // (u^T (x) I3) vec(M) = M u, vec column-major.
    let kron = |u: &Vector3<f64>, r: &Matrix3<f64>| {
        let mut m = SMatrix::<f64, 3, 9>::zeros();
        for c in 0..3 {
            m.fixed_view_mut::<3, 3>(0, 3 * c).copy_from(&(r * u[c]));
        }
        m
    };
    for (t, s, u) in &w[1..] {
        let dr = r0t * s.rot;
        let mut a = SMatrix::<f64, 3, 15>::zeros();
        a.fixed_view_mut::<3, 9>(0, 0)
            .copy_from(&(kron(u, &dr) - kron(u0, &Matrix3::identity())));
        a.fixed_view_mut::<3, 3>(0, 9)
            .copy_from(&(-(dr * hat(&s.w)) + hat(&s0.w)));
        a.fixed_view_mut::<3, 3>(0, 12)
            .copy_from(&(r0t * (s.sr - s0.sr)));
        let c = Matrix3::identity() * -(t - t0);
        let b = r0t * (s.sf - s0.sf);
        ata += a.transpose() * a;
        atc += a.transpose() * c;
        ctc += c.transpose() * c;
        atb += a.transpose() * b;
        ctb += c.transpose() * b;
        btb += b.norm_squared();
        out.rows += 3;
    }
    let Some(ci) = ctc.try_inverse() else { return };
    out.n += ata - atc * ci * atc.transpose();
    out.r += atb - atc * ci * ctb;
    out.c += btb - ctb.dot(&(ci * ctb));
    out.windows.push(Window {
        t: *t0,
        ci,
        cta: atc.transpose(),
        ctb,
    });
}

/// The least-squares solution of `N` restricted to `x = T z`, and its cost per row.
fn solve_in<const K: usize>(
    nm: &Normal,
    t: &SMatrix<f64, 15, K>,
) -> Option<(SMatrix<f64, K, 1>, f64)> {
    let n = t.transpose() * nm.n * t;
    let r = t.transpose() * nm.r;
    let z = n.cholesky()?.solve(&r);
    let cost = nm.c - r.dot(&z);
    Some((z, cost / nm.rows.max(1) as f64))
}

/// The clock offset within `max_offset` whose dead-reckoning fit is best, then the rest.
pub(crate) fn initial_dvl_imu(
    dr: &DeadReckoning,
    obs: &[DvlObs],
    max_offset: f64,
    gravity: f64,
) -> Result<DvlImuStart> {
    let free = SMatrix::<f64, 15, 15>::identity();
    let score = |offset: f64| -> Option<f64> {
        let nm = normal(dr, obs, offset);
        (nm.rows >= 60).then(|| solve_in(&nm, &free).map(|(_, c)| c))?
    };
    // The candidates scored in parallel, the best picked in their order (the first of equals).
    let search = |from: f64, to: f64, step: f64| -> Option<(f64, f64)> {
        let n = ((to - from) / step).round() as i64;
        let scored: Vec<Option<(f64, f64)>> = (0..=n)
            .into_par_iter()
            .map(|i| {
                let o = from + step * i as f64;
                score(o).map(|c| (o, c))
            })
            .collect();
        scored
            .into_iter()
            .flatten()
            .min_by(|a, b| a.1.total_cmp(&b.1))
    };
    let (coarse, _) = search(-max_offset, max_offset, 0.02).ok_or_else(|| {
        Error::NoTimeOverlap(
            "too few DVL reports fall inside the IMU's recording at any clock offset searched"
                .into(),
        )
    })?;
    let (mut offset, best) =
        search(coarse - 0.03, coarse + 0.03, 0.002).unwrap_or((coarse, f64::INFINITY));
    if let (Some(a), Some(b)) = (score(offset - 0.002), score(offset + 0.002)) {
        let curv = a + b - 2.0 * best;
        if curv > 0.0 {
            offset += 0.002 * 0.5 * (a - b) / curv;
        }
    }
    let nm = normal(dr, obs, offset);
    let (x, _) = solve_in(&nm, &free).ok_or_else(|| {
        Error::Numerical(
            "the DVL's first estimate against the IMU is not determined: rotate the vehicle and \
             vary its speed"
                .into(),
        )
    })?;
    let m = Matrix3::from_column_slice(&x.as_slice()[0..9]);
    let svd = m.svd(true, true);
    let (u, vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => {
            return Err(Error::Numerical(
                "DVL-IMU first rotation: SVD failed".into(),
            ));
        }
    };
    let d = (u * vt).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt;
    // With the rotation held: z = [1 / kappa, p, b_a].
    let mut t = SMatrix::<f64, 15, 7>::zeros();
    for (i, v) in r.as_slice().iter().enumerate() {
        t[(i, 0)] = *v;
    }
    for i in 0..6 {
        t[(9 + i, 1 + i)] = 1.0;
    }
    let (z, _) = solve_in(&nm, &t)
        .ok_or_else(|| Error::Numerical("DVL-IMU first lever arm: singular system".into()))?;
    if !(z[0] > 0.2 && z[0] < 5.0) {
        return Err(Error::Input(format!(
            "the DVL's velocities come out at {:.2} times the IMU's: does the IMU belong to this \
             recording, and is its accelerometer in m/s^2 (not g)?",
            1.0 / z[0]
        )));
    }
    // Each window's gravity, in the reference frame; their mean direction.
    let xs: SMatrix<f64, 15, 1> = t * z;
    let mut g = Vector3::zeros();
    let mut mags = Vec::new();
    let mut windows = Vec::with_capacity(nm.windows.len());
    for w in &nm.windows {
        let g0 = w.ci * (w.ctb - w.cta * xs);
        let Some(s) = dr.at(w.t) else { continue };
        mags.push(g0.norm());
        g += s.rot * g0;
        if let Some(body) = g0.try_normalize(1e-9) {
            windows.push(WindowGravity { t: w.t, body });
        }
    }
    mags.sort_by(f64::total_cmp);
    let median = mags.get(mags.len() / 2).copied().unwrap_or(0.0);
    if !(median > 0.5 * gravity && median < 1.5 * gravity) {
        return Err(Error::Input(format!(
            "the accelerometer's gravity comes out at {median:.2} m/s^2 against {gravity:.2}: \
             is the accelerometer in m/s^2 (not g), and does the IMU belong to this recording?"
        )));
    }
    Ok(DvlImuStart {
        offset,
        r_imu_dvl: r,
        scale: 1.0 / z[0],
        lever: Vector3::new(z[1], z[2], z[3]),
        accel_bias: Vector3::new(z[4], z[5], z[6]),
        gravity: g.normalize() * gravity,
        windows,
    })
}

/// Consecutive windows further apart than this are not paired, s.
const PAIR_GAP_S: f64 = 10.0;

/// A gyro bias's prior std about zero, rad/s: keeps a component the motion never turned into
/// view (about gravity on a calm stretch) at zero rather than undetermined.
const BIAS_PRIOR_STD: f64 = 0.1;

/// Directions of gravity between windows that scatter more than this (rad) are not a bias.
const MAX_SCATTER: f64 = 0.1;

/// The gyro's bias at `nodes` (linear between them) from how the windows' gravity drifts in
/// the dead reckoning `dr` (which already has whatever bias it was built with removed; the
/// result is what is left). A bias `b` left in the gyro turns the reckoned attitude `R` away
/// from the true one: gravity's direction in the reckoning's frame, `a = R g_body`, obeys
/// `da/dt = (R b) x a`. Between two windows a few seconds apart that is
/// `a_1 - a_0 = -[a]x (S_1 - S_0) b`, with `S` the reckoning's integral of `R`: linear in
/// `b`, however far the reckoning has drifted by then. The pairs' scatter weighs the biases'
/// random walk (`random_walk`, rad/s/sqrt(s)) between nodes and a loose prior about zero.
/// `None` when too few windows pair up or their directions scatter too much to say.
pub(crate) fn gyro_bias_from_gravity(
    dr: &DeadReckoning,
    windows: &[WindowGravity],
    nodes: &BiasNodes,
    random_walk: f64,
) -> Option<Vec<Vector3<f64>>> {
    let m = nodes.times.len();
    let dim = 3 * m;
    let mut n = DMatrix::<f64>::zeros(dim, dim);
    let mut r = DVector::<f64>::zeros(dim);
    let mut rows = Vec::new();
    let at: Vec<Option<Reckoned>> = windows.iter().map(|w| dr.at(w.t)).collect();
    for (pair, s) in windows.windows(2).zip(at.windows(2)) {
        let ((w0, w1), (Some(s0), Some(s1))) = ((&pair[0], &pair[1]), (&s[0], &s[1])) else {
            continue;
        };
        if w1.t - w0.t > PAIR_GAP_S {
            continue;
        }
        let (a0, a1) = (s0.rot * w0.body, s1.rot * w1.body);
        let Some(mean) = (a0 + a1).try_normalize(1e-9) else {
            continue;
        };
        let j = hat(&mean) * (s1.sr - s0.sr);
        let y = a0 - a1;
        let (i, u) = nodes.weights(0.5 * (w0.t + w1.t));
        let parts = [(i, 1.0 - u), ((i + 1).min(m - 1), u)];
        for &(a, wa) in &parts {
            r.fixed_rows_mut::<3>(3 * a)
                .add_assign(&(j.transpose() * y * wa));
            for &(b, wb) in &parts {
                let mut blk = n.fixed_view_mut::<3, 3>(3 * a, 3 * b);
                blk += j.transpose() * j * (wa * wb);
            }
        }
        rows.push((j, y, parts));
    }
    if rows.len() < 3 * m + 10 {
        return None;
    }
    let solve = |n: &DMatrix<f64>| n.clone().cholesky().map(|c| c.solve(&r));
    // First with a ridge for what the pairs leave undetermined, for the pairs' scatter.
    let ridge = 1e-9 * (n.trace() / dim as f64).max(1e-300);
    let mut first = n.clone();
    for d in 0..dim {
        first[(d, d)] += ridge;
    }
    let b = solve(&first)?;
    let rss: f64 = rows
        .iter()
        .map(|(j, y, parts)| {
            let bias: Vector3<f64> = parts
                .iter()
                .map(|&(a, w)| b.fixed_rows::<3>(3 * a) * w)
                .sum();
            (y - j * bias).norm_squared()
        })
        .sum();
    let var = rss / (3 * rows.len()).saturating_sub(dim).max(1) as f64;
    if var.is_nan() || var.sqrt() >= MAX_SCATTER {
        return None;
    }
    for d in 0..dim {
        n[(d, d)] += var / (BIAS_PRIOR_STD * BIAS_PRIOR_STD);
    }
    for i in 0..m.saturating_sub(1) {
        let dt = (nodes.times[i + 1] - nodes.times[i]).max(1e-6);
        let w = var / (random_walk.max(1e-12).powi(2) * dt);
        for d in 0..3 {
            let (p, q) = (3 * i + d, 3 * (i + 1) + d);
            n[(p, p)] += w;
            n[(q, q)] += w;
            n[(p, q)] -= w;
            n[(q, p)] -= w;
        }
    }
    let b = solve(&n)?;
    Some(
        (0..m)
            .map(|i| b.fixed_rows::<3>(3 * i).into_owned())
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gyro_bias_comes_back_from_how_gravity_drifts_in_the_reckoning() {
        // Ten minutes of turning about every axis, a gyro bias that changes half-way, and each
        // 2 s window's gravity in the body frame with 1 mrad of noise: the reckoning with the
        // bias left in drifts by most of a radian, the bias comes back at every node.
        let dt = 0.01;
        let n = 60_001;
        let bias_at = |t: f64| {
            let u = (t / 600.0).clamp(0.0, 1.0);
            Vector3::new(0.004, -0.006, 0.003) * (1.0 - u) + Vector3::new(0.005, -0.004, 0.002) * u
        };
        let mut bins = Vec::with_capacity(n);
        let mut truth = Vec::with_capacity(n);
        let mut r = Matrix3::identity();
        for i in 0..n {
            let t = dt * i as f64;
            let w = Vector3::new(0.3 * (0.5 * t).sin(), 0.25 * (0.31 * t).cos(), 0.2);
            truth.push(r);
            bins.push(ImuBin {
                t,
                gyro: w + bias_at(t),
                accel: Vector3::zeros(),
                n: 2,
            });
            r *= so3::exp(&(w * dt));
        }
        let up = Vector3::new(0.0, 0.0, 1.0);
        let mut rng = 12345u64;
        let mut noise = || {
            // A small linear congruential generator: uniform on [-1, 1] scaled to ~1 mrad std.
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * 1.7e-3
        };
        let windows: Vec<WindowGravity> = (0..n)
            .step_by(200)
            .map(|i| {
                let e = Vector3::new(noise(), noise(), noise());
                WindowGravity {
                    t: bins[i].t,
                    body: (truth[i].transpose() * up + e).normalize(),
                }
            })
            .collect();
        let nodes = BiasNodes::spanning(0.0, 600.0, 100.0, Default::default());
        let dr = DeadReckoning::new(&bins, Vector3::zeros());
        let drift = so3::log(&(dr.at(600.0).expect("inside").rot * truth[n - 1].transpose()));
        assert!(
            drift.norm() > 0.5,
            "the reckoning drifted by {drift:?} only"
        );
        let b = gyro_bias_from_gravity(&dr, &windows, &nodes, 3.8e-5).expect("determined");
        // The end nodes have half the pairs of the others; the bias itself is 7.8e-3 rad/s.
        let last = nodes.times.len() - 1;
        for (i, (t, est)) in nodes.times.iter().zip(&b).enumerate() {
            let err = (est - bias_at(*t)).norm();
            let bound = if i == 0 || i == last { 5e-4 } else { 2e-4 };
            assert!(err < bound, "at {t} s: {est:?} against {:?}", bias_at(*t));
        }
    }

    #[test]
    fn dead_reckoning_turns_at_a_constant_rate_exactly() {
        let w = Vector3::new(0.1, -0.2, 0.3);
        let bins: Vec<ImuBin> = (0..101)
            .map(|i| ImuBin {
                t: 0.01 * i as f64,
                gyro: w,
                accel: Vector3::new(0.0, 0.0, 9.81),
                n: 1,
            })
            .collect();
        let dr = DeadReckoning::new(&bins, Vector3::zeros());
        let s = dr.at(0.555).expect("inside");
        assert!((s.rot - so3::exp(&(w * 0.555))).norm() < 1e-9);
        assert!(dr.at(1.5).is_none());
    }
}
