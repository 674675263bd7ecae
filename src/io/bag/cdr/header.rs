//! The two types whose layout differs between the serialisations, written out by hand: the
//! time stamp and `std_msgs/Header` (ROS 1 has unsigned seconds and a sequence number); and
//! the cheap read of a message's leading header.

use super::reader::{CdrMessage, CdrReader};
use crate::error::Result;
use crate::io::bag::Serialization;

/// A time stamp: `builtin_interfaces/msg/Time` in ROS 2 (`int32 sec`, `uint32 nanosec`), the
/// primitive `time` in ROS 1 (`uint32 sec`, `uint32 nsec`). The seconds are held in an `i64`,
/// which holds both: ROS 1 times after 2038 stay positive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Time {
    /// Whole seconds (since the Unix epoch for wall-clock stamps).
    pub sec: i64,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// The time in seconds.
    pub fn as_secs_f64(&self) -> f64 {
        self.sec as f64 + f64::from(self.nanosec) * 1e-9
    }

    /// The time in nanoseconds (saturating at the ends of `i64`, some 292 years from 1970,
    /// which no message read can reach).
    pub fn as_nanos(&self) -> i64 {
        self.sec
            .saturating_mul(1_000_000_000)
            .saturating_add(i64::from(self.nanosec))
    }
}

impl CdrMessage for Time {
    const TYPE_NAME: &'static str = "builtin_interfaces/msg/Time";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        let sec = if r.is_ros1() {
            i64::from(r.u32("Time.sec")?)
        } else {
            i64::from(r.i32("Time.sec")?)
        };
        Ok(Self {
            sec,
            nanosec: r.u32("Time.nanosec")?,
        })
    }
}

/// `std_msgs/msg/Header`: ROS 2 `builtin_interfaces/Time stamp`, `string frame_id`; ROS 1
/// `uint32 seq`, `time stamp`, `string frame_id`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Header {
    /// The ROS 1 sequence number (0 when read from CDR, which has none).
    pub seq: u32,
    /// The time of the data.
    pub stamp: Time,
    /// The frame the data is in.
    pub frame_id: String,
}

impl CdrMessage for Header {
    const TYPE_NAME: &'static str = "std_msgs/msg/Header";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        let seq = if r.is_ros1() { r.u32("Header.seq")? } else { 0 };
        Ok(Self {
            seq,
            stamp: Time::read(r)?,
            frame_id: r.string("Header.frame_id")?,
        })
    }
}

/// The smallest serialised `Header` in either serialisation: CDR's stamp and an empty
/// string's length (ROS 1 adds four bytes of `seq`).
pub(super) const HEADER_MIN: usize = 12;

/// Reads only the leading `std_msgs/Header` of a message that starts with one (a stamped
/// message, an image, an odometry, ...), serialised as `ser`, and ignores the rest: the cheap
/// way to the stamp of a large message, as nothing after the header is read or copied.
pub fn decode_header(data: &[u8], ser: Serialization) -> Result<Header> {
    let mut r = CdrReader::with_serialization(data, ser)?;
    Header::read(&mut r)
}
