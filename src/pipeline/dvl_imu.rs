//! DVL + IMU, no camera: when a dataset has a DVL log and an IMU stream with its noise file
//! but no camera data, the DVL is calibrated against the IMU ([`calibrate_dvl_imu`]). Its
//! result file holds `T_imu_dvl`, the clock offset on the IMU's clock and the scale
//! ([`crate::io::dvl_imu_result`]), with std and verdicts as the camera's result has them.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use nalgebra::Vector3;

use super::calibration::{OutputOptions, ResultPaths, flag, prepare_outputs, sibling};
use super::dataset::Dataset;
use super::exports::notes_of;
use crate::calib::diagnostics::verdict_by_std;
use crate::calib::imu::ImuOptions;
use crate::calib::imu::dvl::{DvlImuEstimate, calibrate_dvl_imu};
use crate::calib::options::CalibOptions;
use crate::calib::outcome::{Verdict, WeakCause};
use crate::error::{Error, Result};
use crate::io::calib_yaml::{
    CalibrationInfo, CalibrationStd, ImuBiasFile, ObservabilityFlags, ResultStatus, RunFigures,
    rows,
};
use crate::io::dvl_imu_result::{DvlImuResultFile, write_dvl_imu_result_yaml};
use crate::io::exports::{Export, FrameNames, ros_static_transform, urdf_robot};
use crate::io::write_atomic;
use crate::report::ImuOnlyKind;

use super::imu_only::{ImuOnlyPage, write_imu_only_report};

/// The mode in words, as the summary and the result's notes state it.
pub use super::dataset::DVL_IMU_MODE as MODE;

/// A finished DVL + IMU calibration.
#[derive(Clone, Debug)]
pub struct DvlImuRun {
    /// What the estimator produced.
    pub estimate: DvlImuEstimate,
    /// The verdicts: rotation, lever arm, clock offset, scale.
    pub verdicts: [Verdict; 4],
    /// The result file's content.
    pub file: DvlImuResultFile,
    /// Seconds spent calibrating (the dataset was read before).
    pub elapsed_s: f64,
}

/// Calibrates the DVL of `data` (which has no camera data) against its IMU, the DVL's noise
/// and the verdicts' limits as `opts` says.
pub fn calibrate_dvl_imu_dataset(data: &Dataset, opts: &CalibOptions) -> Result<DvlImuRun> {
    let log = data.dvl()?;
    let (Some(imu), Some(noise)) = (&data.imu, &data.imu_noise) else {
        return Err(Error::dataset(
            &data.files.root,
            "no camera data, and no IMU stream with its noise file (give --imu-noise FILE) to \
             calibrate the DVL against",
        ));
    };
    let clock = Instant::now();
    let est = calibrate_dvl_imu(
        &log.samples,
        &imu.samples,
        &noise.noise,
        opts,
        &ImuOptions::default(),
    )
    .map_err(|e| e.during("calibrating the DVL against the IMU"))?;
    let elapsed_s = clock.elapsed().as_secs_f64();
    let verdicts = judge(&est, opts);
    let s = est.std();
    let mut info = CalibrationInfo {
        method: Some("DVL + IMU".into()),
        iterations: Some(est.iterations as u64),
        ..CalibrationInfo::default()
    };
    info.notes.push(format!(
        "{MODE}: the DVL was calibrated against the IMU (T_imu_dvl, t_imu = t_dvl + \
         time_offset_s)"
    ));
    info.warnings
        .extend(verdicts.iter().filter(|v| !v.ok).map(|v| v.reason.clone()));
    if let Some(shift) = est.prior_shift {
        let data = est.data_std();
        let over: [f64; 8] =
            std::array::from_fn(|i| shift[i].abs() / data[i].max(f64::MIN_POSITIVE));
        let groups = [
            ("rotation", &over[0..3]),
            ("lever arm", &over[3..6]),
            ("velocity scale", &over[6..7]),
            ("clock offset", &over[7..8]),
        ];
        if let Some((led, most)) = super::imu::prior_leads(&groups) {
            info.warnings.push(format!(
                "the DVL's {} depend more on the motion prior than on the sensors' noise: a \
                 motion prior ten times looser moves them by up to {:.1} times the standard \
                 deviation the data alone give (info.dvl_prior_shift_per_parameter), and \
                 their standard deviations include that move. Turn and change speed more \
                 during the recording",
                led, most
            ));
        }
    }
    let mut failure = Vec::new();
    if !est.converged {
        failure.push(format!(
            "the DVL-IMU calibration stopped after {} iterations without converging",
            est.iterations
        ));
    }
    info.figures = RunFigures {
        imu_file: Some(imu.path.display().to_string()),
        imu_samples: Some(imu.samples.len()),
        imu_bins_used: Some(est.bins_used),
        imu_bins: Some(est.bins_total),
        imu_noise_factor_gyro: Some(est.noise_factor.0),
        imu_noise_factor_accel: Some(est.noise_factor.1),
        imu_iterations: Some(est.iterations),
        dvl_log: Some(log.stats.path.display().to_string()),
        dvl_samples: Some(est.dvl_total),
        dvl_used: Some(est.dvl_used),
        dvl_noise_over_stated_variance: Some(est.noise_factor.2.powi(2)),
        dvl_prior_shift_per_parameter: est.prior_shift.map(|s| s.iter().copied().collect()),
        ..RunFigures::default()
    };
    let v3 = |v: &Vector3<f64>| [v.x, v.y, v.z];
    let file = DvlImuResultFile {
        status: Some(if failure.is_empty() {
            ResultStatus::Ok
        } else {
            ResultStatus::Failed
        }),
        failure,
        t_imu_dvl: rows(&est.params.t_cam_dvl.to_matrix()),
        time_offset_s: est.params.time_offset_s,
        velocity_scale: est.params.velocity_scale,
        imu_bias_start: est.imu.bias.values.first().map(|b| ImuBiasFile {
            gyro_radps: v3(&b.gyro),
            accel_mps2: v3(&b.accel),
        }),
        std: Some(CalibrationStd {
            rotation_deg: Some([s[0], s[1], s[2]].map(f64::to_degrees)),
            lever_arm_m: Some([s[3], s[4], s[5]]),
            time_offset_s: Some(s[7]),
            velocity_scale: Some(s[6]),
            clock_drift_ppm: None,
            imu: None,
        }),
        observability: Some(ObservabilityFlags {
            rotation: flag(&verdicts[0]),
            lever_arm: flag(&verdicts[1]),
            time_offset: flag(&verdicts[2]),
            velocity_scale: flag(&verdicts[3]),
            imu: None,
        }),
        info: Some(info),
        provenance: None,
    };
    Ok(DvlImuRun {
        estimate: est,
        verdicts,
        file,
        elapsed_s,
    })
}

/// The verdicts by the DVL's limits, with the motion each one needs.
fn judge(est: &DvlImuEstimate, opts: &CalibOptions) -> [Verdict; 4] {
    let s = est.std();
    let w = &opts.weak;
    let rot = s[0].max(s[1]).max(s[2]).to_degrees();
    let lever = s[3].max(s[4]).max(s[5]);
    [
        verdict_by_std(
            rot,
            w.rotation_deg,
            "rotation",
            "deg",
            "the vehicle moved along too few directions: move forwards, sideways and up and down",
            WeakCause::FewDirections,
        ),
        verdict_by_std(
            lever,
            w.lever_arm_m,
            "lever arm",
            "m",
            "the vehicle rotated too little: turn, pitch and roll it while it moves",
            WeakCause::LittleRotation,
        ),
        verdict_by_std(
            s[7],
            w.time_offset_s,
            "clock offset",
            "s",
            "the speed changed too little: speed up and slow down",
            WeakCause::LittleSpeedChange,
        ),
        verdict_by_std(
            s[6],
            w.velocity_scale,
            "velocity scale",
            "",
            "the vehicle moved too little: travel further, faster",
            WeakCause::LittleMotion,
        ),
    ]
}

impl DvlImuRun {
    /// Whether the calibration passed its checks (`status: ok`).
    pub fn ok(&self) -> bool {
        self.file.failure.is_empty()
    }

    /// The summary `dvlcal calibrate` prints: the mode, the counts, each estimate with its std
    /// and verdict, and every warning.
    pub fn summary(&self) -> String {
        let mut out = String::new();
        let e = &self.estimate;
        let s = e.std();
        let _ = writeln!(out, "mode      {MODE}");
        let _ = writeln!(
            out,
            "DVL: {} of {} reports used; IMU: {} of {} bins used; {} iterations{}; {:.2} s",
            e.dvl_used,
            e.dvl_total,
            e.bins_used,
            e.bins_total,
            e.iterations,
            if e.converged { "" } else { " (not converged)" },
            self.elapsed_s
        );
        let word = |v: &Verdict| if v.ok { "ok" } else { "WEAK" };
        let p = e.params.t_cam_dvl.trans;
        let q = e.params.t_cam_dvl.quaternion_xyzw();
        let _ = writeln!(
            out,
            "rotation  q_imu_dvl (xyzw) [{:.5}, {:.5}, {:.5}, {:.5}]  std {:.3} {:.3} {:.3} deg  {}",
            q[0],
            q[1],
            q[2],
            q[3],
            s[0].to_degrees(),
            s[1].to_degrees(),
            s[2].to_degrees(),
            word(&self.verdicts[0])
        );
        let _ = writeln!(
            out,
            "lever arm p_imu_dvl [{:.4}, {:.4}, {:.4}] m  std {:.1} {:.1} {:.1} mm  {}",
            p.x,
            p.y,
            p.z,
            1e3 * s[3],
            1e3 * s[4],
            1e3 * s[5],
            word(&self.verdicts[1])
        );
        let _ = writeln!(
            out,
            "offset    {:.4} s (t_imu = t_dvl + offset)  std {:.2} ms  {}",
            e.params.time_offset_s,
            1e3 * s[7],
            word(&self.verdicts[2])
        );
        let _ = writeln!(
            out,
            "scale     {:.5}  std {:.5}  {}",
            e.params.velocity_scale,
            s[6],
            word(&self.verdicts[3])
        );
        for w in self.file.info.iter().flat_map(|i| i.warnings.iter()) {
            let _ = writeln!(out, "warning: {w}");
        }
        out
    }
}

/// The exports' frame names: `--frames` (checked), else `imu` (the parent) and `dvl`.
fn frame_names(opts: &OutputOptions) -> Result<FrameNames> {
    match &opts.frames {
        Some(f) => {
            f.validate()?;
            Ok(f.clone())
        }
        None => Ok(FrameNames {
            camera: "imu".into(),
            dvl: "dvl".into(),
        }),
    }
}

/// Writes the DVL + IMU result YAML to `out` (its folder created, its `provenance` filled in)
/// and beside it, each atomically: `RESULT-tf.txt` (ROS static transforms of the DVL frame in
/// the IMU frame) and `RESULT-urdf.xml` (the IMU link, the DVL link and a fixed joint). There
/// is no Kalibr camchain-imucam file: it describes cameras, and this run has none; one left
/// beside `out` by an earlier run is removed. A failed calibration writes the result alone
/// (`status: failed`, its exports removed) unless `opts.force`.
///
/// With `report`, the HTML report ([`crate::report::render_imu_only_html`]) is written there
/// last, atomically, also for a failed calibration (it says why).
pub fn write_dvl_imu_results(
    out: &Path,
    run: &DvlImuRun,
    data: &Dataset,
    opts: &OutputOptions,
    report: Option<&Path>,
) -> Result<ResultPaths> {
    let names = frame_names(opts)?;
    let tf = sibling(out, "tf.txt");
    let imucam = sibling(out, "camchain-imucam.yaml");
    let urdf = sibling(out, "urdf.xml");
    let mut file = run.file.clone();
    file.provenance = Some(prepare_outputs(out, &[&tf, &imucam, &urdf], data, opts)?);
    write_dvl_imu_result_yaml(out, &file)?;
    crate::files::remove_stale(&[&imucam])?;
    let mut paths = ResultPaths {
        result: out.to_path_buf(),
        tf: None,
        camchain_imucam: None,
        urdf: None,
        report: None,
    };
    if let Some(path) = report {
        let e = &run.estimate;
        let counts = [format!(
            "DVL {}: {} of {} reports used; IMU {}: {} of {} bins used",
            data.dvl_path
                .as_ref()
                .map_or("?".into(), |p| p.display().to_string()),
            e.dvl_used,
            e.dvl_total,
            data.imu
                .as_ref()
                .map_or("?".into(), |l| l.path.display().to_string()),
            e.bins_used,
            e.bins_total
        )];
        let page = ImuOnlyPage {
            kind: ImuOnlyKind::DvlImu {
                estimate: e,
                verdicts: &run.verdicts,
            },
            mode: MODE,
            failure: &run.file.failure,
            warnings: run.file.info.as_ref().map_or(&[][..], |i| &i.warnings),
            counts: &counts,
            elapsed_s: run.elapsed_s,
        };
        write_imu_only_report(path, out, data, &page)?;
        paths.report = Some(path.to_path_buf());
    }
    if !(run.ok() || opts.force) {
        crate::files::remove_stale(&[&tf, &urdf])?;
        return Ok(paths);
    }
    let v = &run.verdicts;
    let notes = notes_of(
        [&v[0], &v[1], &v[2], &v[3]],
        (!run.ok()).then(|| run.file.failure.clone()),
    );
    let export = Export::dvl_in_imu(&run.estimate.params, &names, &notes);
    write_atomic(&tf, ros_static_transform(&export).as_bytes())?;
    write_atomic(&urdf, urdf_robot(&export).as_bytes())?;
    paths.tf = Some(tf);
    paths.urdf = Some(urdf);
    Ok(paths)
}
