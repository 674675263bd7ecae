//! `dvlcal watch --json` run while a test writes its data: the updates as they arrive, each
//! with the time it arrived, and the run's end.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::thread::JoinHandle;
use std::time::Instant;

use dvlcal::io::calib_yaml::read_calib_yaml;
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

/// Asserts that the result file `watched` holds `calibrate`'s result `reference` to the bit:
/// the extrinsics, the clock offset, the scale and the std.
pub fn assert_same_result(watched: &Path, reference: &Path) {
    let (w, c) = (
        read_calib_yaml(watched).expect("watch's result"),
        read_calib_yaml(reference).expect("calibrate's result"),
    );
    assert_eq!(w.t_cam_dvl, c.t_cam_dvl);
    assert_eq!(w.time_offset_s, c.time_offset_s);
    assert_eq!(w.velocity_scale, c.velocity_scale);
    assert_eq!(format!("{:?}", w.std), format!("{:?}", c.std));
}
