//! `dvlcal watch` on stereo images with no camchain: the cameras are calibrated by the first
//! update that can, the later updates solve their poses with that model until the frames with
//! a board pose have grown enough (`dvlcal::pipeline::watch::GROWTH`, `GROWTH_WEAK`,
//! `MIN_NEW_FRAMES`), updates that bring no new images never calibrate again, and the result
//! written at the end is the one `calibrate` gives on the finished folder (which calibrates the
//! cameras from all the images).

mod tmp_common;
#[allow(dead_code)] // this binary uses only the result check
mod watch_common;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use dvlcal::pipeline::watch::{GROWTH, GROWTH_WEAK, MIN_NEW_FRAMES};
use serde_json::Value;
use tmp_common::{TmpDir, dvlcal_ok, s};
use watch_common::assert_same_result;

const STEREO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/stereo");

/// Puts frames `from..to` of `sample_data/stereo` (both cameras, in `names`' order) into `dst`,
/// all written under hidden names first and then renamed into place (so that an update sees
/// the batch whole, but for the moment of the renames), and the DVL log up to the same share of
/// its reports.
fn put_frames(dst: &Path, names: &[String], from: usize, to: usize) {
    let src = Path::new(STEREO);
    let mut hidden = Vec::new();
    for n in &names[from..to] {
        for cam in ["cam0", "cam1"] {
            let h = dst.join(cam).join(format!(".{n}"));
            std::fs::copy(src.join(cam).join(n), &h).expect("copy");
            hidden.push((h, dst.join(cam).join(n)));
        }
    }
    for (h, name) in hidden {
        std::fs::rename(h, name).expect("rename");
    }
    let log = std::fs::read_to_string(src.join("dvl.jsonl")).expect("log");
    let lines: Vec<&str> = log.split_inclusive('\n').collect();
    let keep = (lines.len() * to).div_ceil(names.len());
    let part = dst.join("dvl.jsonl.part");
    std::fs::write(&part, lines[..keep].concat()).expect("log");
    std::fs::rename(&part, dst.join("dvl.jsonl")).expect("rename");
}

/// The frames of five batches (the camera model is weak on this recording: the board stays
/// near the image's centre), then two updates with nothing new: calibrated at 50 frames, reused
/// at 55 (below 1.25 times 50), calibrated again at 65, reused at 75, calibrated at 251, and
/// reused by the two updates that bring no image.
#[test]
fn a_camchain_less_watch_reuses_its_camera_model_and_ends_as_calibrate() {
    let tmp = TmpDir::new("watch-cameras");
    let (dir, out) = (tmp.path("live"), tmp.path("watch.yaml"));
    let mut names: Vec<String> = std::fs::read_dir(Path::new(STEREO).join("cam0"))
        .expect("cam0")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    for cam in ["cam0", "cam1"] {
        std::fs::create_dir_all(dir.join(cam)).expect("folder");
    }
    std::fs::copy(
        Path::new(STEREO).join("target.yaml"),
        dir.join("target.yaml"),
    )
    .expect("board");
    let batches = [50, 55, 65, 75, names.len()];
    put_frames(&dir, &names, 0, batches[0]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args([
            "watch",
            s(&dir),
            "--json",
            "--interval",
            "0.3",
            "--until-idle",
            "3",
        ])
        .args(["--no-progress", "--out", s(&out)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run dvlcal watch");
    let stdout = child.stdout.take().expect("stdout");
    let (tx, rx) = mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(|l| l.ok()) {
            let v: Value = serde_json::from_str(&line)
                .unwrap_or_else(|e| panic!("not one JSON object per line: {line}: {e}"));
            if tx.send(v).is_err() {
                break;
            }
        }
    });
    let mut updates = Vec::new();
    let next = |updates: &mut Vec<Value>| {
        let u = rx
            .recv_timeout(Duration::from_secs(600))
            .expect("an update");
        updates.push(u);
    };
    next(&mut updates);
    for w in batches.windows(2) {
        put_frames(&dir, &names, w[0], w[1]);
        next(&mut updates);
    }
    for _ in 0..2 {
        // Nothing new: a file touched.
        std::thread::sleep(Duration::from_millis(400));
        let log = dir.join("dvl.jsonl");
        let text = std::fs::read(&log).expect("log");
        std::fs::write(&log, text).expect("touch");
        next(&mut updates);
    }
    let end = child.wait_with_output().expect("the watch ends");
    let stderr = String::from_utf8_lossy(&end.stderr).into_owned();
    assert!(end.status.success(), "{stderr}");
    reader.join().expect("reader");
    updates.extend(rx.try_iter());

    // Each update says which model it used; the count grows by one exactly when it calibrated.
    let mut calibrations = 0;
    let mut kept: Option<(u64, bool)> = None;
    let mut table = String::new();
    for u in &updates {
        let c = &u["cameras"];
        let (model, frames) = (
            c["model"].as_str().expect("model"),
            c["frames"].as_u64().expect("frames"),
        );
        table.push_str(&format!(
            "update {}: {frames} frames, {model}, {} calibrations, {:.2} s\n",
            u["update"],
            u["counts"]["camera_calibrations"],
            u["update_s"].as_f64().unwrap_or(0.0)
        ));
        match model {
            "calibrated" => {
                calibrations += 1;
                kept = Some((frames, c["weak"].as_bool().expect("weak")));
            }
            "reused" => {
                let (at, weak) = kept.expect("a model calibrated before one is reused");
                assert_eq!(c["calibrated_frames"].as_u64(), Some(at), "{u}");
                let growth = if weak { GROWTH_WEAK } else { GROWTH };
                let due =
                    frames >= at + MIN_NEW_FRAMES as u64 && frames as f64 >= growth * at as f64;
                assert!(
                    !due,
                    "{frames} frames after {at} should have calibrated again: {u}"
                );
            }
            other => panic!("model {other}: {u}"),
        }
        assert_eq!(u["counts"]["camera_calibrations"], calibrations, "{table}");
    }
    eprintln!("{table}");
    let models: Vec<&str> = updates
        .iter()
        .map(|u| u["cameras"]["model"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(models.first(), Some(&"calibrated"), "{table}");
    assert!(
        models.iter().filter(|m| **m == "reused").count() >= 3,
        "{table}"
    );
    // The updates that bring no image reuse the model of those before them.
    let n = updates.len();
    let last = &updates[n - 1];
    for u in &updates[n - 2..] {
        assert_eq!(u["cameras"]["model"], "reused", "{table}");
        assert_eq!(
            u["cameras"]["frames"].as_u64(),
            Some(names.len() as u64),
            "{table}"
        );
    }
    assert_eq!(
        last["counts"]["camera_calibrations"],
        updates[n - 3]["counts"]["camera_calibrations"],
        "{table}"
    );
    assert_eq!(last["status"], "ok", "{last}");

    // The end is `calibrate`'s result on the finished folder: the cameras calibrated from all
    // the images, not the model the updates kept.
    let reference = tmp.path("calibrate/calibration.yaml");
    dvlcal_ok(&[
        "calibrate",
        s(&dir),
        "--out",
        s(&reference),
        "--no-progress",
    ]);
    assert_same_result(&out, &reference);
    // The camchains beside the results, alike but for the first line (the result's name).
    let chain = |p: &Path| {
        let text = std::fs::read_to_string(p.with_file_name("camchain.yaml")).expect("camchain");
        text.lines().skip(1).collect::<Vec<_>>().join("\n")
    };
    assert_eq!(chain(&out), chain(&reference));
}
