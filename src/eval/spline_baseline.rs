//! An independent reference estimator: smoothing splines through the poses, least squares for the
//! calibration.
//!
//! It shares nothing with [`crate::calib`] or [`crate::trajectory`] (no Gaussian process, no
//! closed form, no joint refinement), so that agreement between the two is evidence and a
//! difference points at one of them:
//! 1. the poses are cut into stretches at gaps; in each, every position coordinate and every
//!    (sign-aligned) quaternion component gets a cubic smoothing spline, its smoothing weight chosen
//!    by the unbiased risk estimate (Mallows' C_p) from the stated pose noise;
//! 2. the body twist at any time follows from the splines and their derivatives:
//!    `v = R^T p'`, `w = 2 vec(conj(q) q') / |q|^2`;
//! 3. for a clock offset, the rotation, lever arm and scale minimise the squared DVL residuals
//!    `y - kappa R_dvl_cam (v + w x p)` by alternating an exact linear solve (scale and scaled lever
//!    arm) with an orthogonal Procrustes step (rotation); the offset minimises the resulting cost,
//!    by a grid scan and golden-section refinement.
//!
//! Smoothing splines: Green and Silverman's formulation (second derivatives at the interior knots
//! from a pentadiagonal system); the trace of the smoother, which C_p needs, from the band of the
//! inverse of that system (the Hutchinson-de Hoog recursion).

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4, Vector6};

use crate::error::{Error, Result};
use crate::lie::so3;
use crate::types::{CalibrationParams, DvlSample, PoseMeasurement};

/// Settings of [`spline_baseline`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaselineOptions {
    /// Standard deviation of each pose position coordinate, m.
    pub pose_sigma_pos_m: f64,
    /// Standard deviation of each pose rotation component, rad.
    pub pose_sigma_rot_rad: f64,
    /// Clock offsets searched, `t_cam = t_dvl + offset`, seconds.
    pub offset_range_s: (f64, f64),
    /// A step between poses longer than this starts a new stretch, seconds.
    pub max_gap_s: f64,
    /// DVL reports closer than this to a stretch's ends are not used (spline ends are poor),
    /// seconds.
    pub end_margin_s: f64,
}

impl Default for BaselineOptions {
    fn default() -> Self {
        BaselineOptions {
            pose_sigma_pos_m: 0.002,
            pose_sigma_rot_rad: 0.1f64.to_radians(),
            offset_range_s: (-1.0, 1.0),
            max_gap_s: 0.5,
            end_margin_s: 0.2,
        }
    }
}

/// The reference estimate.
#[derive(Clone, Debug)]
pub struct BaselineEstimate {
    /// The calibration.
    pub params: CalibrationParams,
    /// DVL reports used at the chosen offset.
    pub dvl_used: usize,
    /// Pose stretches with splines.
    pub stretches: usize,
    /// RMS DVL residual per axis at the estimate, m/s.
    pub rms_residual_mps: f64,
}

/// A cubic smoothing spline: values and second derivatives at the knots.
#[derive(Clone, Debug)]
pub struct SmoothingSpline {
    x: Vec<f64>,
    g: Vec<f64>,
    /// Second derivatives at the knots (zero at the two ends).
    gamma: Vec<f64>,
}

/// Symmetric pentadiagonal matrix by its three diagonals (`d0[i] = A[i][i]`,
/// `d1[i] = A[i][i+1]`, `d2[i] = A[i][i+2]`), factorised as `L D L^T`.
struct Penta {
    d: Vec<f64>,
    l1: Vec<f64>,
    l2: Vec<f64>,
}

impl Penta {
    fn factor(d0: &[f64], d1: &[f64], d2: &[f64]) -> Option<Penta> {
        let m = d0.len();
        let mut d = vec![0.0; m];
        let mut l1 = vec![0.0; m];
        let mut l2 = vec![0.0; m];
        for i in 0..m {
            // A[i][i] = d_i + l1_{i-1}^2 d_{i-1} + l2_{i-2}^2 d_{i-2}
            let mut di = d0[i];
            if i >= 1 {
                di -= l1[i - 1] * l1[i - 1] * d[i - 1];
            }
            if i >= 2 {
                di -= l2[i - 2] * l2[i - 2] * d[i - 2];
            }
            if !(di.is_finite() && di > 0.0) {
                return None;
            }
            d[i] = di;
            // A[i+1][i] = l1_i d_i + l2_{i-1} l1_{i-1} d_{i-1}
            if i + 1 < m {
                let mut a = d1[i];
                if i >= 1 {
                    a -= l2[i - 1] * l1[i - 1] * d[i - 1];
                }
                l1[i] = a / di;
            }
            if i + 2 < m {
                l2[i] = d2[i] / di;
            }
        }
        Some(Penta { d, l1, l2 })
    }

    fn solve(&self, b: &[f64]) -> Vec<f64> {
        let m = b.len();
        let mut z = b.to_vec();
        for i in 0..m {
            if i >= 1 {
                z[i] -= self.l1[i - 1] * z[i - 1];
            }
            if i >= 2 {
                z[i] -= self.l2[i - 2] * z[i - 2];
            }
        }
        for (zi, di) in z.iter_mut().zip(&self.d) {
            *zi /= di;
        }
        for i in (0..m).rev() {
            if i + 1 < m {
                z[i] -= self.l1[i] * z[i + 1];
            }
            if i + 2 < m {
                z[i] -= self.l2[i] * z[i + 2];
            }
        }
        z
    }

    /// The three diagonals of the inverse (the rest of it is not needed).
    fn inverse_band(&self) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let m = self.d.len();
        let (mut s0, mut s1, mut s2) = (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
        let get = |s0: &[f64], s1: &[f64], s2: &[f64], a: usize, b: usize| -> f64 {
            let (i, j) = if a <= b { (a, b) } else { (b, a) };
            match j - i {
                0 => s0[i],
                1 => s1[i],
                _ => s2[i],
            }
        };
        for i in (0..m).rev() {
            let lk = |k: usize| -> f64 {
                match k - i {
                    1 => self.l1[i],
                    _ => self.l2[i],
                }
            };
            let ks: Vec<usize> = (i + 1..(i + 3).min(m)).collect();
            for j in ks.iter().rev() {
                let v: f64 = ks.iter().map(|&k| -lk(k) * get(&s0, &s1, &s2, k, *j)).sum();
                if *j == i + 1 {
                    s1[i] = v;
                } else {
                    s2[i] = v;
                }
            }
            let mut v = 1.0 / self.d[i];
            for &k in &ks {
                v -= lk(k) * get(&s0, &s1, &s2, i, k);
            }
            s0[i] = v;
        }
        (s0, s1, s2)
    }
}

impl SmoothingSpline {
    /// Fits `y(x)` (x strictly increasing, at least 4 knots) with the smoothing weight that
    /// minimises the unbiased risk estimate for noise of standard deviation `sigma`.
    pub fn fit(x: &[f64], y: &[f64], sigma: f64) -> Result<SmoothingSpline> {
        let n = x.len();
        if n < 4 || y.len() != n {
            return Err(Error::Input(format!(
                "a smoothing spline needs at least 4 knots and one value per knot (got {n} and {})",
                y.len()
            )));
        }
        let increasing = x.windows(2).all(|w| w[1] > w[0]);
        if !increasing || sigma.is_nan() || sigma <= 0.0 {
            return Err(Error::Input(
                "smoothing spline: knots must increase strictly and sigma be positive".into(),
            ));
        }
        let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
        let m = n - 2;
        // Q (n x m), column j: rows j, j+1, j+2.
        let q: Vec<[f64; 3]> = (0..m)
            .map(|j| [1.0 / h[j], -1.0 / h[j] - 1.0 / h[j + 1], 1.0 / h[j + 1]])
            .collect();
        let qty: Vec<f64> = (0..m)
            .map(|j| q[j][0] * y[j] + q[j][1] * y[j + 1] + q[j][2] * y[j + 2])
            .collect();
        // Q^T Q diagonals.
        let qq0: Vec<f64> = q
            .iter()
            .map(|c| c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
            .collect();
        let qq1: Vec<f64> = (0..m)
            .map(|j| {
                if j + 1 < m {
                    q[j][1] * q[j + 1][0] + q[j][2] * q[j + 1][1]
                } else {
                    0.0
                }
            })
            .collect();
        let qq2: Vec<f64> = (0..m)
            .map(|j| {
                if j + 2 < m {
                    q[j][2] * q[j + 2][0]
                } else {
                    0.0
                }
            })
            .collect();
        let r0: Vec<f64> = (0..m).map(|j| (h[j] + h[j + 1]) / 3.0).collect();
        let r1: Vec<f64> = (0..m).map(|j| h[j + 1] / 6.0).collect();

        // Fit for one smoothing weight: (spline values, gamma, risk estimate).
        let solve = |lambda: f64| -> Option<(Vec<f64>, Vec<f64>, f64)> {
            let d0: Vec<f64> = (0..m).map(|j| r0[j] + lambda * qq0[j]).collect();
            let d1: Vec<f64> = (0..m).map(|j| r1[j] + lambda * qq1[j]).collect();
            let d2: Vec<f64> = (0..m).map(|j| lambda * qq2[j]).collect();
            let f = Penta::factor(&d0, &d1, &d2)?;
            let gam = f.solve(&qty);
            let mut g = y.to_vec();
            for j in 0..m {
                for (r, c) in q[j].iter().enumerate() {
                    g[j + r] -= lambda * c * gam[j];
                }
            }
            let rss: f64 = g.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum();
            // trace(H) = n - lambda trace(Q A^-1 Q^T) = n - lambda sum (A^-1 . Q^T Q).
            let (s0, s1, s2) = f.inverse_band();
            let mut tr = 0.0;
            for j in 0..m {
                tr += s0[j] * qq0[j] + 2.0 * s1[j] * qq1[j] + 2.0 * s2[j] * qq2[j];
            }
            let edf = n as f64 - lambda * tr;
            let risk = rss + 2.0 * sigma * sigma * edf;
            let mut gamma = vec![0.0; n];
            gamma[1..n - 1].copy_from_slice(&gam);
            Some((g, gamma, risk))
        };
        // Scan log(lambda) over a wide range scaled to the knot spacing, then refine.
        let hmean = (x[n - 1] - x[0]) / (n - 1) as f64;
        let base = hmean.powi(3);
        let mut best: Option<(f64, f64)> = None;
        let grid: Vec<f64> = (0..=60).map(|k| -6.0 + 0.25 * k as f64).collect();
        for &e in &grid {
            if let Some((_, _, risk)) = solve(base * 10f64.powf(e)) {
                if best.is_none_or(|(_, r)| risk < r) {
                    best = Some((e, risk));
                }
            }
        }
        let (lo, hi) = match best {
            Some((e, _)) => (e - 0.25, e + 0.25),
            None => {
                return Err(Error::Input(
                    "smoothing spline: no smoothing weight gives a solvable system".into(),
                ));
            }
        };
        let risk_at = |e: f64| solve(base * 10f64.powf(e)).map_or(f64::INFINITY, |s| s.2);
        let e = golden_section(risk_at, lo, hi, 30);
        let (g, gamma, _) = solve(base * 10f64.powf(e)).ok_or_else(|| {
            Error::Input("smoothing spline: the chosen smoothing weight is not solvable".into())
        })?;
        Ok(SmoothingSpline {
            x: x.to_vec(),
            g,
            gamma,
        })
    }

    /// Value and first derivative at `t` (inside the knots; clamped to the end intervals).
    pub fn eval(&self, t: f64) -> (f64, f64) {
        let n = self.x.len();
        let i = match self.x.partition_point(|&v| v <= t) {
            0 => 0,
            k if k >= n => n - 2,
            k => k - 1,
        };
        let h = self.x[i + 1] - self.x[i];
        let a = t - self.x[i];
        let b = self.x[i + 1] - t;
        let (g0, g1, c0, c1) = (self.g[i], self.g[i + 1], self.gamma[i], self.gamma[i + 1]);
        let value = (b * g0 + a * g1) / h
            + ((b * b * b - h * h * b) * c0 + (a * a * a - h * h * a) * c1) / (6.0 * h);
        let slope =
            (g1 - g0) / h + (-(3.0 * b * b - h * h) * c0 + (3.0 * a * a - h * h) * c1) / (6.0 * h);
        (value, slope)
    }
}

/// The minimiser of `f` on `[lo, hi]` by `iterations` golden-section steps (the middle of the
/// last bracket).
fn golden_section(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64, iterations: usize) -> f64 {
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..iterations {
        let a = hi - phi * (hi - lo);
        let b = lo + phi * (hi - lo);
        if f(a) < f(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    0.5 * (lo + hi)
}

/// Splines of one stretch of poses.
struct Stretch {
    t0: f64,
    t1: f64,
    pos: [SmoothingSpline; 3],
    quat: [SmoothingSpline; 4],
}

impl Stretch {
    /// Body twist `[v; w]` at `t`.
    fn twist(&self, t: f64) -> Vector6<f64> {
        let mut p_dot = Vector3::zeros();
        for k in 0..3 {
            p_dot[k] = self.pos[k].eval(t).1;
        }
        let mut q = [0.0; 4];
        let mut qd = [0.0; 4];
        for k in 0..4 {
            let (v, d) = self.quat[k].eval(t);
            q[k] = v;
            qd[k] = d;
        }
        let r = so3::matrix_from_quaternion(&q);
        let v = r.transpose() * p_dot;
        let qv = Vector3::new(q[0], q[1], q[2]);
        let qdv = Vector3::new(qd[0], qd[1], qd[2]);
        let n2 = q.iter().map(|c| c * c).sum::<f64>();
        let w = (qdv * q[3] - qv * qd[3] - qv.cross(&qdv)) * (2.0 / n2);
        Vector6::new(v[0], v[1], v[2], w[0], w[1], w[2])
    }
}

/// Twists of a pose track from smoothing splines, stretch by stretch.
pub struct SplineTrack {
    stretches: Vec<Stretch>,
    margin: f64,
}

impl SplineTrack {
    /// Fits the splines of every stretch of at least 6 poses (`opts.max_gap_s` separates them).
    pub fn fit(poses: &[PoseMeasurement], opts: &BaselineOptions) -> Result<SplineTrack> {
        let mut stretches = Vec::new();
        let mut start = 0;
        for k in 1..=poses.len() {
            if k == poses.len() || poses[k].t - poses[k - 1].t > opts.max_gap_s {
                if k - start >= 6 {
                    stretches.push(fit_stretch(&poses[start..k], opts)?);
                }
                start = k;
            }
        }
        if stretches.is_empty() {
            return Err(Error::Input(
                "spline baseline: no stretch of at least 6 poses without a gap".into(),
            ));
        }
        Ok(SplineTrack {
            stretches,
            margin: opts.end_margin_s,
        })
    }

    /// The body twist at `t`, when `t` is inside a stretch (away from its ends by the margin).
    pub fn twist(&self, t: f64) -> Option<Vector6<f64>> {
        let i = self.stretches.partition_point(|s| s.t1 < t);
        let s = self.stretches.get(i)?;
        (t >= s.t0 + self.margin && t <= s.t1 - self.margin).then(|| s.twist(t))
    }
}

fn fit_stretch(poses: &[PoseMeasurement], opts: &BaselineOptions) -> Result<Stretch> {
    let t: Vec<f64> = poses.iter().map(|p| p.t).collect();
    let fit = |vals: Vec<f64>, sigma: f64| SmoothingSpline::fit(&t, &vals, sigma);
    let pos = [
        fit(
            poses.iter().map(|p| p.pose.trans[0]).collect(),
            opts.pose_sigma_pos_m,
        )?,
        fit(
            poses.iter().map(|p| p.pose.trans[1]).collect(),
            opts.pose_sigma_pos_m,
        )?,
        fit(
            poses.iter().map(|p| p.pose.trans[2]).collect(),
            opts.pose_sigma_pos_m,
        )?,
    ];
    let mut quats: Vec<[f64; 4]> = Vec::with_capacity(poses.len());
    for p in poses {
        let mut q = p.pose.quaternion_xyzw();
        if let Some(prev) = quats.last() {
            let dot: f64 = q.iter().zip(prev).map(|(a, b)| a * b).sum();
            if dot < 0.0 {
                q.iter_mut().for_each(|c| *c = -*c);
            }
        }
        quats.push(q);
    }
    let sq = 0.5 * opts.pose_sigma_rot_rad;
    let quat = [
        fit(quats.iter().map(|q| q[0]).collect(), sq)?,
        fit(quats.iter().map(|q| q[1]).collect(), sq)?,
        fit(quats.iter().map(|q| q[2]).collect(), sq)?,
        fit(quats.iter().map(|q| q[3]).collect(), sq)?,
    ];
    Ok(Stretch {
        t0: t[0],
        t1: t[t.len() - 1],
        pos,
        quat,
    })
}

/// Rotation, lever arm and scale for fixed twists: `(R_dvl_cam, p, kappa, sum of squares)`.
fn fit_fixed_offset(
    rows: &[(Vector3<f64>, Vector6<f64>)],
) -> Option<(Matrix3<f64>, Vector3<f64>, f64, f64)> {
    if rows.len() < 8 {
        return None;
    }
    let procrustes = |h: Matrix3<f64>| -> Option<Matrix3<f64>> {
        // R_cam_dvl maximising trace(R^T H), H = sum u y^T.
        let svd = h.svd(true, true);
        let (u, vt) = (svd.u?, svd.v_t?);
        let mut d = Matrix3::identity();
        d[(2, 2)] = (u * vt).determinant().signum();
        Some(u * d * vt)
    };
    let twist_parts = |t: &Vector6<f64>| {
        (
            t.fixed_rows::<3>(0).into_owned(),
            t.fixed_rows::<3>(3).into_owned(),
        )
    };
    let cost = |r: &Matrix3<f64>, p: &Vector3<f64>, kappa: f64| -> f64 {
        rows.iter()
            .map(|(y, t)| {
                let (v, w) = twist_parts(t);
                (y - r.transpose() * (v + w.cross(p)) * kappa).norm_squared()
            })
            .sum()
    };
    let mut h = Matrix3::zeros();
    for (y, t) in rows {
        h += twist_parts(t).0 * y.transpose();
    }
    let mut r = procrustes(h)?;
    let mut p = Vector3::zeros();
    let mut kappa = 1.0;
    let mut last = f64::INFINITY;
    for _ in 0..500 {
        // R y = kappa v + [w]x (kappa p): linear in (kappa, kappa p).
        let mut ata = Matrix4::zeros();
        let mut atb = Vector4::zeros();
        for (y, t) in rows {
            let (v, w) = twist_parts(t);
            let z = r * y;
            let wx = crate::lie::hat(&w);
            for i in 0..3 {
                let a = Vector4::new(v[i], wx[(i, 0)], wx[(i, 1)], wx[(i, 2)]);
                ata += a * a.transpose();
                atb += a * z[i];
            }
        }
        let x = ata.cholesky()?.solve(&atb);
        kappa = x[0];
        if !(kappa.is_finite() && kappa > 0.0) {
            return None;
        }
        p = Vector3::new(x[1], x[2], x[3]) / kappa;
        let mut h = Matrix3::zeros();
        for (y, t) in rows {
            let (v, w) = twist_parts(t);
            h += (v + w.cross(&p)) * y.transpose();
        }
        r = procrustes(h)?;
        let c = cost(&r, &p, kappa);
        if (last - c).abs() <= 1e-13 * c.max(1e-300) {
            last = c;
            break;
        }
        last = c;
    }
    Some((r.transpose(), p, kappa, last))
}

/// The reference estimate from `poses` and the valid reports of `dvl`.
pub fn spline_baseline(
    poses: &[PoseMeasurement],
    dvl: &[DvlSample],
    opts: &BaselineOptions,
) -> Result<BaselineEstimate> {
    let track = SplineTrack::fit(poses, opts)?;
    let valid: Vec<&DvlSample> = dvl.iter().filter(|s| s.valid).collect();
    let rows_at = |offset: f64| -> Vec<(Vector3<f64>, Vector6<f64>)> {
        valid
            .iter()
            .filter_map(|s| track.twist(s.t + offset).map(|tw| (s.v, tw)))
            .collect()
    };
    // Mean squared residual per used report (the number of reports changes with the offset).
    let score = |offset: f64| -> f64 {
        let rows = rows_at(offset);
        fit_fixed_offset(&rows).map_or(f64::INFINITY, |f| f.3 / rows.len() as f64)
    };
    let (a, b) = opts.offset_range_s;
    if !(a.is_finite() && b.is_finite() && b > a) {
        return Err(Error::Input(format!(
            "spline baseline: offset range ({a}, {b}) is empty"
        )));
    }
    let step = 0.01;
    let steps = ((b - a) / step).ceil() as usize;
    let mut best = (a, f64::INFINITY);
    for k in 0..=steps {
        let o = (a + k as f64 * step).min(b);
        let s = score(o);
        if s < best.1 {
            best = (o, s);
        }
    }
    if !best.1.is_finite() {
        return Err(Error::Input(
            "spline baseline: too few DVL reports inside the pose stretches".into(),
        ));
    }
    let offset = golden_section(score, (best.0 - step).max(a), (best.0 + step).min(b), 40);
    let rows = rows_at(offset);
    let (r_dvl_cam, p, kappa, ss) = fit_fixed_offset(&rows).ok_or_else(|| {
        Error::Input("spline baseline: the least-squares fit failed at the best offset".into())
    })?;
    Ok(BaselineEstimate {
        params: CalibrationParams::from_r_dvl_cam(r_dvl_cam, p, kappa, offset),
        dvl_used: rows.len(),
        stretches: track.stretches.len(),
        rms_residual_mps: (ss / (3 * rows.len()) as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smoothing_spline_reproduces_a_line_and_smooths_noise() {
        let x: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = x.iter().map(|t| 2.0 * t - 1.0).collect();
        let s = SmoothingSpline::fit(&x, &y, 0.01).expect("fit");
        for t in [0.05, 1.0, 3.33, 4.85] {
            let (v, d) = s.eval(t);
            assert!((v - (2.0 * t - 1.0)).abs() < 1e-9 && (d - 2.0).abs() < 1e-8);
        }
        // A sine with noise: the slope error is a fraction of a finite difference's
        // (sqrt(2) 0.002 / 0.1 = 0.028).
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * 3f64.sqrt() * 0.002
        };
        let x: Vec<f64> = (0..300).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = x.iter().map(|t| (0.7 * t).sin() + noise()).collect();
        let s = SmoothingSpline::fit(&x, &y, 0.002).expect("fit");
        let mut e2 = 0.0;
        for k in 20..280 {
            let t = k as f64 * 0.1 + 0.05;
            e2 += (s.eval(t).1 - 0.7 * (0.7 * t).cos()).powi(2);
        }
        let rms = (e2 / 260.0).sqrt();
        assert!(rms < 0.25 * 0.028, "slope RMS error {rms}");
    }

    #[test]
    fn inverse_band_matches_a_dense_inverse() {
        let d0 = [4.0, 5.0, 6.0, 5.5, 4.5, 7.0];
        let d1 = [1.0, -0.5, 0.8, 0.3, -1.1, 0.0];
        let d2 = [0.4, 0.2, -0.3, 0.6, 0.0, 0.0];
        let m = 6;
        let mut a = nalgebra::DMatrix::<f64>::zeros(m, m);
        for i in 0..m {
            a[(i, i)] = d0[i];
            if i + 1 < m {
                a[(i, i + 1)] = d1[i];
                a[(i + 1, i)] = d1[i];
            }
            if i + 2 < m {
                a[(i, i + 2)] = d2[i];
                a[(i + 2, i)] = d2[i];
            }
        }
        let inv = a.clone().try_inverse().expect("invertible");
        let f = Penta::factor(&d0, &d1, &d2).expect("positive definite");
        let (s0, s1, s2) = f.inverse_band();
        for i in 0..m {
            assert!((s0[i] - inv[(i, i)]).abs() < 1e-12);
            if i + 1 < m {
                assert!((s1[i] - inv[(i, i + 1)]).abs() < 1e-12);
            }
            if i + 2 < m {
                assert!((s2[i] - inv[(i, i + 2)]).abs() < 1e-12);
            }
        }
        let b = [1.0, 2.0, -1.0, 0.5, 3.0, -2.0];
        let x = f.solve(&b);
        let r = &a * nalgebra::DVector::from_column_slice(&x)
            - nalgebra::DVector::from_column_slice(&b);
        assert!(r.norm() < 1e-12);
    }
}
