//! `dvlcal watch DIR --dvl-tcp HOST:PORT`: a fake A50 on a local port streams the DVL reports
//! of a simulated recording at eight times real speed while the camera's pose file is written
//! into the folder at the same pace (each line in two halves with a flush between). The watch
//! records the stream into DIR/dvl.jsonl as `record-dvl` would, its updates see the DVL data
//! while they arrive, and it ends with the result `calibrate` gives on the finished folder. An
//! address that does not resolve, `--dvl` beside it and a folder that already holds a DVL log
//! are refused before anything is written.

mod tmp_common;
mod watch_common;

use std::io::{ErrorKind, Write};
use std::net::TcpListener;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde_json::Value;
use tmp_common::{TmpDir, dvlcal, dvlcal_ok, s};
use watch_common::{Watching, assert_same_result};

const SPEED: f64 = 8.0;

/// The lines of a pose file (TUM, seconds) or a DVL log (`time_of_validity`, microseconds),
/// each with its time (a header line: minus infinity, so that it goes first).
fn timed_lines(path: &Path) -> Vec<(f64, String)> {
    let text = std::fs::read_to_string(path).expect("recording");
    text.lines()
        .map(|line| {
            let t = match serde_json::from_str::<Value>(line) {
                Ok(v) => v["time_of_validity"].as_f64().map(|t| t * 1e-6),
                Err(_) => line.split_whitespace().next().and_then(|t| t.parse().ok()),
            };
            (t.unwrap_or(f64::NEG_INFINITY), line.to_owned())
        })
        .collect()
}

/// Waits until the time of `t` at `SPEED` times real speed, the recording's `t0` at `start`.
fn pace(start: Instant, t0: f64, t: f64) {
    let due = Duration::from_secs_f64((t.max(t0) - t0) / SPEED);
    if let Some(wait) = due.checked_sub(start.elapsed()) {
        std::thread::sleep(wait);
    }
}

/// Writes `line` in two halves with a flush between, as a buffered writer may.
fn in_halves(w: &mut impl Write, line: &str) {
    let (a, b) = line.split_at(line.len() / 2);
    w.write_all(a.as_bytes()).expect("write");
    w.flush().expect("flush");
    w.write_all(b.as_bytes()).expect("write");
    w.flush().expect("flush");
}

/// A fake A50 on a local port: once the watch connects, it sends the start time on `started`
/// and streams `lines` (CR LF ended, as the A50 ends them) paced by their times; then it keeps
/// the connection open, sending nothing, until `hang_up` is set.
fn fake_a50(
    lines: Vec<(f64, String)>,
    t0: f64,
    started: mpsc::Sender<Instant>,
    hang_up: Arc<AtomicBool>,
) -> (String, std::thread::JoinHandle<()>) {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("address").to_string();
    listener.set_nonblocking(true).expect("non-blocking");
    let server = std::thread::spawn(move || {
        let deadline = Instant::now() + Duration::from_secs(20);
        let mut c = loop {
            match listener.accept() {
                Ok((c, _)) => break c,
                Err(e) if e.kind() == ErrorKind::WouldBlock && Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(10));
                }
                // The watch never connected: the test's wait for `started` says so.
                Err(_) => return,
            }
        };
        c.set_nonblocking(false).expect("blocking");
        c.set_nodelay(true).expect("no delay");
        let start = Instant::now();
        started.send(start).expect("the test waits");
        for (t, line) in &lines {
            pace(start, t0, *t);
            in_halves(&mut c, &format!("{line}\r\n"));
        }
        while !hang_up.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(20));
        }
    });
    (addr, server)
}

/// The live DVL is recorded into the folder while the poses are written, the updates see its
/// reports as they arrive, the log holds every report served with its host time, the recording
/// is stopped and reported before the final calibration, and the result is `calibrate`'s on the
/// finished folder.
#[test]
fn watch_records_a_live_dvl_beside_a_pose_file_and_ends_as_calibrate() {
    let tmp = TmpDir::new("watch-tcp");
    let src = tmp.path("recording");
    dvlcal_ok(&[
        "simulate",
        "--duration",
        "60",
        "--seed",
        "3",
        "--out",
        s(&src),
    ]);
    let served = timed_lines(&src.join("dvl.jsonl"));
    let poses = timed_lines(&src.join("poses.txt"));
    let t0 = served
        .iter()
        .chain(&poses)
        .map(|l| l.0)
        .filter(|t| t.is_finite())
        .fold(f64::INFINITY, f64::min);
    let (started, start_rx) = mpsc::channel();
    let hang_up = Arc::new(AtomicBool::new(false));
    let (addr, server) = fake_a50(served.clone(), t0, started, Arc::clone(&hang_up));

    let (dir, out) = (tmp.path("live"), tmp.path("watch.yaml"));
    std::fs::create_dir_all(&dir).expect("folder");
    let t_run = Instant::now();
    let watching = Watching::start(&[
        s(&dir),
        "--dvl-tcp",
        &addr,
        "--interval",
        "0.5",
        "--until-idle",
        "2",
        "--out",
        s(&out),
    ]);
    let start = start_rx
        .recv_timeout(Duration::from_secs(20))
        .expect("the watch connects to the DVL");
    let mut file = std::fs::File::create(dir.join("poses.txt")).expect("pose file");
    for (t, line) in &poses {
        pace(start, t0, *t);
        in_halves(&mut file, &format!("{line}\n"));
    }
    let fed = Instant::now();
    let (updates, run) = watching.finish();
    let took = t_run.elapsed();
    hang_up.store(true, Ordering::SeqCst);
    server.join().expect("fake A50");
    let err = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(run.status.success(), "{err}");

    // The updates came while the data came, and saw the DVL's reports grow.
    let during: Vec<&Value> = updates
        .iter()
        .filter(|(t, _)| *t < fed)
        .map(|(_, u)| u)
        .collect();
    assert!(
        during.len() >= 3,
        "{} updates while the data came",
        during.len()
    );
    let reports: Vec<u64> = updates
        .iter()
        .map(|(_, u)| u["counts"]["dvl_reports"].as_u64().expect("a count"))
        .collect();
    assert!(reports.windows(2).all(|w| w[0] <= w[1]), "{reports:?}");
    let seen_live = during
        .iter()
        .map(|u| u["counts"]["dvl_reports"].as_u64().unwrap_or(0))
        .filter(|&n| n > 0 && n < served.len() as u64)
        .count();
    assert!(seen_live >= 2, "{reports:?}");
    assert!(
        during.iter().any(|u| u["status"] == "ok"),
        "no update calibrated while the data came: {during:?}"
    );
    let last = &updates.last().expect("updates").1;
    assert_eq!(last["counts"]["poses"], 601, "{last}");
    assert_eq!(last["counts"]["dvl_reports"], served.len(), "{last}");

    // The log: every report served, in order, with the host's receive time added.
    let log = std::fs::read_to_string(dir.join("dvl.jsonl")).expect("the recorded log");
    let logged: Vec<&str> = log.lines().collect();
    assert_eq!(logged.len(), served.len());
    for (l, (_, sent)) in logged.iter().zip(&served) {
        let (head, host) = l.rsplit_once(",\"host_time_us\":").expect("host_time_us");
        assert_eq!(format!("{head}}}"), *sent);
        assert!(host.trim_end_matches('}').parse::<i64>().is_ok(), "{l}");
    }
    // Recorded from the start, stopped and reported as record-dvl reports it, before the final
    // calibration printed its result.
    assert!(err.contains(&format!("watch: recording the DVL stream from {addr}")));
    let stats = format!(
        "watch: {} lines ({} bytes) written to {}; 1 connections, 0 dropped, 0 partial lines lost",
        served.len(),
        log.len(),
        dir.join("dvl.jsonl").display()
    );
    let stopped = err.find(&stats).unwrap_or_else(|| panic!("{stats}\n{err}"));
    let wrote = err
        .find(&format!("wrote {}", s(&out)))
        .unwrap_or_else(|| panic!("{err}"));
    assert!(stopped < wrote, "{err}");

    // The end: the same result as calibrate on the finished folder.
    let reference = tmp.path("calibrate.yaml");
    dvlcal_ok(&["calibrate", s(&dir), "--out", s(&reference)]);
    assert_same_result(&out, &reference);
    eprintln!(
        "watch --dvl-tcp: {} updates ({} while the data came), {:.1} s in all",
        updates.len(),
        during.len(),
        took.as_secs_f64()
    );
}

/// An address without a port or one that does not parse, `--dvl` beside `--dvl-tcp`, and a
/// folder that already holds a DVL log are refused at once, naming the problem, with no
/// result and no recorded log written.
#[test]
fn a_live_dvl_that_cannot_be_recorded_is_refused() {
    let tmp = TmpDir::new("watch-tcp-refused");
    let src = tmp.path("recording");
    dvlcal_ok(&[
        "simulate",
        "--duration",
        "10",
        "--seed",
        "3",
        "--out",
        s(&src),
    ]);
    let dir = tmp.path("live");
    std::fs::create_dir_all(&dir).expect("folder");
    std::fs::copy(src.join("poses.txt"), dir.join("poses.txt")).expect("poses");
    let out = tmp.path("r.yaml");
    let watch = |extra: &[&str]| {
        let t = Instant::now();
        let mut args = vec!["watch", s(&dir), "--until-idle", "1", "--out", s(&out)];
        args.extend_from_slice(extra);
        let run = dvlcal(&args);
        assert!(!run.status.success(), "{args:?} was accepted");
        assert!(
            t.elapsed() < Duration::from_secs(5),
            "{args:?} was not refused at once"
        );
        assert!(!out.exists() && !dir.join("dvl.jsonl").exists(), "{args:?}");
        (
            run.status.code(),
            String::from_utf8_lossy(&run.stderr).into_owned(),
        )
    };
    for addr in ["192.168.194.95", "192.168.194.95:notaport"] {
        let (_, err) = watch(&["--dvl-tcp", addr]);
        assert!(
            err.contains(&format!("--dvl-tcp '{addr}' is not a HOST:PORT address")),
            "{err}"
        );
    }
    let log = s(&src.join("dvl.jsonl")).to_owned();
    let (code, err) = watch(&["--dvl-tcp", "127.0.0.1:16171", "--dvl", &log]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--dvl-tcp") && err.contains("cannot be used with '--dvl"),
        "{err}"
    );
    std::fs::copy(src.join("dvl.jsonl"), dir.join("a50.log")).expect("a DVL log");
    let (_, err) = watch(&["--dvl-tcp", "127.0.0.1:16171"]);
    assert!(
        err.contains("already holds a DVL log") && err.contains("a50.log"),
        "{err}"
    );
}
