//! Recording the A50's TCP JSON stream to a log, one JSON object per line, each with the host
//! receive time added as `host_time_us` (Unix microseconds), so that logs without absolute DVL
//! time (json_v1) and DVL clocks that were never synchronised can be handled later.

use std::fs::{File, OpenOptions};
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use super::json::HOST_TIME_KEY;
use crate::error::{Error, Result};

/// How to record.
#[derive(Clone, Debug)]
pub struct RecordOptions {
    /// Stop after this long; `None`: until `stop` is set.
    pub duration: Option<Duration>,
    /// Wait between connection attempts.
    pub reconnect_delay: Duration,
    /// Give up one connection attempt after this long.
    pub connect_timeout: Duration,
}

impl Default for RecordOptions {
    fn default() -> Self {
        RecordOptions {
            duration: None,
            reconnect_delay: Duration::from_millis(500),
            connect_timeout: Duration::from_secs(2),
        }
    }
}

/// What a recording did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecordStats {
    /// Lines written.
    pub lines: usize,
    /// Bytes written.
    pub bytes: u64,
    /// Connections made.
    pub connections: usize,
    /// Connections that ended before the recording did.
    pub dropped_connections: usize,
    /// Incomplete lines lost when a connection dropped (or longer than 1 MiB).
    pub partial_lines_dropped: usize,
}

impl RecordStats {
    /// What the recording wrote to `out`, in one line: lines, bytes, connections made and
    /// dropped, partial lines lost.
    pub fn summary(&self, out: &Path) -> String {
        format!(
            "{} lines ({} bytes) written to {}; {} connections, {} dropped, {} partial lines lost",
            self.lines,
            self.bytes,
            out.display(),
            self.connections,
            self.dropped_connections,
            self.partial_lines_dropped
        )
    }

    /// Why a recording from `addr` that wrote no line holds nothing: where the DVL was looked
    /// for.
    pub fn nothing_recorded(&self, addr: &str) -> String {
        format!(
            "nothing was recorded from {addr} ({} connections): is the DVL at that address and \
             port (the A50 serves its JSON stream on port 16171)?",
            self.connections
        )
    }
}

/// Checks that `addr` is a `host:port` address that resolves, so that a mistyped address is
/// an error at once rather than a recording that retries forever; `option` names it in the
/// error.
pub fn check_address(addr: &str, option: &'static str) -> Result<()> {
    match addr.to_socket_addrs().map(|a| a.count()) {
        Ok(n) if n > 0 => Ok(()),
        Ok(_) => Err(Error::option(
            option,
            format!("'{addr}' resolves to no address"),
        )),
        Err(e) => Err(Error::option(
            option,
            format!("'{addr}' is not a HOST:PORT address that resolves: {e}"),
        )),
    }
}

/// Longest line kept; a longer run of bytes without a line end is dropped.
const MAX_LINE: usize = 1 << 20;

/// The current host time in Unix microseconds.
fn now_us() -> i64 {
    match SystemTime::now().duration_since(UNIX_EPOCH) {
        Ok(d) => d.as_micros() as i64,
        Err(e) => -(e.duration().as_micros() as i64),
    }
}

/// Adds `"host_time_us":T` to a one-line JSON object (lines that are not one are kept as they
/// are; a line that already has a host time keeps it).
pub fn add_host_time(line: &str, t_us: i64) -> String {
    let t = line.trim();
    if !(t.starts_with('{') && t.ends_with('}')) || t.contains(&format!("\"{HOST_TIME_KEY}\"")) {
        return t.to_string();
    }
    let body = t[..t.len() - 1].trim_end();
    let sep = if body.ends_with('{') { "" } else { "," };
    format!("{body}{sep}\"{HOST_TIME_KEY}\":{t_us}}}")
}

/// Connects to a DVL's JSON stream at `addr` (`host:port`) and appends every line to `out`,
/// flushed line by line, until `duration` has passed or `stop` is set. A dropped or refused
/// connection is retried every `reconnect_delay`. `note` receives one-line progress messages
/// (connected, dropped, ...).
pub fn record_tcp(
    addr: &str,
    out: &Path,
    opts: &RecordOptions,
    stop: &AtomicBool,
    note: &mut dyn FnMut(&str),
) -> Result<RecordStats> {
    // A malformed or unresolvable address is an error now, not a retry loop.
    check_address(addr, "--tcp")?;
    let mut file: File = OpenOptions::new()
        .create(true)
        .read(true)
        .append(true)
        .open(out)
        .map_err(|e| Error::io(out, e))?;
    // A log whose last line was cut (a recording killed mid-line) gets a line end first, so that
    // the next line is not glued to the fragment.
    {
        use std::io::{Seek, SeekFrom};
        let len = file.metadata().map_err(|e| Error::io(out, e))?.len();
        if len > 0 {
            let mut last = [0u8; 1];
            file.seek(SeekFrom::Start(len - 1))
                .and_then(|_| file.read_exact(&mut last))
                .map_err(|e| Error::io(out, e))?;
            if last[0] != b'\n' {
                file.write_all(b"\n").map_err(|e| Error::io(out, e))?;
                note("the log ended mid-line: a line end was added before the new lines");
            }
        }
    }
    let start = Instant::now();
    let done =
        || stop.load(Ordering::SeqCst) || opts.duration.is_some_and(|d| start.elapsed() >= d);
    let mut stats = RecordStats::default();
    let mut first_attempt = true;
    while !done() {
        if !first_attempt {
            // Sleep in small steps so that a stop is honoured at once.
            let until = Instant::now() + opts.reconnect_delay;
            while Instant::now() < until && !done() {
                std::thread::sleep(Duration::from_millis(20));
            }
            if done() {
                break;
            }
        }
        first_attempt = false;
        let stream = match connect(addr, opts.connect_timeout) {
            Ok(s) => s,
            Err(e) => {
                note(&format!("cannot connect to {addr}: {e}; retrying"));
                continue;
            }
        };
        stats.connections += 1;
        note(&format!("connected to {addr}"));
        match pump(stream, &mut file, out, &mut stats, &done)? {
            true => {
                stats.dropped_connections += 1;
                note(&format!("connection to {addr} dropped; reconnecting"));
            }
            false => break,
        }
    }
    file.sync_data().map_err(|e| Error::io(out, e))?;
    Ok(stats)
}

fn connect(addr: &str, timeout: Duration) -> std::io::Result<TcpStream> {
    let mut last = std::io::Error::new(ErrorKind::NotFound, "address resolves to nothing");
    for a in addr.to_socket_addrs()? {
        match TcpStream::connect_timeout(&a, timeout) {
            Ok(s) => return Ok(s),
            Err(e) => last = e,
        }
    }
    Err(last)
}

/// Copies lines from `stream` to `file`. Returns `Ok(true)` when the connection dropped and
/// `Ok(false)` when the recording is done.
fn pump(
    mut stream: TcpStream,
    file: &mut File,
    out: &Path,
    stats: &mut RecordStats,
    done: &dyn Fn() -> bool,
) -> Result<bool> {
    stream
        .set_read_timeout(Some(Duration::from_millis(100)))
        .map_err(|e| Error::io(out, e))?;
    let mut pending: Vec<u8> = Vec::new();
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        if done() {
            return Ok(false);
        }
        let n = match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => continue,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(_) => break,
        };
        let t_us = now_us();
        pending.extend_from_slice(&buf[..n]);
        let mut consumed = 0;
        while let Some(pos) = pending[consumed..].iter().position(|&b| b == b'\n') {
            let raw = &pending[consumed..consumed + pos];
            consumed += pos + 1;
            let text = String::from_utf8_lossy(raw);
            if text.trim().is_empty() {
                continue;
            }
            let mut line = add_host_time(&text, t_us);
            line.push('\n');
            file.write_all(line.as_bytes())
                .and_then(|_| file.flush())
                .map_err(|e| Error::io(out, e))?;
            stats.lines += 1;
            stats.bytes += line.len() as u64;
        }
        pending.drain(..consumed);
        if pending.len() > MAX_LINE {
            pending.clear();
            stats.partial_lines_dropped += 1;
        }
    }
    if !pending.iter().all(|b| b.is_ascii_whitespace()) {
        stats.partial_lines_dropped += 1;
    }
    Ok(true)
}
