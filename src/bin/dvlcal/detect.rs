//! `dvlcal detect`: camera poses `T_world_cam0` (board frame as world) from folders of stereo
//! images of an AprilTag board, with per-frame statistics and covariances.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;

use dvlcal::io::tum::write_tum;
use dvlcal::io::write_atomic;
use dvlcal::time::Epoch;
use dvlcal::types::PoseMeasurement;
use dvlcal::vision::board::Board;
use dvlcal::vision::camera::Camchain;
use dvlcal::vision::detect::DetectorSettings;
use dvlcal::vision::images::{Layout, ScanStats, raw_time, scan_images};
use dvlcal::vision::pipeline::{DetectStats, FrameResult, detect_frames};
use dvlcal::vision::pnp::PnpOptions;

/// Detection and PnP settings shared by `detect` and `calibrate --images`.
#[derive(Args, Debug, Clone)]
pub struct VisionTuning {
    /// Worker threads (one image pair per thread at a time; default: all cores).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Decimation of the image for quad detection (corners are refined at full resolution).
    #[arg(long, value_name = "X", default_value_t = 2.0)]
    pub decimate: f32,
    /// Largest time difference between paired cam0 / cam1 images, milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 2.0)]
    pub pair_tolerance_ms: f64,
    /// Frames with fewer board corners (all cameras) get no pose.
    #[arg(long, value_name = "N", default_value_t = 8)]
    pub min_corners: usize,
    /// Corner noise (pixels) for the pose covariances (default: estimated per frame from the
    /// residuals).
    #[arg(long, value_name = "PX")]
    pub pixel_sigma: Option<f64>,
    /// No progress bar (it is shown only when stderr is a terminal anyway).
    #[arg(long)]
    pub no_progress: bool,
}

#[derive(Args, Debug)]
pub struct DetectArgs {
    /// Image folder: DIR/cam0/<t_ns>.png (+ DIR/cam1/...) or EuRoC's DIR/mav0/camN/data.csv.
    /// Without cam1 images the poses come from cam0 alone (with a warning); unreadable images
    /// and unpaired frames are counted and skipped.
    #[arg(long, value_name = "DIR")]
    pub images: PathBuf,
    /// Kalibr camchain YAML (intrinsics, distortion, T_cn_cnm1).
    #[arg(long, value_name = "FILE")]
    pub camchain: PathBuf,
    /// Board YAML (dvlcal grid or tag list, or Kalibr aprilgrid target).
    #[arg(long, value_name = "FILE")]
    pub target: PathBuf,
    /// TUM file of T_world_cam0 to write; per-frame statistics go to OUT.frames.csv.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    #[command(flatten)]
    pub tuning: VisionTuning,
}

/// A thread pool of `threads` workers (default: all cores).
pub fn worker_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let n = threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if n == 0 {
        bail!("--threads must be at least 1");
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .context("starting the worker threads")
}

/// Everything a run of the pipeline produced.
pub struct VisionRun {
    /// The camera chain the poses were solved with.
    pub chain: Camchain,
    pub epoch: Epoch,
    /// One per posed frame, in time order, with covariances.
    pub poses: Vec<PoseMeasurement>,
    pub results: Vec<FrameResult>,
    pub scan: ScanStats,
    pub stats: DetectStats,
    pub seconds: f64,
}

/// Scans the folder, detects and solves every frame; prints warnings and image problems to
/// stderr. Fails when no frame gets a pose.
pub fn run_pipeline(
    images: &Path,
    camchain: &Path,
    target: &Path,
    t: &VisionTuning,
) -> Result<VisionRun> {
    let chain = Camchain::load(camchain)?;
    let board = Board::load(target)?;
    if !(t.pair_tolerance_ms.is_finite() && t.pair_tolerance_ms >= 0.0) {
        bail!("--pair-tolerance-ms must be a non-negative number");
    }
    if t.min_corners < 4 {
        bail!("--min-corners must be at least 4");
    }
    if let Some(s) = t.pixel_sigma
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--pixel-sigma must be positive");
    }
    let tol_ns = (t.pair_tolerance_ms * 1e6).round() as i64;
    let (frames, scan) = scan_images(images, chain.cams.len(), tol_ns)?;
    for w in &scan.warnings {
        eprintln!("warning: {w}");
    }
    let det = DetectorSettings {
        family: board.family,
        decimate: t.decimate,
        threads: 1,
        ..DetectorSettings::default()
    };
    let opts = PnpOptions {
        min_corners: t.min_corners,
        sigma_px: t.pixel_sigma,
        ..PnpOptions::default()
    };
    let pool = worker_pool(t.threads)?;
    let start = Instant::now();
    let (results, stats) =
        pool.install(|| detect_frames(&frames, &board, &chain, &det, &opts, !t.no_progress))?;
    let seconds = start.elapsed().as_secs_f64();
    const SHOWN: usize = 10;
    for p in stats.problems.iter().take(SHOWN) {
        eprintln!("skipped: {p}");
    }
    if stats.problems.len() > SHOWN {
        eprintln!(
            "skipped: ... and {} more images",
            stats.problems.len() - SHOWN
        );
    }
    let epoch = Epoch::at(raw_time(frames.first().map_or(0, |f| f.t_ns)));
    let poses: Vec<PoseMeasurement> = results
        .iter()
        .filter_map(|r| {
            r.pose.as_ref().map(|p| PoseMeasurement {
                t: epoch.rel(raw_time(r.frame.t_ns)),
                pose: p.t_board_cam0,
                cov: Some(p.cov),
            })
        })
        .collect();
    let run = VisionRun {
        chain,
        epoch,
        poses,
        results,
        scan,
        stats,
        seconds,
    };
    print_summary(images, &run);
    if run.poses.is_empty() {
        bail!(
            "{}: no frame gave a pose ({} frames)",
            images.display(),
            run.stats.frames
        );
    }
    Ok(run)
}

fn print_summary(dir: &Path, r: &VisionRun) {
    let sc = &r.scan;
    let st = &r.stats;
    let layout = match sc.layout {
        Layout::Kalibr => "camN/<t_ns> layout",
        Layout::Euroc => "EuRoC layout",
    };
    let per_cam: Vec<String> = sc
        .images
        .iter()
        .enumerate()
        .map(|(c, n)| format!("cam{c} {n}"))
        .collect();
    println!(
        "images {} ({layout}): {} images; {} frames, {} with every camera, {} cam0 alone, \
         {} unpaired images of other cameras dropped, {} other files ignored",
        dir.display(),
        per_cam.join(", "),
        st.frames,
        sc.complete,
        sc.unpaired_cam0,
        sc.unpaired_other,
        sc.ignored
    );
    println!(
        "poses {} of {} frames; {:.1} tags detected per frame, {} used, {} rejected as outliers, \
         {} not on the board; reprojection RMS {:.3} px; {:.2} s ({:.1} frames/s)",
        st.poses,
        st.frames,
        st.tags_per_frame(),
        st.tags_used,
        st.tags_rejected,
        st.tags_unknown,
        st.rms_px,
        r.seconds,
        st.frames as f64 / r.seconds.max(1e-9)
    );
    println!(
        "skipped frames: {} too few corners, {} no solution, {} no usable image \
         ({} unreadable images, {} of the wrong size)",
        st.too_few_corners, st.no_solution, st.no_image, st.unreadable, st.wrong_size
    );
}

/// The per-frame CSV written beside the TUM file: one row per pose, same order.
pub fn frames_csv(run: &VisionRun) -> String {
    let mut s = String::from(
        "# one row per pose of the TUM file: time (s), tag observations used (a tag in both \
         cameras counts twice), corners used, reprojection RMS (px), observations rejected, \
         pixel sigma used for the covariance, then the 21 upper-triangle values (row by row) of \
         the 6x6 covariance of the right perturbation [rho; phi] of T_world_cam0 (m, rad)\n",
    );
    s.push_str("t,tags,corners,rms_px,rejected,sigma_px");
    for i in 0..6 {
        for j in i..6 {
            let _ = write!(s, ",c{i}{j}");
        }
    }
    s.push('\n');
    for r in &run.results {
        let Some(p) = &r.pose else { continue };
        let t = run.epoch.rel(raw_time(r.frame.t_ns));
        let _ = write!(
            s,
            "{},{},{},{},{},{}",
            run.epoch.format_abs(t, 9),
            p.tags_used,
            p.corners_used,
            p.rms_px,
            p.tags_rejected,
            p.sigma_px
        );
        for i in 0..6 {
            for j in i..6 {
                let _ = write!(s, ",{:e}", p.cov[(i, j)]);
            }
        }
        s.push('\n');
    }
    s
}

/// `OUT.frames.csv` beside `OUT`.
pub fn frames_path(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".frames.csv");
    PathBuf::from(name)
}

pub fn run(a: DetectArgs) -> Result<()> {
    let run = run_pipeline(&a.images, &a.camchain, &a.target, &a.tuning)?;
    write_tum(&a.out, run.epoch, &run.poses)?;
    let frames = frames_path(&a.out);
    write_atomic(&frames, frames_csv(&run).as_bytes())?;
    println!("wrote {} and {}", a.out.display(), frames.display());
    Ok(())
}
