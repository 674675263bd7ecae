//! A live DVL recorded into the folder `dvlcal watch` follows (`--dvl-tcp HOST:PORT`): the
//! A50's TCP JSON stream is appended to `DIR/dvl.jsonl` on a thread of its own, exactly as
//! `record-dvl` writes its log ([`record_tcp`]: each line with `host_time_us` added, flushed
//! line by line, reconnecting when the connection drops), so that the watcher's updates and the
//! final calibration find it as the folder's DVL log.
//!
//! The name is chosen for both readers: the dataset finder recognises a DVL log by its content
//! whatever its name, and the watcher stages `.jsonl` files up to their last complete line.
//! While the DVL streams the folder keeps changing, so a watch does not end on `--until-idle`
//! then: Ctrl-C or `--stop-when-done` ends it (or the stream stopping for that long).

use std::fmt;
use std::fs::OpenOptions;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;

use crate::error::{Error, Result};
use crate::io::dataset::dvl_logs_in;
use crate::io::dvl::{RecordOptions, RecordStats, check_address, record_tcp};

/// The log's name in the watched folder.
pub const LIVE_DVL_LOG: &str = "dvl.jsonl";

/// The option that names the DVL's address, in errors.
const OPTION: &str = "--dvl-tcp";

/// A DVL's stream being recorded into a dataset folder; [`LiveDvl::stop`] ends it (dropping it
/// ends it too, without the summary).
pub struct LiveDvl {
    addr: String,
    log: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<RecordStats>>>,
}

/// What a live recording wrote: its counts, and where from and to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LiveDvlRecording {
    /// The DVL's address, `host:port`.
    pub addr: String,
    /// The log written.
    pub log: PathBuf,
    /// Lines, bytes, connections made and dropped, partial lines lost.
    pub stats: RecordStats,
}

impl fmt::Display for LiveDvlRecording {
    /// `record-dvl`'s words: the counts, or that nothing was recorded and where the DVL was
    /// looked for.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.stats.lines == 0 {
            f.write_str(&self.stats.nothing_recorded(&self.addr))
        } else {
            f.write_str(&self.stats.summary(&self.log))
        }
    }
}

impl LiveDvl {
    /// Starts recording the DVL stream at `addr` (`host:port`; the A50 serves it on port
    /// 16171) into [`LIVE_DVL_LOG`] in the dataset folder `dir`, appending when that log is
    /// already there (a watch started again). `note` receives one-line progress messages
    /// (recording, connected, dropped, ...), each only once while it repeats (a DVL that is
    /// not up yet is said once, not at every retry), from the recording's thread.
    ///
    /// Errors, before anything is written: `dir` is not a folder; `addr` is not a `host:port`
    /// address that resolves; `dir` already holds a DVL log under another name (the dataset
    /// would then have two); `dir/dvl.jsonl` holds something that is not a DVL log; the log
    /// cannot be opened for writing.
    pub fn start(
        addr: &str,
        dir: &Path,
        opts: RecordOptions,
        mut note: impl FnMut(&str) + Send + 'static,
    ) -> Result<LiveDvl> {
        if !dir.is_dir() {
            return Err(Error::dataset(
                dir,
                "not a folder: the live DVL is recorded into the dataset folder",
            ));
        }
        check_address(addr, OPTION)?;
        let log = dir.join(LIVE_DVL_LOG);
        let logs = dvl_logs_in(dir)?;
        let others: Vec<String> = logs
            .iter()
            .filter(|p| **p != log)
            .map(|p| p.display().to_string())
            .collect();
        if !others.is_empty() {
            return Err(Error::dataset(
                dir,
                format!(
                    "already holds a DVL log ({}), and {OPTION} records the live DVL into \
                     {LIVE_DVL_LOG} beside it: a dataset has one DVL log; move it away, or \
                     calibrate with it instead of {OPTION}",
                    others.join(", ")
                ),
            ));
        }
        let held = log.metadata().map_or(0, |m| m.len());
        if held > 0 && !logs.contains(&log) {
            return Err(Error::dataset(
                &log,
                format!(
                    "is not a DVL log, and {OPTION} would append the live DVL's stream to it; \
                     move it away"
                ),
            ));
        }
        // Opened once now so that a folder that cannot be written is an error before the
        // watch starts rather than a note from the thread.
        OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .map_err(|e| Error::io(&log, e))?;
        note(&if held > 0 {
            format!(
                "recording the DVL stream from {addr} into {} (appended to the {held} bytes \
                 already there)",
                log.display()
            )
        } else {
            format!(
                "recording the DVL stream from {addr} into {}",
                log.display()
            )
        });
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (addr, log, stop) = (addr.to_owned(), log.clone(), Arc::clone(&stop));
            std::thread::Builder::new()
                .name("dvl-tcp".into())
                .spawn(move || {
                    let mut last = String::new();
                    let mut once = |m: &str| {
                        if m != last {
                            note(m);
                            last = m.to_owned();
                        }
                    };
                    let run = record_tcp(&addr, &log, &opts, &stop, &mut once);
                    if let Err(e) = &run {
                        note(&format!("the DVL recording stopped: {e}"));
                    }
                    run
                })
                .map_err(|e| Error::Input(format!("cannot start the DVL recording: {e}")))?
        };
        Ok(LiveDvl {
            addr: addr.to_owned(),
            log,
            stop,
            thread: Some(thread),
        })
    }

    /// The log being written.
    pub fn log(&self) -> &Path {
        &self.log
    }

    /// Whether the recording still runs (it ends on its own only when it fails, or after
    /// [`RecordOptions::duration`]).
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops the recording (within a read timeout, or a connection attempt's timeout) and
    /// says what it wrote. Errors: the recording failed (the log could not be written).
    pub fn stop(mut self) -> Result<LiveDvlRecording> {
        self.stop.store(true, Ordering::SeqCst);
        let stats = match self.thread.take() {
            Some(t) => t
                .join()
                .map_err(|_| Error::Input("the DVL recording's thread panicked".into()))??,
            None => RecordStats::default(),
        };
        Ok(LiveDvlRecording {
            addr: std::mem::take(&mut self.addr),
            log: std::mem::take(&mut self.log),
            stats,
        })
    }
}

impl Drop for LiveDvl {
    fn drop(&mut self) {
        // A watch that ends in an error still closes the log cleanly.
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write as _;
    use std::net::TcpListener;
    use std::sync::Mutex;
    use std::time::{Duration, Instant};

    const REPORT: &str = r#"{"time":100,"vx":0.35,"vy":-0.09,"vz":0.03,"fom":0.01,"covariance":[[0.0001,0,0],[0,0.0001,0],[0,0,0.0001]],"altitude":1.5,"velocity_valid":true,"status":0,"format":"json_v3.1","type":"velocity","time_of_validity":1700000000000190,"time_of_transmission":1700000000040190}"#;

    fn folder(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("dvlcal-live-dvl-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("folder");
        d
    }

    /// A note sink the test can read.
    fn notes() -> (Arc<Mutex<Vec<String>>>, impl FnMut(&str) + Send + 'static) {
        let all = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&all);
        (all, move |m: &str| {
            if let Ok(mut v) = sink.lock() {
                v.push(m.to_owned());
            }
        })
    }

    fn wait_for(what: impl Fn() -> bool) {
        let until = Instant::now() + Duration::from_secs(10);
        while !what() && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    #[test]
    fn records_the_stream_into_the_folder_as_record_dvl_does() {
        let dir = folder("rec");
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = listener.local_addr().expect("addr").to_string();
        let server = std::thread::spawn(move || {
            let (mut c, _) = listener.accept().expect("accept");
            for _ in 0..3 {
                c.write_all(format!("{REPORT}\r\n").as_bytes())
                    .expect("send");
            }
            c.flush().expect("flush");
            // The connection stays open, as the A50's does, until the recording stops.
            std::thread::sleep(Duration::from_millis(800));
        });
        let (said, note) = notes();
        let live = LiveDvl::start(&addr, &dir, RecordOptions::default(), note).expect("start");
        assert_eq!(live.log(), dir.join("dvl.jsonl"));
        let log = live.log().to_owned();
        wait_for(|| std::fs::read_to_string(&log).is_ok_and(|t| t.lines().count() == 3));
        assert!(live.is_running());
        let rec = live.stop().expect("stop");
        server.join().expect("server");
        assert_eq!((rec.stats.lines, rec.stats.connections), (3, 1));
        let text = std::fs::read_to_string(&log).expect("log");
        assert!(text.lines().all(|l| l.contains("\"host_time_us\":")));
        assert!(rec.to_string().starts_with("3 lines"), "{rec}");
        // The finder takes it for the folder's DVL log.
        assert_eq!(dvl_logs_in(&dir).expect("logs"), vec![log.clone()]);
        let said = said.lock().expect("notes").clone();
        assert!(
            said[0].starts_with("recording the DVL stream from"),
            "{said:?}"
        );
        // Started again on the same folder: appended to, said so.
        let (said, note) = notes();
        let again = LiveDvl::start(&addr, &dir, RecordOptions::default(), note).expect("again");
        assert_eq!(again.stop().expect("stop").stats.lines, 0);
        assert!(said.lock().expect("notes")[0].contains("appended to the"));
        assert_eq!(std::fs::read_to_string(&log).expect("log"), text);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_dvl_not_up_yet_is_said_once_and_nothing_recorded_is_said() {
        let dir = folder("none");
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let (said, note) = notes();
        let opts = RecordOptions {
            reconnect_delay: Duration::from_millis(50),
            ..RecordOptions::default()
        };
        let addr = format!("127.0.0.1:{port}");
        let live = LiveDvl::start(&addr, &dir, opts, note).expect("start");
        std::thread::sleep(Duration::from_millis(400));
        let rec = live.stop().expect("stop");
        assert_eq!((rec.stats.lines, rec.stats.connections), (0, 0));
        let said = said.lock().expect("notes").clone();
        let retries = said.iter().filter(|m| m.contains("cannot connect")).count();
        assert_eq!(retries, 1, "{said:?}");
        let words = rec.to_string();
        assert!(words.contains("nothing was recorded from") && words.contains(&addr));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn refuses_before_writing_anything() {
        let dir = folder("refused");
        let start = |addr: &str| LiveDvl::start(addr, &dir, RecordOptions::default(), |_| {});
        for addr in ["127.0.0.1", "127.0.0.1:notaport"] {
            let e = start(addr).err().expect("refused").to_string();
            assert!(e.contains("--dvl-tcp") && e.contains(addr), "{e}");
        }
        assert!(!dir.join("dvl.jsonl").exists());
        // Another DVL log in the folder: named in the refusal.
        std::fs::write(dir.join("a50.log"), format!("{REPORT}\n")).expect("write");
        let e = start("127.0.0.1:16171").err().expect("refused").to_string();
        assert!(
            e.contains("already holds a DVL log") && e.contains("a50.log"),
            "{e}"
        );
        assert!(!dir.join("dvl.jsonl").exists());
        // dvl.jsonl that is not a DVL log is not appended to.
        std::fs::remove_file(dir.join("a50.log")).expect("remove");
        std::fs::write(dir.join("dvl.jsonl"), "notes of the dive\n").expect("write");
        let e = start("127.0.0.1:16171").err().expect("refused").to_string();
        assert!(e.contains("is not a DVL log"), "{e}");
        let e = LiveDvl::start(
            "127.0.0.1:16171",
            &dir.join("missing"),
            RecordOptions::default(),
            |_| {},
        );
        assert!(e.is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
