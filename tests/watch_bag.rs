//! `dvlcal watch BAG` on a bag written as a recorder writes it: the bytes of a finished bag
//! (made by the independent `rosbags` writer, `sample_data/bags/`) appended to the watched file
//! in pieces with pauses, so that updates read it cut inside a chunk, as a growing bag is. A
//! bare MCAP file grows under its name; a ROS 1 bag grows as `NAME.bag.active` and is renamed
//! `NAME.bag` at the end, as `rosbag record` does. The updates must come while the bag grows,
//! none failing to read it, their counts growing to the whole bag's; and the end must be the
//! result `calibrate` gives on the finished bag.

mod tmp_common;
mod watch_common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde_json::Value;
use tmp_common::{TmpDir, dvlcal_ok, s};
use watch_common::{Watching, assert_same_result};

/// Pieces each bag is written in, and the pause after each.
const PIECES: usize = 10;
const PAUSE: Duration = Duration::from_millis(400);

fn sample(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("sample_data/bags")
        .join(rel)
}

/// Appends `src`'s bytes to `dst` in [`PIECES`] pieces (their ends fall inside chunks), with a
/// flush and a [`PAUSE`] after each.
fn grow(src: &Path, dst: &Path) {
    let bytes = std::fs::read(src).expect("bag");
    let mut f = std::fs::File::create(dst).expect("create");
    let step = bytes.len().div_ceil(PIECES);
    for piece in bytes.chunks(step) {
        f.write_all(piece).expect("write");
        f.flush().expect("flush");
        std::thread::sleep(PAUSE);
    }
}

/// The updates of `dvlcal watch BAG --json ARGS` while `feeder` writes the bag, each with the
/// time it arrived; when the feed ended; and what the watch said on its standard error.
fn watch_while(
    bag: &Path,
    args: &[&str],
    feeder: impl FnOnce(),
) -> (Vec<(Instant, Value)>, Instant, String) {
    let mut all = vec![s(bag), "--interval", "0.3", "--until-idle", "2"];
    all.extend_from_slice(args);
    let watching = Watching::start(&all);
    feeder();
    let fed = Instant::now();
    let (updates, out) = watching.finish();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    (updates, fed, stderr)
}

fn count(u: &Value, key: &str) -> u64 {
    u["counts"][key].as_u64().expect("count")
}

/// What every run of the watch must show: at least two updates while the bag grew, each read
/// without an error (a cut last chunk is the normal state of a growing bag), the camera's and
/// the DVL's counts never falling and growing from the first update to the whole bag's at the
/// last, whose calibration succeeded.
fn check_updates(updates: &[(Instant, Value)], fed: Instant, poses: u64, reports: u64) {
    let during = updates.iter().filter(|(t, _)| *t < fed).count();
    assert!(during >= 2, "{during} updates while the bag grew");
    for (_, u) in updates {
        let status = u["status"].as_str().expect("status");
        assert!(["ok", "not yet", "failed"].contains(&status), "{u}");
        let reason = u["reason"].as_str().unwrap_or_default();
        for word in ["damaged", "not a bag", "No such file", "could not be read"] {
            assert!(!reason.contains(word), "{u}");
        }
    }
    for key in ["poses", "dvl_reports"] {
        let n: Vec<u64> = updates.iter().map(|(_, u)| count(u, key)).collect();
        assert!(n.windows(2).all(|w| w[0] <= w[1]), "{key}: {n:?}");
        assert!(
            n.iter().any(|&k| k > 0 && k < n[n.len() - 1]),
            "{key}: {n:?}"
        );
    }
    let last = &updates.last().expect("updates").1;
    assert_eq!(last["status"], "ok", "{last}");
    assert_eq!(count(last, "poses"), poses, "{last}");
    assert_eq!(count(last, "dvl_reports"), reports, "{last}");
}

/// The watch's result is `calibrate`'s on the finished bag, to the bit.
fn check_result_is_calibrates(bag: &Path, watched: &Path, args: &[&str], tmp: &TmpDir) {
    let reference = tmp.path("calibrate.yaml");
    let mut a = vec!["calibrate", s(bag), "--out", s(&reference), "--no-progress"];
    a.extend_from_slice(args);
    dvlcal_ok(&a);
    assert_same_result(watched, &reference);
}

/// A bare MCAP file of camera poses and DVL reports (lz4 chunks), growing under its name with
/// no summary or footer until its last piece: the updates follow it, and the watch ends once
/// it stops growing with `calibrate`'s result.
#[test]
fn a_growing_mcap_file_is_followed_and_ends_as_calibrate() {
    let tmp = TmpDir::new("watch-bag-mcap");
    let (bag, out) = (tmp.path("run.mcap"), tmp.path("watch.yaml"));
    let src = sample("poses_mcap.mcap");
    let (updates, fed, _) = watch_while(&bag, &["--out", s(&out)], || grow(&src, &bag));
    check_updates(&updates, fed, 601, 600);
    check_result_is_calibrates(&bag, &out, &[], &tmp);
}

/// A ROS 1 bag of stereo JPEG images and the A50's JSON, written as `run.bag.active` (read with
/// its index not yet there) and renamed `run.bag` at the end: the rename ends the watch, the
/// final calibration reads `run.bag` and says so, and it reuses the images' detections made by
/// the updates.
#[test]
fn a_ros1_bag_recorded_as_active_then_renamed_ends_as_calibrate_on_the_bag() {
    let tmp = TmpDir::new("watch-bag-ros1");
    let (active, out) = (tmp.path("run.bag.active"), tmp.path("watch.yaml"));
    let bag = tmp.path("run.bag");
    let src = sample("stereo_ros1.bag");
    let (chain, target) = (
        sample("recording/camchain.yaml"),
        sample("recording/target.yaml"),
    );
    let cc = ["--camchain", s(&chain), "--target", s(&target)];
    let mut args = vec!["--out", s(&out)];
    args.extend_from_slice(&cc);
    let (updates, fed, stderr) = watch_while(&active, &args, || {
        grow(&src, &active);
        std::fs::rename(&active, &bag).expect("rename");
    });
    let finished = dvlcal_ok(&["bag-info", s(&bag)]);
    assert!(finished.contains("131"), "{finished}");
    check_updates(&updates, fed, 131, 130);
    assert!(
        stderr.contains("run.bag.active was renamed")
            && stderr.contains(&format!("the final calibration reads {}", bag.display())),
        "{stderr}"
    );
    assert!(stderr.contains("reuses the tags of 262 images"), "{stderr}");
    check_result_is_calibrates(&bag, &out, &cc, &tmp);
}
