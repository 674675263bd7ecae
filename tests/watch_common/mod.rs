//! `dvlcal watch --json` run while a test writes its data: the updates as they arrive, each
//! with the time it arrived, and the run's end.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Output, Stdio};
use std::thread::JoinHandle;
use std::time::Instant;

use serde_json::Value;

/// Updates of a running watch, each with the time it arrived.
pub type Updates = Vec<(Instant, Value)>;

/// A `dvlcal watch` started with `--json`, its updates read as they come.
pub struct Watching {
    child: Child,
    reader: JoinHandle<Updates>,
}

impl Watching {
    /// Starts `dvlcal watch ARGS --json`.
    pub fn start(args: &[&str]) -> Watching {
        let mut child = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
            .arg("watch")
            .args(args)
            .arg("--json")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run dvlcal watch");
        let stdout = child.stdout.take().expect("stdout");
        let reader = std::thread::spawn(move || {
            BufReader::new(stdout)
                .lines()
                .map_while(|l| l.ok())
                .map(|l| {
                    let v: Value = serde_json::from_str(&l)
                        .unwrap_or_else(|e| panic!("not one JSON object per line: {l}: {e}"));
                    (Instant::now(), v)
                })
                .collect()
        });
        Watching { child, reader }
    }

    /// Waits for the watch to end: its updates and its output (the standard error).
    pub fn finish(self) -> (Updates, Output) {
        let out = self.child.wait_with_output().expect("the watch ends");
        (self.reader.join().expect("reader"), out)
    }
}
