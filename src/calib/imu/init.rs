//! A first estimate of the IMU's calibration from the camera trajectory alone, for the joint
//! refinement to start from:
//!
//! 1. the clock offset that best aligns the gyro's rate magnitude with the trajectory's
//!    (magnitudes do not depend on the unknown rotation);
//! 2. the rotation and the gyro bias from the rates so aligned (the rotation that best maps the
//!    camera's rates onto the gyro's, both centred: Kabsch's solution);
//! 3. the lever arm, gravity and the accelerometer bias from the specific forces, which are
//!    linear in them once the rotation is known (gravity then scaled to its magnitude and the
//!    other two solved again).

use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, SVector, Vector3};
use rayon::prelude::*;

use super::bins::ImuBin;
use super::state::{BiasNodes, ImuState};
use crate::calib::correlate::Correlator;
use crate::error::{Error, Result};
use crate::lie::{Se3, hat};
use crate::trajectory::Trajectory;
use crate::types::imu::ImuBias;

/// The most bins the first rotation, lever arm, gravity and biases are fitted to, spread evenly
/// over the overlap: ten minutes of 50 Hz bins. They only start the joint problem, which
/// refines them on every sample; more bins cost time (an hour's 180,000 trajectory states
/// took 0.2 s) and not convergence.
const MAX_FIRST_BINS: usize = 30_000;

/// The first estimate, and the other clock offsets that align the rates about as well (a
/// motion that repeats; empty when the offset is unique): [`ImuEstimate::offset_alternatives_s`].
///
/// [`ImuEstimate::offset_alternatives_s`]: super::ImuEstimate::offset_alternatives_s
pub struct FirstEstimate {
    pub state: ImuState,
    pub offset_alternatives_s: Vec<f64>,
}

/// The first estimate; `spacing` its bias nodes' spacing (on the IMU's clock), `max_offset` the largest clock offset
/// searched (s), `gravity` its magnitude.
pub fn initial_state(
    traj: &Trajectory,
    bins: &[ImuBin],
    spacing: f64,
    max_offset: f64,
    gravity: f64,
) -> Result<FirstEstimate> {
    let Lag {
        offset,
        others: offset_alternatives_s,
    } = search_offset(traj, bins, max_offset)?;
    // Pairs of camera and gyro rates, camera state at each bin (every `every`-th of those the
    // trajectory spans).
    let (a, z) = traj.span();
    let inside: Vec<&ImuBin> = bins
        .iter()
        .filter(|b| (a..=z).contains(&(b.t + offset)))
        .collect();
    if inside.len() < 20 {
        return Err(Error::Input(format!(
            "only {} IMU bins overlap the camera trajectory at the clock offset found ({offset:.3} s)",
            inside.len()
        )));
    }
    let every = inside.len().div_ceil(MAX_FIRST_BINS).max(1);
    let states: Vec<_> = inside
        .par_iter()
        .step_by(every)
        .filter_map(|b| traj.state(b.t + offset).ok().map(|s| (*b, s)))
        .collect();
    if states.len() < 20 {
        return Err(Error::Numerical(format!(
            "the camera trajectory could not be evaluated at the IMU's times (clock offset \
             {offset:.3} s)"
        )));
    }
    let n = states.len() as f64;
    let w_cam = |s: &crate::trajectory::TrajectoryState| -> Vector3<f64> {
        s.twist.fixed_rows::<3>(3).into_owned()
    };
    let mean_c: Vector3<f64> = states.iter().map(|(_, s)| w_cam(s)).sum::<Vector3<f64>>() / n;
    let mean_i: Vector3<f64> = states.iter().map(|(b, _)| b.gyro).sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (b, s) in &states {
        h += (w_cam(s) - mean_c) * (b.gyro - mean_i).transpose();
    }
    // Q = R_imu_cam minimises sum |w_imu - Q w_cam|^2 over the centred rates.
    let svd = h.svd(true, true);
    let (u, vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Err(Error::Numerical("IMU initial rotation: SVD failed".into())),
    };
    let v = vt.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let q = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let gyro_bias = mean_i - q * mean_c;

    // Specific force: Q^T f - a0 = A p - R_wc^T g + Q^T b_a, with A = hat(w') + hat(w)^2.
    // With gravity given, its three columns are left zero and only the first six solved.
    let solve = |g_fixed: Option<Vector3<f64>>| -> Option<DVector<f64>> {
        let cols = if g_fixed.is_some() { 6 } else { 9 };
        let mut ata = SMatrix::<f64, 9, 9>::zeros();
        let mut atb = SVector::<f64, 9>::zeros();
        for (b, s) in &states {
            let v: Vector3<f64> = s.twist.fixed_rows::<3>(0).into_owned();
            let w = w_cam(s);
            let dv: Vector3<f64> = s.rate.fixed_rows::<3>(0).into_owned();
            let dw: Vector3<f64> = s.rate.fixed_rows::<3>(3).into_owned();
            let mut rhs = q.transpose() * b.accel - (dv + w.cross(&v));
            let mut a = SMatrix::<f64, 3, 9>::zeros();
            a.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&(hat(&dw) + hat(&w) * hat(&w)));
            a.fixed_view_mut::<3, 3>(0, 3)
                .copy_from(&Matrix3::identity());
            match g_fixed {
                Some(g) => rhs += s.pose.rot.transpose() * g,
                None => a
                    .fixed_view_mut::<3, 3>(0, 6)
                    .copy_from(&-s.pose.rot.transpose()),
            }
            ata += a.tr_mul(&a);
            atb += a.tr_mul(&rhs);
        }
        let ata = DMatrix::from_fn(cols, cols, |r, c| ata[(r, c)]);
        let atb = DVector::from_fn(cols, |r, _| atb[r]);
        ata.cholesky().map(|c| c.solve(&atb))
    };
    let free = solve(None).ok_or_else(|| {
        Error::Numerical("IMU initial lever arm and gravity: singular system".into())
    })?;
    let g_dir = Vector3::new(free[6], free[7], free[8]);
    if !(g_dir.norm() > 0.5 * gravity && g_dir.norm() < 1.5 * gravity) {
        return Err(Error::Input(format!(
            "the accelerometer's gravity comes out at {:.2} m/s^2 against {gravity:.2}: is the \
             accelerometer in m/s^2 (not g), and does the IMU belong to this recording?",
            g_dir.norm()
        )));
    }
    let g = g_dir.normalize() * gravity;
    let fixed = solve(Some(g))
        .ok_or_else(|| Error::Numerical("IMU initial lever arm: singular system".into()))?;
    let lever = Vector3::new(fixed[0], fixed[1], fixed[2]);
    let accel_bias = q * Vector3::new(fixed[3], fixed[4], fixed[5]);
    let (t0, t1) = (
        bins.first().map_or(0.0, |b| b.t),
        bins.last().map_or(0.0, |b| b.t),
    );
    let state = ImuState {
        t_cam_imu: Se3::new(q.transpose(), lever),
        time_offset_s: offset,
        gravity_rotation: ImuState::gravity_rotation_of(&g),
        gravity_magnitude: gravity,
        bias: BiasNodes::spanning(
            t0,
            t1,
            spacing,
            ImuBias {
                gyro: gyro_bias,
                accel: accel_bias,
            },
        ),
        dvl: None,
    };
    Ok(FirstEstimate {
        state,
        offset_alternatives_s,
    })
}

/// How far around the coarse lag the fine search looks, s (at most `max_offset`): five of the
/// coarse grid's 10 ms steps. The two score the same misfit of rate magnitudes, so the fine
/// minimum lies within a step or two of the coarse one; a wider span only costs time (a
/// quarter of the first estimate's at 1 h with 0.5 s).
const FINE_SPAN_S: f64 = 0.05;

/// The clock offset (`t_cam = t_imu + offset`) that best aligns the gyro's rate magnitudes with
/// the trajectory's: the coarse lag over every overlap, then a grid at 2 ms within
/// [`FINE_SPAN_S`] (and `max_offset`) of it, then a parabola through the best point and its
/// neighbours.
fn search_offset(traj: &Trajectory, bins: &[ImuBin], max_offset: f64) -> Result<Lag> {
    let (a, b) = traj.span();
    // The trajectory's rate magnitude on the coarse search's 10 ms grid, read linearly
    // between its points by the fine search: the GP's rates are smooth on that scale (their
    // knots are a pose interval apart), and a 2 ms grid cost 1.8 M evaluations an hour.
    let step = 0.01;
    let n = ((b - a) / step).floor() as usize + 1;
    let grid: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            let w = traj.twist(a + i as f64 * step)?;
            Ok(w.fixed_rows::<3>(3).norm())
        })
        .collect::<Result<_>>()?;
    let at = |t: f64| -> Option<f64> {
        let x = (t - a) / step;
        if x < 0.0 || x > (n - 1) as f64 {
            return None;
        }
        let i = (x.floor() as usize).min(n.saturating_sub(2));
        let u = x - i as f64;
        Some(grid[i] * (1.0 - u) + grid[(i + 1).min(n - 1)] * u)
    };
    let mags: Vec<f64> = bins.iter().map(|b| b.gyro.norm()).collect();
    let Lag {
        offset: centre,
        others,
    } = coarse_offset(&grid, a, step, bins, &mags).unwrap_or(Lag {
        offset: 0.0,
        others: Vec::new(),
    });
    let score = |d: f64| -> Option<f64> {
        let mut sum = 0.0;
        let mut count = 0usize;
        for (bin, m) in bins.iter().zip(&mags) {
            if let Some(c) = at(bin.t + d) {
                sum += (c - m).powi(2);
                count += 1;
            }
        }
        (count * 2 > bins.len()).then(|| sum / count as f64)
    };
    let dstep = 0.002;
    // Around the coarse lag, within max_offset of it.
    let score = |d: f64| score(centre + d);
    let k = (max_offset.min(FINE_SPAN_S) / dstep).ceil() as i64;
    let mut best: Option<(i64, f64)> = None;
    let mut scores = std::collections::HashMap::new();
    let all: Vec<(i64, Option<f64>)> = (-k..=k)
        .into_par_iter()
        .map(|i| (i, score(i as f64 * dstep)))
        .collect();
    for (i, s) in all {
        if let Some(s) = s {
            scores.insert(i, s);
            if best.is_none_or(|(_, b)| s < b) {
                best = Some((i, s));
            }
        }
    }
    let (i, s0) = best.ok_or_else(|| {
        Error::Input(format!(
            "the IMU's times do not overlap the camera's within {max_offset} s of each other"
        ))
    })?;
    let mut d = i as f64 * dstep;
    if let (Some(sm), Some(sp)) = (scores.get(&(i - 1)), scores.get(&(i + 1))) {
        let curv = sp + sm - 2.0 * s0;
        if curv > 0.0 {
            d += 0.5 * dstep * (sm - sp) / curv;
        }
    }
    Ok(Lag {
        offset: centre + d,
        others,
    })
}

/// The lag, on a 10 ms grid over every lag at which the IMU's span and the trajectory's
/// overlap by at least half the shorter, that best aligns the gyro's rate magnitudes (`mags`,
/// one per bin) with the trajectory's (`grid`, from `a` every `step`): clocks may be any
/// distance apart (a device's uptime against a motion-capture clock). `None` without bins.
fn coarse_offset(grid: &[f64], a: f64, step: f64, bins: &[ImuBin], mags: &[f64]) -> Option<Lag> {
    let res = 0.01;
    let (c, d) = (bins.first()?.t, bins.last()?.t);
    // The IMU's magnitudes on a 10 ms grid from c (the bins' nearest, by time).
    let m = ((d - c) / res).floor() as usize + 1;
    let mut imu = vec![f64::NAN; m];
    for (b, v) in bins.iter().zip(mags) {
        let i = ((b.t - c) / res).round() as usize;
        if i < m {
            imu[i] = *v;
        }
    }
    let cam: Vec<f64> = (0..)
        .map(|i| i as f64 * res)
        .take_while(|t| *t <= (grid.len() - 1) as f64 * step)
        .map(|t| {
            let x = t / step;
            let i = (x.floor() as usize).min(grid.len() - 2);
            let u = x - i as f64;
            grid[i] * (1.0 - u) + grid[i + 1] * u
        })
        .collect();
    // At least half of the IMU's filled slots (bins wider than 10 ms leave some empty).
    let need = imu.iter().filter(|v| v.is_finite()).count().min(cam.len()) / 2;
    // Lag l: IMU index j sits at camera index j + l. Per lag, over the overlap: the filled
    // slots, and the sum of squared differences as `sum cam^2 - 2 sum cam imu + sum imu^2`,
    // all lags at once from four FFT correlations (a plain loop over lags is quadratic in the
    // recording's length: a quarter of an hour for 3 h).
    let mask: Vec<f64> = imu
        .iter()
        .map(|v| f64::from(u8::from(v.is_finite())))
        .collect();
    let iv: Vec<f64> = imu
        .iter()
        .map(|v| if v.is_finite() { *v } else { 0.0 })
        .collect();
    let iv2: Vec<f64> = iv.iter().map(|v| v * v).collect();
    let cam2: Vec<f64> = cam.iter().map(|v| v * v).collect();
    let ones = vec![1.0; cam.len()];
    let size = (m + cam.len()).next_power_of_two();
    let cor = Correlator::new(size);
    let f = cor.forward(&[&mask, &ones, &iv, &iv2, &cam, &cam2]);
    let (f_mask, f_ones, f_iv, f_iv2, f_cam, f_cam2) = (&f[0], &f[1], &f[2], &f[3], &f[4], &f[5]);
    let corr = cor.correlate(&[
        (f_ones, f_mask),
        (f_ones, f_iv2),
        (f_cam2, f_mask),
        (f_cam, f_iv),
    ]);
    let (count, imu_sq, cam_sq, cross) = (&corr[0], &corr[1], &corr[2], &corr[3]);
    // Every lag's mean misfit and overlap.
    let (lo, hi) = (-(m as i64) + 1, cam.len() as i64 - 1);
    let scored: Vec<(i64, f64, f64)> = (lo..=hi)
        .filter_map(|l| {
            let at = l.rem_euclid(size as i64) as usize;
            let n = count[at].round();
            (n >= need.max(1) as f64).then(|| {
                (
                    l,
                    (cam_sq[at] - 2.0 * cross[at] + imu_sq[at]).max(0.0) / n,
                    n,
                )
            })
        })
        .collect();
    let lowest = scored.iter().map(|x| x.1).min_by(f64::total_cmp)?;
    // The peaks near the lowest misfit: runs of lags within `REPEAT_RATIO` of it, apart by
    // more than `PEAK_GAP_S`, each at its own lowest.
    let mut peaks: Vec<(i64, f64, f64)> = Vec::new();
    let gap = (PEAK_GAP_S / res).round() as i64;
    let mut last = i64::MIN;
    for x in scored.iter().filter(|x| x.1 <= lowest * REPEAT_RATIO) {
        match peaks.last_mut() {
            Some(p) if x.0 - last <= gap => {
                if x.1 < p.1 {
                    *p = *x;
                }
            }
            _ => peaks.push(*x),
        }
        last = x.0;
    }
    // Of the peaks that tie with the lowest, the one the recordings overlap most at.
    let chosen = peaks
        .iter()
        .filter(|p| p.1 <= lowest * TIE_RATIO)
        .max_by(|p, q| p.2.total_cmp(&q.2).then(q.1.total_cmp(&p.1)))?;
    // t_cam = t_imu + offset: camera index j + l at a + (j + l) res, IMU index j at c + j res.
    let offset = |l: i64| a + l as f64 * res - c;
    let others = peaks
        .iter()
        .filter(|p| p.0 != chosen.0)
        .map(|p| offset(p.0))
        .collect();
    Some(Lag {
        offset: offset(chosen.0),
        others,
    })
}

/// Misfits within this ratio of the lowest tie with it: a motion that repeats aligns as well a
/// period away, and the misfits then differ by their noise alone.
const TIE_RATIO: f64 = 1.1;

/// Lags whose misfit is within this ratio of the lowest fit the rates about as well: the
/// offset is ambiguous among them, and the result says so.
const REPEAT_RATIO: f64 = 1.5;

/// Lags within this of each other belong to one peak, s.
const PEAK_GAP_S: f64 = 1.0;

/// A lag found as a clock offset (`t_cam = t_imu + offset`, s), and the other peaks' offsets
/// that fit the rate magnitudes about as well (to the coarse grid's 10 ms).
struct Lag {
    offset: f64,
    others: Vec<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rate magnitude with no period in the span.
    fn rate(t: f64) -> f64 {
        1.0 + 0.5 * (0.7 * t).sin() + 0.3 * (2.3 * t + 0.4 * (0.11 * t).sin()).sin()
    }

    #[test]
    fn the_coarse_search_finds_the_lag_whichever_clock_is_ahead() {
        let (a, step) = (1000.0, 0.002);
        let grid: Vec<f64> = (0..50_000).map(|i| rate(a + i as f64 * step)).collect();
        for offset in [1000.0 - 2.0 + 0.013, 1000.0 + 37.5] {
            // The IMU covers 60 s of the camera's 100 s; every fifth bin is missing.
            let bins: Vec<ImuBin> = (0..3000)
                .filter(|j| j % 5 != 3)
                .map(|j| {
                    let t = 20.0 + 0.02 * j as f64;
                    ImuBin {
                        t,
                        gyro: Vector3::new(rate(t + offset), 0.0, 0.0),
                        accel: Vector3::zeros(),
                        n: 4,
                    }
                })
                .collect();
            let mags: Vec<f64> = bins.iter().map(|b| b.gyro.norm()).collect();
            let lag = coarse_offset(&grid, a, step, &bins, &mags).expect("a lag");
            assert!(lag.others.is_empty(), "{:?}", lag.others);
            let found = lag.offset;
            assert!(
                (found - offset).abs() <= 0.0051,
                "offset {offset}: found {found}"
            );
        }
    }

    #[test]
    fn a_repeating_motion_keeps_the_largest_overlap_and_names_the_other_lags() {
        // A rate magnitude with a 5 s period; the IMU and the camera cover the same 200 s, the
        // IMU's clock 0.013 s behind, its magnitudes with a noise of 0.02 rad/s.
        let period = 5.0;
        let rate = |t: f64| {
            let u = std::f64::consts::TAU * t / period;
            1.0 + 0.5 * u.sin() + 0.3 * (2.0 * u + 0.3).sin()
        };
        let (a, step) = (1000.0, 0.01);
        let grid: Vec<f64> = (0..20_001).map(|i| rate(a + i as f64 * step)).collect();
        let offset = 1000.013;
        let bins: Vec<ImuBin> = (0..10_000)
            .map(|j| {
                let t = 0.02 * j as f64;
                let noise = 0.02 * (2.0 * ((j as f64 * 12.9898).sin() * 43758.5453).fract() - 1.0);
                ImuBin {
                    t,
                    gyro: Vector3::new(rate(t + offset) + noise, 0.0, 0.0),
                    accel: Vector3::zeros(),
                    n: 4,
                }
            })
            .collect();
        let mags: Vec<f64> = bins.iter().map(|b| b.gyro.norm()).collect();
        let lag = coarse_offset(&grid, a, step, &bins, &mags).expect("a lag");
        assert!(
            (lag.offset - offset).abs() <= 0.0051,
            "found {} for {offset}",
            lag.offset
        );
        // Every other period within the half overlap the search allows is named, and nothing
        // else: 20 periods either side.
        assert_eq!(lag.others.len(), 40, "{:?}", lag.others);
        for o in &lag.others {
            let periods = (o - offset) / period;
            assert!(
                (periods - periods.round()).abs() * period <= 0.02 && periods.round() != 0.0,
                "{o}"
            );
        }
    }
}
