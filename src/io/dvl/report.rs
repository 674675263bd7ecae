//! What a single line (or bag message) of a DVL log turns into, whatever its format.

use std::hash::{Hash, Hasher};

use crate::time::RawTime;

/// A bottom-tracking velocity report, as read from one line or message.
#[derive(Clone, Debug, PartialEq)]
pub struct VelocityReport {
    /// Format label for the summary (`json_v3.1`, `serial wrz`, `rosbag /dvl/data`, ...).
    pub label: String,
    /// Velocity in the DVL frame, m/s.
    pub v: [f64; 3],
    /// Row-major covariance of `v`, (m/s)^2, when the report carries one.
    pub cov: Option<[f64; 9]>,
    /// The DVL's validity flag.
    pub valid: bool,
    /// Milliseconds since the previous velocity report (`time`).
    pub time_ms: Option<f64>,
    /// Mid-ping time, Unix microseconds on the DVL clock.
    pub time_of_validity_us: Option<i64>,
    /// Time the report left the DVL, Unix microseconds on the DVL clock.
    pub time_of_transmission_us: Option<i64>,
    /// Host receive time, when the container records one.
    pub host_time: Option<RawTime>,
    /// What `host_time` is (`bag record time (host)`, ...).
    pub host_time_kind: Option<&'static str>,
    /// Hash of the report's own content (without any host time): equal for exact repeats.
    pub key: u64,
}

impl VelocityReport {
    /// Whether `other` repeats this report exactly (the host receive time aside).
    pub fn same_report(&self, other: &VelocityReport) -> bool {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        self.key == other.key
            && bits(&self.v) == bits(&other.v)
            && self.cov.map(|c| bits(&c)) == other.cov.map(|c| bits(&c))
            && self.valid == other.valid
            && self.time_ms.map(f64::to_bits) == other.time_ms.map(f64::to_bits)
            && self.time_of_validity_us == other.time_of_validity_us
            && self.time_of_transmission_us == other.time_of_transmission_us
    }
}

/// One line of a DVL log, understood.
#[derive(Clone, Debug, PartialEq)]
pub enum Parsed {
    /// A bottom-tracking velocity report (valid or not).
    Velocity(VelocityReport),
    /// A water-tracking velocity report: counted, never used as a velocity.
    WaterVelocity {
        /// Format label for the summary, as in [`VelocityReport::label`].
        label: String,
    },
    /// The DVL's configuration (a JSON `get_config` reply, a serial `wrc` sentence): counted as
    /// another report, and the sound speed it assumes is kept.
    Config {
        /// Format label for the summary, as in [`VelocityReport::label`].
        label: String,
        /// The speed of sound the DVL assumes, m/s, when the reply states it.
        speed_of_sound: Option<f64>,
    },
    /// A well-formed report of another type (dead reckoning, transducers, replies, ...).
    Other {
        /// Format label for the summary, as in [`VelocityReport::label`].
        label: String,
        /// The report's type: the JSON `type` field or the serial sentence name (`wru`, ...).
        kind: String,
    },
}

/// Why a line was rejected.
#[derive(Clone, Debug, PartialEq)]
pub struct Reject {
    /// Short category, e.g. `not valid JSON`, `bad checksum`, `non-numeric field`.
    pub reason: &'static str,
    /// The details.
    pub detail: String,
}

impl Reject {
    /// A rejection with a short category `reason` and its `detail`.
    pub fn new(reason: &'static str, detail: impl Into<String>) -> Reject {
        Reject {
            reason,
            detail: detail.into(),
        }
    }
}

/// A 64-bit hash of a byte string (the identity of a report's text).
pub fn content_hash(bytes: &[u8]) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    bytes.hash(&mut h);
    h.finish()
}

/// CRC-8 of the Water Linked serial protocol: polynomial 0x07, initial value 0, no reflection,
/// no final xor (check value 0xf4 for `123456789`).
pub fn crc8(bytes: &[u8]) -> u8 {
    const TABLE: [u8; 256] = {
        let mut t = [0u8; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u8;
            let mut k = 0;
            while k < 8 {
                c = if c & 0x80 != 0 {
                    (c << 1) ^ 0x07
                } else {
                    c << 1
                };
                k += 1;
            }
            t[i] = c;
            i += 1;
        }
        t
    };
    bytes.iter().fold(0u8, |c, &b| TABLE[(c ^ b) as usize])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc8_check_values() {
        assert_eq!(crc8(b"123456789"), 0xf4);
        assert_eq!(crc8(b"wru,0,0.070,1.10,-40,-95"), 0x9c);
    }
}
