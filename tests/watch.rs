//! `dvlcal watch` on a recording fed into a folder at six times real speed, as a recorder
//! writes it: the pose file and the DVL log grow line by line, each line written in two halves
//! with a flush between, so that an update can see a line cut in two. The updates must arrive
//! while the data arrive, ask for rotation in the calm first part of the recording, say done
//! once it rotates, and end with the result `calibrate` gives on the finished folder; a
//! recording that barely rotates must never say done and must keep asking for rotation.

mod tmp_common;
mod watch_common;

use std::io::Write;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;
use tmp_common::{TmpDir, dvlcal_ok, s};
use watch_common::{Watching, assert_same_result};

const SPEED: f64 = 6.0;

/// The time of a pose line (TUM) or a DVL report (`time_of_validity`, microseconds).
fn line_time(name: &str, line: &str) -> Option<f64> {
    if name == "poses.txt" {
        return line.split_whitespace().next()?.parse().ok();
    }
    let v: Value = serde_json::from_str(line).ok()?;
    Some(v.get("time_of_validity")?.as_f64()? * 1e-6)
}

/// Writes `src`'s pose file and DVL log into `dst` in time order at `SPEED` times real speed,
/// each line in two halves with a flush between.
fn feed(src: &Path, dst: &Path) {
    let mut events = Vec::new();
    for name in ["poses.txt", "dvl.jsonl"] {
        let text = std::fs::read_to_string(src.join(name)).expect("recording");
        for line in text.split_inclusive('\n') {
            // A header line goes first.
            let t = line_time(name, line).unwrap_or(f64::NEG_INFINITY);
            events.push((t, name, line.to_owned()));
        }
    }
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    let t0 = events
        .iter()
        .map(|e| e.0)
        .find(|t| t.is_finite())
        .unwrap_or(0.0);
    let mut files: Vec<(&str, std::fs::File)> = ["poses.txt", "dvl.jsonl"]
        .iter()
        .map(|&n| (n, std::fs::File::create(dst.join(n)).expect("create")))
        .collect();
    let start = Instant::now();
    for (t, name, line) in events {
        let due = Duration::from_secs_f64((t.max(t0) - t0) / SPEED);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        let f = &mut files.iter_mut().find(|(n, _)| *n == name).expect("file").1;
        let (a, b) = line.split_at(line.len() / 2);
        f.write_all(a.as_bytes()).expect("write");
        f.flush().expect("flush");
        f.write_all(b.as_bytes()).expect("write");
    }
}

/// The updates of `dvlcal watch --json` on `dir` while `src` is fed into it, each with the time
/// it arrived; and when the feed ended.
fn watch_while_fed(src: &Path, dir: &Path, out: &Path) -> (Vec<(Instant, Value)>, Instant) {
    let (updates, fed, _) = watch_while(dir, out, || feed(src, dir));
    (updates, fed)
}

/// The updates of `dvlcal watch --json` on `dir` while `feeder` writes into it, each with the
/// time it arrived; when the feed ended; and what the watch said on its standard error.
fn watch_while(
    dir: &Path,
    out: &Path,
    feeder: impl FnOnce(),
) -> (Vec<(Instant, Value)>, Instant, String) {
    std::fs::create_dir_all(dir).expect("folder");
    let watching = Watching::start(&[
        s(dir),
        "--interval",
        "0.5",
        "--until-idle",
        "3",
        "--out",
        s(out),
    ]);
    feeder();
    let fed = Instant::now();
    let (updates, status) = watching.finish();
    let stderr = String::from_utf8_lossy(&status.stderr).into_owned();
    assert!(status.status.success(), "{stderr}");
    (updates, fed, stderr)
}

fn advice(u: &Value) -> Vec<String> {
    u["advice"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|a| a.as_str().map(String::from))
        .collect()
}

fn simulate(dir: &Path, motion: &str) {
    dvlcal_ok(&[
        "simulate",
        "--duration",
        "60",
        "--seed",
        "3",
        "--motion",
        motion,
        "--out",
        s(dir),
    ]);
}

/// Calm for the first half, then rotating: the updates come while the data come, ask for a
/// rotation while the lever arm is not observed, then say done; the result written at the end
/// is the one `calibrate` writes on the finished folder.
#[test]
fn watch_asks_for_rotation_then_says_done_and_ends_as_calibrate() {
    let tmp = TmpDir::new("watch-strong");
    let src = tmp.path("recording");
    simulate(&src, "calm-then-rotate");
    let (dir, out) = (tmp.path("live"), tmp.path("watch.yaml"));
    let (updates, fed) = watch_while_fed(&src, &dir, &out);
    let during = updates.iter().filter(|(t, _)| *t < fed).count();
    assert!(during >= 3, "{during} updates while the data came");
    for (_, u) in &updates {
        for key in ["done", "advice", "parameters", "counts", "status"] {
            assert!(u.get(key).is_some(), "no {key}: {u}");
        }
        for p in ["rotation", "lever_arm", "time_offset", "velocity_scale"] {
            assert!(u["parameters"][p].get("verdict").is_some(), "{u}");
        }
    }
    // The first update that calibrated, in the calm part: the lever arm is not observed, and
    // the advice is to rotate.
    let first = updates
        .iter()
        .map(|(_, u)| u)
        .find(|u| u["parameters"]["lever_arm"]["std"].is_number())
        .expect("an update that calibrated");
    assert_eq!(first["done"], false, "{first}");
    let a = advice(first);
    assert!(
        a.first().is_some_and(|a| a.starts_with("rotate about")),
        "{first}"
    );
    // Then it says done, and stays done to the end.
    let done_at = updates
        .iter()
        .position(|(_, u)| u["done"] == true)
        .expect("an update that says done");
    let first_at = updates.iter().position(|(_, u)| std::ptr::eq(u, first));
    assert!(first_at.is_some_and(|f| f < done_at));
    assert!(updates[done_at..].iter().all(|(_, u)| u["done"] == true));
    assert!(advice(&updates[done_at].1).is_empty());
    // Updates after one that passed its checks start from its solution.
    let warm = updates
        .iter()
        .filter(|(_, u)| u["started_from_last"] == true)
        .count();
    assert!(warm >= 2, "{warm} updates started from the last solution");
    let last = &updates.last().expect("updates").1;
    assert_eq!(last["counts"]["poses"], 601, "{last}");
    // The end: the same result as calibrate on the finished folder.
    let reference = tmp.path("calibrate.yaml");
    dvlcal_ok(&["calibrate", s(&dir), "--out", s(&reference)]);
    assert_same_result(&out, &reference);
    assert!(tmp.path("watch-tf.txt").exists());
}

/// A recording that barely rotates: never done, and it keeps asking for rotation.
#[test]
fn a_recording_that_barely_rotates_never_says_done() {
    let tmp = TmpDir::new("watch-weak");
    let src = tmp.path("recording");
    simulate(&src, "weak-rotation");
    let (dir, out) = (tmp.path("live"), tmp.path("watch.yaml"));
    let (updates, _) = watch_while_fed(&src, &dir, &out);
    assert!(updates.len() >= 3, "{} updates", updates.len());
    assert!(updates.iter().all(|(_, u)| u["done"] == false));
    let last = &updates.last().expect("updates").1;
    assert!(
        advice(last).iter().any(|a| a.starts_with("rotate about")),
        "{last}"
    );
    assert_eq!(last["parameters"]["lever_arm"]["verdict"], "weak", "{last}");
    assert!(out.exists());
}

/// `--target-std` sets the updates' targets: the barely rotating recording, already complete,
/// is done against targets ten times looser than the verdict limits on the lever arm; targets
/// that are not four positive numbers are refused, naming the option.
#[test]
fn targets_of_its_own_decide_done() {
    let tmp = TmpDir::new("watch-targets");
    let dir = tmp.path("recording");
    simulate(&dir, "weak-rotation");
    std::fs::remove_dir_all(dir.join("truth")).expect("truth");
    let out = tmp.path("r.yaml");
    let run = |targets: &str| {
        Command::new(env!("CARGO_BIN_EXE_dvlcal"))
            .args([
                "watch",
                s(&dir),
                "--json",
                "--interval",
                "0.2",
                "--until-idle",
                "0.1",
            ])
            .args(["--target-std", targets, "--out", s(&out)])
            .output()
            .expect("run dvlcal watch")
    };
    let r = run("0.5,0.1,0.01,0.005");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let text = String::from_utf8_lossy(&r.stdout);
    let u: Value = serde_json::from_str(text.lines().next().expect("an update")).expect("JSON");
    assert_eq!(u["done"], true, "{u}");
    assert_eq!(u["parameters"]["lever_arm"]["target"], 0.1, "{u}");
    let r = run("0.5,0.1");
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("--target-std") && err.contains("four positive numbers"),
        "{err}"
    );
}

/// Each image is detected once: with a [`DetectionCache`] the second solve of the same image
/// files reads no image at all (the files are overwritten with bytes that do not decode, and
/// the poses come out the same, to the bit), while a solve without it finds the images
/// unreadable.
#[test]
fn images_are_detected_once_across_solves() {
    use dvlcal::pipeline::{VisionOptions, poses_from_images};
    use dvlcal::vision::detect::DetectionCache;
    let tmp = TmpDir::new("watch-cache");
    let src = Path::new("sample_data/stereo");
    let dir = tmp.path("frames");
    let mut names: Vec<_> = std::fs::read_dir(src.join("cam0"))
        .expect("cam0")
        .filter_map(|e| e.ok().map(|e| e.file_name()))
        .collect();
    names.sort();
    names.truncate(20);
    for cam in ["cam0", "cam1"] {
        std::fs::create_dir_all(dir.join(cam)).expect("folder");
        for n in &names {
            std::fs::copy(src.join(cam).join(n), dir.join(cam).join(n)).expect("copy");
        }
    }
    let (chain, target) = (src.join("camchain.yaml"), src.join("target.yaml"));
    let cache = DetectionCache::default();
    let opts = VisionOptions {
        cache: Some(cache.clone()),
        ..VisionOptions::default()
    };
    let first = poses_from_images(&dir, &chain, &target, &opts).expect("first solve");
    assert_eq!(first.poses.len(), 20);
    assert_eq!(cache.len(), 40);
    // Each frame's pose is kept too, so a frame seen before is not solved again.
    assert_eq!(cache.frames(), 20);
    for cam in ["cam0", "cam1"] {
        for n in &names {
            std::fs::write(dir.join(cam).join(n), b"not an image").expect("overwrite");
        }
    }
    let again = poses_from_images(&dir, &chain, &target, &opts).expect("cached solve");
    assert_eq!(format!("{:?}", again.poses), format!("{:?}", first.poses));
    let fresh = poses_from_images(&dir, &chain, &target, &VisionOptions::default());
    assert!(fresh.map_or(true, |r| r.poses.is_empty()));
}

/// Seconds of a stretch in [`a_long_recording_is_calibrated_in_stretches`].
const STRETCH: f64 = 40.0;

/// The value of `key` in a result file's `std` section (the largest of a vector's entries).
fn result_std(v: &serde_yaml::Value, key: &str) -> f64 {
    let x = &v["std"][key];
    match x.as_sequence() {
        Some(s) => s.iter().filter_map(|e| e.as_f64()).fold(0.0, f64::max),
        None => x.as_f64().expect("std"),
    }
}

/// A recording longer than two stretches is calibrated in stretches, each closed stretch once,
/// and their results combined: the combined std and estimate are those of `calibrate` on the
/// whole recording (to a tenth of a std), and a later update calibrates only the open stretch.
#[test]
fn a_long_recording_is_calibrated_in_stretches() {
    use dvlcal::pipeline::watch::{WatchOptions, Watcher};
    let tmp = TmpDir::new("watch-stretches");
    let dir = tmp.path("rec");
    dvlcal_ok(&[
        "simulate",
        "--duration",
        "200",
        "--seed",
        "5",
        "--time-offset",
        "0.25",
        "--out",
        s(&dir),
    ]);
    let truth = tmp.path("truth");
    std::fs::rename(dir.join("truth"), &truth).expect("truth out of the folder");
    let opts = WatchOptions {
        stretch_s: Some(STRETCH),
        threads: Some(2),
        ..WatchOptions::default()
    };
    let mut w = Watcher::new(&dir).expect("watcher");
    assert!(w.changed().expect("listing"));
    let first = w.update(&opts).expect("update");
    assert_eq!(first.status, "ok", "{:?}", first.reason);
    assert!(!first.started_from_last, "no update before the first");
    // (200 - 2) / 40: three closed stretches and the open one, solved at the first update.
    assert_eq!(first.counts.stretches, 4);
    assert_eq!(first.counts.stretches_failed, 0);
    assert!(
        (first.counts.solved_s - 200.0).abs() < 0.2,
        "{:?}",
        first.counts
    );
    let result = tmp.path("whole.yaml");
    dvlcal_ok(&["calibrate", s(&dir), "--out", s(&result)]);
    let whole: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(&result).expect("result")).expect("yaml");
    let est = first.estimate.as_ref().expect("estimate");
    let p = &first.parameters;
    for (name, key) in [
        ("rotation", "rotation_deg"),
        ("lever_arm", "lever_arm_m"),
        ("time_offset", "time_offset_s"),
        ("velocity_scale", "velocity_scale"),
    ] {
        let (combined, one) = (p[name].std.expect("std"), result_std(&whole, key));
        assert!(
            (combined / one - 1.0).abs() < 0.15,
            "{name}: std {combined} combined, {one} whole"
        );
    }
    let num = |v: &serde_yaml::Value| v.as_f64().expect("number");
    let lever_std = result_std(&whole, "lever_arm_m");
    for k in 0..3 {
        let d = est.lever_arm_cam_m[k] - num(&whole["lever_arm_cam_m"][k]);
        assert!(d.abs() < lever_std, "lever arm {k}: {d} m apart");
    }
    let d_offset = est.time_offset_s - num(&whole["time_offset_s"]);
    assert!(
        d_offset.abs() < result_std(&whole, "time_offset_s"),
        "{d_offset} s"
    );
    assert!((est.time_offset_s - 0.25).abs() < 4.0 * result_std(&whole, "time_offset_s"));
    let d_scale = est.velocity_scale - num(&whole["velocity_scale"]);
    assert!(
        d_scale.abs() < result_std(&whole, "velocity_scale"),
        "{d_scale}"
    );
    let q: Vec<f64> = (0..4)
        .map(|k| num(&whole["quaternion_cam_dvl_xyzw"][k]))
        .collect();
    let dot: f64 = (0..4).map(|k| q[k] * est.quaternion_cam_dvl_xyzw[k]).sum();
    let angle_deg = 2.0 * dot.abs().min(1.0).acos().to_degrees();
    assert!(
        angle_deg < result_std(&whole, "rotation_deg"),
        "{angle_deg} deg apart"
    );
    // A later update calibrates the open stretch alone and reuses the closed ones.
    let poses = dir.join("poses.txt");
    let text = std::fs::read(&poses).expect("poses");
    std::thread::sleep(Duration::from_millis(20));
    std::fs::write(&poses, text).expect("rewrite");
    assert!(w.changed().expect("listing"));
    let second = w.update(&opts).expect("update");
    // The open stretch starts from the first update's solution and ends where UIC ends.
    assert!(second.started_from_last, "{}", second.text());
    assert!(
        second.counts.solved_s <= 2.0 * STRETCH + 2.5,
        "{:?}",
        second.counts
    );
    assert_eq!(second.counts.stretches, 4);
    assert!(
        second.text().contains(", 4 stretches combined ("),
        "{}",
        second.text()
    );
    for (name, state) in &second.parameters {
        let (a, b) = (
            state.std.expect("std"),
            first.parameters[name].std.expect("std"),
        );
        assert!((a / b - 1.0).abs() < 1e-9, "{name}: {a} then {b}");
    }
}

/// Writes `sample_data/stereo` into `dst` at `SPEED` times real speed: the camera model and the
/// board first, then each image written under `NAME.part` in two halves (with a pause between)
/// and renamed into place, and the DVL log's lines each in two halves.
fn feed_stereo(src: &Path, dst: &Path) {
    for f in ["camchain.yaml", "target.yaml"] {
        std::fs::copy(src.join(f), dst.join(f)).expect("copy");
    }
    let mut events: Vec<(f64, Option<String>, String)> = Vec::new();
    for e in std::fs::read_dir(src.join("cam0")).expect("cam0") {
        let name = e.expect("entry").file_name().to_string_lossy().into_owned();
        let ns: f64 = name.trim_end_matches(".jpg").parse().expect("time name");
        events.push((ns * 1e-9, Some(name), String::new()));
    }
    let text = std::fs::read_to_string(src.join("dvl.jsonl")).expect("log");
    for line in text.split_inclusive('\n') {
        let t = line_time("dvl.jsonl", line).expect("report time");
        events.push((t, None, line.to_owned()));
    }
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    let t0 = events[0].0;
    for cam in ["cam0", "cam1"] {
        std::fs::create_dir_all(dst.join(cam)).expect("folder");
    }
    let mut log = std::fs::File::create(dst.join("dvl.jsonl")).expect("log");
    let start = Instant::now();
    for (t, image, line) in events {
        let due = Duration::from_secs_f64((t - t0) / SPEED);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        match image {
            Some(name) => {
                for cam in ["cam0", "cam1"] {
                    let bytes = std::fs::read(src.join(cam).join(&name)).expect("image");
                    let part = dst.join(cam).join(format!("{name}.part"));
                    let mut f = std::fs::File::create(&part).expect("part");
                    let (a, b) = bytes.split_at(bytes.len() / 2);
                    f.write_all(a).expect("write");
                    f.flush().expect("flush");
                    std::thread::sleep(Duration::from_millis(2));
                    f.write_all(b).expect("write");
                    drop(f);
                    std::fs::rename(&part, dst.join(cam).join(&name)).expect("rename");
                }
            }
            None => {
                let (a, b) = line.split_at(line.len() / 2);
                log.write_all(a.as_bytes()).expect("write");
                log.flush().expect("flush");
                log.write_all(b.as_bytes()).expect("write");
                log.flush().expect("flush");
            }
        }
    }
}

/// Stereo images renamed into place as a recorder writes them, beside a growing DVL log: the
/// updates come while the images come, never see a half-written image, and the end is the
/// result `calibrate` gives on the finished folder, made without detecting the images again.
#[test]
fn images_renamed_into_place_are_followed_and_end_as_calibrate() {
    let tmp = TmpDir::new("watch-images");
    let (dir, out) = (tmp.path("live"), tmp.path("watch.yaml"));
    let src = Path::new("sample_data/stereo");
    let (updates, fed, stderr) = watch_while(&dir, &out, || {
        std::fs::create_dir_all(&dir).expect("folder");
        feed_stereo(src, &dir)
    });
    let during = updates.iter().filter(|(t, _)| *t < fed).count();
    assert!(during >= 2, "{during} updates while the images came");
    let poses: Vec<u64> = updates
        .iter()
        .map(|(_, u)| u["counts"]["poses"].as_u64().expect("count"))
        .collect();
    assert!(poses.windows(2).all(|w| w[0] <= w[1]), "{poses:?}");
    assert!(poses.iter().any(|&n| n > 0 && n < 251), "{poses:?}");
    for (_, u) in &updates {
        let reason = u["reason"].as_str().unwrap_or_default();
        assert!(!reason.contains(".part"), "{u}");
    }
    let last = &updates.last().expect("updates").1;
    assert_eq!(last["status"], "ok", "{last}");
    assert_eq!(last["counts"]["dvl_reports"], 250, "{last}");
    assert!(stderr.contains("reuses the tags of 502 images"), "{stderr}");
    let reference = tmp.path("calibrate.yaml");
    dvlcal_ok(&["calibrate", s(&dir), "--out", s(&reference)]);
    let whole: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(&reference).expect("result")).expect("yaml");
    assert_eq!(
        last["counts"]["poses"].as_u64(),
        whole["info"]["poses"].as_u64(),
        "{last}"
    );
    assert_same_result(&out, &reference);
}
