//! The IMU's samples between consecutive knots integrated once, before any iteration: each
//! window's rotation, velocity and position increments in the IMU frame at its start, their
//! first-order derivatives with respect to the biases, and their covariance, so that an
//! iteration compares the knots' relative motion with one 9-vector per window instead of
//! predicting every sample from the trajectory's interpolation.
//!
//! The knots stay on the camera's clock; a window spans the IMU-clock interval that the clock
//! offset at integration (`offset0`) maps onto two consecutive knots. When the estimated offset
//! differs from it by `eps`, the window's ends are the knots' states `eps` later, extrapolated
//! from each knot alone (second order in `eps`); the caller integrates again when `eps` grows
//! beyond a few milliseconds.
//!
//! Each sample is held over the half-way points to its neighbours (a midpoint rule: the error
//! is second order in the sample period), the rotation applied to a sample's specific force is
//! the one at the middle of its span. The increments' covariance is kept as its gyro and
//! accelerometer parts per unit sample variance, so that scaling either sensor's noise costs
//! nothing.

use nalgebra::{Cholesky, Matrix3, SMatrix, SVector, Vector3, Vector6};

use super::state::{ImuState, NFIXED};
use crate::lie::{Se3, hat, se3_right_jacobian, so3};
use crate::trajectory::gp::Knot;
use crate::types::imu::{ImuBias, ImuNoise, ImuSample};

/// 9 x 9.
pub type M9 = SMatrix<f64, 9, 9>;
/// A window's residual: rotation, velocity, position.
pub type V9 = SVector<f64, 9>;

/// One window's increments.
#[derive(Clone, Debug)]
pub struct Preintegrated {
    /// Start, IMU clock, s.
    pub t0: f64,
    /// Length, s.
    pub dt: f64,
    /// The biases the samples were corrected by (the window's then: the mean of its knots').
    pub bias: ImuBias,
    /// `Delta R`, `Delta v`, `Delta p` in the IMU frame at the start, gravity not removed.
    pub rot: Matrix3<f64>,
    pub vel: Vector3<f64>,
    pub pos: Vector3<f64>,
    /// Their derivatives with respect to the gyro and accelerometer biases.
    pub dr_dbg: Matrix3<f64>,
    pub dv_dbg: Matrix3<f64>,
    pub dv_dba: Matrix3<f64>,
    pub dp_dbg: Matrix3<f64>,
    pub dp_dba: Matrix3<f64>,
    /// The covariance of `[dphi; dv; dp]` per unit gyro sample variance, and per unit
    /// accelerometer sample variance.
    pub cov_gyro: M9,
    pub cov_accel: M9,
    /// Samples that contributed.
    pub samples: usize,
}

/// Integrates `samples` (sorted by time) over `[a, b]` with the biases `bias`; `None` when the
/// samples do not cover the window or a gap of more than two sample periods lies inside it.
pub fn integrate(
    samples: &[ImuSample],
    a: f64,
    b: f64,
    bias: &ImuBias,
    rate: f64,
) -> Option<Preintegrated> {
    let gap = 2.0 / rate;
    let n = samples.len();
    if n < 2 || b <= a {
        return None;
    }
    // The first sample whose span reaches past `a`.
    let first = samples.partition_point(|s| s.t < a).saturating_sub(1);
    let cover_start = |i: usize| {
        if i == 0 {
            samples[0].t - 0.5 * (samples[1].t - samples[0].t)
        } else {
            0.5 * (samples[i - 1].t + samples[i].t)
        }
    };
    let cover_end = |i: usize| {
        if i + 1 == n {
            samples[i].t + 0.5 * (samples[i].t - samples[i - 1].t)
        } else {
            0.5 * (samples[i].t + samples[i + 1].t)
        }
    };
    if cover_start(first) > a {
        return None;
    }
    let mut p = Preintegrated {
        t0: a,
        dt: b - a,
        bias: *bias,
        rot: Matrix3::identity(),
        vel: Vector3::zeros(),
        pos: Vector3::zeros(),
        dr_dbg: Matrix3::zeros(),
        dv_dbg: Matrix3::zeros(),
        dv_dba: Matrix3::zeros(),
        dp_dbg: Matrix3::zeros(),
        dp_dba: Matrix3::zeros(),
        cov_gyro: M9::zeros(),
        cov_accel: M9::zeros(),
        samples: 0,
    };
    let mut i = first;
    loop {
        if i >= n {
            return None;
        }
        if i > first && samples[i].t - samples[i - 1].t > gap {
            return None;
        }
        let (c0, c1) = (cover_start(i).max(a), cover_end(i).min(b));
        let h = c1 - c0;
        if h > 0.0 {
            let (gyro, accel) = piece_mean(samples, i, c0, c1, gap);
            step(&mut p, &gyro, &accel, h);
        }
        if cover_end(i) >= b {
            break;
        }
        i += 1;
    }
    Some(p)
}

/// The mean over `[c0, c1]` (inside sample `i`'s span) of the parabola through samples `i -
/// 1`, `i` and `i + 1`: over a whole span it is the sample plus a twenty-fourth of the second
/// difference, which removes the midpoint rule's error in the signal's curvature; over a part
/// span at a window's end it is the value at the part's middle, not the sample's (a first-order
/// error at both ends otherwise). The sample alone where a neighbour is missing or beyond a gap.
fn piece_mean(
    samples: &[ImuSample],
    i: usize,
    c0: f64,
    c1: f64,
    gap: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let s = &samples[i];
    if i == 0 || i + 1 >= samples.len() {
        return (s.gyro, s.accel);
    }
    let (l, r) = (&samples[i - 1], &samples[i + 1]);
    let (x0, x1) = (l.t - s.t, r.t - s.t);
    if -x0 > gap || x1 > gap {
        return (s.gyro, s.accel);
    }
    // Times relative to the sample; the mean of (t - x)(t - y) over [a, b].
    let (a, b) = (c0 - s.t, c1 - s.t);
    let mean = |x: f64, y: f64| (b * b + a * b + a * a) / 3.0 - (x + y) * (a + b) / 2.0 + x * y;
    let wl = mean(0.0, x1) / (x0 * (x0 - x1));
    let wc = mean(x0, x1) / (x0 * x1);
    let wr = mean(x0, 0.0) / (x1 * (x1 - x0));
    (
        l.gyro * wl + s.gyro * wc + r.gyro * wr,
        l.accel * wl + s.accel * wc + r.accel * wr,
    )
}

/// One reading (its mean over the step) held over `h` seconds.
fn step(p: &mut Preintegrated, gyro: &Vector3<f64>, accel: &Vector3<f64>, h: f64) {
    let w = gyro - p.bias.gyro;
    let f = accel - p.bias.accel;
    let dr = so3::exp(&(w * h));
    let jr = so3::right_jacobian(&(w * h));
    let rmid = p.rot * so3::exp(&(w * (0.5 * h)));
    let rf = rmid * hat(&f);
    // The error state's transition over the step: dphi' = dR^T dphi, dv' = dv - R hat(f) h
    // dphi, dp' = dp + h dv - R hat(f) h^2 / 2 dphi; the noise enters as J_r h on dphi, R h on
    // dv and R h^2 / 2 on dp.
    let b = -rf * h;
    let jh = jr * h;
    let rh = rmid * h;
    let transition = Transition {
        a: dr.transpose(),
        b,
        c: b * (0.5 * h),
        h,
    };
    transition.propagate(&mut p.cov_gyro);
    add_block(&mut p.cov_gyro, 0, 0, &(jh * jh.transpose()));
    transition.propagate(&mut p.cov_accel);
    let rr = rh * rh.transpose();
    add_block(&mut p.cov_accel, 3, 3, &rr);
    add_block(&mut p.cov_accel, 3, 6, &(rr * (0.5 * h)));
    add_block(&mut p.cov_accel, 6, 3, &(rr * (0.5 * h)));
    add_block(&mut p.cov_accel, 6, 6, &(rr * (0.25 * h * h)));
    // The bias derivatives, from the state before the step.
    p.dp_dba += p.dv_dba * h - rmid * (0.5 * h * h);
    p.dp_dbg += p.dv_dbg * h - rf * p.dr_dbg * (0.5 * h * h);
    p.dv_dba -= rmid * h;
    p.dv_dbg -= rf * p.dr_dbg * h;
    p.dr_dbg = dr.transpose() * p.dr_dbg - jr * h;
    // The increments.
    p.pos += p.vel * h + rmid * f * (0.5 * h * h);
    p.vel += rmid * f * h;
    p.rot = so3::exp(&so3::log(&(p.rot * dr)));
    p.samples += 1;
}

/// A step's transition of the error state `[dphi; dv; dp]`, lower block triangular:
/// `F = [A 0 0; B I 0; C hI I]`.
struct Transition {
    a: Matrix3<f64>,
    b: Matrix3<f64>,
    c: Matrix3<f64>,
    h: f64,
}

impl Transition {
    /// `P <- F P F^T`, on the blocks (about a twentieth of the dense products' work, which made
    /// most of the integration's time).
    fn propagate(&self, p: &mut M9) {
        let blk = |p: &M9, r: usize, c: usize| p.fixed_view::<3, 3>(r, c).into_owned();
        // Y = F P, by block rows.
        let (pr, pv, pp) = (
            p.fixed_view::<3, 9>(0, 0).into_owned(),
            p.fixed_view::<3, 9>(3, 0).into_owned(),
            p.fixed_view::<3, 9>(6, 0).into_owned(),
        );
        let mut y = M9::zeros();
        y.fixed_view_mut::<3, 9>(0, 0).copy_from(&(self.a * pr));
        y.fixed_view_mut::<3, 9>(3, 0)
            .copy_from(&(self.b * pr + pv));
        y.fixed_view_mut::<3, 9>(6, 0)
            .copy_from(&(self.c * pr + pv * self.h + pp));
        // P = Y F^T, by block columns.
        for r in [0, 3, 6] {
            let (yr, yv, yp) = (blk(&y, r, 0), blk(&y, r, 3), blk(&y, r, 6));
            p.fixed_view_mut::<3, 3>(r, 0)
                .copy_from(&(yr * self.a.transpose()));
            p.fixed_view_mut::<3, 3>(r, 3)
                .copy_from(&(yr * self.b.transpose() + yv));
            p.fixed_view_mut::<3, 3>(r, 6)
                .copy_from(&(yr * self.c.transpose() + yv * self.h + yp));
        }
    }
}

/// `m[r.., c..] += x` on a 3 x 3 block.
fn add_block(m: &mut M9, r: usize, c: usize, x: &Matrix3<f64>) {
    let mut v = m.fixed_view_mut::<3, 3>(r, c);
    v += x;
}

/// The windows between consecutive knot times `times` (camera clock) at clock offset `offset0`,
/// window `k` corrected by the biases `bias(k)`: `None` where the samples do not cover a window.
pub fn integrate_windows(
    samples: &[ImuSample],
    times: &[f64],
    offset0: f64,
    bias: impl Fn(usize) -> ImuBias + Sync,
    noise: &ImuNoise,
) -> Vec<Option<Preintegrated>> {
    crate::parallel::map_indices(times.len().saturating_sub(1), 1024, |k| {
        let (a, b) = (times[k] - offset0, times[k + 1] - offset0);
        integrate(samples, a, b, &bias(k), noise.update_rate)
    })
}

/// The biases of window `k` (between knots `k` and `k + 1`): the mean of the two knots'.
pub fn window_bias(st: &ImuState, k: usize) -> ImuBias {
    st.bias.between(k, 0.5)
}

/// The IMU's samples integrated between consecutive knots, each window with its whitening,
/// the IMU's factors in place of the bins.
#[derive(Clone, Debug)]
pub struct Windows {
    /// Per interval between knots: its increments and their [`whitening`], or `None` where the
    /// samples do not cover it (or its covariance is not positive definite).
    pub list: Vec<Option<(Preintegrated, M9)>>,
    /// The clock offset the windows were placed at.
    pub offset0: f64,
    /// The gyro's and the accelerometer's sample variances the windows are weighed by.
    pub var: (f64, f64),
}

impl Windows {
    /// The windows between the knot times `times` (camera clock) at the clock offset and the
    /// biases of `st` (one per knot), weighed by the sample variances `var`.
    pub fn new(
        samples: &[ImuSample],
        times: &[f64],
        st: &ImuState,
        noise: &ImuNoise,
        var: (f64, f64),
    ) -> Windows {
        let list = integrate_windows(
            samples,
            times,
            st.time_offset_s,
            |k| window_bias(st, k),
            noise,
        )
        .into_iter()
        .map(|p| p.and_then(|p| whitening(&p, var).map(|w| (p, w))))
        .collect();
        Windows {
            list,
            offset0: st.time_offset_s,
            var,
        }
    }

    /// The gyro's and the accelerometer's sample variances `noise` states.
    pub fn stated_variances(noise: &ImuNoise) -> (f64, f64) {
        (
            noise.gyro_sample_std().powi(2),
            noise.accel_sample_std().powi(2),
        )
    }

    /// The same windows weighed by the sample variances `var`.
    pub fn reweigh(&mut self, var: (f64, f64)) {
        self.var = var;
        for slot in &mut self.list {
            if let Some((p, w)) = slot {
                match whitening(p, var) {
                    Some(x) => *w = x,
                    None => *slot = None,
                }
            }
        }
    }

    /// The intervals with a window, as `(window, interval, 0)` (the shape of a placed bin).
    pub fn placed(&self) -> Vec<(usize, usize, f64)> {
        (0..self.list.len())
            .filter(|&k| self.list[k].is_some())
            .map(|k| (k, k, 0.0))
            .collect()
    }
}

/// The IMU's attitude, position and velocity in the world at `eps` after knot `k` (camera
/// clock), from the knot's state alone, with what [`end`] derives them from: the extrapolated
/// camera pose, its local step `xi` and twist.
struct ImuAt {
    r: Matrix3<f64>,
    p: Vector3<f64>,
    v: Vector3<f64>,
    pose: Se3,
    xi: Vector6<f64>,
    twist: Vector6<f64>,
}

fn imu_state(k: &Knot, eps: f64, st: &ImuState) -> ImuAt {
    let xi = k.twist * eps + k.rate * (0.5 * eps * eps);
    let pose = k.pose * Se3::exp(&xi);
    let twist = k.twist + k.rate * eps;
    let v = twist.fixed_rows::<3>(0).into_owned();
    let w = twist.fixed_rows::<3>(3).into_owned();
    let p = &st.t_cam_imu.trans;
    ImuAt {
        r: pose.rot * st.t_cam_imu.rot,
        p: pose.trans + pose.rot * p,
        v: pose.rot * (v + w.cross(p)),
        pose,
        xi,
        twist,
    }
}

/// A window's residual at the IMU's states `a` and `b` at its ends, and the parts its
/// Jacobians reuse: the rotation's residual `er`, `y_v = R_a^T (v_b - v_a - g T)`, `y_p = R_a^T
/// (p_b - p_a - v_a T - g T^2 / 2)` and the gyro bias's rotation correction `x`.
struct Misfit {
    e: V9,
    er: Vector3<f64>,
    yv: Vector3<f64>,
    yp: Vector3<f64>,
    x: Vector3<f64>,
}

fn misfit(a: &ImuAt, b: &ImuAt, pre: &Preintegrated, st: &ImuState, bias: &ImuBias) -> Misfit {
    let dbg = bias.gyro - pre.bias.gyro;
    let dba = bias.accel - pre.bias.accel;
    let g = st.gravity_world();
    let t = pre.dt;
    let x = pre.dr_dbg * dbg;
    let rc = pre.rot * so3::exp(&x);
    let er = so3::log(&(rc.transpose() * a.r.transpose() * b.r));
    let rat = a.r.transpose();
    let yv = rat * (b.v - a.v - g * t);
    let yp = rat * (b.p - a.p - a.v * t - g * (0.5 * t * t));
    let mut e = V9::zeros();
    e.fixed_rows_mut::<3>(0).copy_from(&er);
    e.fixed_rows_mut::<3>(3)
        .copy_from(&(yv - (pre.vel + pre.dv_dbg * dbg + pre.dv_dba * dba)));
    e.fixed_rows_mut::<3>(6)
        .copy_from(&(yp - (pre.pos + pre.dp_dbg * dbg + pre.dp_dba * dba)));
    Misfit { e, er, yv, yp, x }
}

/// The residual of window `pre` between knots `k` (`k1`) and `k + 1` (`k2`), unwhitened: the
/// measured increments (corrected to the biases of `st` there) against those of the knots'
/// states.
pub fn residual(
    (k, k1): (usize, &Knot),
    k2: &Knot,
    pre: &Preintegrated,
    offset0: f64,
    st: &ImuState,
) -> V9 {
    let eps = st.time_offset_s - offset0;
    let bias = window_bias(st, k);
    misfit(
        &imu_state(k1, eps, st),
        &imu_state(k2, eps, st),
        pre,
        st,
        &bias,
    )
    .e
}

/// The window's covariance with the gyro's and the accelerometer's sample variances `var`.
pub fn covariance(pre: &Preintegrated, var: (f64, f64)) -> M9 {
    pre.cov_gyro * var.0 + pre.cov_accel * var.1
}

/// A window's whitened residual and Jacobians: `L^-1 e` and `L^-1 J` for `Sigma = L L^T`
/// (lower triangular: the first three rows, the rotation's, depend on the gyro alone).
pub struct WindowTerms {
    pub e: V9,
    pub j1: SMatrix<f64, 9, 18>,
    pub j2: SMatrix<f64, 9, 18>,
    /// On the fixed parameters.
    pub jl: SMatrix<f64, 9, NFIXED>,
    /// On the window's biases (gyro, then accelerometer), the mean of its two knots': each
    /// knot's biases move it by half of this.
    pub jb: SMatrix<f64, 9, 6>,
}

/// The whitening of a window: `L^-1`, or `None` if its covariance is not positive definite.
pub fn whitening(pre: &Preintegrated, var: (f64, f64)) -> Option<M9> {
    let c = Cholesky::new(covariance(pre, var))?;
    c.l().try_inverse()
}

/// One end of a window: the IMU's attitude, position and velocity there and their derivatives
/// (rows `[dphi (right, IMU frame); dp; dv]`) with respect to the knot it is extrapolated from,
/// the clock offset and the extrinsics.
struct End {
    at: ImuAt,
    d_knot: SMatrix<f64, 9, 18>,
    d_eps: SVector<f64, 9>,
    /// On `R_cam_imu` (right) and `p_cam_imu`.
    d_ext: SMatrix<f64, 9, 6>,
}

/// [`imu_state`] with its derivatives. The knot's pose `T` moves as `T Exp(d)`, so the
/// extrapolated pose `T Exp(xi)` moves by `Ad(Exp(-xi)) d`, and by `J_r(xi) d xi` when `xi`
/// does; the IMU's pose `T T_cam_imu` and velocity `R (v + w x p_cam_imu)` follow.
fn end(k: &Knot, eps: f64, st: &ImuState) -> End {
    let at = imu_state(k, eps, st);
    let (xi, tw) = (&at.xi, &at.twist);
    let v = tw.fixed_rows::<3>(0).into_owned();
    let w = tw.fixed_rows::<3>(3).into_owned();
    let (rci, pci) = (&st.t_cam_imu.rot, &st.t_cam_imu.trans);
    let r = at.pose.rot;
    let jr = se3_right_jacobian(xi);
    let mut dpose = SMatrix::<f64, 6, 18>::zeros();
    dpose
        .fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&Se3::exp(&-xi).adjoint());
    dpose.fixed_view_mut::<6, 6>(0, 6).copy_from(&(jr * eps));
    dpose
        .fixed_view_mut::<6, 6>(0, 12)
        .copy_from(&(jr * (0.5 * eps * eps)));
    // The IMU's state against the extrapolated pose's `[rho; phi]` and against its twist.
    let u = v + w.cross(pci);
    let mut m = SMatrix::<f64, 9, 6>::zeros();
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&rci.transpose());
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(&r);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(-r * hat(pci)));
    m.fixed_view_mut::<3, 3>(6, 3).copy_from(&(-r * hat(&u)));
    let mut n = SMatrix::<f64, 9, 6>::zeros();
    n.fixed_view_mut::<3, 3>(6, 0).copy_from(&r);
    n.fixed_view_mut::<3, 3>(6, 3).copy_from(&(-r * hat(pci)));
    let mut d_knot = m * dpose;
    let mut add = d_knot.fixed_view_mut::<9, 6>(0, 6);
    add += n;
    let mut add = d_knot.fixed_view_mut::<9, 6>(0, 12);
    add += n * eps;
    let d_eps = m * (jr * tw) + n * k.rate;
    let mut d_ext = SMatrix::<f64, 9, 6>::zeros();
    d_ext
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    d_ext.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    d_ext.fixed_view_mut::<3, 3>(6, 3).copy_from(&(r * hat(&w)));
    End {
        at,
        d_knot,
        d_eps,
        d_ext,
    }
}

/// The whitened residual and Jacobians of window `pre` between knots `k1` and `k2` (`white`:
/// its [`whitening`]). The residual's derivatives with respect to the ends' states are the
/// usual ones of preintegration: with `y_v = R_a^T (v_b - v_a - g T)` and `y_p = R_a^T (p_b -
/// p_a - v_a T - g T^2 / 2)`, a right turn `d` of `R_a` adds `hat(y) d` to both, and the
/// rotation's residual moves by `J_r^-1(e_R)` times the turn of `R_b` less `R_b^T R_a` that of
/// `R_a`.
pub fn window_terms(
    (k, k1): (usize, &Knot),
    k2: &Knot,
    pre: &Preintegrated,
    offset0: f64,
    st: &ImuState,
    white: &M9,
) -> WindowTerms {
    let eps = st.time_offset_s - offset0;
    let (a, b) = (end(k1, eps, st), end(k2, eps, st));
    let bias = window_bias(st, k);
    let Misfit { e, er, yv, yp, x } = misfit(&a.at, &b.at, pre, st, &bias);
    let t = pre.dt;
    let rat = a.at.r.transpose();
    // The residual against each end's `[dphi; dp; dv]`.
    let jri = so3::right_jacobian_inv(&er);
    let mut ea = M9::zeros();
    let mut eb = M9::zeros();
    ea.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-jri * b.at.r.transpose() * a.at.r));
    eb.fixed_view_mut::<3, 3>(0, 0).copy_from(&jri);
    ea.fixed_view_mut::<3, 3>(3, 0).copy_from(&hat(&yv));
    ea.fixed_view_mut::<3, 3>(3, 6).copy_from(&-rat);
    eb.fixed_view_mut::<3, 3>(3, 6).copy_from(&rat);
    ea.fixed_view_mut::<3, 3>(6, 0).copy_from(&hat(&yp));
    ea.fixed_view_mut::<3, 3>(6, 3).copy_from(&-rat);
    ea.fixed_view_mut::<3, 3>(6, 6).copy_from(&(-rat * t));
    eb.fixed_view_mut::<3, 3>(6, 3).copy_from(&rat);
    let j1 = ea * a.d_knot;
    let j2 = eb * b.d_knot;
    let mut jl = SMatrix::<f64, 9, NFIXED>::zeros();
    jl.fixed_view_mut::<9, 6>(0, 0)
        .copy_from(&(ea * a.d_ext + eb * b.d_ext));
    jl.set_column(6, &(ea * a.d_eps + eb * b.d_eps));
    // Gravity: g = R_g g0 moves by -R_g hat(g0) d.
    let g0 = Vector3::new(0.0, 0.0, -st.gravity_magnitude);
    let dg = -(st.gravity_rotation * hat(&g0));
    let dg2 = dg.fixed_columns::<2>(0);
    jl.fixed_view_mut::<3, 2>(3, 7).copy_from(&(-rat * dg2 * t));
    jl.fixed_view_mut::<3, 2>(6, 7)
        .copy_from(&(-rat * dg2 * (0.5 * t * t)));
    // The window's biases.
    let mut jb = SMatrix::<f64, 9, 6>::zeros();
    jb.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-jri * so3::exp(&er).transpose() * so3::right_jacobian(&x) * pre.dr_dbg));
    jb.fixed_view_mut::<3, 3>(3, 0).copy_from(&-pre.dv_dbg);
    jb.fixed_view_mut::<3, 3>(3, 3).copy_from(&-pre.dv_dba);
    jb.fixed_view_mut::<3, 3>(6, 0).copy_from(&-pre.dp_dbg);
    jb.fixed_view_mut::<3, 3>(6, 3).copy_from(&-pre.dp_dba);
    WindowTerms {
        e: white * e,
        j1: white * j1,
        j2: white * j2,
        jl: white * jl,
        jb: white * jb,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::imu::state::BiasNodes;
    use crate::sim::imu::{ImuSimConfig, simulate_imu};
    use crate::sim::motion::{Motion, SinusoidMotion};

    /// A noiseless IMU on a smooth motion that turns and accelerates throughout, the truth as
    /// the state.
    fn setup() -> (SinusoidMotion, ImuSimConfig, Vec<ImuSample>, ImuState) {
        let motion = SinusoidMotion::lively(20.0).expect("motion");
        let mut cfg = ImuSimConfig::default_truth();
        let noise = cfg.noise;
        cfg.noise.gyroscope_noise_density = 0.0;
        cfg.noise.accelerometer_noise_density = 0.0;
        cfg.noise.gyroscope_random_walk = 0.0;
        cfg.noise.accelerometer_random_walk = 0.0;
        let imu = simulate_imu(&motion, &cfg, 0.0, 20.0, 3).expect("imu");
        cfg.noise = noise;
        let st = ImuState {
            t_cam_imu: cfg.t_cam_imu,
            time_offset_s: cfg.time_offset_s,
            gravity_rotation: ImuState::gravity_rotation_of(&cfg.gravity_world),
            gravity_magnitude: cfg.gravity_world.norm(),
            bias: BiasNodes::spanning(-1.0, 21.0, 10.0, cfg.initial_bias),
            dvl: None,
        };
        (motion, cfg, imu.samples, st)
    }

    fn knot(m: &dyn Motion, t: f64) -> Knot {
        let s = m.state(t);
        Knot {
            pose: s.pose,
            twist: s.twist,
            rate: s.twist_rate,
        }
    }

    fn variances(cfg: &ImuSimConfig) -> (f64, f64) {
        (
            cfg.noise.gyro_sample_std().powi(2),
            cfg.noise.accel_sample_std().powi(2),
        )
    }

    /// The whitened residual of every window at the truth stays far below the noise: the
    /// integration's error (200 Hz, on a motion whose rotation rate has components at 1.7 Hz)
    /// and the ends' extrapolation by a clock offset up to 2 ms from the windows' are a tenth of
    /// a standard deviation at worst, a fortieth in RMS (the plain midpoint rule left 0.2 at
    /// worst, in the rotation).
    #[test]
    fn the_truth_leaves_residuals_far_below_the_noise() {
        let (m, cfg, samples, mut st) = setup();
        let times: Vec<f64> = (1..190).map(|i| 0.1 * i as f64).collect();
        st.bias = st.bias.resampled(&times, st.time_offset_s);
        for shift in [0.0, 0.0005, -0.0005, 0.002] {
            let offset0 = st.time_offset_s + shift;
            let w = integrate_windows(
                &samples,
                &times,
                offset0,
                |k| window_bias(&st, k),
                &cfg.noise,
            );
            let (mut worst, mut sum): (f64, f64) = (0.0, 0.0);
            for (k, p) in w.iter().enumerate() {
                let p = p.as_ref().expect("covered");
                assert!((p.dt - 0.1).abs() < 1e-9);
                assert!((19..=21).contains(&p.samples), "{}", p.samples);
                let white = whitening(p, variances(&cfg)).expect("positive definite");
                let (k1, k2) = (knot(&m, times[k]), knot(&m, times[k + 1]));
                let e = white * residual((k, &k1), &k2, p, offset0, &st);
                worst = worst.max(e.amax());
                sum += e.norm_squared();
            }
            let rms = (sum / (9 * w.len()) as f64).sqrt();
            assert!(
                worst < 0.15,
                "shift {shift}: worst whitened residual {worst}"
            );
            assert!(rms < 0.03, "shift {shift}: rms whitened residual {rms}");
        }
    }

    /// The block form of `F P F^T` is the dense product.
    #[test]
    fn the_block_propagation_is_the_dense_product() {
        let mut rng = crate::rng::Rng::new(5);
        let m3 = |rng: &mut crate::rng::Rng| Matrix3::from_fn(|_, _| rng.normal());
        let h = 0.005;
        let t = Transition {
            a: so3::exp(&rng.normal_vec3()),
            b: m3(&mut rng),
            c: m3(&mut rng),
            h,
        };
        let root = M9::from_fn(|_, _| rng.normal());
        let p0 = root * root.transpose();
        let mut f = M9::identity();
        f.fixed_view_mut::<3, 3>(0, 0).copy_from(&t.a);
        f.fixed_view_mut::<3, 3>(3, 0).copy_from(&t.b);
        f.fixed_view_mut::<3, 3>(6, 0).copy_from(&t.c);
        f.fixed_view_mut::<3, 3>(6, 3)
            .copy_from(&(Matrix3::identity() * h));
        let dense = f * p0 * f.transpose();
        let mut p = p0;
        t.propagate(&mut p);
        assert!(
            (p - dense).amax() < 1e-12 * dense.amax(),
            "{}",
            (p - dense).amax()
        );
    }

    /// The increments' covariance is what noisy samples give: a window of 0.3 s integrated
    /// 2000 times with white noise of the stated std on every sample, the increments' spread
    /// (rotation error on the right, velocity and position errors) against the propagated
    /// covariance, diagonal within 12 % (a variance from 2000 draws has a relative std of 3 %)
    /// and correlations within 0.08.
    #[test]
    fn the_propagated_covariance_is_the_spread_of_noisy_integrations() {
        let (_, cfg, samples, _) = setup();
        let (vg, va) = variances(&cfg);
        let (a, b) = (5.0, 5.3);
        let bias = cfg.initial_bias;
        let rate = cfg.noise.update_rate;
        let clean = integrate(&samples, a, b, &bias, rate).expect("covered");
        let model = clean.cov_gyro * vg + clean.cov_accel * va;
        let mut rng = crate::rng::Rng::new(11);
        let draws = 2000;
        let mut second = M9::zeros();
        let mut noisy = samples.clone();
        for _ in 0..draws {
            for (n, s) in noisy.iter_mut().zip(&samples) {
                n.gyro = s.gyro + rng.normal_vec3() * vg.sqrt();
                n.accel = s.accel + rng.normal_vec3() * va.sqrt();
            }
            let q = integrate(&noisy, a, b, &bias, rate).expect("covered");
            let mut e = V9::zeros();
            e.fixed_rows_mut::<3>(0)
                .copy_from(&so3::log(&(clean.rot.transpose() * q.rot)));
            e.fixed_rows_mut::<3>(3).copy_from(&(q.vel - clean.vel));
            e.fixed_rows_mut::<3>(6).copy_from(&(q.pos - clean.pos));
            second += e * e.transpose();
        }
        let spread = second / draws as f64;
        for i in 0..9 {
            let ratio = spread[(i, i)] / model[(i, i)];
            assert!(
                (ratio - 1.0).abs() < 0.12,
                "variance {i}: spread / model {ratio}"
            );
            for j in 0..i {
                let corr = |m: &M9| m[(i, j)] / (m[(i, i)] * m[(j, j)]).sqrt();
                let (cs, cm) = (corr(&spread), corr(&model));
                assert!(
                    (cs - cm).abs() < 0.08,
                    "correlation {i},{j}: {cs} against {cm}"
                );
            }
        }
    }

    /// The first-order bias correction matches integrating again with the other biases.
    #[test]
    fn the_bias_derivatives_match_integrating_again() {
        let (_, cfg, samples, _) = setup();
        let b0 = cfg.initial_bias;
        let d = ImuBias {
            gyro: Vector3::new(2e-3, -1e-3, 1.5e-3),
            accel: Vector3::new(0.02, 0.03, -0.01),
        };
        let b1 = ImuBias {
            gyro: b0.gyro + d.gyro,
            accel: b0.accel + d.accel,
        };
        let (a, b) = (15.0, 15.1);
        let p0 = integrate(&samples, a, b, &b0, 200.0).expect("covered");
        let p1 = integrate(&samples, a, b, &b1, 200.0).expect("covered");
        let rot = p0.rot * so3::exp(&(p0.dr_dbg * d.gyro));
        let vel = p0.vel + p0.dv_dbg * d.gyro + p0.dv_dba * d.accel;
        let pos = p0.pos + p0.dp_dbg * d.gyro + p0.dp_dba * d.accel;
        // The first order leaves a hundredth of the change or less.
        let dr = so3::log(&(p0.rot.transpose() * p1.rot)).norm();
        assert!(so3::log(&(rot.transpose() * p1.rot)).norm() < 0.01 * dr);
        assert!((vel - p1.vel).norm() < 0.01 * (p0.vel - p1.vel).norm());
        assert!((pos - p1.pos).norm() < 0.01 * (p0.pos - p1.pos).norm());
    }

    /// A window the samples do not cover, or one with a gap inside, is refused.
    #[test]
    fn uncovered_windows_and_gaps_are_refused() {
        let (_, _, mut samples, _) = setup();
        let b = ImuBias::default();
        let (first, last) = (samples[0].t, samples[samples.len() - 1].t);
        assert!(integrate(&samples, last - 0.05, last + 0.05, &b, 200.0).is_none());
        assert!(integrate(&samples, first - 0.05, first + 0.05, &b, 200.0).is_none());
        let i = samples.partition_point(|s| s.t < 10.0);
        samples.drain(i..i + 3);
        assert!(integrate(&samples, 9.95, 10.05, &b, 200.0).is_none());
        assert!(integrate(&samples, 10.2, 10.3, &b, 200.0).is_some());
    }

    /// The residual moved along one column's direction, by central differences.
    fn numeric_column(
        k1: &Knot,
        k2: &Knot,
        pre: &Preintegrated,
        off0: f64,
        st: &ImuState,
        c: usize,
    ) -> V9 {
        let h = 1e-6;
        let at = |s: f64| {
            let (mut a, mut b, mut x) = (*k1, *k2, st.clone());
            let knot = |k: &mut Knot, c: usize| match c {
                0..6 => {
                    let mut xi = nalgebra::Vector6::zeros();
                    xi[c] = s;
                    k.pose = k.pose * Se3::exp(&xi);
                }
                6..12 => k.twist[c - 6] += s,
                _ => k.rate[c - 12] += s,
            };
            match c {
                0..18 => knot(&mut a, c),
                18..36 => knot(&mut b, c - 18),
                36..45 => {
                    let mut d = nalgebra::DVector::zeros(st.dim());
                    d[c - 36] = s;
                    x = x.retract(&d);
                }
                _ => {
                    // The two knots' biases, gyro then accelerometer.
                    let (i, r) = ((c - 45) / 6, (c - 45) % 6);
                    let b = &mut x.bias.values[i];
                    if r < 3 {
                        b.gyro[r] += s;
                    } else {
                        b.accel[r - 3] += s;
                    }
                }
            }
            residual((0, &a), &b, pre, off0, &x)
        };
        (at(h) - at(-h)) / (2.0 * h)
    }

    /// The analytic Jacobians against central differences of the residual, away from the
    /// truth (a clock offset 3 ms from the windows', biases off the window's, a turned
    /// extrinsic) so that no term hides behind a zero residual.
    #[test]
    fn the_analytic_jacobians_match_differences_of_the_residual() {
        let (m, cfg, samples, mut st) = setup();
        let off0 = st.time_offset_s - 0.003;
        st.bias = st.bias.resampled(&[7.2, 7.3], st.time_offset_s);
        let w = integrate_windows(
            &samples,
            &[7.2, 7.3],
            off0,
            |k| window_bias(&st, k),
            &cfg.noise,
        );
        let pre = w[0].as_ref().expect("covered");
        st.bias.values[0].gyro += Vector3::new(3e-3, -2e-3, 1e-3);
        st.bias.values[1].accel += Vector3::new(0.05, -0.02, 0.03);
        st.t_cam_imu = st.t_cam_imu.retract(&nalgebra::Vector6::new(
            0.01, -0.02, 0.03, 0.02, 0.01, -0.03,
        ));
        st.gravity_rotation *= so3::exp(&Vector3::new(0.01, -0.02, 0.0));
        let (k1, k2) = (knot(&m, 7.2), knot(&m, 7.3));
        let t = window_terms((0, &k1), &k2, pre, off0, &st, &M9::identity());
        let e = residual((0, &k1), &k2, pre, off0, &st);
        assert!((t.e - e).norm() < 1e-12);
        assert!(e.norm() > 1e-3, "{}", e.norm());
        // Both knots' biases: columns 45..51 and 51..57.
        for c in 0..36 + NFIXED + 12 {
            let num = numeric_column(&k1, &k2, pre, off0, &st, c);
            let ana: V9 = match c {
                0..18 => t.j1.column(c).into_owned(),
                18..36 => t.j2.column(c - 18).into_owned(),
                _ if c - 36 < NFIXED => t.jl.column(c - 36).into_owned(),
                _ => t.jb.column((c - 45) % 6) * 0.5,
            };
            let scale = 1.0 + num.amax();
            assert!(
                (ana - num).amax() < 1e-6 * scale,
                "column {c}: {ana} vs {num}"
            );
        }
    }
}
