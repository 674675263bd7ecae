//! The IMU beside the camera: when a dataset holds an IMU stream and its noise file, the
//! camera-IMU calibration runs on the same camera poses as the DVL's, and its result joins the
//! DVL's in the result file (`T_cam_imu`, `imu_time_offset_s`, gravity, the biases at the
//! start, and the IMU's std and verdicts).

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::dataset::Dataset;
use crate::calib::diagnostics::{ImuVerdicts, imu_verdicts};
use crate::calib::imu::{ImuEstimate, ImuOptions, calibrate_camera_imu};
use crate::calib::options::WeakThresholds;
use crate::io::calib_yaml::{
    CalibrationFile, ImuBiasFile, ImuObservability, ImuStd, Observability, rows,
};
use crate::io::exports::ImuExport;
use crate::report::ImuReportInput;

/// The camera-IMU calibration of `data`, when it has an IMU stream and a noise file; a
/// warning (and `None`) when it has one without the other, or when the calibration fails (the
/// DVL's result stands without the IMU's, and the warning says why).
pub fn calibrate_imu(data: &Dataset, warnings: &mut Vec<String>) -> Option<ImuEstimate> {
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
            match calibrate_camera_imu(
                &data.poses,
                &log.samples,
                &noise.noise,
                &ImuOptions::default(),
            ) {
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
    let warnings: Vec<String> = [&judged.rotation, &judged.lever_arm, &judged.time_offset]
        .into_iter()
        .filter(|v| !v.ok)
        .map(|v| v.reason.clone())
        .collect();
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
