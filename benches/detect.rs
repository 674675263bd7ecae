//! Throughput of `detect` (PNG decode + tag detection + corner refinement + stereo PnP) on
//! rendered 752x480 stereo frames, against Debian's `apriltag` CLI on the same frames as PGM;
//! the board printed as libapriltag draws its tags and as Kalibr prints it.
//!
//! `cargo bench --bench detect [-- FRAMES]` (default 60 stereo frames; 10 run in well under a
//! minute). Prints, per board print, a table of every configuration at 1 thread and at all
//! cores, then images/s against threads (1 up to `available_parallelism`) with the ratio to
//! the CLI's fastest use of as many cores (that many processes of `-t 1`). The CLI rows are
//! skipped when it is not installed.

#[path = "common/detect_compare.rs"]
mod detect_compare;

use std::time::Instant;

use rayon::prelude::*;

use detect_compare::{DECIMATE, Frames, Print, Row, best_of, have_cli, pipeline_settings};
use dvlcal::io::image::load_gray;
use dvlcal::types::board::Board;
use dvlcal::vision::detect::Detector;

fn main() {
    let n: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(60);
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    let cli = have_cli();
    let threads: Vec<usize> = if cores > 1 { vec![1, cores] } else { vec![1] };
    let mut summary: Vec<(Print, Vec<Row>)> = Vec::new();
    for print in [Print::Apriltag, Print::Kalibr] {
        eprintln!("rendering {n} stereo frames ({}) ...", print.label());
        let frames = Frames::render(print, n);
        let images = frames.images() as f64;
        println!(
            "\n{} images ({n} stereo frames 752x480), {}, decimate {DECIMATE}, {cores} cores",
            frames.images(),
            print.label()
        );
        println!("| what | threads | images/s | stereo frames/s | x real time (10 Hz) |");
        println!("|---|---|---|---|---|");
        let row = |what: &str, threads: usize, secs: f64| {
            let ips = images / secs;
            println!(
                "| {what} | {threads} | {ips:.0} | {:.1} | {:.1} |",
                ips / 2.0,
                ips / 2.0 / 10.0
            );
            ips
        };
        let gray: Vec<image::GrayImage> = frames
            .frames
            .iter()
            .flat_map(|f| f.images.iter().flatten())
            .map(|p| load_gray(p.path().expect("file")).expect("png"))
            .collect();
        for &t in &threads {
            let full = row(
                "dvlcal detect (PNG decode + detect + refine + PnP)",
                t,
                frames.dvlcal_seconds(t, 3),
            );
            row(
                "dvlcal detection alone (decoded images)",
                t,
                detection_alone(&gray, &frames.board, t),
            );
            if !cli {
                continue;
            }
            if let Some(s) = frames.cli_seconds(1, t, 3) {
                let c = row("apriltag CLI, one process (-t N)", t, s);
                println!("|   dvlcal detect / CLI | {t} | {:.2}x | | |", full / c);
            }
            if t > 1
                && let Some(s) = frames.cli_seconds(t, 1, 3)
            {
                let c = row("apriltag CLI, N processes (-t 1)", t, s);
                println!("|   dvlcal detect / CLI | {t} | {:.2}x | | |", full / c);
            }
        }
        // Images/s against threads, with the CLI as as many single-threaded processes; the
        // two timed back to back for each thread count.
        let rows: Vec<Row> = (1..=cores)
            .map(|t| {
                let ours = images / frames.dvlcal_seconds(t, 3);
                let theirs = if cli {
                    frames.cli_seconds(t, 1, 3).map(|s| images / s)
                } else {
                    None
                };
                Row {
                    threads: t,
                    dvlcal: ours,
                    cli: theirs,
                }
            })
            .collect();
        summary.push((print, rows));
    }
    println!("\nimages/s by threads: dvlcal detect, and the CLI as N processes of -t 1");
    println!("| board print | threads | dvlcal detect | apriltag CLI | dvlcal / CLI |");
    println!("|---|---|---|---|---|");
    for (print, rows) in &summary {
        for r in rows {
            let (c, q) = match (r.cli, r.ratio()) {
                (Some(c), Some(q)) => (format!("{c:.0}"), format!("{q:.2}x")),
                _ => ("-".into(), "-".into()),
            };
            println!(
                "| {} | {} | {:.0} | {c} | {q} |",
                print.label(),
                r.threads,
                r.dvlcal
            );
        }
    }
}

/// Best of three wall times of detection alone (no decoding, no PnP) on decoded images, one
/// detector per worker.
fn detection_alone(images: &[image::GrayImage], board: &Board, threads: usize) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    let settings = pipeline_settings(board);
    best_of(3, || {
        let s = Instant::now();
        let total: usize = pool.install(|| {
            images
                .par_iter()
                .map_init(
                    || Detector::new(&settings).expect("detector"),
                    |d, g| d.detect(g).len(),
                )
                .sum()
        });
        assert!(total > 0);
        Some(s.elapsed().as_secs_f64())
    })
    .unwrap_or(f64::NAN)
}
