//! Motion replayed from a recorded track (motion capture, INS): a real vehicle's dynamics as the
//! truth of a simulation.
//!
//! The body twist between consecutive recorded poses, `log(T_k^-1 T_k+1) / dt_k`, is taken at the
//! middle of each step, smoothed with a Gaussian kernel (to remove the tracker's own jitter) and
//! sampled on a fine grid with its rate; [`SampledMotion::from_twists`] then integrates it from the
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
    /// playback time.
    pub smoothing_s: f64,
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
    /// RMS body speed and angular rate of the replay, m/s and rad/s.
    pub rms_speed_mps: f64,
    /// RMS angular rate of the replay, rad/s.
    pub rms_rate_radps: f64,
}

fn input(msg: impl Into<String>) -> Error {
    Error::Input(msg.into())
}

/// Replays `track` (poses in time order, `T_world_body`) as a [`SampledMotion`] whose body is the
/// simulated camera.
pub fn replay_track(track: &[PoseMeasurement], opts: &TrackOptions) -> Result<TrackMotion> {
    let ok = |x: f64| x.is_finite() && x > 0.0;
    if !ok(opts.time_scale) || !ok(opts.smoothing_s) || !ok(opts.grid_dt_s) {
        return Err(input(format!(
            "track replay: time scale, smoothing and grid step must be positive, got {}, {}, {}",
            opts.time_scale, opts.smoothing_s, opts.grid_dt_s
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
    // Body twist of each step at its middle, in playback time.
    let mut mid = Vec::with_capacity(steps.len());
    let mut twist = Vec::with_capacity(steps.len());
    for (k, w) in track.windows(2).enumerate() {
        let d = steps[k] * s;
        let xi = (w[0].pose.inverse() * w[1].pose).log() / d;
        if !xi.iter().all(|x| x.is_finite()) {
            return Err(input(format!(
                "track replay: the step after pose {k} gives a non-finite twist"
            )));
        }
        mid.push((0.5 * (w[0].t + w[1].t) - t0) * s);
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
    // Gaussian-kernel average of the step twists at every grid time (kernel cut at 4 sigma; the
    // window always holds at least the nearest step).
    let sigma = opts.smoothing_s;
    let reach = 4.0 * sigma;
    let mut lo = 0usize;
    let mut smoothed = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * h;
        while lo + 1 < mid.len() && mid[lo] < t - reach {
            lo += 1;
        }
        let mut acc = Vector6::zeros();
        let mut wsum = 0.0;
        let mut j = lo;
        while j < mid.len() && mid[j] <= t + reach {
            let u = (mid[j] - t) / sigma;
            let wgt = (-0.5 * u * u).exp();
            acc += twist[j] * wgt;
            wsum += wgt;
            j += 1;
        }
        if wsum > 1e-12 {
            smoothed.push(acc / wsum);
        } else {
            // Farther than 4 sigma from every step (a step longer than the kernel): the nearest.
            let near = if lo + 1 < mid.len() && (mid[lo + 1] - t).abs() < (mid[lo] - t).abs() {
                lo + 1
            } else {
                lo
            };
            smoothed.push(twist[near]);
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
        rms_speed_mps: (v2 / g).sqrt(),
        rms_rate_radps: (w2 / g).sqrt(),
    })
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
}
