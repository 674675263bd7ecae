//! `record-dvl` against a local server that replays a real log and drops the connection in the
//! middle of a line.

mod dvl_common;

use std::io::Write;
use std::net::TcpListener;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use dvl_common::*;
use dvlcal::io::dvl::{
    DvlReadOptions, DvlTimeSource, RecordOptions, add_host_time, read_dvl_log, record_tcp,
};

#[test]
fn records_a_replayed_stream_across_a_dropped_connection() {
    let lines: Vec<String> = std::fs::read_to_string(real("dvl_circle", "jsonl"))
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let cut = 150; // lines[cut] is sent only half before the drop
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let lines = lines.clone();
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            // First connection: lines before the cut, then half a line, then a drop.
            let (mut c, _) = listener.accept().unwrap();
            for l in &lines[..cut] {
                c.write_all(format!("{l}\r\n").as_bytes()).unwrap();
            }
            c.write_all(&lines[cut].as_bytes()[..100]).unwrap();
            c.flush().unwrap();
            std::thread::sleep(Duration::from_millis(50));
            drop(c);
            // Second connection: the rest, in small pieces.
            let (mut c, _) = listener.accept().unwrap();
            for l in &lines[cut + 1..] {
                let b = format!("{l}\r\n");
                let (x, y) = b.as_bytes().split_at(b.len() / 3);
                c.write_all(x).unwrap();
                c.flush().unwrap();
                c.write_all(y).unwrap();
            }
            c.flush().unwrap();
            std::thread::sleep(Duration::from_millis(300));
            stop.store(true, Ordering::SeqCst);
            // Keep the connection open until the recorder has seen the stop.
            std::thread::sleep(Duration::from_millis(500));
            drop(c);
        })
    };
    let dir = temp_dir("record");
    let out = dir.join("rec.jsonl");
    let _ = std::fs::remove_file(&out);
    let opts = RecordOptions {
        duration: Some(Duration::from_secs(20)),
        reconnect_delay: Duration::from_millis(100),
        connect_timeout: Duration::from_secs(1),
    };
    let t0 = Instant::now();
    let mut notes = Vec::new();
    let stats = record_tcp(&addr, &out, &opts, &stop, &mut |m| {
        notes.push(m.to_string())
    })
    .unwrap();
    server.join().unwrap();
    assert!(
        t0.elapsed() < Duration::from_secs(15),
        "stopped by the flag"
    );
    assert_eq!(stats.connections, 2, "{notes:?}");
    assert_eq!(stats.dropped_connections, 1);
    assert_eq!(stats.partial_lines_dropped, 1);
    assert_eq!(stats.lines, lines.len() - 1);

    let text = std::fs::read_to_string(&out).unwrap();
    let rec: Vec<&str> = text.lines().collect();
    assert_eq!(rec.len(), lines.len() - 1);
    let expected: Vec<&String> = lines
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != cut)
        .map(|(_, l)| l)
        .collect();
    let now_us = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_micros() as i64;
    let mut last_host = 0i64;
    for (r, e) in rec.iter().zip(&expected) {
        // Each line is the original object with the host time appended.
        let (head, host) = r.rsplit_once(",\"host_time_us\":").unwrap();
        assert_eq!(format!("{head}}}"), **e);
        let host: i64 = host.trim_end_matches('}').parse().unwrap();
        assert!(host >= last_host && (now_us - host) < 60_000_000);
        last_host = host;
        let v: serde_json::Value = serde_json::from_str(r).unwrap();
        assert!(v.is_object());
    }
    // The recorded log reads back: same reports, with host receive times available.
    let log = read_dvl_log(&out, &DvlReadOptions::default()).unwrap();
    assert_eq!(log.stats.velocity_reports, 377);
    assert_eq!(log.stats.rejected_lines, 0);
    let host = read_dvl_log(
        &out,
        &DvlReadOptions {
            time_source: DvlTimeSource::Host,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(host.stats.time_source_used.contains("record-dvl"));
    assert_eq!(host.samples.len(), log.samples.len());
    // Re-recording the same stream repeats every report exactly: all duplicates.
    let doubled = dir.join("doubled.jsonl");
    std::fs::write(&doubled, format!("{text}{text}")).unwrap();
    let d = read_dvl_log(&doubled, &DvlReadOptions::default()).unwrap();
    assert_eq!(d.stats.duplicates, 377);
    assert_eq!(d.samples.len(), log.samples.len());
}

#[test]
fn stops_when_nobody_listens() {
    // A port with no server: the recorder retries until its duration is over.
    let port = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let dir = temp_dir("record-none");
    let out = dir.join("none.jsonl");
    let stop = AtomicBool::new(false);
    let opts = RecordOptions {
        duration: Some(Duration::from_millis(400)),
        reconnect_delay: Duration::from_millis(50),
        connect_timeout: Duration::from_millis(200),
    };
    let t0 = Instant::now();
    let stats = record_tcp(
        &format!("127.0.0.1:{port}"),
        &out,
        &opts,
        &stop,
        &mut |_| {},
    )
    .unwrap();
    assert!(t0.elapsed() < Duration::from_secs(5));
    assert_eq!((stats.connections, stats.lines), (0, 0));
}

#[test]
fn host_time_is_added_to_objects_only() {
    assert_eq!(
        add_host_time("{\"a\":1}", 5),
        "{\"a\":1,\"host_time_us\":5}"
    );
    assert_eq!(add_host_time(" {} \r", 7), "{\"host_time_us\":7}");
    assert_eq!(add_host_time("garbage", 7), "garbage");
    assert_eq!(
        add_host_time("{\"host_time_us\":1}", 7),
        "{\"host_time_us\":1}"
    );
}

#[test]
fn bad_addresses_fail_at_once_and_a_cut_log_is_not_glued() {
    let dir = temp_dir("record-bad");
    let out = dir.join("bad.jsonl");
    let stop = AtomicBool::new(false);
    let opts = RecordOptions {
        duration: Some(Duration::from_millis(300)),
        reconnect_delay: Duration::from_millis(50),
        connect_timeout: Duration::from_millis(100),
    };
    for addr in ["127.0.0.1", "127.0.0.1:notaport", ":::"] {
        let t0 = Instant::now();
        let e = record_tcp(addr, &out, &opts, &stop, &mut |_| {}).unwrap_err();
        assert!(t0.elapsed() < Duration::from_secs(2), "{addr}");
        assert!(e.to_string().contains("--tcp"), "{e}");
    }
    // A log that ends mid-line (a recording killed while writing) gets a line end before new
    // lines are appended.
    let cut = dir.join("cut.jsonl");
    std::fs::write(&cut, "{\"a\":1}\n{\"b\":").unwrap();
    let port = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let mut notes = Vec::new();
    record_tcp(&format!("127.0.0.1:{port}"), &cut, &opts, &stop, &mut |m| {
        notes.push(m.to_string())
    })
    .unwrap();
    assert_eq!(
        std::fs::read_to_string(&cut).unwrap(),
        "{\"a\":1}\n{\"b\":\n"
    );
    assert!(notes.iter().any(|n| n.contains("mid-line")), "{notes:?}");
    // The program says so and fails when nothing was recorded.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args([
            "record-dvl",
            "--tcp",
            &format!("127.0.0.1:{port}"),
            "--out",
            dir.join("none.jsonl").to_str().unwrap(),
            "--duration",
            "0.3",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("nothing was recorded"));
}
