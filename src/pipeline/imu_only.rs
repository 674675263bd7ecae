//! Camera + IMU, no DVL log (Kalibr's camera-IMU job): when a dataset has camera poses (or
//! images) and an IMU stream with its noise file but no DVL log, only the camera-IMU
//! calibration runs. Its result file holds the IMU's keys and no DVL keys
//! ([`crate::io::imu_result`]); beside it the exports that need no DVL: the ROS static
//! transform and the URDF joint of the IMU, and Kalibr's camchain-imucam with the IMU in its
//! IMU slot.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use crate::calib::diagnostics::ImuVerdicts;
use crate::calib::imu::{ImuEstimate, ImuOptions, calibrate_camera_imu};
use crate::calib::options::WeakThresholds;
use crate::error::{Error, Result};
use crate::io::calib_yaml::{
    CalibrationFile, CalibrationInfo, CalibrationStd, Observability, ObservabilityFlags,
    ResultStatus,
};
use crate::io::exports::{
    Export, ExportNotes, Parent, kalibr_camchain_imucam, ros_static_transform, urdf_robot,
};
use crate::io::imu_result::{ImuResultFile, write_imu_result_yaml};
use crate::io::write_atomic;
use crate::lie::Se3;
use crate::report::{ImuOnlyKind, ImuOnlyReportInput, ImuReportInput, render_imu_only_html};
use crate::types::CalibrationParams;

use super::calibration::{
    OutputOptions, ResultPaths, frame_names, kalibr_cameras, prepare_outputs, sibling,
};
use super::dataset::Dataset;

/// The mode in words, as the summary and the result's notes state it.
pub const MODE: &str = "camera + IMU: no DVL log given";

/// A finished camera + IMU calibration.
#[derive(Clone, Debug)]
pub struct CameraImuRun {
    /// What the estimator produced.
    pub estimate: ImuEstimate,
    /// Its verdicts and the motion they were made from.
    pub verdicts: ImuVerdicts,
    /// The result file's content (no DVL keys).
    pub file: ImuResultFile,
    /// Seconds spent calibrating (the dataset was read before).
    pub elapsed_s: f64,
    /// The same keys in a whole result file's form (the DVL's placeholders never written):
    /// what the summary and the exports read.
    whole: CalibrationFile,
}

/// Calibrates the IMU of `data` (which has no DVL log) against its camera poses, on a pool of
/// `threads` workers (`None`: all cores), with the verdicts by `weak` (the DVL's thresholds,
/// as in the three-sensor mode).
pub fn calibrate_camera_imu_dataset(
    data: &Dataset,
    weak: &WeakThresholds,
    threads: Option<usize>,
) -> Result<CameraImuRun> {
    let (Some(log), Some(noise)) = (&data.imu, &data.imu_noise) else {
        return Err(Error::dataset(
            &data.files.root,
            format!(
                "{MODE}, and no IMU stream with its noise file to calibrate (an IMU CSV: \
                 imu0/data.csv or --imu FILE, or a bag's sensor_msgs/Imu topic; its noise: \
                 imu.yaml or --imu-noise FILE)"
            ),
        ));
    };
    let workers = crate::parallel::worker_pool(threads)?;
    let start = Instant::now();
    let estimate = workers
        .install(|| {
            calibrate_camera_imu(
                &data.poses,
                &log.samples,
                &noise.noise,
                &ImuOptions::default(),
            )
        })
        .map_err(|e| {
            e.during(format!(
                "calibrating the IMU {} against {} ({MODE})",
                log.path.display(),
                data.camera_source.display()
            ))
        })?;
    let elapsed_s = start.elapsed().as_secs_f64();
    // A whole result file with the DVL's keys as placeholders: the IMU's keys are filled in
    // by the three-sensor mode's own code, and only they are written.
    let placeholder = CalibrationParams {
        t_cam_dvl: Se3::identity(),
        time_offset_s: 0.0,
        velocity_scale: 1.0,
    };
    let mut whole = CalibrationFile::from_params(&placeholder);
    whole.status = Some(ResultStatus::Ok);
    whole.std = Some(CalibrationStd {
        rotation_deg: None,
        lever_arm_m: None,
        time_offset_s: None,
        velocity_scale: None,
        clock_drift_ppm: None,
        imu: None,
    });
    let ok = Observability::Ok;
    whole.observability = Some(ObservabilityFlags {
        rotation: ok,
        lever_arm: ok,
        time_offset: ok,
        velocity_scale: ok,
        imu: None,
    });
    let mut info = CalibrationInfo {
        method: Some("camera + IMU".into()),
        iterations: Some(estimate.iterations as u64),
        ..CalibrationInfo::default()
    };
    info.notes.push(format!(
        "{MODE}: only the IMU was calibrated against the camera"
    ));
    if !estimate.converged {
        info.warnings.push(format!(
            "the camera-IMU calibration stopped after {} iterations without converging",
            estimate.iterations
        ));
    }
    whole.info = Some(info);
    data.note_held_poses(&mut whole);
    let noted = super::imu::note_imu(&mut whole, estimate, data, weak);
    let (estimate, verdicts) = (noted.estimate, noted.verdicts);
    let file = ImuResultFile::from_calibration_file(&whole)
        .ok_or_else(|| Error::Input("the IMU's result is missing from its result file".into()))?;
    Ok(CameraImuRun {
        estimate,
        verdicts,
        file,
        elapsed_s,
        whole,
    })
}

impl CameraImuRun {
    /// The summary `dvlcal calibrate` prints: the mode, the counts, the IMU's estimates with
    /// their std and verdicts, and every warning.
    pub fn summary(&self, data: &Dataset) -> String {
        let mut out = String::new();
        let e = &self.estimate;
        let _ = writeln!(out, "mode      {MODE}");
        let _ = writeln!(
            out,
            "{} poses; IMU: {} samples, {} of {} bins used; {} iterations{}; {:.2} s",
            data.poses.len(),
            data.imu.as_ref().map_or(0, |l| l.samples.len()),
            e.bins_used,
            e.bins_total,
            e.iterations,
            if e.converged { "" } else { " (not converged)" },
            self.elapsed_s
        );
        out.push_str(&super::imu::summary_lines(&self.whole));
        for w in self.file.info.iter().flat_map(|i| i.warnings.iter()) {
            let _ = writeln!(out, "warning: {w}");
        }
        out
    }
}

/// Writes the camera + IMU result YAML to `out` (its folder created, its `provenance` filled
/// in) and beside it, each atomically: `RESULT-tf.txt` (the IMU's ROS static transforms),
/// `RESULT-urdf.xml` (the camera and IMU links, a fixed joint) and
/// `RESULT-camchain-imucam.yaml` (Kalibr's, the IMU in its IMU slot). The exports' camera
/// frame is `--frames`' parent or the data's, the IMU's `imu`.
///
/// With `report`, the HTML report ([`crate::report::render_imu_only_html`]) is written there
/// last, atomically.
pub fn write_camera_imu_results(
    out: &Path,
    run: &CameraImuRun,
    data: &Dataset,
    opts: &OutputOptions,
    report: Option<&Path>,
) -> Result<ResultPaths> {
    let names = frame_names(opts, data)?;
    let tf = sibling(out, "tf.txt");
    let imucam = sibling(out, "camchain-imucam.yaml");
    let urdf = sibling(out, "urdf.xml");
    let mut file = run.file.clone();
    file.provenance = Some(prepare_outputs(out, &[&tf, &imucam, &urdf], data, opts)?);
    write_imu_result_yaml(out, &file)?;
    let imu = super::imu::imu_export(&run.whole)
        .ok_or_else(|| Error::Input("the IMU's result is missing".into()))?;
    let notes = ExportNotes::default();
    let e = Export {
        dvl: None,
        imu: Some(&imu),
        names: &names,
        notes: &notes,
        parent: Parent::Camera,
    };
    write_atomic(&tf, ros_static_transform(&e).as_bytes())?;
    write_atomic(&urdf, urdf_robot(&e).as_bytes())?;
    write_atomic(
        &imucam,
        kalibr_camchain_imucam(&e, &kalibr_cameras(data)).as_bytes(),
    )?;
    let report = match report {
        Some(path) => {
            let counts = [format!(
                "{} camera poses from {}; IMU {}: {} samples, {} of {} bins used",
                data.poses.len(),
                data.camera_source.display(),
                data.imu
                    .as_ref()
                    .map_or("?".into(), |l| l.path.display().to_string()),
                data.imu.as_ref().map_or(0, |l| l.samples.len()),
                run.estimate.bins_used,
                run.estimate.bins_total,
            )];
            let input = ImuReportInput {
                estimate: &run.estimate,
                verdicts: &run.verdicts,
            };
            let page = ImuOnlyPage {
                kind: ImuOnlyKind::CameraImu(input),
                mode: MODE,
                failure: &run.file.failure,
                warnings: run.file.info.as_ref().map_or(&[][..], |i| &i.warnings),
                counts: &counts,
                elapsed_s: run.elapsed_s,
            };
            write_imu_only_report(path, out, data, &page)?;
            Some(path.to_path_buf())
        }
        None => None,
    };
    Ok(ResultPaths {
        result: out.to_path_buf(),
        tf: Some(tf),
        camchain_imucam: Some(imucam),
        urdf: Some(urdf),
        report,
    })
}

/// What an IMU mode's report shows besides the files: see [`ImuOnlyReportInput`].
pub(crate) struct ImuOnlyPage<'a> {
    pub(crate) kind: ImuOnlyKind<'a>,
    pub(crate) mode: &'a str,
    pub(crate) failure: &'a [String],
    pub(crate) warnings: &'a [String],
    pub(crate) counts: &'a [String],
    pub(crate) elapsed_s: f64,
}

/// Writes the report of an IMU mode's run to `path`, atomically, with the result file `result`
/// (written before) shown in it.
pub(crate) fn write_imu_only_report(
    path: &Path,
    result: &Path,
    data: &Dataset,
    page: &ImuOnlyPage,
) -> Result<()> {
    let text = std::fs::read_to_string(result).map_err(|e| Error::io(result, e))?;
    let name = result.display().to_string();
    let dataset = data.files.root.display().to_string();
    let html = render_imu_only_html(&ImuOnlyReportInput {
        title: "IMU calibration report",
        mode: page.mode,
        dataset: &dataset,
        kind: page.kind,
        failure: page.failure,
        warnings: page.warnings,
        counts: page.counts,
        result: Some((&name, &text)),
        elapsed_s: page.elapsed_s,
    });
    write_atomic(path, html.as_bytes())
}

/// The files a run wrote, in words (`wrote A, B, C and D`, or the result alone with why).
pub fn wrote_words(paths: &ResultPaths) -> String {
    let words = match (&paths.tf, &paths.urdf, &paths.camchain_imucam) {
        (Some(tf), Some(urdf), Some(imucam)) => format!(
            "wrote {}, {}, {} and {}",
            paths.result.display(),
            tf.display(),
            urdf.display(),
            imucam.display()
        ),
        // DVL + IMU: no camera, so no Kalibr file.
        (Some(tf), Some(urdf), None) => format!(
            "wrote {}, {} and {}",
            paths.result.display(),
            tf.display(),
            urdf.display()
        ),
        _ => format!(
            "wrote {} (status: failed; no ROS or Kalibr exports: --force writes them)",
            paths.result.display()
        ),
    };
    match &paths.report {
        Some(r) => format!("{words}; report {}", r.display()),
        None => words,
    }
}
