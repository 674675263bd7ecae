//! Nothing lost, nothing panicked, nothing hung: outputs that would replace a user's own file or a
//! read-only one, paths that are not UTF-8, absurd thread counts, and an sqlite3 bag with a
//! damaged page in the middle.

mod tmp_common;
use tmp_common::{TmpDir, dvlcal, s};

use std::path::{Path, PathBuf};

/// The folder searched for an sqlite3 bag to damage (the first `.db3` below it, by path).
const SQLITE_BAGS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/bags");

/// An sqlite3 bag of the repository: the first `.db3` file below [`SQLITE_BAGS`].
fn sqlite_bag() -> PathBuf {
    fn walk(d: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(d) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "db3") {
                out.push(p);
            }
        }
    }
    let mut found = Vec::new();
    walk(Path::new(SQLITE_BAGS), &mut found);
    found.sort();
    found
        .into_iter()
        .next()
        .expect("an sqlite3 bag (.db3) in sample_data/bags")
}

/// A copy of `bag` in `dir` with the page in the middle of the file (the messages' data, which
/// fill nearly all of it) overwritten with pseudo-random bytes; returns its path, the page
/// number and the page size (from the header, bytes 16-17).
fn damaged_copy(bag: &Path, dir: &Path) -> (PathBuf, u64, u64) {
    let copy = dir.join("damaged.db3");
    std::fs::copy(bag, &copy).unwrap();
    let mut bytes = std::fs::read(&copy).unwrap();
    let page_size = match u16::from_be_bytes([bytes[16], bytes[17]]) {
        1 => 65536,
        n => u64::from(n),
    };
    let pages = bytes.len() as u64 / page_size;
    let page = pages / 2; // 1-based page numbers: page k starts at (k - 1) * page_size
    let start = ((page - 1) * page_size) as usize;
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    for b in &mut bytes[start..start + page_size as usize] {
        x = x
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        *b = (x >> 56) as u8;
    }
    std::fs::write(&copy, &bytes).unwrap();
    (copy, page, page_size)
}

/// The number of rows of the messages table SQLite returns when asked for them by id one at a
/// time (ids 1..=n), and the number it returns in one pass in record order before it fails.
fn sqlite_reference(db: &Path, n: i64) -> (u64, u64) {
    let c = rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .unwrap();
    let mut one = c
        .prepare("SELECT topic_id, timestamp, data FROM messages WHERE id = ?1")
        .unwrap();
    let by_id = (1..=n)
        .filter(|id| {
            matches!(
                one.query([id]).map(|mut r| r.next().map(|r| r.is_some())),
                Ok(Ok(true))
            )
        })
        .count() as u64;
    let mut all = c
        .prepare("SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id")
        .unwrap();
    let mut rows = all.query([]).unwrap();
    let mut in_order = 0u64;
    while let Ok(Some(_)) = rows.next() {
        in_order += 1;
    }
    (by_id, in_order)
}

#[test]
fn a_damaged_sqlite3_page_costs_only_its_rows_and_the_loss_is_counted() {
    let tmp = TmpDir::new("lost-sqlite");
    let bag = sqlite_bag();
    let total: i64 = rusqlite::Connection::open(&bag)
        .unwrap()
        .query_row("SELECT count(*) FROM messages", [], |r| r.get(0))
        .unwrap();
    let (db, page, page_size) = damaged_copy(&bag, &tmp.0);
    // On stereo_sqlite3.db3 (752 messages, 4096-byte pages, page 2835 overwritten) Python's
    // sqlite3 module returned 751 rows by id and 377 in one ordered pass.
    let (by_id, in_order) = sqlite_reference(&db, total);
    println!(
        "{}: {total} messages; page {page} of {page_size} bytes damaged: SQLite reads {by_id} \
         by id, {in_order} in one ordered pass",
        bag.display()
    );
    assert!(
        in_order < by_id,
        "the damage must stop a pass in record order, or the fixture tests nothing"
    );

    let opened = dvlcal::io::bag::Bag::open(&db).expect("a damaged bag still opens");
    let mut read = 0u64;
    let summary = opened
        .messages(&|_| true, &mut |_| {
            read += 1;
            Ok(())
        })
        .expect("the damage is skipped, not an error");
    assert_eq!(summary.messages, read);
    let lost = total as u64 - read;
    println!("dvlcal reads {read}, lost {lost}: {:?}", summary.problems);
    assert!(
        read + 2 >= by_id,
        "dvlcal reads {read} messages where SQLite reads {by_id} by id"
    );
    let counted = format!("Lost: {lost} message");
    assert!(
        summary.problems.iter().any(|p| p.contains(&counted)),
        "the loss is counted ({counted:?}): {:?}",
        summary.problems
    );

    // The command line says the same.
    let out = dvlcal(&["bag-info", s(&db)]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("damage:") && l.contains(&counted)),
        "{stdout}"
    );
}

const POSES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/poses");

/// A copy of the pose dataset (TUM poses and a DVL log) in `dir`.
fn pose_dataset(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for f in ["poses.txt", "dvl.jsonl"] {
        std::fs::copy(Path::new(POSES).join(f), dir.join(f)).unwrap();
    }
    dir.to_path_buf()
}

#[cfg(unix)]
#[test]
fn paths_that_are_not_utf8_are_read_and_written_with_their_bytes() {
    use std::ffi::OsStr;
    use std::os::unix::ffi::OsStrExt;
    let tmp = TmpDir::new("lost-bytes");
    // Latin-1 names, as an old file system or a copied SD card gives them.
    let data = pose_dataset(&tmp.0.join(OsStr::from_bytes(b"data-\xe9t\xe9")));
    let out_dir = tmp.0.join(OsStr::from_bytes(b"r\xffx"));
    let result = out_dir.join(OsStr::from_bytes(b"cal\xfd.yaml"));
    let report = out_dir.join(OsStr::from_bytes(b"rep\xfc.html"));
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .arg("calibrate")
        .arg(&data)
        .arg("--out")
        .arg(&result)
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(r.status.success(), "{stderr}");
    // Every output under the name given, its bytes kept (the exports too).
    for name in [
        &b"cal\xfd.yaml"[..],
        b"cal\xfd-tf.txt",
        b"cal\xfd-urdf.xml",
        b"cal\xfd-camchain-imucam.yaml",
        b"rep\xfc.html",
    ] {
        let p = out_dir.join(OsStr::from_bytes(name));
        assert!(p.is_file(), "{} missing", p.display());
    }
    // The provenance keeps the command line exact, the odd bytes escaped for a shell.
    let yaml = std::fs::read_to_string(&result).unwrap();
    let line = yaml
        .lines()
        .find(|l| l.trim_start().starts_with("command_line:"))
        .expect("a command line in the provenance");
    assert!(line.contains(r"$'"), "{line}");
    assert!(line.contains(r"cal\xfd.yaml'"), "{line}");
    assert!(line.contains(r"data-\xe9t\xe9'"), "{line}");
}

const STEREO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/stereo");

#[test]
fn an_absurd_thread_count_is_capped_and_said() {
    // The pool the pipeline uses starts no more than the limit.
    let limit = dvlcal::parallel::thread_limit();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert!(limit <= 4 * cores && limit <= 256);
    let pool = dvlcal::parallel::worker_pool(Some(100_000)).unwrap();
    assert_eq!(pool.current_num_threads(), limit);

    // Before the cap, `detect --threads 100000` on these 4 frames ran for more than 300 s (it was
    // stopped there); with it, about a second, as without the option.
    let tmp = TmpDir::new("lost-threads");
    let images = tmp.path("images");
    for cam in ["cam0", "cam1"] {
        let dir = images.join(cam);
        std::fs::create_dir_all(&dir).unwrap();
        let mut names: Vec<_> = std::fs::read_dir(Path::new(STEREO).join(cam))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        for n in &names[..4] {
            std::fs::copy(Path::new(STEREO).join(cam).join(n), dir.join(n)).unwrap();
        }
    }
    let start = std::time::Instant::now();
    let r = dvlcal(&[
        "detect",
        "--images",
        s(&images),
        "--camchain",
        &format!("{STEREO}/camchain.yaml"),
        "--target",
        &format!("{STEREO}/target.yaml"),
        "--out",
        s(&tmp.path("poses.txt")),
        "--threads",
        "100000",
    ]);
    let elapsed = start.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&r.stderr);
    println!("detect --threads 100000: {elapsed:.2} s\n{stderr}");
    assert!(r.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "note: --threads 100000 is more threads than this machine can use ({cores} cores): \
             {limit} are used"
        )),
        "{stderr}"
    );
    assert!(elapsed < 60.0, "{elapsed} s");
}

/// Writes `text` to `path` and makes it read-only (0444).
#[cfg(unix)]
fn read_only_file(path: &Path, text: &str) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::write(path, text).unwrap();
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o444)).unwrap();
}

#[cfg(unix)]
#[test]
fn read_only_outputs_are_refused_before_the_run_and_kept() {
    // Tests may run as root, whom permission bits do not stop: the program must read the bits.
    let tmp = TmpDir::new("lost-read-only");
    let data = pose_dataset(&tmp.path("data"));
    for (option, name) in [
        ("--out", "cal.yaml"),
        ("--report", "report.html"),
        ("--out", "cal-tf.txt"),
        ("--out", "cal-urdf.xml"),
        ("--out", "cal-camchain-imucam.yaml"),
    ] {
        let dir = tmp.path(&name.replace('.', "_"));
        std::fs::create_dir_all(&dir).unwrap();
        let kept = dir.join(name);
        read_only_file(&kept, "the user's own\n");
        let r = dvlcal(&[
            "calibrate",
            s(&data),
            "--out",
            s(&dir.join("cal.yaml")),
            "--report",
            s(&dir.join("report.html")),
        ]);
        let stderr = String::from_utf8_lossy(&r.stderr);
        let stdout = String::from_utf8_lossy(&r.stdout);
        assert_eq!(r.status.code(), Some(1), "{name}: {stderr}");
        assert!(
            stderr.contains(option)
                && stderr.contains(&format!("{} is read-only (mode 0444)", kept.display())),
            "{name}: {stderr}"
        );
        // Refused before anything was read or written.
        assert!(stdout.is_empty(), "{name}: {stdout}");
        assert_eq!(
            std::fs::read_to_string(&kept).unwrap(),
            "the user's own\n",
            "{name}"
        );
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "{name}: files written"
        );
    }

    // Every writer of the library refuses to replace a read-only file, too.
    let kept = tmp.path("kept.txt");
    read_only_file(&kept, "mine\n");
    let e = dvlcal::io::write_atomic(&kept, b"theirs\n").expect_err("a read-only file is kept");
    assert!(
        e.to_string().contains("kept.txt") && e.to_string().contains("read-only"),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&kept).unwrap(), "mine\n");
}

/// A dataset folder of stereo images (every `step`-th frame of the rendered sample), its board
/// and DVL log, and no camchain: `calibrate` calibrates the cameras first.
fn images_without_camchain(dir: &Path, step: usize) -> PathBuf {
    for cam in ["cam0", "cam1"] {
        let to = dir.join(cam);
        std::fs::create_dir_all(&to).unwrap();
        let mut names: Vec<_> = std::fs::read_dir(Path::new(STEREO).join(cam))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        for n in names.iter().step_by(step.max(1)) {
            std::fs::copy(Path::new(STEREO).join(cam).join(n), to.join(n)).unwrap();
        }
    }
    for f in ["target.yaml", "dvl.jsonl"] {
        std::fs::copy(Path::new(STEREO).join(f), dir.join(f)).unwrap();
    }
    dir.to_path_buf()
}

#[test]
fn the_camchain_calibrated_by_calibrate_never_replaces_a_users_file() {
    use dvlcal::io::dataset::{DatasetOverrides, discover};
    use dvlcal::pipeline::CameraOutputs;
    let tmp = TmpDir::new("lost-camchain");
    let data = tmp.path("data");
    std::fs::create_dir_all(data.join("cam0")).unwrap();
    for f in ["target.yaml", "dvl.jsonl"] {
        std::fs::copy(Path::new(STEREO).join(f), data.join(f)).unwrap();
    }
    let files = discover(&data, &DatasetOverrides::default()).unwrap();
    assert!(files.calibrates_cameras());
    let out_dir = tmp.path("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    let out = out_dir.join("cal.yaml");
    let beside = out_dir.join("camchain.yaml");
    let named = out_dir.join("cal-camchain.yaml");
    let plan = |report: Option<&Path>| CameraOutputs::plan(&out, report, &files);

    // Nothing there: camchain.yaml beside the result.
    let p = plan(None).unwrap().unwrap();
    assert_eq!(
        (p.camchain.as_path(), p.renamed.as_deref()),
        (beside.as_path(), None)
    );
    // A camchain this result's earlier run wrote (its first line marks it) is replaced.
    let earlier = "# camchain of result cal.yaml: the cameras calibrated by dvlcal calibrate \
                   from its images\ncam0: {}\n";
    std::fs::write(&beside, earlier).unwrap();
    assert_eq!(plan(None).unwrap().unwrap().camchain, beside);
    // One of another result's, or of `calibrate-cameras`, or the user's own, is kept.
    for other in [
        earlier.replace("cal.yaml", "other.yaml"),
        "# dvlcal calibrate-cameras 0.1.0: pinhole-radtan model\ncam0: {}\n".into(),
        "cam0: {}\n".into(),
    ] {
        std::fs::write(&beside, &other).unwrap();
        let p = plan(None).unwrap().unwrap();
        assert_eq!(p.camchain, named, "{other}");
        let why = p.renamed.expect("the reason for the other name");
        assert!(
            why.contains(&beside.display().to_string())
                && why.contains("kept")
                && why.contains(&named.display().to_string()),
            "{why}"
        );
    }
    // Both names taken by files not written for this result: refused, naming both.
    std::fs::write(&named, "cam0: {}\n").unwrap();
    let e = plan(None).unwrap_err().to_string();
    assert!(
        e.contains("--out")
            && e.contains(&beside.display().to_string())
            && e.contains(&named.display().to_string()),
        "{e}"
    );
    std::fs::remove_file(&named).unwrap();
    // This result's own camchain made read-only is not replaced either.
    #[cfg(unix)]
    {
        std::fs::remove_file(&beside).unwrap();
        read_only_file(&beside, earlier);
        assert_eq!(plan(None).unwrap().unwrap().camchain, named);
        // A read-only camera report is refused before the run.
        let report = out_dir.join("r.html");
        read_only_file(&out_dir.join("r-cameras.html"), "mine");
        let e = plan(Some(&report)).unwrap_err().to_string();
        assert!(e.contains("--report") && e.contains("read-only"), "{e}");
    }

    // The whole program: the user's camchain.yaml beside the result stays as it was, the
    // cameras go to the other name, and the output says which.
    let data = images_without_camchain(&tmp.path("images"), 6);
    let run_dir = tmp.path("run");
    std::fs::create_dir_all(&run_dir).unwrap();
    std::fs::write(run_dir.join("camchain.yaml"), "my own camchain\n").unwrap();
    let result = run_dir.join("calibration.yaml");
    let r = dvlcal(&["calibrate", s(&data), "--out", s(&result), "--no-progress"]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    let written = run_dir.join("calibration-camchain.yaml");
    assert_eq!(
        std::fs::read_to_string(run_dir.join("camchain.yaml")).unwrap(),
        "my own camchain\n"
    );
    assert!(
        stdout.contains(&format!(
            "wrote {} (cameras calibrated from the same images)",
            written.display()
        )) && stdout.contains("is not a camchain written for this result: it is kept"),
        "{stdout}\n{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let chain = dvlcal::io::camchain::read_camchain(&written).expect("the camchain written loads");
    assert_eq!(chain.cams.len(), 2);
}
