//! Throughput of `detect` (decode + tag detection + stereo PnP) on rendered 752x480 stereo frames,
//! against Debian's `apriltag` CLI on the same frames as PGM; then the same frames with the board
//! printed the way Kalibr prints it.
//!
//! `cargo bench --bench detect [-- FRAMES]` (default 60 stereo frames). Prints a table; the
//! apriltag rows are skipped when the CLI is not installed.

#[path = "../tests/vision_seq/mod.rs"]
mod vision_seq;

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use rayon::prelude::*;

use dvlcal::sim::render::RenderSettings;
use dvlcal::vision::board::Board;
use dvlcal::vision::camera::Camchain;
use dvlcal::vision::detect::{Detector, DetectorSettings, load_gray};
use dvlcal::vision::frames::detect_frames;
use dvlcal::vision::images::scan_images;
use dvlcal::vision::pnp::PnpOptions;

const DECIMATE: f32 = 2.0;

fn best_of<F: FnMut() -> f64>(reps: usize, mut f: F) -> f64 {
    (0..reps).map(|_| f()).fold(f64::INFINITY, f64::min)
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
}

/// Wall time of the apriltag CLI over `files`, split into `procs` processes of `threads` threads.
fn cli_seconds(files: &[std::path::PathBuf], procs: usize, threads: usize) -> Option<f64> {
    let chunk = files.len().div_ceil(procs);
    let start = Instant::now();
    let children: Vec<_> = files
        .chunks(chunk)
        .map(|c| {
            Command::new("apriltag")
                .args([
                    "-q",
                    "-t",
                    &threads.to_string(),
                    "-x",
                    &DECIMATE.to_string(),
                ])
                .args(c)
                .stdout(std::process::Stdio::null())
                .spawn()
        })
        .collect::<Result<_, _>>()
        .ok()?;
    for mut ch in children {
        if !ch.wait().ok()?.success() {
            return None;
        }
    }
    Some(start.elapsed().as_secs_f64())
}

fn main() {
    let n: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(60);
    let dir = vision_seq::fresh_dir("bench");
    eprintln!("rendering {n} stereo frames into {} ...", dir.display());
    let (_, times) = vision_seq::write_sequence(&dir, n, &RenderSettings::default(), 7);
    let chain = Camchain::load(&dir.join("camchain.yaml")).expect("camchain");
    let board = Board::load(&dir.join("target.yaml")).expect("target");
    let (frames, _) = scan_images(&dir, 2, 1_000_000).expect("scan");
    let images = 2 * frames.len();

    // The same frames as PGM for the CLI, and decoded once for detection alone.
    let pgm = dir.join("pgm");
    std::fs::create_dir_all(&pgm).expect("pgm folder");
    let mut gray = Vec::new();
    let mut pgm_files = Vec::new();
    for &t in &times {
        for c in 0..2 {
            let img = load_gray(&vision_seq::image_path(&dir, c, t)).expect("png");
            let p = pgm.join(format!("cam{c}_{t}.pgm"));
            // Binary PGM (P5) with a minimal header, as libapriltag's reader wants it.
            let mut bytes = format!("P5\n{} {}\n255\n", img.width(), img.height()).into_bytes();
            bytes.extend_from_slice(img.as_raw());
            std::fs::write(&p, bytes).expect("pgm");
            pgm_files.push(p);
            gray.push(img);
        }
    }

    let settings = DetectorSettings {
        decimate: DECIMATE,
        threads: 1,
        ..DetectorSettings::default()
    };
    let opts = PnpOptions::default();
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    println!("{images} images ({n} stereo frames 752x480), decimate {DECIMATE}, {cores} cores");
    println!("| what | threads | images/s | stereo frames/s | x real time (10 Hz) |");
    println!("|---|---|---|---|---|");
    // Best of three timings of the full `detect` (PNG decode, detection, PnP) and of the
    // detection alone on decoded images.
    let time_detect = |p: &rayon::ThreadPool, frames: &[_], board: &Board| {
        best_of(3, || {
            let s = Instant::now();
            let (_, st) = p
                .install(|| detect_frames(frames, board, &chain, &settings, &opts, false))
                .expect("detect");
            assert_eq!(st.poses, n);
            s.elapsed().as_secs_f64()
        })
    };
    let time_detection_alone = |p: &rayon::ThreadPool, images: &[image::GrayImage]| {
        best_of(3, || {
            let s = Instant::now();
            let total: usize = p.install(|| {
                images
                    .par_iter()
                    .map_init(
                        || Detector::new(&settings).expect("detector"),
                        |d, g| d.detect(g).len(),
                    )
                    .sum()
            });
            assert!(total > 0);
            s.elapsed().as_secs_f64()
        })
    };
    let row = |what: &str, threads: &str, secs: f64| {
        let ips = images as f64 / secs;
        println!(
            "| {what} | {threads} | {ips:.0} | {:.1} | {:.1} |",
            ips / 2.0,
            ips / 2.0 / 10.0
        );
        ips
    };
    let mut ours = Vec::new();
    for threads in [1, cores] {
        let p = pool(threads);
        let secs = time_detect(&p, &frames, &board);
        let full = row(
            "dvlcal detect (PNG decode + detect + PnP)",
            &threads.to_string(),
            secs,
        );
        let secs = time_detection_alone(&p, &gray);
        let alone = row(
            "dvlcal detection alone (decoded images)",
            &threads.to_string(),
            secs,
        );
        ours.push((threads, full, alone));
        if threads == cores {
            break;
        }
    }
    let have_cli = Command::new("apriltag").arg("-h").output().is_ok();
    if have_cli {
        for threads in [1, cores] {
            if let Some(s) = best_of_opt(3, || cli_seconds(&pgm_files, 1, threads)) {
                let cli = row("apriltag CLI, one process (-t N)", &threads.to_string(), s);
                if let Some((_, full, _)) = ours.iter().find(|o| o.0 == threads) {
                    println!(
                        "|   dvlcal detect / CLI | {threads} | {:.2}x | | |",
                        full / cli
                    );
                }
            }
            if threads > 1
                && let Some(s) = best_of_opt(3, || cli_seconds(&pgm_files, threads, 1))
            {
                let cli = row("apriltag CLI, N processes (-t 1)", &threads.to_string(), s);
                if let Some((_, full, _)) = ours.iter().find(|o| o.0 == threads) {
                    println!(
                        "|   dvlcal detect / CLI | {threads} | {:.2}x | | |",
                        full / cli
                    );
                }
            }
            if threads == cores {
                break;
            }
        }
    } else {
        println!("(apriltag CLI not installed: no comparison)");
    }
    let _ = std::fs::remove_dir_all(Path::new(&dir));

    // The same frames with the board printed the way Kalibr prints it (two-bit borders, corner
    // squares): found by the detector's two passes.
    let kdir = vision_seq::fresh_dir("bench-kalibr");
    let kboard = vision_seq::board().printed_by_kalibr();
    vision_seq::write_sequence_of(&kdir, n, &RenderSettings::default(), 7, &kboard);
    let (kframes, _) = scan_images(&kdir, 2, 1_000_000).expect("scan");
    let kgray: Vec<_> = kframes
        .iter()
        .flat_map(|f| f.images.iter().flatten())
        .map(|p| load_gray(p.path().expect("file")).expect("png"))
        .collect();
    println!("| Kalibr-printed board: | | | | |");
    for threads in [1, cores] {
        let p = pool(threads);
        let secs = time_detect(&p, &kframes, &kboard);
        row(
            "dvlcal detect, Kalibr print (PNG decode + detect + PnP)",
            &threads.to_string(),
            secs,
        );
        let secs = time_detection_alone(&p, &kgray);
        row(
            "dvlcal detection alone, Kalibr print (decoded images)",
            &threads.to_string(),
            secs,
        );
        if threads == cores {
            break;
        }
    }
    let _ = std::fs::remove_dir_all(&kdir);
}

fn best_of_opt<F: FnMut() -> Option<f64>>(reps: usize, mut f: F) -> Option<f64> {
    let mut best: Option<f64> = None;
    for _ in 0..reps {
        let s = f()?;
        best = Some(best.map_or(s, |b| b.min(s)));
    }
    best
}
