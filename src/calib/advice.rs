//! What motion to add to a recording: for each candidate motion (turning about one of the
//! camera's axes, speeding up and slowing down, moving sideways or up and down), the
//! information its DVL reports would add to the present estimate, and the standard deviations
//! the estimate would then have. The candidates are ranked by how far they bring the parameters
//! that miss their targets towards them, so the advice follows the data already recorded rather
//! than a fixed table.
//!
//! The information of a candidate is that of the DVL's prediction `kappa R (v + w x p)` at its
//! reports ([`super::model::d_predict_d_params`]), the camera's twist taken as known: the same
//! linearisation the refinement's covariance uses, without the trajectory's own uncertainty,
//! so it ranks motions well and is somewhat optimistic about the std they reach.

use nalgebra::{SMatrix, Vector6};

use super::model::{NPARAM, d_predict_d_params};
use super::options::WeakThresholds;
use crate::types::CalibrationParams;

/// The four parameter groups, in the order [`Progress`] lists them.
pub const GROUPS: [&str; 4] = ["rotation", "lever_arm", "time_offset", "velocity_scale"];

/// One parameter group against its target: the largest std of its components (rotation in
/// degrees, lever arm in metres, offset in seconds, the scale unitless).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupStd {
    /// The group's largest standard deviation.
    pub std: f64,
    /// Its target (the verdict's limit).
    pub target: f64,
}

impl GroupStd {
    /// Whether the group meets its target.
    pub fn met(&self) -> bool {
        self.std <= self.target
    }
}

/// The groups' std from an 8x8 covariance in the estimator's coordinates, against `limits`.
pub fn group_std(cov: &SMatrix<f64, NPARAM, NPARAM>, limits: &WeakThresholds) -> [GroupStd; 4] {
    let s = |i: usize| cov[(i, i)].max(0.0).sqrt();
    let max3 = |i: usize| s(i).max(s(i + 1)).max(s(i + 2));
    [
        GroupStd {
            std: max3(0).to_degrees(),
            target: limits.rotation_deg,
        },
        GroupStd {
            std: max3(3),
            target: limits.lever_arm_m,
        },
        GroupStd {
            std: s(7),
            target: limits.time_offset_s,
        },
        GroupStd {
            std: s(6),
            target: limits.velocity_scale,
        },
    ]
}

/// What the recording looks like so far, for shaping the candidates: the DVL's report rate and
/// noise, and the typical speed (m/s) and rate of turn (rad/s) of the camera.
#[derive(Clone, Copy, Debug)]
pub struct Recording {
    /// DVL reports per second.
    pub dvl_rate_hz: f64,
    /// The DVL's noise per axis, m/s.
    pub dvl_sigma: f64,
    /// The camera's RMS speed so far, m/s.
    pub speed_mps: f64,
}

/// The camera's twist `[v; w]` and its rate at a time from the motion's start.
type TwistAt = Box<dyn Fn(f64) -> (Vector6<f64>, Vector6<f64>)>;

/// A candidate motion: what to tell the pilot, and the camera's twist and its rate over it.
struct Candidate {
    words: String,
    duration_s: f64,
    twist: TwistAt,
}

/// The name of the camera's axis `k` (x right, y down, z forward) and the turn about it.
const AXES: [(&str, &str); 3] = [("x", "pitch"), ("y", "yaw"), ("z", "roll")];

/// Turning rate (rad/s) and speed change (m/s) the candidates ask for.
const TURN_RADPS: f64 = 0.5;
const SPEED_CHANGE_MPS: f64 = 0.3;
const SECONDS: f64 = 10.0;

fn candidates(rec: &Recording) -> Vec<Candidate> {
    // The candidates move forward at the recording's speed (at least 0.1 m/s) while they turn,
    // as a vehicle that keeps the board in view would.
    let cruise = rec.speed_mps.clamp(0.1, 1.0);
    let period = 4.0;
    let omega = std::f64::consts::TAU / period;
    let mut v = Vec::new();
    for (k, (axis, turn)) in AXES.iter().enumerate() {
        v.push(Candidate {
            words: format!(
                "rotate about the camera's {axis} axis ({turn}) back and forth at {TURN_RADPS} \
                 rad/s or more for about {SECONDS} s"
            ),
            duration_s: SECONDS,
            twist: Box::new(move |t| {
                let mut tw = Vector6::zeros();
                let mut rate = Vector6::zeros();
                tw[2] = cruise;
                tw[3 + k] = TURN_RADPS * (omega * t).sin();
                rate[3 + k] = TURN_RADPS * omega * (omega * t).cos();
                (tw, rate)
            }),
        });
    }
    v.push(Candidate {
        words: format!(
            "vary the speed: stop and go, speeding up to {} m/s and slowing to a stop, for about \
             {SECONDS} s",
            2.0 * SPEED_CHANGE_MPS
        ),
        duration_s: SECONDS,
        twist: Box::new(move |t| {
            let mut tw = Vector6::zeros();
            let mut rate = Vector6::zeros();
            tw[2] = SPEED_CHANGE_MPS * (1.0 - (omega * t).cos());
            rate[2] = SPEED_CHANGE_MPS * omega * (omega * t).sin();
            (tw, rate)
        }),
    });
    for (k, words) in [
        (0, "sideways (along the camera's x axis)"),
        (1, "up and down (along the camera's y axis)"),
    ] {
        v.push(Candidate {
            words: format!(
                "move {words} back and forth at {SPEED_CHANGE_MPS} m/s for about {SECONDS} s"
            ),
            duration_s: SECONDS,
            twist: Box::new(move |t| {
                let mut tw = Vector6::zeros();
                let mut rate = Vector6::zeros();
                tw[2] = cruise;
                tw[k] = SPEED_CHANGE_MPS * (omega * t).sin();
                rate[k] = SPEED_CHANGE_MPS * omega * (omega * t).cos();
                (tw, rate)
            }),
        });
    }
    v
}

/// The information (8x8) the DVL's reports over a candidate add.
fn information(
    p: &CalibrationParams,
    c: &Candidate,
    rec: &Recording,
) -> SMatrix<f64, NPARAM, NPARAM> {
    let rate = rec.dvl_rate_hz.clamp(0.5, 50.0);
    let n = (c.duration_s * rate).round().max(1.0) as usize;
    let w = 1.0 / rec.dvl_sigma.max(1e-4).powi(2);
    let mut info = SMatrix::<f64, NPARAM, NPARAM>::zeros();
    for i in 0..n {
        let (tw, r) = (c.twist)(i as f64 / rate);
        let j = d_predict_d_params(p, &tw, &r);
        info += j.transpose() * j * w;
    }
    info
}

/// The covariance after adding `info` to the estimate's: `(Sigma^-1 + I)^-1`, computed as
/// `Sigma - Sigma (I^-1 + Sigma)^-1 Sigma` in the form that needs no inverse of a singular
/// `Sigma` (held parameters have zero variance and stay held): `Sigma (1 + I Sigma)^-1`.
fn updated(
    cov: &SMatrix<f64, NPARAM, NPARAM>,
    info: &SMatrix<f64, NPARAM, NPARAM>,
) -> Option<SMatrix<f64, NPARAM, NPARAM>> {
    let m = SMatrix::<f64, NPARAM, NPARAM>::identity() + info * cov;
    let inv = m.try_inverse()?;
    let out = cov * inv;
    Some((out + out.transpose()) * 0.5)
}

/// The components of each group, in the estimator's order.
const MEMBERS: [&[usize]; 4] = [&[0, 1, 2], &[3, 4, 5], &[7], &[6]];

/// The target of component `i` in the estimator's units (rad, m, -, s).
fn component_target(i: usize, limits: &WeakThresholds) -> f64 {
    match i {
        0..=2 => limits.rotation_deg.to_radians(),
        3..=5 => limits.lever_arm_m,
        6 => limits.velocity_scale,
        _ => limits.time_offset_s,
    }
}

/// One piece of advice: the motion, and what it would do to the parameters that miss their
/// targets.
#[derive(Clone, Debug, PartialEq)]
pub struct Advice {
    /// The motion in words.
    pub motion: String,
    /// For each group it helps: the group, the component it helps most (`x`, `y`, `z`, or
    /// empty for the offset and the scale), that component's std now and after the motion.
    pub effect: Vec<(&'static str, &'static str, f64, f64)>,
}

impl Advice {
    /// The advice as one sentence: the motion, then what it would do.
    pub fn sentence(&self) -> String {
        let effects: Vec<String> = self
            .effect
            .iter()
            .map(|(g, axis, now, after)| {
                let (scale, unit) = match *g {
                    "rotation" => (1.0, " deg"),
                    "lever_arm" => (1e3, " mm"),
                    "time_offset" => (1e3, " ms"),
                    _ => (1.0, ""),
                };
                let name = g.replace('_', " ");
                let name = if axis.is_empty() {
                    name
                } else {
                    format!("{name} {axis}")
                };
                format!(
                    "{name} std {} to {}{unit}",
                    short(now * scale),
                    short(after * scale)
                )
            })
            .collect();
        if effects.is_empty() {
            self.motion.clone()
        } else {
            format!("{}: {}", self.motion, effects.join(", "))
        }
    }
}

fn short(x: f64) -> String {
    if x >= 100.0 {
        format!("{x:.0}")
    } else if x >= 1.0 {
        format!("{x:.1}")
    } else {
        format!("{x:.2}")
    }
}

/// Component `i`'s std in the display unit of its group's target (deg for the rotation).
fn component_std(c: &SMatrix<f64, NPARAM, NPARAM>, i: usize) -> f64 {
    let s = c[(i, i)].max(0.0).sqrt();
    if i < 3 { s.to_degrees() } else { s }
}

/// How far the components of the groups in `open` are above their targets, in natural-log
/// units summed.
fn shortfall(c: &SMatrix<f64, NPARAM, NPARAM>, open: &[usize], limits: &WeakThresholds) -> f64 {
    open.iter()
        .flat_map(|&g| MEMBERS[g].iter())
        .map(|&i| {
            (c[(i, i)].max(0.0).sqrt() / component_target(i, limits))
                .ln()
                .max(0.0)
        })
        .sum()
}

/// A plan of at most three motions, best first, for the groups that miss their targets: each
/// step takes the candidate that most reduces what the groups still miss (measured on their
/// components, since a turn about one axis observes only two of the lever arm's three), given
/// the steps before it; the plan stops when every group meets its target or no candidate helps
/// by a tenth of a natural-log unit. Empty when every group meets its target now.
pub fn advise(
    p: &CalibrationParams,
    cov: &SMatrix<f64, NPARAM, NPARAM>,
    limits: &WeakThresholds,
    rec: &Recording,
) -> Vec<Advice> {
    let cands = candidates(rec);
    let infos: Vec<_> = cands.iter().map(|c| information(p, c, rec)).collect();
    let mut current = *cov;
    let mut used = vec![false; cands.len()];
    let mut out = Vec::new();
    while out.len() < 3 {
        let now = group_std(&current, limits);
        let open: Vec<usize> = (0..4).filter(|&g| !now[g].met()).collect();
        if open.is_empty() {
            break;
        }
        let before = shortfall(&current, &open, limits);
        // The first of equals wins: the candidates are listed simplest first.
        let mut best: Option<(usize, f64, SMatrix<f64, NPARAM, NPARAM>)> = None;
        for (i, info) in infos.iter().enumerate() {
            let Some(after) = updated(&current, info).filter(|_| !used[i]) else {
                continue;
            };
            let gain = before - shortfall(&after, &open, limits);
            if best.as_ref().is_none_or(|(_, b, _)| gain > *b) {
                best = Some((i, gain, after));
            }
        }
        let Some((i, gain, after)) = best else { break };
        if gain < 0.1 {
            break;
        }
        used[i] = true;
        let effect = open
            .iter()
            .filter_map(|&g| {
                // The component the motion helps most, if by at least 5 %.
                let (k, ratio) = MEMBERS[g]
                    .iter()
                    .map(|&k| (k, component_std(&after, k) / component_std(&current, k)))
                    .min_by(|a, b| a.1.total_cmp(&b.1))?;
                let axis = match MEMBERS[g].len() {
                    1 => "",
                    _ => ["x", "y", "z"][k % 3],
                };
                (ratio < 0.95).then(|| {
                    (
                        GROUPS[g],
                        axis,
                        component_std(&current, k),
                        component_std(&after, k),
                    )
                })
            })
            .collect();
        out.push(Advice {
            motion: cands[i].words.clone(),
            effect,
        });
        current = after;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::Se3;

    fn params() -> CalibrationParams {
        CalibrationParams {
            t_cam_dvl: Se3::exp(&Vector6::new(0.1, -0.05, 0.15, 0.2, 1.0, -0.4)),
            time_offset_s: 0.05,
            velocity_scale: 1.0,
        }
    }

    fn rec() -> Recording {
        Recording {
            dvl_rate_hz: 8.0,
            dvl_sigma: 0.01,
            speed_mps: 0.2,
        }
    }

    fn cov(std: [f64; NPARAM]) -> SMatrix<f64, NPARAM, NPARAM> {
        SMatrix::from_diagonal(&SMatrix::<f64, NPARAM, 1>::from_fn(|i, _| std[i] * std[i]))
    }

    /// A recording without turns: the lever arm is weak (0.5 m), the rest is fine; the first
    /// advice is to rotate, and it would bring the lever arm's std down by more than ten times.
    #[test]
    fn a_weak_lever_arm_asks_for_rotation() {
        let c = cov([1e-3, 1e-3, 1e-3, 0.5, 0.5, 0.5, 1e-3, 2e-3]);
        let a = advise(&params(), &c, &WeakThresholds::default(), &rec());
        assert!(!a.is_empty());
        assert!(a[0].motion.starts_with("rotate about"), "{a:?}");
        let (g, _, now, after) = a[0].effect[0];
        assert_eq!(g, "lever_arm");
        assert!(after < now / 10.0, "{now} -> {after}");
        // One turn observes the lever arm across its axis only: the advice goes on to a second.
        assert!(
            a.len() >= 2 && a[1].motion.starts_with("rotate about"),
            "{a:?}"
        );
        assert_ne!(a[0].motion, a[1].motion);
    }

    /// A weak clock offset (50 ms) alone asks for speed changes.
    #[test]
    fn a_weak_clock_asks_for_speed_changes() {
        let c = cov([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 0.05]);
        let a = advise(&params(), &c, &WeakThresholds::default(), &rec());
        assert!(a[0].motion.starts_with("vary the speed"), "{a:?}");
        assert_eq!(a[0].effect[0].0, "time_offset");
    }

    /// Every group at its target: no advice. A held parameter (zero variance) stays held.
    #[test]
    fn nothing_to_advise_when_every_target_is_met() {
        let c = cov([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3]);
        assert!(advise(&params(), &c, &WeakThresholds::default(), &rec()).is_empty());
        let held = cov([1e-3, 1e-3, 1e-3, 0.0, 0.0, 0.0, 1e-3, 1e-3]);
        let c = candidates(&rec());
        let after = updated(&held, &information(&params(), &c[0], &rec())).unwrap();
        assert!(after[(3, 3)].abs() < 1e-15);
        assert!(after[(0, 0)] < held[(0, 0)]);
    }

    /// The update is the inverse of the summed information when both are invertible.
    #[test]
    fn the_update_adds_information() {
        let c0 = cov([0.01, 0.02, 0.03, 0.1, 0.2, 0.3, 0.01, 0.02]);
        let cands = candidates(&rec());
        let info = information(&params(), &cands[1], &rec());
        let after = updated(&c0, &info).unwrap();
        let direct = (c0.try_inverse().unwrap() + info).try_inverse().unwrap();
        let d = (after - direct).abs().max() / direct.abs().max();
        assert!(d < 1e-9, "{d}");
    }
}
