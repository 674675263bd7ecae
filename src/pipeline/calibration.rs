//! A calibration of a loaded dataset and everything written from it: the result file, the ROS and
//! Kalibr exports, the HTML report, and the summary printed at the end.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::{Matrix4, Vector3};

use crate::calib::offset::OffsetMethod;
use crate::calib::{CalibOptions, CalibrationOutcome, Method, Status, Verdict, calibrate};
use crate::error::{Error, Result};
use crate::io::calib_yaml::{
    CalibrationFile, CalibrationInfo, CalibrationStd, Observability, ObservabilityFlags,
    ResultStatus, write_calib_yaml,
};
use crate::io::dataset::DatasetFiles;
use crate::io::dvl::DvlLog;
use crate::io::exports::{FrameNames, kalibr_dvl_block, ros_static_transform};
use crate::io::write_atomic;
use crate::report::{ReportInput, frame_stats, render_html};

use super::cameras::{CameraCalRun, SEPARATE_CAMERA_RECORDING};
use super::dataset::Dataset;

/// A finished calibration of a dataset: the outcome, the result file made from it, and the wall
/// time of the calibration itself.
#[derive(Clone, Debug)]
pub struct CalibrationRun {
    /// What the estimator produced.
    pub outcome: CalibrationOutcome,
    /// The result file's content (estimates, standard deviations, verdicts, counts, warnings).
    pub file: CalibrationFile,
    /// Seconds spent in [`calibrate`] (the dataset was read before).
    pub elapsed_s: f64,
}

/// Calibrates `data` with `opts` on a pool of `threads` workers (`None`: all cores; the result
/// is the same for any number), and builds the result file.
pub fn calibrate_dataset(
    data: &Dataset,
    opts: &CalibOptions,
    threads: Option<usize>,
) -> Result<CalibrationRun> {
    let workers = crate::parallel::worker_pool(threads)?;
    let start = Instant::now();
    let outcome = workers.install(|| calibrate(&data.poses, &data.log.samples, opts))?;
    let elapsed_s = start.elapsed().as_secs_f64();
    let mut file = result_file(&outcome, &data.log);
    if let Some(cams) = &data.cameras {
        note_cameras(&mut file, cams);
    }
    note_pose_covariances(&mut file, data);
    Ok(CalibrationRun {
        outcome,
        file,
        elapsed_s,
    })
}

/// Records in the result file where the poses' covariances came from (`info.pose_covariances`).
fn note_pose_covariances(file: &mut CalibrationFile, data: &Dataset) {
    let source = match (&data.vision, data.files.pose_covariances()) {
        _ if data.poses.iter().any(|p| p.cov.is_none()) => {
            "none: the pose noise was estimated by the trajectory fit".to_string()
        }
        (Some(_), _) => "the image pipeline (stereo PnP)".to_string(),
        (None, Some(table)) => table.display().to_string(),
        (None, None) => "the pose source".to_string(),
    };
    let info = file.info.get_or_insert_with(CalibrationInfo::default);
    info.extra.insert("pose_covariances".into(), source.into());
}

/// Records in the result file that the camchain was calibrated from the same images, and warns
/// when that calibration is weak.
fn note_cameras(file: &mut CalibrationFile, cams: &CameraCalRun) {
    let info = file.info.get_or_insert_with(CalibrationInfo::default);
    info.notes.push(format!(
        "no camchain given: the cameras were calibrated from the same images ({}) first: {}",
        cams.images.display(),
        cams.one_line()
    ));
    info.extra.insert(
        "camchain_source".into(),
        "calibrated from the same images".into(),
    );
    if cams.is_weak() {
        let w = &cams.result.warnings;
        let more = match w.len() {
            0 | 1 => String::new(),
            n => format!(
                "; and {} more warning{}",
                n - 1,
                if n == 2 { "" } else { "s" }
            ),
        };
        info.warnings.push(format!(
            "the camchain was calibrated from this recording and is weak ({}{more}): \
             {SEPARATE_CAMERA_RECORDING}",
            w.first().map_or("", String::as_str)
        ));
    }
}

fn flag(v: &Verdict) -> Observability {
    if v.ok {
        Observability::Ok
    } else {
        Observability::Weak
    }
}

/// The method in words, as the result file and the summary name it.
pub fn method_name(m: &Method) -> &'static str {
    match m {
        Method::Uic => "uic",
        Method::Bcd(_) => "bcd",
        Method::Fixed {
            estimate_offset: true,
            ..
        } => "fixed extrinsics, estimated clock offset",
        Method::Fixed { .. } => "fixed extrinsics",
    }
}

/// The result file of an outcome, with the DVL log's own counts.
pub fn result_file(o: &CalibrationOutcome, log: &DvlLog) -> CalibrationFile {
    let mut f = CalibrationFile::from_params(&o.params);
    match &o.status {
        Status::Ok => f.status = Some(ResultStatus::Ok),
        Status::Failed(reasons) => {
            f.status = Some(ResultStatus::Failed);
            f.failure = reasons.clone();
        }
    }
    let v = |x: &Vector3<f64>| [x.x, x.y, x.z];
    f.std = Some(CalibrationStd {
        rotation_deg: v(&o.std.rotation_deg),
        lever_arm_m: v(&o.std.lever_arm_m),
        time_offset_s: o.std.time_offset_s,
        velocity_scale: o.std.velocity_scale,
    });
    f.observability = Some(ObservabilityFlags {
        rotation: flag(&o.verdicts.rotation),
        lever_arm: flag(&o.verdicts.lever_arm),
        time_offset: flag(&o.verdicts.time_offset),
        velocity_scale: flag(&o.verdicts.velocity_scale),
    });
    let mut extra = BTreeMap::new();
    let mut put = |k: &str, val: serde_yaml::Value| {
        extra.insert(k.to_owned(), val);
    };
    put("poses", o.counts.poses.into());
    let st = &log.stats;
    put("dvl_log", st.path.display().to_string().into());
    put("dvl_time_source", st.time_source_used.clone().into());
    put("dvl_velocity_reports", st.velocity_reports.into());
    put("dvl_invalid", st.invalid.into());
    put("dvl_duplicates", st.duplicates.into());
    put("dvl_rejected_lines", st.rejected_lines.into());
    put("dvl_samples", o.counts.dvl_samples.into());
    if let Some(c) = st.sound_speed_mps {
        put("dvl_sound_speed_mps", c.into());
        if o.params.velocity_scale > 0.0 {
            put(
                "water_sound_speed_mps",
                (c / o.params.velocity_scale).into(),
            );
        }
    }
    put("dvl_used", o.counts.dvl_used.into());
    put(
        "dvl_covariance_replaced",
        o.counts.dvl_covariance_replaced.into(),
    );
    put("dvl_outside_camera_span", o.counts.dvl_outside_span.into());
    put("dvl_in_pose_gaps", o.counts.dvl_in_pose_gaps.into());
    put(
        "dvl_residual_rms_mps",
        vec![o.residual_rms.x, o.residual_rms.y, o.residual_rms.z].into(),
    );
    put("dvl_normalized_cost", o.normalized_cost.into());
    put(
        "cost_per_iteration",
        o.iterations
            .iter()
            .map(|i| i.cost)
            .collect::<Vec<_>>()
            .into(),
    );
    put(
        "rms_angular_speed_radps",
        o.excitation.rms_angular_speed.into(),
    );
    put("rms_speed_mps", o.excitation.rms_speed.into());
    put(
        "lever_arm_velocity_ratio",
        o.excitation.lever_arm_ratio.into(),
    );
    put(
        "trajectory_qc",
        o.trajectory.qc.iter().copied().collect::<Vec<_>>().into(),
    );
    if let Some(init) = &o.init {
        put(
            "clock_offset_init",
            match init.offset.method {
                OffsetMethod::CalmSubset => "global speed alignment, then calm subset",
                OffsetMethod::SpeedCorrelation => {
                    "global speed alignment, then speed correlation (no calm segment)"
                }
            }
            .into(),
        );
        let a = &init.offset.alignment;
        put("clock_alignment_lag_s", a.lag_s.into());
        put("clock_alignment_correlation", a.correlation.into());
        if let (Some(l), Some(c)) = (a.second_lag_s, a.second_correlation) {
            put("clock_alignment_second_lag_s", l.into());
            put("clock_alignment_second_correlation", c.into());
        }
        put("clock_alignment_ambiguous", a.ambiguous.into());
        put("calm_samples", o.counts.calm.into());
    }
    put("loss", o.robust.loss.name().into());
    put(
        "dvl_spikes_screened_from_init",
        o.counts.dvl_spikes_screened.into(),
    );
    put("dvl_downweighted", o.counts.dvl_downweighted.into());
    put("poses_downweighted", o.counts.poses_downweighted.into());
    let worst = |w: &[crate::calib::robust::Outlier]| -> serde_yaml::Value {
        w.iter()
            .map(|x| {
                let mut m = serde_yaml::Mapping::new();
                m.insert("t_s".into(), x.t.into());
                m.insert("variances_out".into(), x.s.into());
                m.insert("weight".into(), x.weight.into());
                serde_yaml::Value::Mapping(m)
            })
            .collect::<Vec<_>>()
            .into()
    };
    if !o.robust.dvl.worst.is_empty() {
        put("dvl_worst_residuals", worst(&o.robust.dvl.worst));
    }
    if !o.robust.poses.worst.is_empty() {
        put("poses_worst_residuals", worst(&o.robust.poses.worst));
    }
    put(
        "dvl_noise_over_stated_variance",
        o.robust.dvl.noise_scale.into(),
    );
    let wh = &o.whiteness;
    put(
        "dvl_residual_autocorrelation_time_samples",
        wh.tau.to_vec().into(),
    );
    put("dvl_residuals_correlated", wh.correlated.into());
    put("dvl_information_divided_by", wh.inflation.into());
    if let Some(h) = &o.halves {
        put("halves_split_dvl_time_s", h.split_t.into());
        put(
            "halves_difference_in_std",
            (0..crate::calib::model::NPARAM)
                .map(|k| if h.compared[k] { h.z(k) } else { f64::NAN })
                .collect::<Vec<_>>()
                .into(),
        );
        put("halves_std_inflation", h.inflation.to_vec().into());
    }
    put(
        "lever_arm_from_default_prior",
        o.lever_arm_from_default_prior.into(),
    );
    put("usable_fraction", o.usable_fraction().into());
    if let Some(d) = &o.drift {
        put("clock_offset_first_third_s", d.first_third_s.into());
        put("clock_offset_last_third_s", d.last_third_s.into());
        put("clock_drift_apparent_ppm", d.drift_ppm.into());
    }
    let mut warnings = st.warnings.clone();
    warnings.extend(o.warnings.iter().cloned());
    for (name, vd) in [
        ("rotation", &o.verdicts.rotation),
        ("lever arm", &o.verdicts.lever_arm),
        ("time offset", &o.verdicts.time_offset),
        ("velocity scale", &o.verdicts.velocity_scale),
    ] {
        if !vd.ok {
            warnings.push(format!("{name} is weakly observable: {}", vd.reason));
        }
    }
    f.info = Some(CalibrationInfo {
        method: Some(method_name(&o.method).into()),
        iterations: Some(o.iterations.len() as u64),
        warnings,
        notes: Vec::new(),
        extra,
    });
    f
}

/// `RESULT-<suffix>` beside `RESULT` (its extension dropped).
pub fn sibling(out: &Path, suffix: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "calibration".into());
    out.with_file_name(format!("{stem}-{suffix}"))
}

/// The files [`write_results`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ResultPaths {
    /// The result YAML.
    pub result: PathBuf,
    /// `RESULT-tf.txt`: ROS 1 and ROS 2 static transform commands (not written for a failed
    /// calibration unless forced).
    pub tf: Option<PathBuf>,
    /// `RESULT-camchain-dvl.yaml`: the Kalibr-style `T_cam_dvl` block per camera (as `tf`).
    pub camchain_block: Option<PathBuf>,
}

/// Writes the result YAML to `out` (its folder created) and, when the calibration passed its
/// sanity checks or `force` is set, the ROS and Kalibr exports beside it, each atomically. A
/// failed calibration's result file says `status: failed` with the reasons, and exports left
/// from an earlier run are removed so that none can be mistaken for this run's. With images the
/// Kalibr block is given for every camera of the chain; with poses, for cam0.
pub fn write_results(
    out: &Path,
    run: &CalibrationRun,
    data: &Dataset,
    force: bool,
) -> Result<ResultPaths> {
    let inputs = data.files.inputs();
    for written in [
        out.to_path_buf(),
        sibling(out, "tf.txt"),
        sibling(out, "camchain-dvl.yaml"),
    ] {
        crate::files::refuse_input("--out", &written, inputs.iter().map(|p| p.as_path()))?;
    }
    if let Some(d) = out.parent()
        && !d.as_os_str().is_empty()
    {
        std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
    }
    write_calib_yaml(out, &run.file)?;
    let calib = &run.outcome.params;
    let tf = sibling(out, "tf.txt");
    let block = sibling(out, "camchain-dvl.yaml");
    if !(run.outcome.status.is_ok() || force) {
        for p in [&tf, &block] {
            match std::fs::remove_file(p) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(Error::io(p, e));
                }
                _ => {}
            }
        }
        return Ok(ResultPaths {
            result: out.to_path_buf(),
            tf: None,
            camchain_block: None,
        });
    }
    write_atomic(
        &tf,
        ros_static_transform(calib, &FrameNames::default()).as_bytes(),
    )?;
    let t_cn_c0: Vec<Matrix4<f64>> = match &data.vision {
        Some(run) => run.chain.t_cn_c0.iter().map(|t| t.to_matrix()).collect(),
        None => vec![Matrix4::identity()],
    };
    write_atomic(&block, kalibr_dvl_block(calib, &t_cn_c0).as_bytes())?;
    Ok(ResultPaths {
        result: out.to_path_buf(),
        tf: Some(tf),
        camchain_block: Some(block),
    })
}

/// Where `dvlcal calibrate` writes the cameras it calibrated from a dataset's images (a dataset
/// without a camchain): `camchain.yaml` beside the result, and with a DVL report `R.html` the
/// camera report `R-cameras.html` beside it.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraOutputs {
    /// The camchain YAML.
    pub camchain: PathBuf,
    /// The camera calibration report, when a DVL report is written.
    pub report: Option<PathBuf>,
}

impl CameraOutputs {
    /// The outputs for the result `out` and the DVL report `report`, when `files` have images
    /// without a camchain (`None` otherwise). Errors, before anything is run, when one of them
    /// would overwrite an input of the run or the result.
    pub fn plan(
        out: &Path,
        report: Option<&Path>,
        files: &DatasetFiles,
    ) -> Result<Option<CameraOutputs>> {
        // A bag without a camchain may need its cameras calibrated too (a stereo pair, or no
        // CameraInfo): the paths are reserved, and used only if it does.
        let bag_may = files.bag.is_some() && files.camchain.is_none();
        if !files.calibrates_cameras() && !bag_may {
            return Ok(None);
        }
        let camchain = out.with_file_name("camchain.yaml");
        if camchain == out || crate::files::same_file(&camchain, out) {
            return Err(Error::option(
                "--out",
                format!(
                    "{}: the camchain calibrated from the images is written to {} beside the \
                     result; name the result otherwise",
                    out.display(),
                    camchain.display()
                ),
            ));
        }
        let inputs = files.inputs();
        let inputs = || inputs.iter().map(|p| p.as_path());
        crate::files::refuse_input("--out", &camchain, inputs())?;
        let report = report.map(|r| sibling(r, "cameras.html"));
        if let Some(r) = &report {
            crate::files::refuse_input("--report", r, inputs().chain([out, camchain.as_path()]))?;
        }
        Ok(Some(CameraOutputs { camchain, report }))
    }

    /// Writes the camchain and the report (with `command`, the command line) of `cams`; returns
    /// the paths written, for the user.
    pub fn write(&self, cams: &CameraCalRun, command: Option<String>) -> Result<Vec<String>> {
        cams.write_camchain(&self.camchain)?;
        let mut written = vec![self.camchain.display().to_string()];
        if let Some(r) = &self.report {
            cams.write_report(r, &self.camchain, command)?;
            written.push(r.display().to_string());
        }
        Ok(written)
    }
}

/// Renders the HTML report of a run and writes it atomically to `path`. `result` is the result
/// YAML already written (its text is shown in the report when it can be read).
pub fn write_report(
    path: &Path,
    run: &CalibrationRun,
    data: &Dataset,
    result: &Path,
) -> Result<()> {
    let inputs = data.files.inputs();
    crate::files::refuse_input(
        "--report",
        path,
        inputs.iter().map(|p| p.as_path()).chain([result]),
    )?;
    let frames = data
        .vision
        .as_ref()
        .map(|v| frame_stats(&v.results, &v.epoch));
    let mut dataset = format!(
        "camera poses: {}; DVL log: {}",
        data.camera_source.display(),
        data.log.stats.path.display()
    );
    if let Some(cams) = &data.cameras {
        dataset.push_str(&format!(
            "; camchain: calibrated from the same images ({}){}",
            cams.one_line(),
            if cams.is_weak() {
                ", weak: see the warnings in the result file"
            } else {
                ""
            }
        ));
    }
    // The result file was just written; a report without it is still useful.
    let yaml = std::fs::read_to_string(result).ok();
    let name = result.display().to_string();
    let input = ReportInput {
        dataset: &dataset,
        dvl_stats: Some(&data.log.stats),
        frames: frames.as_deref(),
        result_name: Some(&name),
        result_yaml: yaml.as_deref(),
        elapsed_s: Some(run.elapsed_s),
        ..ReportInput::new(&run.outcome, &data.poses)
    };
    let html = render_html(&input)?;
    write_atomic(path, html.as_bytes())
}

impl CalibrationRun {
    /// The summary `dvlcal calibrate` prints: counts, each parameter with its standard deviation
    /// and verdict, the residuals, and every warning.
    pub fn summary(&self, log: &DvlLog) -> String {
        let o = &self.outcome;
        let ok = |v: &Verdict| if v.ok { "ok" } else { "WEAK" };
        let s = &o.std;
        let st = &log.stats;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "method {}; {} poses; DVL: {} velocity reports, {} invalid, {} duplicates, {} malformed lines; \
             {} used, {} outside the camera span; {:.2} s",
            method_name(&o.method),
            o.counts.poses,
            st.velocity_reports,
            st.invalid,
            st.duplicates,
            st.rejected_lines,
            o.counts.dvl_used,
            o.counts.dvl_outside_span,
            self.elapsed_s
        );
        let q = self.file.quaternion_cam_dvl_xyzw;
        let _ = writeln!(
            out,
            "rotation  q_cam_dvl (xyzw) [{:.5}, {:.5}, {:.5}, {:.5}]  std [{:.3}, {:.3}, {:.3}] deg  {}",
            q[0],
            q[1],
            q[2],
            q[3],
            s.rotation_deg.x,
            s.rotation_deg.y,
            s.rotation_deg.z,
            ok(&o.verdicts.rotation)
        );
        let p = o.params.lever_arm_cam_m();
        let _ = writeln!(
            out,
            "lever arm p_cam_dvl [{:.4}, {:.4}, {:.4}] m  std [{:.4}, {:.4}, {:.4}] m  {}",
            p.x,
            p.y,
            p.z,
            s.lever_arm_m.x,
            s.lever_arm_m.y,
            s.lever_arm_m.z,
            ok(&o.verdicts.lever_arm)
        );
        let _ = writeln!(
            out,
            "clock     time_offset_s {:.5} s  std {:.5} s  {}",
            o.params.time_offset_s,
            s.time_offset_s,
            ok(&o.verdicts.time_offset)
        );
        let _ = writeln!(
            out,
            "scale     velocity_scale {:.5}  std {:.5}  {}",
            o.params.velocity_scale,
            s.velocity_scale,
            ok(&o.verdicts.velocity_scale)
        );
        let _ = writeln!(
            out,
            "sound     {}",
            crate::report::sound_speed_words(
                o.params.velocity_scale,
                s.velocity_scale,
                st.sound_speed_mps
            )
        );
        let _ = writeln!(
            out,
            "residuals {:.4} {:.4} {:.4} m/s RMS; normalized cost {:.2}; {} iterations",
            o.residual_rms.x,
            o.residual_rms.y,
            o.residual_rms.z,
            o.normalized_cost,
            o.iterations.len()
        );
        let _ = writeln!(out, "data      {}", o.usable_words());
        for w in self.file.info.iter().flat_map(|i| i.warnings.iter()) {
            let _ = writeln!(out, "warning: {w}");
        }
        if let Status::Failed(reasons) = &o.status {
            let _ = writeln!(out, "CALIBRATION FAILED: the result cannot be trusted");
            for r in reasons {
                let _ = writeln!(out, "  - {r}");
            }
        }
        out
    }
}
