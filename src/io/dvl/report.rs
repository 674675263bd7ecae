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

/// The rejection of a time field (`time_of_validity`, `time_of_transmission`, `host_time_us`)
/// written as `shown`, a number `x` that is not whole microseconds: the A50 writes Unix times
/// in microseconds as integers. The unit it appears to be in is named (Unix seconds or
/// milliseconds from 2000 to 2100), with the conversion.
pub fn not_microseconds(name: &str, shown: &str, x: f64) -> Reject {
    let unix = |per_s: f64| (946_684_800.0..=4_102_444_800.0).contains(&(x / per_s));
    let guess = if unix(1.0) {
        " (it looks like Unix seconds: multiply by 1e6 and write it without a fraction)"
    } else if unix(1e3) {
        " (it looks like Unix milliseconds: multiply by 1e3 and write it without a fraction)"
    } else {
        ""
    };
    let shown: String = shown.chars().take(32).collect();
    Reject::new(
        "time not in integer microseconds",
        format!(
            "'{name}' is {shown}: the A50 writes it as an integer, microseconds since 1970 \
             (Unix time, us){guess}"
        ),
    )
}

/// A 64-bit hash of a byte string (the identity of a report's text).
pub fn content_hash(bytes: &[u8]) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    bytes.hash(&mut h);
    h.finish()
}

/// The CRC-8 table of polynomial 0x07: `CRC8_TABLE[x]` is the CRC of the single byte `x`.
const CRC8_TABLE: [u8; 256] = {
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

/// CRC-8 of the Water Linked serial protocol: polynomial 0x07, initial value 0, no reflection,
/// no final xor (check value 0xf4 for `123456789`).
pub fn crc8(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |c, &b| CRC8_TABLE[(c ^ b) as usize])
}

/// [`crc8`] of every suffix of `bytes` in one pass: element `i` is `crc8(&bytes[i..])` (the
/// last element, for the empty suffix, is 0).
///
/// Without an initial value or final xor the CRC is linear over GF(2), so
/// `crc8(b + rest) = crc8(rest) ^ T^(rest.len() + 1)(b)`, where `T` is the table as a linear map
/// of a byte. `T^k` is kept as the images of the eight bits and advanced one step per byte.
pub fn suffix_crc8(bytes: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; bytes.len() + 1];
    let mut cols: [u8; 8] = [1, 2, 4, 8, 16, 32, 64, 128];
    for i in (0..bytes.len()).rev() {
        for c in &mut cols {
            *c = CRC8_TABLE[*c as usize];
        }
        let b = bytes[i];
        let image = (0..8)
            .filter(|k| b & (1 << k) != 0)
            .fold(0u8, |acc, k| acc ^ cols[k]);
        out[i] = out[i + 1] ^ image;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc8_check_values() {
        assert_eq!(crc8(b"123456789"), 0xf4);
        assert_eq!(crc8(b"wru,0,0.070,1.10,-40,-95"), 0x9c);
    }

    #[test]
    fn suffix_crc8_matches_crc8_of_each_suffix() {
        let mut bytes: Vec<u8> = b"wrz,0.1,-0.2,*garbage wr".to_vec();
        bytes.extend((0u16..300).map(|i| (i.wrapping_mul(151) % 256) as u8));
        let all = suffix_crc8(&bytes);
        assert_eq!(all.len(), bytes.len() + 1);
        for i in 0..=bytes.len() {
            assert_eq!(all[i], crc8(&bytes[i..]), "suffix from {i}");
        }
    }
}
