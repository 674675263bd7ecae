//! A calibration of a loaded dataset and everything written from it: the result file, the ROS and
//! Kalibr exports, the HTML report, and the summary printed at the end.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::{Matrix4, Vector3};

use crate::calib::segments::{SegmentOffset, calibrate_segments};
use crate::calib::{
    CalibOptions, CalibrationOutcome, DeterminedBy, Method, Status, Verdict, calibrate,
};
use crate::error::{Error, Result};
use crate::io::calib_yaml::{
    CalibrationFile, CalibrationInfo, CalibrationStd, ClockSegmentFigure, Observability,
    ObservabilityFlags, ResultStatus, RunFigures, WorstResidual, write_calib_yaml,
};
use crate::io::camchain::kalibr_entry;
use crate::io::dvl::DvlLog;
use crate::io::exports::{
    Export, FrameNames, KalibrCamera, kalibr_camchain_imucam, ros_static_transform, urdf_robot,
};
use crate::io::provenance::Provenance;
use crate::io::tum::CameraSegment;
use crate::io::write_atomic;
use crate::report::{
    FailureReportInput, ReportInput, frame_stats, render_failure_html, render_html,
};
use crate::types::DvlSample;

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
    /// The IMU calibrated against the camera, when the dataset has one.
    pub imu: Option<super::imu::ImuCalibration>,
}

/// Calibrates `data` with `opts` on a pool of `threads` workers (`None`: all cores; the result
/// is the same for any number), and builds the result file. A clock that stepped (the DVL's, or
/// the camera's in a pose file) is calibrated in clock segments ([`calibrate_segments`]).
pub fn calibrate_dataset(
    data: &Dataset,
    opts: &CalibOptions,
    threads: Option<usize>,
) -> Result<CalibrationRun> {
    let log = data.dvl()?;
    let workers = crate::parallel::worker_pool(threads)?;
    let start = Instant::now();
    let plan = if data.camera_segments.len() > 1 {
        SegmentPlan::camera(data, opts, &workers)?
    } else {
        SegmentPlan::dvl(log)
    };
    let (mut outcome, segments) =
        workers.install(|| calibrate_segments(&data.poses, &plan.parts, &plan.names, opts))?;
    let (mut imu_warnings, mut imu_notes) = (Vec::new(), Vec::new());
    let joint = super::imu::joint_eligible(&outcome, plan.parts.len()).then_some((&outcome, opts));
    let imu = workers.install(|| super::imu::calibrate_imu(data, joint, &mut imu_warnings));
    if let Some(est) = &imu {
        super::imu::adopt_joint_dvl(&mut outcome, est, opts, &mut imu_warnings, &mut imu_notes);
    }
    let elapsed_s = start.elapsed().as_secs_f64();
    let mut file = result_file(&outcome, log);
    let imu = imu.map(|est| super::imu::note_imu(&mut file, est, data, &opts.weak));
    if !imu_warnings.is_empty() || !imu_notes.is_empty() {
        let info = file.info.get_or_insert_with(Default::default);
        info.warnings.extend(imu_warnings);
        info.notes.extend(imu_notes);
    }
    plan.note(&mut file, &outcome, &segments, data);
    if let Some(cams) = &data.cameras {
        note_cameras(&mut file, cams);
    }
    note_pose_covariances(&mut file, data);
    data.note_held_poses(&mut file);
    note_board_size(&mut file, data);
    note_focal_lengths(&mut file, data);
    super::vision::note_image_scan(&mut file, data.vision.as_ref());
    Ok(CalibrationRun {
        outcome,
        file,
        elapsed_s,
        imu,
    })
}

/// The DVL reports of a dataset in clock segments, one offset each: the DVL log's own segments,
/// or the stretches of the camera clock's segments (one part when no clock stepped).
struct SegmentPlan<'d> {
    parts: Vec<&'d [DvlSample]>,
    /// Each part in messages: its lines in the DVL log (and the camera segment's poses).
    names: Vec<String>,
    /// Each part's first and last line in the DVL log.
    lines: Vec<[usize; 2]>,
    /// The camera clock's segments the parts follow (empty: the DVL's own segments).
    camera: &'d [CameraSegment],
}

impl<'d> SegmentPlan<'d> {
    /// The DVL log's clock segments.
    fn dvl(log: &'d DvlLog) -> Self {
        let path = log.stats.path.display();
        SegmentPlan {
            parts: log
                .clock_segments
                .iter()
                .map(|c| log.samples.get(c.samples.clone()).unwrap_or(&[]))
                .collect(),
            names: log
                .clock_segments
                .iter()
                .map(|c| format!("{path}:{}-{}", c.lines.0, c.lines.1))
                .collect(),
            lines: log
                .clock_segments
                .iter()
                .map(|c| [c.lines.0, c.lines.1])
                .collect(),
            camera: &[],
        }
    }

    /// The stretches of the DVL log that the camera clock's segments cover. The poses of each
    /// later camera segment were moved to follow the one before it by a frame's interval, which
    /// holds to the frame's jitter when the camera kept recording; a first calibration of the
    /// whole finds the offset the junctions fall at on the DVL clock, the reports are split
    /// there, and each stretch's own offset absorbs what the one-frame assumption missed.
    fn camera(data: &'d Dataset, opts: &CalibOptions, workers: &rayon::ThreadPool) -> Result<Self> {
        let log = data.dvl()?;
        let cam = &data.camera_segments;
        let poses_path = data.camera_source.display();
        if log.clock_segments.len() > 1 {
            return Err(Error::Input(format!(
                "both clocks step: the camera's ({poses_path}:{}) and the DVL's ({}:{}); \
                 calibrate the stretches between the steps on their own",
                data.camera_clock_steps.first().map_or(0, |s| s.line),
                log.stats.path.display(),
                log.clock_segments.get(1).map_or(0, |c| c.lines.0)
            )));
        }
        // The junctions need the offset only roughly: no drift (which calibrate_segments
        // refuses across clock segments anyway).
        let rough = CalibOptions {
            clock_drift: false,
            ..opts.clone()
        };
        let first = workers.install(|| calibrate(&data.poses, &log.samples, &rough))?;
        let offset = first.params.time_offset_s;
        // Each junction, midway between the segments' poses, on the DVL clock.
        let mut bounds = vec![0usize];
        bounds.extend(cam.windows(2).map(|w| {
            let before = data.poses[w[0].poses.end - 1].t;
            let after = data.poses[w[1].poses.start].t;
            let cut = 0.5 * (before + after) - offset;
            log.samples.partition_point(|x| x.t < cut)
        }));
        bounds.push(log.samples.len());
        let line = |i: usize| log.lines.get(i).copied().unwrap_or(0);
        let lines: Vec<[usize; 2]> = bounds
            .windows(2)
            .map(|b| [line(b[0]), line(b[1].saturating_sub(1))])
            .collect();
        Ok(SegmentPlan {
            parts: bounds
                .windows(2)
                .map(|b| log.samples.get(b[0]..b[1].max(b[0])).unwrap_or(&[]))
                .collect(),
            names: cam
                .iter()
                .zip(&lines)
                .map(|(c, l)| {
                    format!(
                        "{}:{}-{} (camera clock segment {poses_path}:{}-{})",
                        log.stats.path.display(),
                        l[0],
                        l[1],
                        c.lines.0,
                        c.lines.1
                    )
                })
                .collect(),
            lines,
            camera: cam,
        })
    }

    /// Records the segments in the result file (`info.clock_segments`); for camera clock
    /// segments also the steps' warnings, and every offset (the top-level one, the longest
    /// segment's, included) moved onto its segment's own camera clock. Nothing with one part.
    fn note(
        &self,
        file: &mut CalibrationFile,
        outcome: &CalibrationOutcome,
        segments: &[SegmentOffset],
        data: &Dataset,
    ) {
        if segments.is_empty() {
            return;
        }
        let shift = |k: usize| self.camera.get(k).map_or(0.0, |c| c.shift_s);
        // The longest segment's offset, on its own camera clock.
        let main = (0..segments.len())
            .filter(|&k| segments[k].time_offset_s.is_some())
            .max_by(|&a, &b| segments[a].duration_s.total_cmp(&segments[b].duration_s));
        if let Some(k) = main {
            file.time_offset_s = outcome.params.time_offset_s - shift(k);
        }
        let Some(info) = file.info.as_mut() else {
            return;
        };
        let poses_path = data.camera_source.display();
        for (st, seg) in data
            .camera_clock_steps
            .iter()
            .zip(self.camera.iter().skip(1))
        {
            // Its stamps step back by `-step_s` across one frame: the clock by one frame more.
            info.warnings.push(format!(
                "{poses_path}:{}: the camera clock steps back by {:.3} s after line {} (taking \
                 one frame, {:.3} s, between the two lines): the poses from there on are moved to \
                 follow, and the DVL reports of each camera clock segment get their own clock \
                 offset (clock_segments)",
                st.line,
                seg.shift_s,
                st.previous_line,
                seg.shift_s + st.step_s
            ));
        }
        if !self.camera.is_empty() {
            info.notes.push(
                "the camera clock stepped: time_offset_s is the longest clock segment's, on that \
                 segment's own camera clock; clock_segments gives each segment's"
                    .to_owned(),
            );
        }
        info.figures.clock_segments = Some(
            segments
                .iter()
                .zip(&self.lines)
                .enumerate()
                .map(|(k, (s, l))| ClockSegmentFigure {
                    lines: *l,
                    samples: s.samples,
                    duration_s: s.duration_s,
                    time_offset_s: s.time_offset_s.map(|o| o - shift(k)),
                    time_offset_std_s: s.time_offset_std_s,
                    left_out: s.left_out.clone(),
                    camera_lines: self.camera.get(k).map(|c| [c.lines.0, c.lines.1]),
                })
                .collect(),
        );
    }
}

/// Records in the result file where the poses' covariances came from (`info.pose_covariances`).
fn note_pose_covariances(file: &mut CalibrationFile, data: &Dataset) {
    let source = match (&data.vision, data.files.pose_covariances()) {
        _ if data.poses.iter().any(|p| p.cov.is_none()) => {
            "none: the pose noise was estimated by the trajectory fit".to_string()
        }
        (Some(_), _) => "the image pipeline (stereo PnP)".to_string(),
        (None, Some(table)) => table.display().to_string(),
        (None, None) => format!(
            "the pose messages of {} (converted from the parent frame)",
            data.camera_source.display()
        ),
    };
    let info = file.info.get_or_insert_with(CalibrationInfo::default);
    info.figures.pose_covariances = Some(source);
}

/// Records in the result file what the image pipeline found of the board's printed size: the
/// measured scale (`info.board_scale`, `board_scale_std`, `board_scale_applied`), with a warning
/// when it differs from the file's size, or a note on why it was not measured.
fn note_board_size(file: &mut CalibrationFile, data: &Dataset) {
    let Some(run) = &data.vision else { return };
    let words = run.board_size_words();
    let info = file.info.get_or_insert_with(CalibrationInfo::default);
    match run.board_size.measured() {
        Some(b) => {
            info.figures.board_scale = Some(b.scale);
            info.figures.board_scale_std = Some(b.std);
            info.figures.board_scale_applied = Some(b.applied);
            if b.significant() {
                info.warnings.push(words);
            } else {
                info.notes.push(words);
            }
        }
        None => info.notes.push(words),
    }
}

/// Records in the result file each camera's focal length as the recording measures it
/// (`info.focal_length_scale`, `focal_length_scale_std`), with a warning when it contradicts the
/// camchain, or a note when the views did not vary enough to check it. Nothing when no camera
/// was measured (a camchain calibrated from the same images is not: it fits them).
fn note_focal_lengths(file: &mut CalibrationFile, data: &Dataset) {
    let Some(run) = &data.vision else { return };
    if run.focal.iter().all(Option::is_none) {
        return;
    }
    let name = data
        .files
        .camchain
        .as_deref()
        .map_or_else(|| "the camchain".to_owned(), crate::files::file_name_of);
    let info = file.info.get_or_insert_with(CalibrationInfo::default);
    info.figures.focal_length_scale = Some(
        run.focal
            .iter()
            .map(|f| f.as_ref().map(|f| f.scale))
            .collect(),
    );
    info.figures.focal_length_scale_std = Some(
        run.focal
            .iter()
            .map(|f| f.as_ref().map(|f| f.std))
            .collect(),
    );
    for f in run.focal.iter().flatten() {
        if f.significant() {
            info.warnings.push(f.warning(&name));
        } else if !f.useful() {
            info.notes.push(format!(
                "{} (from {} frames): the views of the board vary too little in angle to check \
                 it",
                f.measures(&name),
                f.frames
            ));
        }
    }
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
    info.figures.camchain_source = Some("calibrated from the same images".into());
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

pub(crate) fn flag(v: &Verdict) -> Observability {
    match v.by {
        DeterminedBy::Fixed => Observability::Fixed,
        DeterminedBy::Prior => Observability::Prior,
        DeterminedBy::Data if v.ok => Observability::Ok,
        DeterminedBy::Data => Observability::Weak,
    }
}

/// `value` unless the verdict says the parameter was held fixed (it then has no standard
/// deviation).
fn unless_fixed<T>(v: &Verdict, value: T) -> Option<T> {
    (v.by != DeterminedBy::Fixed).then_some(value)
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
    let vd = &o.verdicts;
    f.std = Some(CalibrationStd {
        rotation_deg: unless_fixed(&vd.rotation, v(&o.std.rotation_deg)),
        lever_arm_m: unless_fixed(&vd.lever_arm, v(&o.std.lever_arm_m)),
        time_offset_s: unless_fixed(&vd.time_offset, o.std.time_offset_s),
        velocity_scale: unless_fixed(&vd.velocity_scale, o.std.velocity_scale),
        clock_drift_ppm: o.clock_drift.as_ref().map(|d| d.std_ppm),
        imu: None,
    });
    if let Some(d) = &o.clock_drift {
        f.clock_drift_ppm = Some(d.ppm);
        f.clock_reference_t_dvl_s = Some(log.epoch.sec as f64 + d.reference_t_s);
    }
    f.observability = Some(ObservabilityFlags {
        rotation: flag(&o.verdicts.rotation),
        lever_arm: flag(&o.verdicts.lever_arm),
        time_offset: flag(&o.verdicts.time_offset),
        velocity_scale: flag(&o.verdicts.velocity_scale),
        imu: None,
    });
    let st = &log.stats;
    let worst = |w: &[crate::calib::robust::Outlier]| -> Option<Vec<WorstResidual>> {
        (!w.is_empty()).then(|| {
            w.iter()
                .map(|x| WorstResidual {
                    t_s: x.t,
                    variances_out: x.s,
                    weight: x.weight,
                })
                .collect()
        })
    };
    let init = o.init.as_ref().map(|i| &i.offset);
    let alignment = init.map(|i| &i.alignment);
    let second = alignment.and_then(|a| a.second_lag_s.zip(a.second_correlation));
    let sound = st.sound_speed_mps;
    let figures = RunFigures {
        poses: Some(o.counts.poses),
        dvl_log: Some(st.path.display().to_string()),
        dvl_time_source: Some(st.time_source_used.clone()),
        dvl_velocity_reports: Some(st.velocity_reports),
        dvl_invalid: Some(st.invalid),
        dvl_duplicates: Some(st.duplicates),
        dvl_rejected_lines: Some(st.rejected_lines),
        dvl_samples: Some(o.counts.dvl_samples),
        dvl_sound_speed_mps: sound,
        water_sound_speed_mps: sound
            .filter(|_| o.params.velocity_scale > 0.0)
            .map(|c| c / o.params.velocity_scale),
        dvl_used: Some(o.counts.dvl_used),
        dvl_covariance_replaced: Some(o.counts.dvl_covariance_replaced),
        dvl_outside_camera_span: Some(o.counts.dvl_outside_span),
        dvl_in_pose_gaps: Some(o.counts.dvl_in_pose_gaps),
        dvl_residual_rms_mps: Some([o.residual_rms.x, o.residual_rms.y, o.residual_rms.z]),
        dvl_normalized_cost: Some(o.normalized_cost),
        dvl_variance_component: Some(o.noise.dvl.total()),
        dvl_variance_component_std: Some(o.noise.dvl.std * o.noise.dvl.applied),
        dvl_variance_applied: Some(o.noise.dvl.applied),
        pose_variance_component: Some(o.noise.cosensor.total()),
        pose_variance_component_std: Some(o.noise.cosensor.std * o.noise.cosensor.applied),
        pose_variance_applied: Some(o.noise.cosensor.applied),
        noise_rounds: Some(o.noise.rounds),
        cost_per_iteration: Some(o.iterations.iter().map(|i| i.cost).collect()),
        rms_angular_speed_radps: Some(o.excitation.rms_angular_speed),
        rms_speed_mps: Some(o.excitation.rms_speed),
        lever_arm_velocity_ratio: Some(o.excitation.lever_arm_ratio),
        trajectory_qc: Some(o.trajectory.qc.iter().copied().collect()),
        jerk_density_varying: o.motion_prior.as_ref().map(|m| m.applied),
        jerk_density_factor_range: o.motion_prior.as_ref().map(|m| m.factor_range_flat()),
        clock_offset_init: init.map(|i| i.method.words().to_owned()),
        clock_alignment_lag_s: alignment.map(|a| a.lag_s),
        clock_alignment_correlation: alignment.map(|a| a.correlation),
        clock_alignment_second_lag_s: second.map(|(l, _)| l),
        clock_alignment_second_correlation: second.map(|(_, c)| c),
        clock_alignment_ambiguous: alignment.map(|a| a.ambiguous),
        calm_samples: init.map(|_| o.counts.calm),
        loss: Some(o.robust.loss.name().to_owned()),
        dvl_spikes_screened_from_init: Some(o.counts.dvl_spikes_screened),
        dvl_downweighted: Some(o.counts.dvl_downweighted),
        poses_downweighted: Some(o.counts.poses_downweighted),
        dvl_worst_residuals: worst(&o.robust.dvl.worst),
        poses_worst_residuals: worst(&o.robust.poses.worst),
        dvl_noise_over_stated_variance: Some(o.robust.dvl.noise_scale),
        dvl_residual_autocorrelation_time_samples: Some(o.whiteness.tau.to_vec()),
        dvl_residuals_correlated: Some(o.whiteness.correlated),
        dvl_information_divided_by: Some(o.whiteness.inflation),
        halves_split_dvl_time_s: o.halves.as_ref().map(|h| h.split_t),
        halves_difference_in_std: o.halves.as_ref().map(|h| {
            (0..crate::calib::model::NPARAM)
                .map(|k| if h.compared[k] { h.z(k) } else { f64::NAN })
                .collect()
        }),
        halves_std_inflation: o.halves.as_ref().map(|h| h.inflation.to_vec()),
        lever_arm_from_default_prior: Some(o.lever_arm_from_default_prior),
        usable_fraction: Some(o.usable_fraction()),
        clock_offset_first_third_s: o.drift.as_ref().map(|d| d.first_third_s),
        clock_offset_last_third_s: o.drift.as_ref().map(|d| d.last_third_s),
        clock_drift_apparent_ppm: o.drift.as_ref().map(|d| d.drift_ppm),
        ..RunFigures::default()
    };
    let mut warnings = st.warnings.clone();
    warnings.extend(o.warnings.iter().cloned());
    if o.verdicts.velocity_scale.by != DeterminedBy::Fixed
        && let Some(w) = crate::report::implausible_water(
            o.params.velocity_scale,
            o.std.velocity_scale,
            st.sound_speed_mps,
        )
    {
        warnings.push(w);
    }
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
        notes: o
            .clock_drift
            .as_ref()
            .map(|d| {
                format!(
                    "the DVL clock drifts {:+.2} ppm: time_offset_s is the offset at \
                     clock_reference_t_dvl_s, and the exports (one time shift each) carry it \
                     alone",
                    d.ppm
                )
            })
            .into_iter()
            .collect(),
        figures,
    });
    f
}

/// `RESULT-<suffix>` beside `RESULT` (its extension dropped).
pub fn sibling(out: &Path, suffix: &str) -> PathBuf {
    // The stem's bytes are kept as they are (a name need not be UTF-8).
    let mut name = out.file_stem().unwrap_or("calibration".as_ref()).to_owned();
    name.push(format!("-{suffix}"));
    out.with_file_name(name)
}

/// The files [`write_results`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ResultPaths {
    /// The result YAML.
    pub result: PathBuf,
    /// `RESULT-tf.txt`: ROS 1 and ROS 2 static transform commands (not written for a failed
    /// calibration unless forced).
    pub tf: Option<PathBuf>,
    /// `RESULT-camchain-imucam.yaml`: the camera chain with the DVL in the IMU's place, as
    /// Kalibr's camchain-imucam.yaml (as `tf`).
    pub camchain_imucam: Option<PathBuf>,
    /// `RESULT-urdf.xml`: a URDF robot, the camera and DVL links and the fixed joint (as `tf`).
    pub urdf: Option<PathBuf>,
    /// The HTML report, when the writer wrote it (the IMU modes' writers do; the DVL's report
    /// is written by [`super::write_report`]).
    pub report: Option<PathBuf>,
}

/// How [`write_results`] writes.
#[derive(Clone, Debug, Default)]
pub struct OutputOptions {
    /// Write the exports even when the calibration failed its sanity checks.
    pub force: bool,
    /// The parent (camera) and child (DVL) frame names of the exports; `None`: the camera
    /// frame the data name (a bag's image `header.frame_id`), else `cam0`, and `dvl`.
    pub frames: Option<FrameNames>,
    /// The command line, recorded in the result's `provenance`.
    pub command_line: Option<String>,
    /// Inputs beyond the dataset's own files (as `("init", guess.yaml)`), digested into the
    /// provenance too.
    pub extra_inputs: Vec<(String, PathBuf)>,
}

/// The frame names of the exports: the options' (checked), else the data's camera frame (when
/// usable as a frame id) and `dvl`.
pub fn frame_names(opts: &OutputOptions, data: &Dataset) -> Result<FrameNames> {
    if let Some(f) = &opts.frames {
        f.validate()?;
        return Ok(f.clone());
    }
    let from_data = data.camera_frame.as_ref().map(|camera| FrameNames {
        camera: camera.clone(),
        ..FrameNames::default()
    });
    Ok(from_data
        .filter(|f| f.validate().is_ok())
        .unwrap_or_default())
}

/// The inputs of a dataset with the part each played: camchain, target, DVL log, pose file, bag,
/// and each camera's image folder.
pub fn dataset_inputs(data: &Dataset) -> Vec<(String, PathBuf)> {
    let f = &data.files;
    let mut v: Vec<(String, PathBuf)> = [
        ("camchain", &f.camchain),
        ("target", &f.target),
        ("dvl_log", &f.dvl),
        ("poses", &f.poses),
        ("bag", &f.bag),
    ]
    .into_iter()
    .filter_map(|(role, p)| p.clone().map(|p| (role.to_owned(), p)))
    .collect();
    // The IMU's files, when its stream was read (the run calibrated it, or says why not).
    if data.imu.is_some() {
        for (role, p) in [("imu", &f.imu), ("imu_noise", &f.imu_noise)] {
            if let Some(p) = p {
                v.push((role.to_owned(), p.clone()));
            }
        }
    }
    if let Some(run) = &data.vision {
        for (n, dir) in run.scan.folders.iter().enumerate() {
            if let Some(d) = dir {
                v.push((format!("images_cam{n}"), d.clone()));
            }
        }
    }
    v.dedup_by(|a, b| a.1 == b.1);
    v
}

/// Before a run's files are written: refuses `out` and `also` (its exports) when one is an
/// input, creates `out`'s folder, and gives the provenance of the run (the command line and
/// the digest of every input: the dataset's files and `opts.extra_inputs`).
pub fn prepare_outputs(
    out: &Path,
    also: &[&Path],
    data: &Dataset,
    opts: &OutputOptions,
) -> Result<Provenance> {
    let inputs = data.files.inputs();
    for written in std::iter::once(out).chain(also.iter().copied()) {
        crate::files::refuse_input("--out", written, inputs.iter().map(|p| p.as_path()))?;
    }
    if let Some(d) = out.parent()
        && !d.as_os_str().is_empty()
    {
        std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
    }
    let mut all_inputs = dataset_inputs(data);
    all_inputs.extend(opts.extra_inputs.iter().cloned());
    Provenance::of_run(opts.command_line.clone(), &all_inputs)
}

/// The cameras of the camchain-imucam export: every camera of the chain the poses were solved
/// with (each overlapping all others: they were paired on the same board views), or, with poses
/// from elsewhere, cam0 without a calibration.
pub(super) fn kalibr_cameras(data: &Dataset) -> Vec<KalibrCamera> {
    match &data.vision {
        Some(run) => {
            let n = run.chain.cams.len();
            (0..n)
                .map(|i| KalibrCamera {
                    entry: kalibr_entry(&run.chain, i),
                    t_cn_c0: run.chain.t_cn_c0[i].to_matrix(),
                    overlaps: (0..n).filter(|&j| j != i).collect(),
                })
                .collect()
        }
        None => vec![KalibrCamera {
            entry: String::new(),
            t_cn_c0: Matrix4::identity(),
            overlaps: Vec::new(),
        }],
    }
}

/// Writes the result YAML to `out` (its folder created, its `provenance` section filled in:
/// version, command line, UTC time, each input's size and SHA-256) and, when the calibration
/// passed its sanity checks or `opts.force` is set, the exports beside it, each atomically:
/// `RESULT-tf.txt` (ROS static transforms), `RESULT-urdf.xml` (a URDF robot) and
/// `RESULT-camchain-imucam.yaml` (Kalibr), each noting what the data did not measure
/// ([`crate::io::exports::ExportNotes`]). A failed calibration's result file says `status:
/// failed` with the reasons, and exports left from an earlier run are removed so that none can
/// be mistaken for this run's. With images the Kalibr file holds every camera of the chain;
/// with poses, cam0's transforms alone.
pub fn write_results(
    out: &Path,
    run: &CalibrationRun,
    data: &Dataset,
    opts: &OutputOptions,
) -> Result<ResultPaths> {
    let names = frame_names(opts, data)?;
    let tf = sibling(out, "tf.txt");
    let imucam = sibling(out, "camchain-imucam.yaml");
    let urdf = sibling(out, "urdf.xml");
    let mut file = run.file.clone();
    file.provenance = Some(prepare_outputs(out, &[&tf, &imucam, &urdf], data, opts)?);
    write_calib_yaml(out, &file)?;
    let calib = &run.outcome.params;
    if !(run.outcome.status.is_ok() || opts.force) {
        crate::files::remove_stale(&[&tf, &imucam, &urdf])?;
        return Ok(ResultPaths {
            report: None,
            result: out.to_path_buf(),
            tf: None,
            camchain_imucam: None,
            urdf: None,
        });
    }
    let notes = super::exports::export_notes(&run.outcome);
    let imu = super::imu::imu_export(&run.file);
    let cams = kalibr_cameras(data);
    let export = Export::dvl(calib, &names, &notes).with_imu(imu.as_ref());
    let (tf_text, urdf_text, imucam_text) = (
        ros_static_transform(&export),
        urdf_robot(&export),
        kalibr_camchain_imucam(&export, &cams),
    );
    write_atomic(&tf, tf_text.as_bytes())?;
    write_atomic(&urdf, urdf_text.as_bytes())?;
    write_atomic(&imucam, imucam_text.as_bytes())?;
    Ok(ResultPaths {
        report: None,
        result: out.to_path_buf(),
        tf: Some(tf),
        camchain_imucam: Some(imucam),
        urdf: Some(urdf),
    })
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
    let log = data.dvl()?;
    let frames = data
        .vision
        .as_ref()
        .map(|v| frame_stats(&v.results, &v.epoch));
    let mut dataset = format!(
        "camera poses: {}; DVL log: {}",
        data.camera_source.display(),
        log.stats.path.display()
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
    let sizes = image_sizes(data);
    let input = ReportInput {
        image_sizes: sizes.as_deref(),
        dataset: &dataset,
        dvl_stats: Some(&log.stats),
        frames: frames.as_deref(),
        result_name: Some(&name),
        result_yaml: yaml.as_deref(),
        elapsed_s: Some(run.elapsed_s),
        imu: run.imu.as_ref().map(|i| i.report_input()),
        ..ReportInput::new(&run.outcome, &data.poses)
    };
    let html = render_html(&input)?;
    write_atomic(path, html.as_bytes())
}

/// Each camera's image size, for runs from images.
fn image_sizes(data: &Dataset) -> Option<Vec<(u32, u32)>> {
    data.vision
        .as_ref()
        .map(|v| v.chain.cams.iter().map(|c| (c.width, c.height)).collect())
}

/// What [`calibrate_dataset`] was doing, in words, for its error messages.
pub fn calibration_context(data: &Dataset) -> String {
    match &data.dvl_path {
        Some(dvl) => format!(
            "calibrating {} against {}",
            dvl.display(),
            data.camera_source.display()
        ),
        None => format!(
            "calibrating the IMU {} against {} (camera + IMU: no DVL log given)",
            data.imu
                .as_ref()
                .map_or("-".into(), |l| l.path.display().to_string()),
            data.camera_source.display()
        ),
    }
}

/// Writes, atomically to `path`, the report of a calibration of `data` that stopped with
/// `error` ([`calibrate_dataset`] returned it): the inputs found, the counts, the time spans of
/// the camera and the DVL logs and their overlap, the detection summary, and the error with what
/// it usually means.
pub fn write_failure_report(path: &Path, data: &Dataset, error: &Error) -> Result<()> {
    let files = &data.files;
    crate::files::refuse_input("--report", path, files.inputs().iter().map(|p| p.as_path()))?;
    let log = data.dvl()?;
    let mut inputs: Vec<(String, String)> = Vec::new();
    let mut add = |k: &str, p: &Option<PathBuf>| {
        if let Some(p) = p {
            inputs.push((k.to_owned(), p.display().to_string()));
        }
    };
    add("images", &files.images);
    add("poses", &files.poses);
    add("bag", &files.bag);
    add("camchain", &files.camchain);
    add("target", &files.target);
    add("DVL log", &files.dvl);
    if files.camchain.is_none()
        && let Some(cams) = &data.cameras
    {
        inputs.push((
            "camchain".into(),
            format!("calibrated from the same images ({})", cams.one_line()),
        ));
    }
    for (p, why) in &files.ignored {
        inputs.push((format!("ignored: {why}"), p.display().to_string()));
    }
    let frames = data
        .vision
        .as_ref()
        .map(|v| frame_stats(&v.results, &v.epoch));
    let detection = data.vision.as_ref().map(|v| v.summary());
    let context = calibration_context(data);
    let html = render_failure_html(&FailureReportInput {
        title: "DVL calibration report: failed",
        context: &context,
        error,
        inputs: &inputs,
        poses: &data.poses,
        dvl: &log.samples,
        dvl_stats: Some(&log.stats),
        frames: frames.as_deref(),
        detection: detection.as_deref(),
        notes: &data.notes,
    });
    if let Some(d) = path.parent()
        && !d.as_os_str().is_empty()
    {
        std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
    }
    write_atomic(path, html.as_bytes())
}

impl CalibrationRun {
    /// The summary `dvlcal calibrate` prints: counts, each parameter with its standard deviation
    /// and verdict, the residuals, and every warning.
    pub fn summary(&self, log: &DvlLog) -> String {
        let o = &self.outcome;
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
        // A held parameter has no standard deviation: it says so instead.
        let spread = |v: &Verdict, sd: String| match v.by {
            DeterminedBy::Fixed => flag(v).words().to_owned(),
            _ => format!("std {sd}  {}", flag(v).words()),
        };
        let q = self.file.quaternion_cam_dvl_xyzw;
        let _ = writeln!(
            out,
            "rotation  q_cam_dvl (xyzw) [{:.5}, {:.5}, {:.5}, {:.5}]  {}",
            q[0],
            q[1],
            q[2],
            q[3],
            spread(
                &o.verdicts.rotation,
                format!(
                    "[{:.3}, {:.3}, {:.3}] deg",
                    s.rotation_deg.x, s.rotation_deg.y, s.rotation_deg.z
                )
            )
        );
        let p = o.params.lever_arm_cam_m();
        let _ = writeln!(
            out,
            "lever arm p_cam_dvl [{:.4}, {:.4}, {:.4}] m  {}",
            p.x,
            p.y,
            p.z,
            spread(
                &o.verdicts.lever_arm,
                format!(
                    "[{:.4}, {:.4}, {:.4}] m",
                    s.lever_arm_m.x, s.lever_arm_m.y, s.lever_arm_m.z
                )
            )
        );
        let _ = writeln!(
            out,
            "clock     time_offset_s {:.5} s  {}",
            o.params.time_offset_s,
            spread(&o.verdicts.time_offset, format!("{:.5} s", s.time_offset_s))
        );
        let _ = writeln!(
            out,
            "scale     velocity_scale {:.5}  {}",
            o.params.velocity_scale,
            spread(
                &o.verdicts.velocity_scale,
                format!("{:.5}", s.velocity_scale)
            )
        );
        let sound = if o.verdicts.velocity_scale.by == DeterminedBy::Fixed {
            "the velocity scale was held at the given value: it says nothing of the water's \
             sound speed"
                .to_owned()
        } else {
            crate::report::sound_speed_words(
                o.params.velocity_scale,
                s.velocity_scale,
                st.sound_speed_mps,
            )
        };
        let _ = writeln!(out, "sound     {sound}");
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
        out.push_str(&super::imu::summary_lines(&self.file));
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
