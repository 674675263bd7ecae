//! Quantities the report plots, derived from the calibration outcome.

use nalgebra::Vector3;

use super::input::ReportInput;
use crate::calib::model::predict;
use crate::error::{Error, Result};

/// One DVL sample the refinement used, evaluated at the start and final parameters.
#[derive(Clone, Debug)]
pub(super) struct Sample {
    /// DVL-clock time (seconds, camera epoch).
    pub t_dvl: f64,
    /// Camera-clock time at the final parameters.
    pub t_cam: f64,
    pub measured: Vector3<f64>,
    /// Prediction with the parameters the refinement started from (`None` when that offset puts
    /// the sample outside the trajectory).
    pub before: Option<Vector3<f64>>,
    pub after: Vector3<f64>,
    /// `|v|` and `|w x p|` of the camera at the final parameters, m/s.
    pub speed: f64,
    pub lever: f64,
    /// Weight of the sample in the result (below 1: down-weighted by the robust loss).
    pub weight: f64,
    /// The standard deviation per DVL axis the calibration gave the sample (its reported
    /// covariance, or `--dvl-sigma`), m/s.
    pub sigma: Vector3<f64>,
}

/// Everything computed from the input before rendering.
#[derive(Clone, Debug)]
pub(super) struct Derived {
    pub samples: Vec<Sample>,
    /// Used samples that could not be evaluated at the final parameters.
    pub skipped: usize,
    pub rms_before: Option<Vector3<f64>>,
    pub rms_after: Vector3<f64>,
    /// RMS of the DVL noise the reports state (or the one set by the user), per axis, m/s.
    pub stated_sigma: Vector3<f64>,
    /// Angular velocity of the fitted trajectory on a regular grid: camera time, `w` (rad/s).
    pub angular: Vec<(f64, Vector3<f64>)>,
    /// Camera-time intervals of the calm samples of the clock-offset search.
    pub calm_spans: Vec<(f64, f64)>,
    /// Per pose: camera time, position residual (m) and rotation residual (rad) against the fit.
    pub pose_residuals: Vec<(f64, f64, f64)>,
    /// World positions: measured camera poses and the fitted trajectory on the grid.
    pub measured_path: Vec<Vector3<f64>>,
    pub fitted_path: Vec<Vector3<f64>>,
    /// The two world axes of the top view (those with the largest spread of positions).
    pub plane: (usize, usize),
    /// Stretches without valid DVL reports (DVL clock): bottom lock lost, reports invalid.
    pub dvl_gaps: Vec<(f64, f64)>,
    /// Gaps between camera poses, on the DVL clock at the final offset.
    pub pose_gaps: Vec<(f64, f64)>,
}

fn rms(v: impl Iterator<Item = Vector3<f64>>) -> Option<Vector3<f64>> {
    let mut n = 0usize;
    let mut s = Vector3::zeros();
    for x in v {
        s += x.component_mul(&x);
        n += 1;
    }
    (n > 0).then(|| (s / n as f64).map(f64::sqrt))
}

impl Derived {
    pub fn compute(input: &ReportInput) -> Result<Derived> {
        let o = input.outcome;
        let traj = &o.fitted;
        let (p, p0) = (&o.params, &o.start);
        let mut samples = Vec::with_capacity(o.used.len());
        let mut skipped = 0;
        for &i in &o.used {
            let Some(obs) = o.observations.get(i) else {
                skipped += 1;
                continue;
            };
            let t_cam = obs.t + p.time_offset_s;
            let Ok(q) = traj.state(t_cam) else {
                skipped += 1;
                continue;
            };
            let before = traj
                .state(obs.t + p0.time_offset_s)
                .ok()
                .map(|q0| predict(p0, &q0.twist));
            let v = q.twist.fixed_rows::<3>(0).into_owned();
            let w = q.twist.fixed_rows::<3>(3).into_owned();
            samples.push(Sample {
                t_dvl: obs.t,
                t_cam,
                measured: obs.v,
                before,
                after: predict(p, &q.twist),
                speed: v.norm(),
                lever: w.cross(&p.lever_arm_cam_m()).norm(),
                weight: o.robust.dvl_weights.get(i).copied().unwrap_or(1.0),
                sigma: Vector3::new(obs.cov[(0, 0)], obs.cov[(1, 1)], obs.cov[(2, 2)])
                    .map(|v| v.max(0.0).sqrt()),
            });
        }
        if samples.is_empty() {
            return Err(Error::Input(
                "the calibration outcome has no DVL sample inside its trajectory: nothing to report"
                    .into(),
            ));
        }
        let rms_after = rms(samples.iter().map(|s| s.measured - s.after)).unwrap_or_default();
        let rms_before = rms(samples
            .iter()
            .filter_map(|s| s.before.map(|b| s.measured - b)));
        let stated_sigma = rms(o
            .used
            .iter()
            .filter_map(|&i| o.observations.get(i))
            .map(|ob| Vector3::new(ob.cov[(0, 0)], ob.cov[(1, 1)], ob.cov[(2, 2)]).map(f64::sqrt)))
        .unwrap_or_default();

        let (a, b) = traj.span();
        let n = (input.poses.len() * 4).clamp(200, 20_000);
        let mut angular = Vec::with_capacity(n);
        let mut fitted_path = Vec::with_capacity(n);
        for k in 0..n {
            let t = a + (b - a) * k as f64 / (n - 1) as f64;
            if let Ok(q) = traj.state(t) {
                angular.push((t, q.twist.fixed_rows::<3>(3).into_owned()));
                fitted_path.push(q.pose.trans);
            }
        }

        let calm_spans = match &o.init {
            Some(init) => {
                let period = median_period(&o.observations.iter().map(|x| x.t).collect::<Vec<_>>());
                init.offset
                    .calm
                    .iter()
                    .filter_map(|&i| o.observations.get(i))
                    .map(|ob| {
                        let t = ob.t + init.offset.offset;
                        (t - 0.5 * period, t + 0.5 * period)
                    })
                    .collect()
            }
            None => Vec::new(),
        };

        let mut pose_residuals = Vec::with_capacity(input.poses.len());
        for m in input.poses {
            if let Ok(q) = traj.state(m.t) {
                let r = (q.pose.inverse() * m.pose).log();
                let rho = Vector3::new(r[0], r[1], r[2]);
                let phi = Vector3::new(r[3], r[4], r[5]);
                pose_residuals.push((m.t, rho.norm(), phi.norm()));
            }
        }
        let measured_path: Vec<Vector3<f64>> = input.poses.iter().map(|m| m.pose.trans).collect();
        let plane = top_view_plane(&measured_path);
        let valid_t: Vec<f64> = o.observations.iter().map(|x| x.t).collect();
        let dvl_gaps = time_gaps(&valid_t);
        let pose_gaps = crate::calib::pose_gaps(traj.times())
            .into_iter()
            .map(|(a, b)| (a - p.time_offset_s, b - p.time_offset_s))
            .collect();
        Ok(Derived {
            samples,
            skipped,
            rms_before,
            rms_after,
            stated_sigma,
            angular,
            calm_spans,
            pose_residuals,
            measured_path,
            fitted_path,
            plane,
            dvl_gaps,
            pose_gaps,
        })
    }
}

/// Stretches between consecutive sorted times longer than four median periods and half a
/// second (the DVL log's own gap rule).
fn time_gaps(t: &[f64]) -> Vec<(f64, f64)> {
    let limit = (4.0 * median_period(t)).max(0.5);
    t.windows(2)
        .filter(|w| w[1] - w[0] >= limit)
        .map(|w| (w[0], w[1]))
        .collect()
}

/// Median spacing of sorted times (0.1 s when there are fewer than two).
fn median_period(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if d.is_empty() {
        return 0.1;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

/// The two axes along which the positions spread most, in increasing axis order.
fn top_view_plane(p: &[Vector3<f64>]) -> (usize, usize) {
    if p.is_empty() {
        return (0, 1);
    }
    let n = p.len() as f64;
    let mean = p.iter().sum::<Vector3<f64>>() / n;
    let var = p
        .iter()
        .map(|x| (x - mean).component_mul(&(x - mean)))
        .sum::<Vector3<f64>>();
    // The axis of least spread is the one looked along.
    let mut least = 0;
    for k in 1..3 {
        if var[k] < var[least] {
            least = k;
        }
    }
    match least {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_drops_the_flattest_axis() {
        let p: Vec<Vector3<f64>> = (0..10)
            .map(|k| Vector3::new(k as f64, 0.01 * (k % 2) as f64, -2.0 * k as f64))
            .collect();
        assert_eq!(top_view_plane(&p), (0, 2));
        assert_eq!(top_view_plane(&[]), (0, 1));
    }

    #[test]
    fn report_gaps_are_the_dvl_logs_gaps_on_the_real_logs() {
        // The real A50 recordings hold dropouts (128 invalid of 1423 reports in dvl.bag): the
        // report's shaded stretches must be the gaps `dvl-info` lists.
        let dir =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/a50-ros-driver");
        for name in ["dvl.bag", "dvl_circle.jsonl", "dvl_slow_rectangle.jsonl"] {
            let log = crate::io::dvl::read_dvl_log(&dir.join(name), &Default::default())
                .expect("real log");
            let valid: Vec<f64> = log
                .samples
                .iter()
                .filter(|s| s.valid)
                .map(|s| s.t)
                .collect();
            let ours = time_gaps(&valid);
            let theirs = log.gaps(log.gap_threshold_s());
            assert!(!theirs.is_empty(), "{name}");
            assert_eq!(ours.len(), theirs.len(), "{name}");
            for (a, b) in ours.iter().zip(&theirs) {
                assert_eq!((a.0, a.1), (b.start_s, b.end_s), "{name}");
            }
        }
    }

    #[test]
    fn median_period_ignores_gaps() {
        assert_eq!(median_period(&[0.0, 0.1, 0.2, 5.0, 5.1]), 0.1);
        assert_eq!(median_period(&[1.0]), 0.1);
    }
}
