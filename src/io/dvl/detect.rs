//! Recognises the format of a DVL log from its first bytes and lines.

use super::log::{DvlFormat, text_lines};

/// The first bytes of a ROS1 bag.
pub const ROSBAG_MAGIC: &[u8] = b"#ROSBAG V2.0\n";
use crate::io::bag::MCAP_MAGIC;

/// How many non-blank lines of a text log are looked at.
const SAMPLE_LINES: usize = 200;

/// The format of a DVL log, or `None` when nothing in it looks like one.
///
/// A bag (ROS 1, or a ROS 2 MCAP or sqlite3 file) is known by its magic; a text log by a vote over its first non-blank lines:
/// lines starting with `{` count for JSON, lines holding a `wr<letter>` sentence for serial.
pub fn detect_format(bytes: &[u8]) -> Option<DvlFormat> {
    if bytes.starts_with(ROSBAG_MAGIC) {
        return Some(DvlFormat::RosBag);
    }
    if bytes.starts_with(MCAP_MAGIC) || bytes.starts_with(crate::io::bag::SQLITE_MAGIC) {
        return Some(DvlFormat::RosBag);
    }
    let (mut json, mut serial) = (0usize, 0usize);
    for (_, line) in text_lines(bytes).take(SAMPLE_LINES) {
        let t = line.trim_ascii();
        if t.first() == Some(&b'{') {
            json += 1;
        } else if t
            .windows(3)
            .any(|w| w[0] == b'w' && w[1] == b'r' && w[2].is_ascii_alphabetic())
        {
            serial += 1;
        }
    }
    match (json, serial) {
        (0, 0) => None,
        (j, s) if j >= s => Some(DvlFormat::JsonLines),
        _ => Some(DvlFormat::Serial),
    }
}
