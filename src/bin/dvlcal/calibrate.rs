//! `dvlcal calibrate`: DVL extrinsics, clock offset and scale from camera poses and a DVL log.

use anyhow::{Context, Result, bail};
use clap::ValueEnum;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::dataset::{DatasetArgs, load, print_found, resolve};
use crate::detect::worker_pool;
use crate::dvl_info::DvlInputArgs;

use dvlcal::calib::offset::OffsetMethod;
use dvlcal::calib::{CalibOptions, CalibrationOutcome, Method, Verdict, calibrate};
use dvlcal::io::calib_yaml::{
    CalibrationFile, CalibrationInfo, CalibrationStd, Observability, ObservabilityFlags,
    read_calib_yaml, write_calib_yaml,
};
use dvlcal::io::dvl::DvlLog;
use dvlcal::io::exports::{FrameNames, kalibr_dvl_block, ros_static_transform};
use dvlcal::io::write_atomic;
use dvlcal::types::CalibrationParams;
use nalgebra::Matrix4;

#[derive(Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// Initialise from the data alone, then refine (no guess needed).
    Uic,
    /// Refine from the guess given with --init.
    Bcd,
    /// Keep the extrinsics of --init; with --estimate-offset estimate clock offset and scale.
    Fixed,
}

#[derive(clap::Args)]
pub struct CalibrateArgs {
    /// Dataset folder: cam0/ (+ cam1/) images or a TUM pose file, a Kalibr camchain YAML, a
    /// board YAML and a DVL log, recognised by their content. Options below override parts.
    #[arg(value_name = "DATASET_DIR")]
    pub dataset: Option<PathBuf>,
    #[command(flatten)]
    pub files: DatasetArgs,
    #[command(flatten)]
    pub vision: crate::detect::VisionTuning,
    #[command(flatten)]
    pub dvl_input: DvlInputArgs,
    /// Standard deviation of each DVL velocity component, m/s, replacing the reports'
    /// covariance in the calibration.
    #[arg(long = "dvl-sigma", value_name = "M_PER_S")]
    pub dvl_sigma: Option<f64>,
    /// Stop at the first malformed DVL line instead of skipping and counting it.
    #[arg(long)]
    pub strict: bool,
    /// Result YAML (written atomically); beside it RESULT-tf.txt (ROS static transform) and
    /// RESULT-camchain-dvl.yaml (Kalibr-style block).
    #[arg(long, default_value = "calibration.yaml")]
    pub out: PathBuf,
    #[arg(long, value_enum, default_value = "uic")]
    pub method: MethodArg,
    /// Initial guess or fixed extrinsics (result YAML schema), for --method bcd and fixed.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// Clock offsets searched, `min,max` seconds (t_cam = t_dvl + offset).
    #[arg(long, value_delimiter = ',', default_values_t = [-1.0, 1.0])]
    pub offset_range: Vec<f64>,
    /// With --method fixed: estimate clock offset and scale with the extrinsics held.
    #[arg(long)]
    pub estimate_offset: bool,
    /// Use the closed form without bias elimination (for comparison only).
    #[arg(long)]
    pub biased: bool,
    /// Self-contained HTML report with plots (written atomically; opens offline).
    #[arg(long, value_name = "REPORT.html")]
    pub report: Option<PathBuf>,
}

fn flag(v: &Verdict) -> Observability {
    if v.ok {
        Observability::Ok
    } else {
        Observability::Weak
    }
}

fn method_name(m: &Method) -> &'static str {
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
    let v = |x: &nalgebra::Vector3<f64>| [x.x, x.y, x.z];
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
    put("dvl_used", o.counts.dvl_used.into());
    put("dvl_outside_camera_span", o.counts.dvl_outside_span.into());
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
                OffsetMethod::CalmSubset => "calm subset",
                OffsetMethod::SpeedCorrelation => "speed correlation (no calm segment)",
            }
            .into(),
        );
        put("calm_samples", o.counts.calm.into());
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

/// The calibration options of the command line; `guess` is the parsed `--init`.
pub fn options(
    method: MethodArg,
    guess: Option<CalibrationParams>,
    estimate_offset: bool,
    dvl_sigma: Option<f64>,
    offset_range: &[f64],
    biased: bool,
) -> Result<CalibOptions> {
    if offset_range.len() != 2
        || offset_range[0].partial_cmp(&offset_range[1]) != Some(std::cmp::Ordering::Less)
    {
        bail!("--offset-range takes two increasing values: min,max");
    }
    let method = match (method, guess) {
        (MethodArg::Uic, _) => Method::Uic,
        (MethodArg::Bcd, Some(g)) => Method::Bcd(g),
        (MethodArg::Fixed, Some(g)) => Method::Fixed {
            guess: g,
            estimate_offset,
        },
        (_, None) => bail!("--method bcd and fixed need --init FILE"),
    };
    if let Some(s) = dvl_sigma
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--dvl-sigma must be positive");
    }
    let mut opts = CalibOptions {
        method,
        dvl_sigma,
        bias_corrected: !biased,
        ..CalibOptions::default()
    };
    opts.offset.range = (offset_range[0], offset_range[1]);
    Ok(opts)
}

/// `RESULT-<suffix>` beside `RESULT` (its extension dropped).
pub fn sibling(out: &Path, suffix: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "calibration".into());
    out.with_file_name(format!("{stem}-{suffix}"))
}

pub fn run(a: CalibrateArgs) -> Result<()> {
    let files = resolve(a.dataset.as_deref(), &a.files)?;
    if a.dataset.is_some() {
        print_found(&files);
    }
    let guess = match &a.init {
        Some(p) => Some(read_calib_yaml(p)?.to_params()?),
        None => None,
    };
    let opts = options(
        a.method,
        guess,
        a.estimate_offset,
        a.dvl_sigma,
        &a.offset_range,
        a.biased,
    )?;
    if let Some(d) = a.out.parent()
        && !d.as_os_str().is_empty()
    {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    let data = load(files, &a.vision, &a.dvl_input.read_options(a.strict))?;
    let workers = worker_pool(a.vision.threads)?;
    let start = Instant::now();
    let o = workers
        .install(|| calibrate(&data.poses, &data.log.samples, &opts))
        .with_context(|| {
            format!(
                "calibrating {} against {}",
                data.dvl_path.display(),
                data.camera_source.display()
            )
        })?;
    let elapsed = start.elapsed().as_secs_f64();
    let file = result_file(&o, &data.log);
    write_calib_yaml(&a.out, &file)?;
    let calib = o.params;
    let tf = sibling(&a.out, "tf.txt");
    write_atomic(
        &tf,
        ros_static_transform(&calib, &FrameNames::default()).as_bytes(),
    )?;
    // With images, the DVL block is given for every camera of the chain; with poses, for cam0.
    let t_cn_c0: Vec<Matrix4<f64>> = match &data.vision {
        Some(run) => run.chain.t_cn_c0.iter().map(|t| t.to_matrix()).collect(),
        None => vec![Matrix4::identity()],
    };
    let block = sibling(&a.out, "camchain-dvl.yaml");
    write_atomic(&block, kalibr_dvl_block(&calib, &t_cn_c0).as_bytes())?;
    print_summary(&o, &data.log, &file, elapsed);
    println!(
        "wrote {}, {} and {}",
        a.out.display(),
        tf.display(),
        block.display()
    );
    if let Some(path) = &a.report {
        let frames = data
            .vision
            .as_ref()
            .map(|run| dvlcal::report::frame_stats(&run.results, &run.epoch));
        let run = crate::html_report::RunInfo {
            poses_src: &data.camera_source,
            poses: &data.poses,
            log: &data.log,
            frames: frames.as_deref(),
            result: &a.out,
            elapsed_s: elapsed,
        };
        crate::html_report::write(path, &o, &run)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn print_summary(o: &CalibrationOutcome, log: &DvlLog, f: &CalibrationFile, secs: f64) {
    let ok = |v: &Verdict| if v.ok { "ok" } else { "WEAK" };
    let s = &o.std;
    let st = &log.stats;
    println!(
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
        secs
    );
    let q = f.quaternion_cam_dvl_xyzw;
    println!(
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
    println!(
        "lever arm p_cam_dvl [{:.4}, {:.4}, {:.4}] m  std [{:.4}, {:.4}, {:.4}] m  {}",
        p.x,
        p.y,
        p.z,
        s.lever_arm_m.x,
        s.lever_arm_m.y,
        s.lever_arm_m.z,
        ok(&o.verdicts.lever_arm)
    );
    println!(
        "clock     time_offset_s {:.5} s  std {:.5} s  {}",
        o.params.time_offset_s,
        s.time_offset_s,
        ok(&o.verdicts.time_offset)
    );
    println!(
        "scale     velocity_scale {:.5}  std {:.5}  {}",
        o.params.velocity_scale,
        s.velocity_scale,
        ok(&o.verdicts.velocity_scale)
    );
    println!(
        "residuals {:.4} {:.4} {:.4} m/s RMS; normalized cost {:.2}; {} iterations",
        o.residual_rms.x,
        o.residual_rms.y,
        o.residual_rms.z,
        o.normalized_cost,
        o.iterations.len()
    );
    for w in f.info.iter().flat_map(|i| i.warnings.iter()) {
        println!("warning: {w}");
    }
}
