//! The IMU beside the camera: when a dataset holds an IMU stream and its noise file, the
//! camera-IMU calibration runs on the same camera poses as the DVL's, and its result joins the
//! DVL's in the result file (`T_cam_imu`, `imu_time_offset_s`, gravity, the biases at the
//! start, and the IMU's std and verdicts).

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::dataset::Dataset;
use crate::calib::diagnostics::{ImuVerdicts, imu_verdicts, param_std, verdicts};
use crate::calib::halves::flag_inconsistent;
use crate::calib::imu::{
    CarriedDvl, ImuEstimate, ImuOptions, calibrate_camera_imu, calibrate_camera_imu_carried,
};
use crate::calib::model::{NPARAM, PARAM_NAMES, difference};
use crate::calib::options::CalibOptions;
use crate::calib::options::WeakThresholds;
use crate::calib::outcome::{CalibrationOutcome, DeterminedBy, Status};
use crate::io::calib_yaml::{
    CalibrationFile, ImuBiasFile, ImuObservability, ImuStd, Observability, rows,
};
use crate::io::exports::ImuExport;
use crate::report::ImuReportInput;

/// The camera-IMU calibration of `data`, when it has an IMU stream and a noise file; a
/// warning (and `None`) when it has one without the other, or when the calibration fails (the
/// DVL's result stands without the IMU's, and the warning says why). With `dvl` (the DVL's
/// camera-only outcome, when [`joint_eligible`]), the DVL's velocities join the problem with
/// the noise the camera-only run found ([`CarriedDvl`]) and the estimate's state carries the
/// DVL's parameters from the three sensors together; should that fail, the camera-IMU
/// calibration alone runs.
pub fn calibrate_imu(
    data: &Dataset,
    dvl: Option<(&CalibrationOutcome, &CalibOptions)>,
    warnings: &mut Vec<String>,
) -> Option<ImuEstimate> {
    match (&data.imu, &data.imu_noise) {
        (None, None) => None,
        (Some(log), None) => {
            warnings.push(format!(
                "{}: an IMU stream without a noise file (Kalibr's imu.yaml): the IMU was not \
                 calibrated; give --imu-noise FILE (or put its imu.yaml beside the dataset)",
                log.path.display()
            ));
            None
        }
        (None, Some(_)) => None,
        (Some(log), Some(noise)) => {
            let opts = ImuOptions::default();
            let joint = dvl.map(|(o, c)| {
                let carried = CarriedDvl::from_outcome(o, c);
                calibrate_camera_imu_carried(
                    &data.poses,
                    &log.samples,
                    &noise.noise,
                    &carried,
                    &opts,
                )
            });
            let alone = || calibrate_camera_imu(&data.poses, &log.samples, &noise.noise, &opts);
            let result = match joint {
                Some(Ok(est)) => Ok(est),
                Some(Err(e)) => {
                    warnings.push(format!(
                        "{}: the camera, IMU and DVL could not be calibrated together ({e}); \
                         the IMU was calibrated against the camera alone",
                        log.path.display()
                    ));
                    alone()
                }
                None => alone(),
            };
            match result {
                Ok(est) => Some(est),
                Err(e) => {
                    warnings.push(format!(
                        "{}: the IMU could not be calibrated: {e}",
                        log.path.display()
                    ));
                    None
                }
            }
        }
    }
}

/// Whether the DVL's camera-only outcome may be refined with the IMU in one problem: it
/// succeeded on one clock without drift, every parameter was estimated from the data, and no
/// DVL report was down-weighted as an outlier (the joint problem keeps the camera-only run's
/// weights, [`CarriedDvl`], and does not judge its own residuals: an outlier the IMU would show
/// otherwise would stay down-weighted as the camera alone judged it).
pub fn joint_eligible(o: &CalibrationOutcome, segments: usize) -> bool {
    let v = &o.verdicts;
    matches!(o.status, Status::Ok)
        && segments <= 1
        && o.clock_drift.is_none()
        && o.robust.dvl.outliers == 0
        && [&v.rotation, &v.lever_arm, &v.time_offset, &v.velocity_scale]
            .iter()
            .all(|x| x.by == DeterminedBy::Data)
}

/// Takes the DVL's values from the three-sensor problem into `o` when they agree with the
/// camera-only ones (each within 3 of the camera-only std); a disagreement keeps the
/// camera-only values and is a warning. The joint problem carries the camera-only run's findings
/// on the DVL's noise ([`CarriedDvl`]), so its std of the DVL's parameters are formed as the
/// camera-only ones are; they replace the camera-only covariance (and the verdicts are judged
/// again from them, by the same rule, the halves' flags kept) when none is larger than the
/// camera-only one and nothing makes them doubtful ([`joint_std_doubt`]). Otherwise the
/// camera-only std stay, an upper bound, and a note gives the joint ones with the reason.
/// `opts`: the camera-only run's options (its thresholds judge the verdicts).
pub fn adopt_joint_dvl(
    o: &mut CalibrationOutcome,
    est: &ImuEstimate,
    opts: &CalibOptions,
    warnings: &mut Vec<String>,
    notes: &mut Vec<String>,
) -> bool {
    let Some(p) = est.state.dvl else {
        return false;
    };
    let d = difference(&p, &o.params);
    let worst = (0..NPARAM)
        .map(|i| d[i].abs() / o.covariance[(i, i)].max(1e-300).sqrt())
        .fold(0.0, f64::max);
    if worst.is_nan() || worst > 3.0 {
        warnings.push(format!(
            "the DVL's calibration with the IMU differs from the camera-only one by {worst:.1} \
             of its std: the camera-only values are kept (is the IMU's noise file right, and \
             its stream from this recording?)"
        ));
        return false;
    }
    o.params = p;
    let c0 = est.state.dvl_start();
    let cov = crate::calib::update::ParamMat::from_fn(|i, j| {
        est.covariance
            .get((c0 + i, c0 + j))
            .copied()
            .unwrap_or(f64::NAN)
    });
    let js: [f64; NPARAM] = std::array::from_fn(|i| cov[(i, i)].max(0.0).sqrt());
    let cs: [f64; NPARAM] = std::array::from_fn(|i| o.covariance[(i, i)].max(0.0).sqrt());
    let head = format!(
        "the DVL's values come from the camera, IMU and DVL calibrated together (within \
         {worst:.1} std of the camera-only values)"
    );
    match joint_std_doubt(o, est, opts, &js, &cs) {
        None => {
            o.covariance = cov;
            o.std = param_std(&cov);
            let mut v = verdicts(
                &o.std,
                opts,
                &o.excitation,
                o.init.as_ref(),
                &[true; NPARAM],
            );
            if let Some(h) = &o.halves {
                flag_inconsistent(&mut v, h);
            }
            o.verdicts = v;
            notes.push(format!(
                "{head}, and so do its std, each at most the camera-only one (the DVL's noise \
                 as the camera-only run found it): {}; camera-only {}",
                std_words(&js),
                std_words(&cs)
            ));
        }
        Some(why) => notes.push(format!(
            "{head}; its std are the camera-only ones, an upper bound ({why}): together they are \
             {}",
            std_words(&js)
        )),
    }
    true
}

/// Why the joint problem's std `js` of the DVL's parameters may not replace the camera-only
/// ones `cs` (`None`: they may): the joint problem did not converge, a std is not a positive
/// number, the camera-only run had priors or held lever-arm directions (the joint problem has
/// neither, so its std are of another problem), or a joint std exceeds the camera-only one (the
/// IMU cannot make the DVL's parameters less certain: a larger std says the joint problem saw
/// the DVL's noise otherwise, and the camera-only std stay, the smaller).
pub fn joint_std_doubt(
    o: &CalibrationOutcome,
    est: &ImuEstimate,
    opts: &CalibOptions,
    js: &[f64; NPARAM],
    cs: &[f64; NPARAM],
) -> Option<String> {
    if !est.converged {
        return Some("the joint problem did not converge".into());
    }
    if js.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Some("the joint problem's std are not all positive".into());
    }
    if opts.priors.any() || o.priors.held_lever_axes.is_some() {
        return Some(
            "the camera-only calibration used priors, which the joint problem lacks".into(),
        );
    }
    let larger: Vec<String> = (0..NPARAM)
        .filter(|&k| js[k] > cs[k])
        .map(|k| {
            let (name, _, _) = PARAM_NAMES[k];
            format!("{name} {:.2}x", js[k] / cs[k])
        })
        .collect();
    (!larger.is_empty()).then(|| {
        format!(
            "the joint std exceed the camera-only ones: {}",
            larger.join(", ")
        )
    })
}

/// The DVL's std in words: rotation deg, lever arm mm, scale, offset ms.
fn std_words(s: &[f64; NPARAM]) -> String {
    format!(
        "rotation {:.3} {:.3} {:.3} deg, lever arm {:.1} {:.1} {:.1} mm, scale {:.5}, offset \
         {:.2} ms",
        s[0].to_degrees(),
        s[1].to_degrees(),
        s[2].to_degrees(),
        1e3 * s[3],
        1e3 * s[4],
        1e3 * s[5],
        s[6],
        1e3 * s[7]
    )
}

/// The IMU's calibration in a run, with its verdicts (for the report).
#[derive(Clone, Debug)]
pub struct ImuCalibration {
    /// The estimate.
    pub estimate: ImuEstimate,
    /// Its verdicts and the motion they were made from.
    pub verdicts: ImuVerdicts,
}

impl ImuCalibration {
    /// What the report shows of it.
    pub fn report_input(&self) -> ImuReportInput<'_> {
        ImuReportInput {
            estimate: &self.estimate,
            verdicts: &self.verdicts,
        }
    }
}

/// Writes `est` into the result file `f`, with verdicts by the thresholds `weak` (the DVL's:
/// per-axis rotation and lever-arm std and the offset's) and a warning per weak one; the
/// calibration with its verdicts.
pub fn note_imu(
    f: &mut CalibrationFile,
    est: ImuEstimate,
    data: &Dataset,
    weak: &WeakThresholds,
) -> ImuCalibration {
    let v = |x: &Vector3<f64>| [x.x, x.y, x.z];
    let st = &est.state;
    f.t_cam_imu = Some(rows(&st.t_cam_imu.to_matrix()));
    f.imu_time_offset_s = Some(st.time_offset_s);
    f.imu_gravity_world_mps2 = Some(v(&st.gravity_world()));
    f.imu_bias_start = st.bias.values.first().map(|b| ImuBiasFile {
        gyro_radps: v(&b.gyro),
        accel_mps2: v(&b.accel),
    });
    let (s_rot, s_lever, s_off) = est.std();
    let s_rot_deg = s_rot.map(f64::to_degrees);
    let judged = imu_verdicts(&est, weak);
    let verdicts = ImuObservability {
        rotation: super::exports::state(&judged.rotation),
        lever_arm: super::exports::state(&judged.lever_arm),
        time_offset: super::exports::state(&judged.time_offset),
    };
    let mut warnings: Vec<String> = [&judged.rotation, &judged.lever_arm, &judged.time_offset]
        .into_iter()
        .filter(|v| !v.ok)
        .map(|v| v.reason.clone())
        .collect();
    let prior_share = est.prior_shift.map(|p| (p, p.over_data_std(&est)));
    if let Some((_, over)) = &prior_share {
        let groups = [
            ("rotation", &over[0..3]),
            ("lever arm", &over[3..6]),
            ("clock offset", &over[6..7]),
        ];
        if let Some((led, most)) = prior_leads(&groups) {
            warnings.push(format!(
                "the IMU's {} depend more on the motion prior than on the sensors' noise: a                  motion prior ten times looser moves them by up to {:.1} times the standard                  deviation the data alone give (info.imu_prior_shift_*), and their standard                  deviations include that move. The IMU saw too little angular acceleration                  for its noise: rotate more briskly about several axes, and check that its                  noise file is the IMU's",
                led, most
            ));
        }
    }
    if let Some(s) = f.std.as_mut() {
        s.imu = Some(ImuStd {
            rotation_deg: v(&s_rot_deg),
            lever_arm_m: v(&s_lever),
            time_offset_s: s_off,
        });
    }
    if let Some(o) = f.observability.as_mut() {
        o.imu = Some(verdicts);
    }
    let info = f.info.get_or_insert_with(Default::default);
    info.warnings.extend(warnings);
    let fig = &mut info.figures;
    fig.imu_file = data.imu.as_ref().map(|l| l.path.display().to_string());
    fig.imu_samples = data.imu.as_ref().map(|l| l.samples.len());
    fig.imu_bins_used = Some(est.bins_used);
    fig.imu_bins = Some(est.bins_total);
    fig.imu_noise_factor_gyro = Some(est.noise_factor.0);
    fig.imu_noise_factor_accel = Some(est.noise_factor.1);
    fig.imu_iterations = Some(est.iterations);
    if let Some((p, _)) = &prior_share {
        fig.imu_prior_shift_rotation_deg = Some(v(&p.rotation.map(f64::to_degrees)));
        fig.imu_prior_shift_lever_arm_m = Some(v(&p.lever_arm));
        fig.imu_prior_shift_time_offset_s = Some(p.time_offset_s);
    }
    if est.noise_factor.0 > 1.0 || est.noise_factor.1 > 1.0 {
        info.notes.push(format!(
            "the IMU's residuals scatter {:.1}x (gyro) and {:.1}x (accelerometer) its stated \
             noise densities; its standard deviations are scaled by these factors",
            est.noise_factor.0, est.noise_factor.1
        ));
    }
    ImuCalibration {
        estimate: est,
        verdicts: judged,
    }
}

/// A quantity's shift under a ten times looser motion prior, over the std the data alone give
/// it, beyond which the result warns that the prior, not the sensors' noise, leads its std
/// (the std are then more than twice the data's).
pub const PRIOR_LEADS: f64 = 2.0;

/// Of the named groups of ratios (a quantity's shift under the looser prior over its data
/// std), the names of those with a ratio above [`PRIOR_LEADS`], joined with "and", and the
/// largest ratio of all; `None` when no group is led by the prior.
pub(crate) fn prior_leads(groups: &[(&str, &[f64])]) -> Option<(String, f64)> {
    let led: Vec<&str> = groups
        .iter()
        .filter(|(_, r)| r.iter().any(|x| *x > PRIOR_LEADS))
        .map(|(n, _)| *n)
        .collect();
    let most = groups
        .iter()
        .flat_map(|(_, r)| r.iter().copied())
        .fold(0.0, f64::max);
    (!led.is_empty()).then(|| (led.join(" and "), most))
}

/// The IMU's lines of the run summary (empty without an IMU result).
pub fn summary_lines(f: &CalibrationFile) -> String {
    let (Some(m), Some(off)) = (&f.t_cam_imu, f.imu_time_offset_s) else {
        return String::new();
    };
    let std = f.std.as_ref().and_then(|s| s.imu.as_ref());
    let obs = f.observability.as_ref().and_then(|o| o.imu.as_ref());
    let words = |o: Option<Observability>| o.map_or("", |o| o.words());
    let mut out = String::new();
    let r = crate::lie::Se3::from_matrix(&nalgebra::Matrix4::from_fn(|i, j| m[i][j]));
    let q = r.quaternion_xyzw();
    let _ = writeln!(
        out,
        "imu rot   q_cam_imu (xyzw) [{:.5}, {:.5}, {:.5}, {:.5}]  std [{}] deg  {}",
        q[0],
        q[1],
        q[2],
        q[3],
        std.map_or(String::new(), |s| format!(
            "{:.3}, {:.3}, {:.3}",
            s.rotation_deg[0], s.rotation_deg[1], s.rotation_deg[2]
        )),
        words(obs.map(|o| o.rotation))
    );
    let _ = writeln!(
        out,
        "imu lever p_cam_imu [{:.4}, {:.4}, {:.4}] m  std [{}] m  {}",
        m[0][3],
        m[1][3],
        m[2][3],
        std.map_or(String::new(), |s| format!(
            "{:.4}, {:.4}, {:.4}",
            s.lever_arm_m[0], s.lever_arm_m[1], s.lever_arm_m[2]
        )),
        words(obs.map(|o| o.lever_arm))
    );
    let _ = writeln!(
        out,
        "imu clock imu_time_offset_s {off:.5} s  std {}  {}",
        std.map_or(String::new(), |s| format!("{:.5} s", s.time_offset_s)),
        words(obs.map(|o| o.time_offset))
    );
    out
}

/// The IMU of a result file, for the exports (frame `imu`); `None` without one.
pub fn imu_export(f: &CalibrationFile) -> Option<ImuExport> {
    let (m, off) = (f.t_cam_imu.as_ref()?, f.imu_time_offset_s?);
    Some(ImuExport {
        t_cam_imu: crate::lie::Se3::from_matrix(&nalgebra::Matrix4::from_fn(|i, j| m[i][j])),
        time_offset_s: off,
        frame: "imu".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_prior_leads_the_groups_with_a_ratio_above_its_bound() {
        let groups = [
            ("rotation", &[0.1, 2.5, 0.3][..]),
            ("lever arm", &[1.9, 0.2, 3.0][..]),
            ("clock offset", &[2.0][..]),
        ];
        assert_eq!(
            prior_leads(&groups),
            Some(("rotation and lever arm".to_string(), 3.0))
        );
        assert_eq!(prior_leads(&groups[2..]), None);
    }
}
