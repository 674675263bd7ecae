//! Throughput of DVL log parsing on a large generated log (JSON lines and serial `wrz`), and on
//! the real ROS1 bag. Run with `cargo bench --bench dvl_parse` (optionally `-- MB` for the size
//! of the generated logs, default 100).

use std::path::Path;
use std::time::Instant;

use dvlcal::io::dvl::a50::wrz_sentence;
use dvlcal::io::dvl::a50::{parse_velocity_report, velocity_report_line};
use dvlcal::io::dvl::{DvlReadOptions, read_dvl_log};

/// The real logs, in the shared folder beside the repository.
const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/a50-ros-driver");

fn main() {
    let mb: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(100);
    let mut reports = Vec::new();
    for name in [
        "dvl",
        "dvl_circle",
        "dvl_fast_rectangle",
        "dvl_slow_rectangle",
    ] {
        let Ok(text) = std::fs::read_to_string(format!("{DATA}/{name}.jsonl")) else {
            eprintln!("real logs not found in {DATA}");
            return;
        };
        reports.extend(text.lines().filter_map(|l| parse_velocity_report(l).ok()));
    }
    let dir = std::env::temp_dir().join(format!("dvlcal-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    // Real reports repeated with shifted times (no duplicates) until the log is `mb` MB.
    let (mut json, mut serial) = (String::new(), String::new());
    let mut k = 0usize;
    let mut n = 0usize;
    while json.len() < mb << 20 {
        let mut r = reports[k % reports.len()].clone();
        let shift = (k / reports.len()) as i64 * 1_000_000_000;
        r.time_of_validity += shift;
        r.time_of_transmission += shift;
        json.push_str(&velocity_report_line(&r));
        json.push_str("\r\n");
        serial.push_str(&wrz_sentence(&r));
        k += 1;
        n += 1;
    }
    let jp = dir.join("big.jsonl");
    let sp = dir.join("big.txt");
    std::fs::write(&jp, &json).expect("write");
    std::fs::write(&sp, &serial).expect("write");
    println!("{n} velocity reports per generated log");
    measure("json lines", &jp, n);
    measure("serial wrz", &sp, n);
    measure(
        "rosbag /dvl/json_data",
        Path::new(&format!("{DATA}/dvl.bag")),
        1423,
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn measure(what: &str, path: &Path, n: usize) {
    let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0) as f64;
    let reps = if bytes > 1e7 { 3 } else { 20 };
    let mut best = f64::INFINITY;
    for _ in 0..reps {
        let t0 = Instant::now();
        let log = read_dvl_log(path, &DvlReadOptions::default()).expect("read");
        let dt = t0.elapsed().as_secs_f64();
        assert_eq!(log.stats.velocity_reports, n);
        best = best.min(dt);
    }
    println!(
        "{what:<22} {:8.1} MB in {:7.3} s: {:7.1} MB/s, {:9.0} reports/s (best of {reps})",
        bytes / 1e6,
        best,
        bytes / 1e6 / best,
        n as f64 / best
    );
}
