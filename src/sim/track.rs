//! Motion replayed from a recorded track (motion capture, INS): a real vehicle's dynamics as the
//! truth of a simulation.
//!
//! The body twist between consecutive recorded poses, `log(T_k^-1 T_k+1) / dt_k`, held over its
//! step, is convolved with a Gaussian kernel at least two of the track's steps wide (to remove the
//! tracker's own jitter, which differencing turns into a vibration at the track's rate; the convolution
//! keeps the twist's integral however unevenly the poses are spaced) and sampled on a fine grid
//! with its rate; [`SampledMotion::from_twists`] then integrates it from the
//! first recorded pose. The replay therefore has exactly the recorded vehicle's speeds, turns and
//! calm stretches, and poses, twists and rates that agree with each other to integration accuracy;
//! its positions drift slowly away from the recorded ones (the integral of the smoothing error),
//! which does not matter for a calibration, where only the motion's shape counts.

use nalgebra::Vector6;

use super::motion::SampledMotion;
use crate::error::{Error, Result};
use crate::types::PoseMeasurement;

/// How a recorded track is replayed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackOptions {
    /// Playback slowdown: 2 plays the track at half speed (twice as long, half the velocities and
    /// angular rates). Lets a fast vehicle's track (a drone's) stand in for a slower one's.
    pub time_scale: f64,
    /// Standard deviation of the Gaussian kernel that smooths the recorded twists, seconds of
    /// playback time (at least [`Self::min_smoothing_steps`] of the track's steps).
    pub smoothing_s: f64,
    /// Smallest kernel, in median steps between recorded poses (in playback time). A twist
    /// differenced from poses `dt` apart holds the tracker's own noise at up to `1 / (2 dt)` Hz;
    /// a kernel of two steps passes that frequency at 3e-9 and half of it at 7e-3, so that the
    /// tracker's jitter is not replayed as a vibration of the vehicle. 0 leaves
    /// [`Self::smoothing_s`] alone.
    pub min_smoothing_steps: f64,
    /// Grid step of the replayed twist, seconds.
    pub grid_dt_s: f64,
    /// Largest accepted step between recorded poses, in multiples of the median step: the replay
    /// needs a track without tracking losses (cut it first).
    pub max_step_ratio: f64,
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            time_scale: 1.0,
            smoothing_s: 0.05,
            min_smoothing_steps: 2.0,
            grid_dt_s: 0.005,
            max_step_ratio: 5.0,
        }
    }
}

/// A replayed track and what the replay did to it.
#[derive(Clone, Debug)]
pub struct TrackMotion {
    /// The replay; its time 0 is the first recorded pose.
    pub motion: SampledMotion,
    /// Playback duration, seconds.
    pub duration_s: f64,
    /// Number of recorded poses used.
    pub poses_used: usize,
    /// RMS over the recorded poses of the distance between recorded and replayed positions, m
    /// (the drift of the integrated smoothed twist).
    pub position_drift_rms_m: f64,
    /// Standard deviation of the kernel that smoothed the twists, seconds of playback time.
    pub smoothing_s: f64,
    /// RMS body speed and angular rate of the replay, m/s and rad/s.
    pub rms_speed_mps: f64,
    /// RMS angular rate of the replay, rad/s.
    pub rms_rate_radps: f64,
}

fn input(msg: impl Into<String>) -> Error {
    Error::Input(msg.into())
}

/// The standard normal distribution function, from the complementary error function's
/// Chebyshev approximation (relative error below 1.2e-7), good to 1e-7 absolute.
fn normal_cdf(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * z);
    let c = [
        -1.265_512_23,
        1.000_023_68,
        0.374_091_96,
        0.096_784_18,
        -0.186_288_06,
        0.278_868_07,
        -1.135_203_98,
        1.488_515_87,
        -0.822_152_23,
        0.170_872_77,
    ];
    let poly = c.iter().rev().fold(0.0, |acc, &ck| acc * t + ck);
    let erfc = t * (-z * z + poly).exp();
    if x >= 0.0 {
        1.0 - 0.5 * erfc
    } else {
        0.5 * erfc
    }
}

/// Replays `track` (poses in time order, `T_world_body`) as a [`SampledMotion`] whose body is the
/// simulated camera.
pub fn replay_track(track: &[PoseMeasurement], opts: &TrackOptions) -> Result<TrackMotion> {
    let ok = |x: f64| x.is_finite() && x > 0.0;
    let steps_ok = opts.min_smoothing_steps.is_finite() && opts.min_smoothing_steps >= 0.0;
    if !(ok(opts.time_scale) && ok(opts.smoothing_s) && ok(opts.grid_dt_s) && steps_ok) {
        return Err(input(format!(
            "track replay: time scale, smoothing and grid step must be positive and the smallest \
             kernel in steps at least 0, got {}, {}, {}, {}",
            opts.time_scale, opts.smoothing_s, opts.grid_dt_s, opts.min_smoothing_steps
        )));
    }
    if track.len() < 10 {
        return Err(input(format!(
            "track replay needs at least 10 poses, got {}",
            track.len()
        )));
    }
    let mut steps: Vec<f64> = track.windows(2).map(|w| w[1].t - w[0].t).collect();
    if let Some(k) = steps.iter().position(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(input(format!(
            "track replay: pose {} (t = {:.6} s) is not after the previous one",
            k + 1,
            track[k + 1].t
        )));
    }
    let mut sorted = steps.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    if let Some(k) = steps.iter().position(|&d| d > opts.max_step_ratio * median) {
        return Err(input(format!(
            "track replay: {:.3} s without a pose after pose {k} (t = {:.6} s), more than {} times \
             the median step {median:.4} s; cut the track at tracking losses",
            steps[k], track[k].t, opts.max_step_ratio
        )));
    }
    let s = opts.time_scale;
    let t0 = track[0].t;
    // Each step's span and body twist, in playback time.
    let mut span = Vec::with_capacity(steps.len());
    let mut twist = Vec::with_capacity(steps.len());
    for (k, w) in track.windows(2).enumerate() {
        let d = steps[k] * s;
        let xi = (w[0].pose.inverse() * w[1].pose).log() / d;
        if !xi.iter().all(|x| x.is_finite()) {
            return Err(input(format!(
                "track replay: the step after pose {k} gives a non-finite twist"
            )));
        }
        span.push(((w[0].t - t0) * s, (w[1].t - t0) * s));
        twist.push(xi);
    }
    steps.clear();

    let duration = (track[track.len() - 1].t - t0) * s;
    let h = opts.grid_dt_s;
    let n = (duration / h).ceil() as usize + 1;
    if n > SampledMotion::MAX_GRID_POINTS {
        return Err(input(format!(
            "track replay: {n} grid points of {h} s exceed the limit of {}",
            SampledMotion::MAX_GRID_POINTS
        )));
    }
    // The step twists, each held over its step, convolved with the Gaussian kernel at every grid
    // time: step j weighs the kernel's mass over its span (kernel cut at 4 sigma; near the ends
    // the weights are renormalised).
    let sigma = opts
        .smoothing_s
        .max(opts.min_smoothing_steps * median * opts.time_scale);
    let reach = 4.0 * sigma;
    let mut lo = 0usize;
    let mut smoothed = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * h;
        while lo + 1 < span.len() && span[lo].1 < t - reach {
            lo += 1;
        }
        let mut acc = Vector6::zeros();
        let mut wsum = 0.0;
        let mut j = lo;
        while j < span.len() && span[j].0 <= t + reach {
            let (a, b) = span[j];
            let wgt = normal_cdf((b - t) / sigma) - normal_cdf((a - t) / sigma);
            acc += twist[j] * wgt;
            wsum += wgt;
            j += 1;
        }
        if wsum > 1e-12 {
            smoothed.push(acc / wsum);
        } else {
            // Farther than 4 sigma from every step (cannot happen inside the track): the nearest.
            smoothed.push(twist[lo.min(twist.len() - 1)]);
        }
    }
    // Rates: central differences of the smoothed twist (one-sided at the ends).
    let rates: Vec<Vector6<f64>> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            (smoothed[b] - smoothed[a]) / ((b - a) as f64 * h)
        })
        .collect();
    let motion = SampledMotion::from_twists(track[0].pose, smoothed, rates, h, duration)?;

    use super::motion::Motion;
    let mut drift = 0.0;
    for p in track {
        let replay = motion.state((p.t - t0) * s);
        drift += (replay.pose.trans - p.pose.trans).norm_squared();
    }
    let (mut v2, mut w2) = (0.0, 0.0);
    for k in 0..motion.grid_len() {
        if let Some(st) = motion.grid_state(k) {
            v2 += st.twist.fixed_rows::<3>(0).norm_squared();
            w2 += st.twist.fixed_rows::<3>(3).norm_squared();
        }
    }
    let g = motion.grid_len().max(1) as f64;
    Ok(TrackMotion {
        motion,
        duration_s: duration,
        poses_used: track.len(),
        position_drift_rms_m: (drift / track.len() as f64).sqrt(),
        smoothing_s: sigma,
        rms_speed_mps: (v2 / g).sqrt(),
        rms_rate_radps: (w2 / g).sqrt(),
    })
}

/// How [`cut_track`] cuts a recorded track at tracking losses and cleans it of glitches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutOptions {
    /// A step longer than this multiple of the median step between poses is a tracking loss:
    /// the track is split there.
    pub max_step_ratio: f64,
    /// A step whose speed (or angular rate) exceeds this multiple of the median over its
    /// neighbourhood is a jump; a jump away and one back within [`Self::max_glitch_poses`] poses
    /// enclose a glitch (a marker swap, a mistracked frame), whose poses are dropped. A jump that
    /// does not come back splits the track.
    pub jump_ratio: f64,
    /// Smallest displacement of a jump, metres: the jitter of a vehicle at rest is no jump,
    /// however large its ratio to the median.
    pub min_jump_m: f64,
    /// Smallest rotation of a jump, radians.
    pub min_jump_rad: f64,
    /// Steps on either side of a step that make up its neighbourhood.
    pub half_window: usize,
    /// Most poses a glitch may have.
    pub max_glitch_poses: usize,
    /// Pieces shorter than this, seconds, are dropped.
    pub min_piece_s: f64,
}

impl Default for CutOptions {
    fn default() -> Self {
        CutOptions {
            max_step_ratio: 5.0,
            jump_ratio: 8.0,
            min_jump_m: 0.03,
            min_jump_rad: 0.05,
            half_window: 10,
            max_glitch_poses: 10,
            min_piece_s: 5.0,
        }
    }
}

/// A recorded track cut into usable pieces, with counts of what was dropped and why.
#[derive(Clone, Debug, Default)]
pub struct CutTrack {
    /// The usable pieces in time order, each without tracking losses or glitches.
    pub pieces: Vec<Vec<PoseMeasurement>>,
    /// Poses dropped because their time repeated the previous pose's.
    pub duplicates: usize,
    /// Holds: runs of poses that repeat the pose before them while the track moves
    /// ([`crate::types::held_pose_runs`]), dropped.
    pub holds: usize,
    /// Poses those holds had.
    pub held_poses: usize,
    /// Tracking losses the track was split at.
    pub gaps: usize,
    /// Glitches removed.
    pub glitches: usize,
    /// Poses those glitches had.
    pub glitch_poses: usize,
    /// Jumps that did not come back, where the track was split.
    pub jumps: usize,
    /// Pieces dropped as shorter than [`CutOptions::min_piece_s`].
    pub short_pieces: usize,
}

impl CutTrack {
    /// The longest piece (by duration), if any.
    pub fn longest(&self) -> Option<&[PoseMeasurement]> {
        let span = |p: &Vec<PoseMeasurement>| match (p.first(), p.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        };
        self.pieces
            .iter()
            .max_by(|a, b| span(a).total_cmp(&span(b)))
            .map(|p| p.as_slice())
    }
}

fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => 0.0,
        n => v[n / 2],
    }
}

/// Distance and rotation angle between two poses.
fn step_size(a: &PoseMeasurement, b: &PoseMeasurement) -> (f64, f64) {
    let d = (b.pose.trans - a.pose.trans).norm();
    let angle = (a.pose.inverse() * b.pose).log().fixed_rows::<3>(3).norm();
    (d, angle)
}

/// Splits `poses` (in time order, `T_world_body`) where the time step exceeds
/// [`CutOptions::max_step_ratio`] times the median step, and drops glitches: a pose (or a short
/// run of them) reached by a jump in position or attitude far beyond its neighbourhood's speed
/// and left by a jump back. A jump that does not come back splits the track. Poses whose time
/// repeats the previous one's are dropped, and so are held poses (the tracker repeating its last
/// pose at new times, [`crate::types::held_pose_runs`]); time going backwards is an error.
pub fn cut_track(poses: &[PoseMeasurement], opts: &CutOptions) -> Result<CutTrack> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    let non_negative = |x: f64| x.is_finite() && x >= 0.0;
    let valid = positive(opts.max_step_ratio)
        && positive(opts.jump_ratio)
        && non_negative(opts.min_jump_m)
        && non_negative(opts.min_jump_rad)
        && non_negative(opts.min_piece_s);
    if !valid {
        return Err(input(format!("track cut: invalid options {opts:?}")));
    }
    let mut out = CutTrack::default();
    let mut clean: Vec<PoseMeasurement> = Vec::with_capacity(poses.len());
    for (k, p) in poses.iter().enumerate() {
        if !p.t.is_finite() {
            return Err(input(format!("track cut: pose {k} has a non-finite time")));
        }
        let finite = p
            .pose
            .trans
            .iter()
            .chain(p.pose.rot.iter())
            .all(|x| x.is_finite());
        if !finite {
            return Err(input(format!(
                "track cut: pose {k} (t = {:.6} s) is not finite",
                p.t
            )));
        }
        match clean.last() {
            Some(q) if p.t < q.t => {
                return Err(input(format!(
                    "track cut: pose {k} (t = {:.6} s) is before the previous one (t = {:.6} s)",
                    p.t, q.t
                )));
            }
            Some(q) if p.t == q.t => out.duplicates += 1,
            _ => clean.push(p.clone()),
        }
    }
    let holds = crate::types::held_pose_runs(&clean);
    out.holds = holds.len();
    out.held_poses = holds.iter().map(|r| r.len()).sum();
    let clean = crate::types::without_runs(clean, &holds).0;
    if clean.len() < 3 {
        return Err(input(format!(
            "track cut needs at least 3 poses at distinct times, got {}",
            clean.len()
        )));
    }
    let steps: Vec<f64> = clean.windows(2).map(|w| w[1].t - w[0].t).collect();
    let limit = opts.max_step_ratio * median(&steps);
    let mut runs: Vec<Vec<PoseMeasurement>> = vec![Vec::new()];
    for (k, p) in clean.into_iter().enumerate() {
        if k > 0 && steps[k - 1] > limit {
            out.gaps += 1;
            runs.push(Vec::new());
        }
        if let Some(run) = runs.last_mut() {
            run.push(p);
        }
    }
    for run in runs {
        for piece in remove_glitches(run, opts, &mut out) {
            let span = match (piece.first(), piece.last()) {
                (Some(a), Some(b)) => b.t - a.t,
                _ => 0.0,
            };
            if piece.len() < 2 || span < opts.min_piece_s {
                out.short_pieces += 1;
            } else {
                out.pieces.push(piece);
            }
        }
    }
    Ok(out)
}

/// The glitch-free pieces of one run without tracking losses.
fn remove_glitches(
    run: Vec<PoseMeasurement>,
    opts: &CutOptions,
    out: &mut CutTrack,
) -> Vec<Vec<PoseMeasurement>> {
    let n = run.len();
    if n < 3 {
        return vec![run];
    }
    // Speed and angular rate of every step.
    let (speed, rate): (Vec<f64>, Vec<f64>) = run
        .windows(2)
        .map(|w| {
            let (d, a) = step_size(&w[0], &w[1]);
            let dt = w[1].t - w[0].t;
            (d / dt, a / dt)
        })
        .unzip();
    let m = speed.len();
    let hw = opts.half_window.max(1);
    let jump = |k: usize| -> bool {
        let (lo, hi) = (k.saturating_sub(hw), (k + hw + 1).min(m));
        let dt = run[k + 1].t - run[k].t;
        let far = |v: &[f64], floor: f64| {
            v[k] > opts.jump_ratio * median(&v[lo..hi]) && v[k] * dt > floor
        };
        far(&speed, opts.min_jump_m) || far(&rate, opts.min_jump_rad)
    };
    // A step from pose a to pose b is normal when it would not be a jump at step k's place.
    let bridge_ok = |a: usize, b: usize, k: usize| -> bool {
        let (lo, hi) = (k.saturating_sub(hw), (k + hw + 1).min(m));
        let (d, ang) = step_size(&run[a], &run[b]);
        let dt = run[b].t - run[a].t;
        let ok = |x: f64, v: &[f64], floor: f64| {
            x / dt <= opts.jump_ratio * median(&v[lo..hi]) || x <= floor
        };
        ok(d, &speed, opts.min_jump_m) && ok(ang, &rate, opts.min_jump_rad)
    };
    let jumps: Vec<usize> = (0..m).filter(|&k| jump(k)).collect();
    let mut drop = vec![false; n];
    let mut split_after = vec![false; n];
    let mut i = 0;
    while i < jumps.len() {
        let a = jumps[i];
        // The first later jump whose end the pose before the glitch reaches normally.
        let back = jumps[i + 1..]
            .iter()
            .position(|&b| b - a <= opts.max_glitch_poses && bridge_ok(a, b + 1, a));
        match back {
            Some(j) => {
                let b = jumps[i + 1 + j];
                for d in drop.iter_mut().take(b + 1).skip(a + 1) {
                    *d = true;
                }
                out.glitches += 1;
                out.glitch_poses += b - a;
                i += j + 2;
            }
            None if a == 0 || a + 1 == m => {
                // A first or last pose off the track: a glitch at the end.
                let k = if a == 0 { 0 } else { n - 1 };
                drop[k] = true;
                out.glitches += 1;
                out.glitch_poses += 1;
                i += 1;
            }
            None => {
                split_after[a] = true;
                out.jumps += 1;
                i += 1;
            }
        }
    }
    let mut pieces = vec![Vec::new()];
    for (k, p) in run.into_iter().enumerate() {
        if !drop[k] {
            if let Some(piece) = pieces.last_mut() {
                piece.push(p);
            }
        }
        if split_after[k] {
            pieces.push(Vec::new());
        }
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::Se3;
    use crate::sim::motion::Motion;

    /// The pose at `t` of the constant screw motion `xi` from the identity.
    fn pose_at(t: f64, xi: Vector6<f64>) -> PoseMeasurement {
        PoseMeasurement {
            t,
            pose: Se3::exp(&(xi * t)),
            cov: None,
        }
    }

    #[test]
    fn the_normal_distribution_function_is_right() {
        for (x, p) in [
            (0.0, 0.5),
            (1.0, 0.841_344_746),
            (-1.96, 0.024_997_895),
            (4.0, 0.999_968_329),
        ] {
            assert!((normal_cdf(x) - p).abs() < 2e-7, "{x}: {}", normal_cdf(x));
        }
    }

    #[test]
    fn a_constant_screw_is_replayed_exactly() {
        let xi = Vector6::new(0.3, -0.1, 0.05, 0.2, 0.4, -0.3);
        let track: Vec<_> = (0..200).map(|k| pose_at(k as f64 * 0.05, xi)).collect();
        let r = replay_track(&track, &TrackOptions::default()).expect("replay");
        assert!((r.duration_s - 9.95).abs() < 1e-9);
        for t in [0.0, 1.234, 5.0, 9.9] {
            let st = r.motion.state(t);
            assert!((st.twist - xi).norm() < 1e-9, "twist at {t}: {}", st.twist);
            assert!(st.twist_rate.norm() < 1e-6);
        }
        assert!(r.position_drift_rms_m < 1e-9, "{}", r.position_drift_rms_m);
    }

    #[test]
    fn unevenly_spaced_poses_replay_without_drift() {
        // A vehicle whose speed and turn change at every pose, recorded at uneven steps of
        // 80-120 ms: the replay keeps its positions.
        let mut pose = Se3::identity();
        let mut t = 0.0;
        let mut track = Vec::new();
        for k in 0..1500 {
            track.push(PoseMeasurement { t, pose, cov: None });
            let dt = 0.1 + 0.02 * ((k * 7 % 11) as f64 / 5.0 - 1.0);
            let xi = Vector6::new(
                0.1 + 0.05 * (k as f64 * 0.3).sin(),
                0.0,
                0.0,
                0.0,
                0.0,
                0.05 * ((k * 5 % 13) as f64 / 6.0 - 1.0),
            );
            pose = pose * Se3::exp(&(xi * dt));
            t += dt;
        }
        let r = replay_track(&track, &TrackOptions::default()).expect("replay");
        assert!(r.position_drift_rms_m < 0.01, "{}", r.position_drift_rms_m);
    }

    #[test]
    fn the_tracker_jitter_is_not_replayed_as_a_vibration() {
        // A vehicle driving straight at 0.1 m/s, tracked at 10 Hz with a yaw that alternates by
        // +-0.1 deg from one pose to the next (a tracker's jitter at its Nyquist frequency).
        let jitter = 0.1f64.to_radians();
        let track: Vec<_> = (0..300)
            .map(|k| {
                let t = k as f64 * 0.1;
                let yaw = if k % 2 == 0 { jitter } else { -jitter };
                let xi = Vector6::new(0.1 * t, 0.0, 0.0, 0.0, 0.0, yaw);
                PoseMeasurement {
                    t,
                    pose: Se3::exp(&xi),
                    cov: None,
                }
            })
            .collect();
        let peak_rate = |opts: &TrackOptions| {
            let r = replay_track(&track, opts).expect("replay");
            let rate = (100..2800)
                .map(|k| r.motion.state(k as f64 * 0.01).twist[5].abs())
                .fold(0.0, f64::max);
            (r.smoothing_s, rate)
        };
        // Differenced, the jitter is a yaw rate of +-0.035 rad/s; 50 ms of smoothing keeps a
        // large part of it, two steps (200 ms) remove it.
        let (sigma, rate) = peak_rate(&TrackOptions {
            min_smoothing_steps: 0.0,
            ..TrackOptions::default()
        });
        assert!((sigma - 0.05).abs() < 1e-12);
        assert!(rate > 0.005, "{rate}");
        let (sigma, rate) = peak_rate(&TrackOptions::default());
        assert!((sigma - 0.2).abs() < 1e-9, "{sigma}");
        assert!(rate < 1e-6, "{rate}");
        // At half speed the steps are 0.2 s of playback, and so is the floor.
        let (sigma, _) = peak_rate(&TrackOptions {
            time_scale: 2.0,
            ..TrackOptions::default()
        });
        assert!((sigma - 0.4).abs() < 1e-9, "{sigma}");
        let bad = TrackOptions {
            min_smoothing_steps: -1.0,
            ..TrackOptions::default()
        };
        assert!(replay_track(&track, &bad).is_err());
    }

    #[test]
    fn time_scale_slows_the_twist_and_stretches_the_span() {
        let xi = Vector6::new(0.3, 0.0, 0.0, 0.0, 0.0, 0.6);
        let track: Vec<_> = (0..100).map(|k| pose_at(k as f64 * 0.1, xi)).collect();
        let opts = TrackOptions {
            time_scale: 2.0,
            ..TrackOptions::default()
        };
        let r = replay_track(&track, &opts).expect("replay");
        assert!((r.duration_s - 19.8).abs() < 1e-9);
        assert!((r.motion.state(7.0).twist - xi * 0.5).norm() < 1e-9);
        // The pose at playback time 2t is the recorded pose at t.
        let d = r.motion.state(12.0).pose.inverse() * track[60].pose;
        assert!(d.log().norm() < 1e-8);
    }

    #[test]
    fn twists_that_cannot_make_a_motion_are_refused() {
        let w = vec![Vector6::zeros(); 11];
        let ok = SampledMotion::from_twists(Se3::identity(), w.clone(), w.clone(), 0.1, 1.0);
        assert!(ok.is_ok());
        let short = SampledMotion::from_twists(Se3::identity(), w.clone(), w.clone(), 0.1, 1.5);
        assert!(
            short
                .expect_err("short")
                .to_string()
                .contains("ends before")
        );
        let mismatch =
            SampledMotion::from_twists(Se3::identity(), w.clone(), w[..5].to_vec(), 0.1, 0.4);
        assert!(mismatch.is_err());
        let mut bad = w.clone();
        bad[3][2] = f64::NAN;
        let e = SampledMotion::from_twists(Se3::identity(), bad, w, 0.1, 1.0).expect_err("nan");
        assert!(e.to_string().contains("twist 3"), "{e}");
    }

    #[test]
    fn a_tracking_loss_is_refused_with_its_time() {
        let xi = Vector6::new(0.1, 0.0, 0.0, 0.0, 0.0, 0.1);
        let mut track: Vec<_> = (0..50).map(|k| pose_at(k as f64 * 0.05, xi)).collect();
        track.drain(20..30);
        let e = replay_track(&track, &TrackOptions::default())
            .expect_err("gap")
            .to_string();
        assert!(e.contains("after pose 19") && e.contains("0.550 s"), "{e}");
        track.swap(3, 4);
        let e = replay_track(&track, &TrackOptions::default())
            .expect_err("order")
            .to_string();
        assert!(e.contains("pose 4"), "{e}");
    }

    /// A slow screw track at 20 Hz.
    fn steady(n: usize) -> Vec<PoseMeasurement> {
        let xi = Vector6::new(0.2, 0.05, 0.0, 0.0, 0.0, 0.1);
        (0..n).map(|k| pose_at(k as f64 * 0.05, xi)).collect()
    }

    #[test]
    fn a_tracking_loss_splits_the_track() {
        let mut track = steady(600);
        track.drain(200..240); // 2 s without poses
        let cut = cut_track(&track, &CutOptions::default()).expect("cut");
        assert_eq!(cut.gaps, 1);
        assert_eq!(cut.pieces.len(), 2);
        assert_eq!((cut.pieces[0].len(), cut.pieces[1].len()), (200, 360));
        assert_eq!((cut.glitches, cut.jumps, cut.duplicates), (0, 0, 0));
        assert_eq!(cut.longest().map(|p| p.len()), Some(360));
        // A piece shorter than the minimum is dropped and counted.
        track.drain(260..560);
        let cut = cut_track(&track, &CutOptions::default()).expect("cut");
        assert_eq!((cut.pieces.len(), cut.short_pieces), (1, 1));
    }

    #[test]
    fn a_glitch_is_removed_and_counted() {
        let mut track = steady(400);
        // A marker swap: two poses 20 cm off, one pose turned by 30 degrees.
        for k in [100, 101] {
            track[k].pose.trans.x += 0.2;
        }
        let turn = Se3::exp(&Vector6::new(0.0, 0.0, 0.0, 0.0, 0.5, 0.0));
        track[300].pose = track[300].pose * turn;
        // A repeated time stamp.
        let dup = track[50].clone();
        track.insert(51, dup);
        let cut = cut_track(&track, &CutOptions::default()).expect("cut");
        assert_eq!(cut.duplicates, 1);
        assert_eq!((cut.glitches, cut.glitch_poses), (2, 3));
        assert_eq!((cut.gaps, cut.jumps), (0, 0));
        assert_eq!(cut.pieces.len(), 1);
        assert_eq!(cut.pieces[0].len(), 397);
        let gone = |t: f64| cut.pieces[0].iter().all(|p| (p.t - t).abs() > 1e-9);
        assert!(gone(5.0) && gone(5.05) && gone(15.0));
        // What is left replays.
        let r = replay_track(&cut.pieces[0], &TrackOptions::default()).expect("replay");
        assert!(r.position_drift_rms_m < 0.01, "{}", r.position_drift_rms_m);
    }

    #[test]
    fn a_jump_that_stays_splits_and_bad_input_is_refused() {
        let mut track = steady(400);
        for p in &mut track[200..] {
            p.pose.trans.y += 0.5;
        }
        let cut = cut_track(&track, &CutOptions::default()).expect("cut");
        assert_eq!((cut.jumps, cut.glitches, cut.pieces.len()), (1, 0, 2));
        // A vehicle at rest: its jitter is no glitch.
        let mut still = steady(200);
        for (k, p) in still.iter_mut().enumerate() {
            p.pose = Se3::identity();
            p.pose.trans.x = if k % 2 == 0 { 1e-4 } else { -1e-4 };
        }
        let cut = cut_track(&still, &CutOptions::default()).expect("cut");
        assert_eq!((cut.glitches, cut.jumps, cut.pieces.len()), (0, 0, 1));
        track.swap(10, 11);
        let e = cut_track(&track, &CutOptions::default()).expect_err("order");
        assert!(e.to_string().contains("pose 11"), "{e}");
        assert!(cut_track(&track[..2], &CutOptions::default()).is_err());
        let mut nan = steady(20);
        nan[5].pose.trans.z = f64::NAN;
        assert!(cut_track(&nan, &CutOptions::default()).is_err());
        let bad = CutOptions {
            jump_ratio: 0.0,
            ..CutOptions::default()
        };
        assert!(cut_track(&steady(20), &bad).is_err());
    }
}
