//! The two serialisations of ROS messages in bags, and decoders for the message types dvlcal
//! reads: CDR, ROS 2's (sqlite3 and MCAP storage alike), and ROS 1's.
//!
//! **CDR.** A message is a 4-byte encapsulation header followed by the payload. The header's
//! second byte says the byte order: `00 01` is plain CDR little-endian (what ROS 2 writes on
//! every common platform), `00 00` plain CDR big-endian; both are read. The parameter-list and
//! XCDR2 encapsulations are refused with an error that names them. The last two header bytes
//! are options and are not used. In the payload every primitive is aligned to its own size,
//! counted from the start of the payload (the byte after the header). A string is a `u32`
//! length that counts a trailing NUL, then the bytes and the NUL. `builtin_interfaces/Time` is
//! `int32 sec, uint32 nanosec`; `std_msgs/Header` is `Time stamp, string frame_id`.
//!
//! **ROS 1.** No header and no alignment: the fields are packed, little-endian. A string is a
//! `u32` length (no NUL) then the bytes. `time` is `uint32 sec, uint32 nsec`, and
//! `std_msgs/Header` is `uint32 seq, time stamp, string frame_id`.
//!
//! In both, a sequence is a `u32` element count then the elements, a fixed array is its
//! elements with no count, and `bool` is one byte. One decoder per type reads both: the
//! [`CdrReader`] knows which serialisation it reads, and [`decode`] takes it as an argument.
//! A type that exists in one ROS version only (`marine_acoustic_msgs/Dvl`) is read from the
//! other's bytes with the same field list.
//!
//! Nothing read is trusted: every read checks the bytes left, every length is checked against
//! the bytes left before anything is allocated, and a message that ends early, has a length
//! running past its end, a CDR string without its NUL, a string not in UTF-8, a `bool` other
//! than 0 or 1, or bytes after its last field (CDR: more than three, the most padding a writer
//! adds; ROS 1: any), is an [`Error::Input`] naming what was being read and the byte offset,
//! counted from the start of the message (CDR: encapsulation header included).

use super::Serialization;
use crate::error::{Error, Result};

/// Bytes of the encapsulation header before the payload.
pub const ENCAPSULATION_LEN: usize = 4;

/// The most bytes accepted after a CDR message's last field (writers pad the payload to a
/// multiple of four).
const MAX_TRAILING: usize = 3;

/// A bounds-checked reader of one serialised message, CDR or ROS 1.
///
/// Reads advance through the payload in field order; each takes a `what` naming the field for
/// the error message.
#[derive(Clone, Debug)]
pub struct CdrReader<'a> {
    /// The payload (CDR: the message after the encapsulation header; ROS 1: the message).
    payload: &'a [u8],
    /// The read position in `payload`.
    pos: usize,
    /// Whether the message is big-endian.
    big_endian: bool,
    /// The serialisation read.
    ser: Serialization,
}

impl<'a> CdrReader<'a> {
    /// A reader of the CDR message `msg`, after checking its encapsulation header.
    pub fn new(msg: &'a [u8]) -> Result<Self> {
        let Some((head, payload)) = msg.split_first_chunk::<ENCAPSULATION_LEN>() else {
            return Err(Error::Input(format!(
                "CDR: encapsulation header at byte 0: the message has {} bytes, the header needs 4",
                msg.len()
            )));
        };
        let big_endian = match (head[0], head[1]) {
            (0, 1) => false,
            (0, 0) => true,
            (0, 2) | (0, 3) => {
                return Err(Error::Input(
                    "CDR: encapsulation header at byte 0: parameter-list CDR (PL_CDR) is not \
                     supported, only plain CDR"
                        .into(),
                ));
            }
            (0, 6..=11) => {
                return Err(Error::Input(format!(
                    "CDR: encapsulation header at byte 0: XCDR2 (kind {:#04x}) is not supported, \
                     only plain CDR",
                    head[1]
                )));
            }
            (a, b) => {
                return Err(Error::Input(format!(
                    "CDR: encapsulation header at byte 0: {a:02x} {b:02x} is not a CDR \
                     encapsulation (plain CDR is 00 01 little-endian or 00 00 big-endian)"
                )));
            }
        };
        Ok(Self {
            payload,
            pos: 0,
            big_endian,
            ser: Serialization::Cdr,
        })
    }

    /// A reader of the ROS 1 message `msg` (which has no header to check).
    pub fn ros1(msg: &'a [u8]) -> Self {
        Self {
            payload: msg,
            pos: 0,
            big_endian: false,
            ser: Serialization::Ros1,
        }
    }

    /// A reader of `msg` serialised as `ser`: [`CdrReader::new`] or [`CdrReader::ros1`].
    pub fn with_serialization(msg: &'a [u8], ser: Serialization) -> Result<Self> {
        match ser {
            Serialization::Cdr => Self::new(msg),
            Serialization::Ros1 => Ok(Self::ros1(msg)),
        }
    }

    /// The serialisation this reader reads.
    pub fn serialization(&self) -> Serialization {
        self.ser
    }

    /// Whether the message is ROS 1 (no alignment, strings without NUL, `Header.seq`).
    pub fn is_ros1(&self) -> bool {
        self.ser == Serialization::Ros1
    }

    /// Whether the message is big-endian (only CDR can be).
    pub fn is_big_endian(&self) -> bool {
        self.big_endian
    }

    /// Bytes before the payload: the encapsulation header in CDR, none in ROS 1.
    fn base(&self) -> usize {
        match self.ser {
            Serialization::Cdr => ENCAPSULATION_LEN,
            Serialization::Ros1 => 0,
        }
    }

    /// The read position as a byte offset from the start of the message (CDR: header
    /// included).
    pub fn offset(&self) -> usize {
        self.pos + self.base()
    }

    /// The payload bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.payload.len().saturating_sub(self.pos)
    }

    /// An error about reading `what` at byte offset `at` of the payload.
    fn err(&self, what: &str, at: usize, msg: &str) -> Error {
        let kind = match self.ser {
            Serialization::Cdr => "CDR",
            Serialization::Ros1 => "ROS 1 message",
        };
        Error::Input(format!(
            "{kind}: {what} at byte {}: {msg}",
            at + self.base()
        ))
    }

    /// Skips the padding before a primitive of `size` bytes (CDR only: ROS 1 is packed).
    fn align(&mut self, size: usize, what: &str) -> Result<()> {
        if self.is_ros1() || size <= 1 {
            return Ok(());
        }
        let pad = (size - self.pos % size) % size;
        if pad > self.remaining() {
            return Err(self.err(what, self.pos, "the message ends in the alignment padding"));
        }
        self.pos += pad;
        Ok(())
    }

    /// The next `n` bytes, with no alignment.
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let Some(s) = self
            .pos
            .checked_add(n)
            .and_then(|end| self.payload.get(self.pos..end))
        else {
            return Err(self.err(
                what,
                self.pos,
                &format!(
                    "{n} bytes needed, the message has {} left",
                    self.remaining()
                ),
            ));
        };
        self.pos += n;
        Ok(s)
    }

    /// The next `N` bytes after aligning to `N`, in little-endian order.
    fn prim<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        self.align(N, what)?;
        let mut b = [0u8; N];
        b.copy_from_slice(self.take(N, what)?);
        if self.big_endian {
            b.reverse();
        }
        Ok(b)
    }

    /// Reads a `uint8` (or `byte`, `char`).
    pub fn u8(&mut self, what: &str) -> Result<u8> {
        let [b] = self.prim::<1>(what)?;
        Ok(b)
    }

    /// Reads a `bool` (one byte, 0 or 1).
    pub fn bool(&mut self, what: &str) -> Result<bool> {
        let at = self.pos;
        match self.u8(what)? {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(self.err(what, at, &format!("{b} is not a bool (0 or 1)"))),
        }
    }

    /// Reads a `uint32`.
    pub fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.prim(what)?))
    }

    /// Reads an `int32`.
    pub fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.prim(what)?))
    }

    /// Reads a `float32`.
    pub fn f32(&mut self, what: &str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.prim(what)?))
    }

    /// Reads a `float64`.
    pub fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.prim(what)?))
    }

    /// Reads a `string`. CDR: a `u32` length counting the trailing NUL, the bytes and the NUL
    /// (a length of 0, no NUL, is read as the empty string, as some writers emit it). ROS 1: a
    /// `u32` length and the bytes.
    pub fn string(&mut self, what: &str) -> Result<String> {
        let len = self.u32(what)? as usize;
        let at = self.pos;
        if len == 0 {
            return Ok(String::new());
        }
        let bytes = self.take(len, what)?;
        let text = if self.is_ros1() {
            bytes
        } else {
            let Some((&0, text)) = bytes.split_last() else {
                return Err(self.err(what, at, "the string does not end in a NUL byte"));
            };
            text
        };
        match std::str::from_utf8(text) {
            Ok(s) => Ok(s.to_owned()),
            Err(e) => Err(self.err(what, at, &format!("the string is not UTF-8 ({e})"))),
        }
    }

    /// Reads a sequence's element count and checks that `count` elements of at least
    /// `min_elem_size` bytes each fit in the bytes left, so that a bogus count is an error and
    /// never a large allocation.
    pub fn seq_len(&mut self, what: &str, min_elem_size: usize) -> Result<usize> {
        let at = self.pos;
        let count = self.u32(what)? as usize;
        let fits = count
            .checked_mul(min_elem_size.max(1))
            .is_some_and(|need| need <= self.remaining());
        if !fits {
            return Err(self.err(
                what,
                at,
                &format!(
                    "a count of {count} elements of at least {min_elem_size} bytes does not fit \
                     in the {} bytes left",
                    self.remaining()
                ),
            ));
        }
        Ok(count)
    }

    /// Reads a `uint8[]` sequence, borrowing its bytes.
    pub fn byte_seq(&mut self, what: &str) -> Result<&'a [u8]> {
        let n = self.seq_len(what, 1)?;
        self.take(n, what)
    }

    /// Reads a `float64[]` sequence.
    pub fn f64_seq(&mut self, what: &str) -> Result<Vec<f64>> {
        let n = self.seq_len(what, 8)?;
        (0..n).map(|_| self.f64(what)).collect()
    }

    /// Reads a fixed array `float64[N]`.
    pub fn f64_array<const N: usize>(&mut self, what: &str) -> Result<[f64; N]> {
        let mut a = [0.0; N];
        for v in &mut a {
            *v = self.f64(what)?;
        }
        Ok(a)
    }

    /// Reads a fixed array `float32[N]`.
    pub fn f32_array<const N: usize>(&mut self, what: &str) -> Result<[f32; N]> {
        let mut a = [0.0; N];
        for v in &mut a {
            *v = self.f32(what)?;
        }
        Ok(a)
    }

    /// Checks that the message ends here: CDR allows at most three bytes of padding, ROS 1
    /// none.
    pub fn finish(&self, what: &str) -> Result<()> {
        let allowed = if self.is_ros1() { 0 } else { MAX_TRAILING };
        if self.remaining() > allowed {
            return Err(self.err(
                what,
                self.pos,
                &format!(
                    "{} bytes after the end of the message (is it of another type?)",
                    self.remaining()
                ),
            ));
        }
        Ok(())
    }
}

/// Decodes one whole serialised message of type `M`, serialised as `ser` (CDR: encapsulation
/// header included). Bytes after the last field are an error (CDR: beyond three of padding).
pub fn decode<M: CdrMessage>(data: &[u8], ser: Serialization) -> Result<M> {
    let mut r = CdrReader::with_serialization(data, ser)?;
    let m = M::read(&mut r)?;
    r.finish(M::TYPE_NAME)?;
    Ok(m)
}

/// Reads only the leading `std_msgs/Header` of a message that starts with one (a stamped
/// message, an image, an odometry, ...), serialised as `ser`, and ignores the rest: the cheap
/// way to the stamp of a large message, as nothing after the header is read or copied.
pub fn decode_header(data: &[u8], ser: Serialization) -> Result<Header> {
    let mut r = CdrReader::with_serialization(data, ser)?;
    Header::read(&mut r)
}

/// A message type with a decoder of both serialisations (the name is CDR's, for history).
pub trait CdrMessage: Sized {
    /// The ROS 2 type name (`package/msg/Type`).
    const TYPE_NAME: &'static str;

    /// Reads the message's fields from `r`, in the order of the type's definition, in the
    /// reader's serialisation.
    fn read(r: &mut CdrReader<'_>) -> Result<Self>;

    /// Decodes one whole CDR message (encapsulation header included); [`decode`] reads
    /// either serialisation.
    fn decode(msg: &[u8]) -> Result<Self> {
        decode(msg, Serialization::Cdr)
    }
}

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
const HEADER_MIN: usize = 12;

/// `std_msgs/msg/String`: `string data`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StringMsg {
    /// The text.
    pub data: String,
}

impl CdrMessage for StringMsg {
    const TYPE_NAME: &'static str = "std_msgs/msg/String";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            data: r.string("String.data")?,
        })
    }
}

/// `geometry_msgs/msg/Vector3`: `float64 x, y, z`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl CdrMessage for Vector3 {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/Vector3";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        let [x, y, z] = r.f64_array::<3>("Vector3")?;
        Ok(Self { x, y, z })
    }
}

/// `geometry_msgs/msg/Point`: `float64 x, y, z`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl CdrMessage for Point {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/Point";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        let [x, y, z] = r.f64_array::<3>("Point")?;
        Ok(Self { x, y, z })
    }
}

/// `geometry_msgs/msg/Quaternion`: `float64 x, y, z, w` (the scalar part last).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w, the scalar part.
    pub w: f64,
}

impl Default for Quaternion {
    /// The identity, as the message's own default (`w = 1`).
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

impl CdrMessage for Quaternion {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/Quaternion";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        let [x, y, z, w] = r.f64_array::<4>("Quaternion")?;
        Ok(Self { x, y, z, w })
    }
}

/// `geometry_msgs/msg/Pose`: `Point position`, `Quaternion orientation`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    /// The position.
    pub position: Point,
    /// The orientation.
    pub orientation: Quaternion,
}

impl CdrMessage for Pose {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/Pose";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            position: Point::read(r)?,
            orientation: Quaternion::read(r)?,
        })
    }
}

/// `geometry_msgs/msg/PoseStamped`: `std_msgs/Header header`, `Pose pose`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

impl CdrMessage for PoseStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/PoseStamped";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            pose: Pose::read(r)?,
        })
    }
}

/// `geometry_msgs/msg/PoseWithCovariance`: `Pose pose`, `float64[36] covariance` (row-major
/// 6x6 over x, y, z and rotations about x, y, z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Row-major 6x6 covariance.
    pub covariance: [f64; 36],
}

impl CdrMessage for PoseWithCovariance {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/PoseWithCovariance";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            pose: Pose::read(r)?,
            covariance: r.f64_array("PoseWithCovariance.covariance")?,
        })
    }
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped`: `std_msgs/Header header`,
/// `PoseWithCovariance pose`.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseWithCovarianceStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose and its covariance.
    pub pose: PoseWithCovariance,
}

impl CdrMessage for PoseWithCovarianceStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/PoseWithCovarianceStamped";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            pose: PoseWithCovariance::read(r)?,
        })
    }
}

/// `geometry_msgs/msg/Twist`: `Vector3 linear`, `Vector3 angular`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Twist {
    /// Linear velocity.
    pub linear: Vector3,
    /// Angular velocity.
    pub angular: Vector3,
}

impl CdrMessage for Twist {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/Twist";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            linear: Vector3::read(r)?,
            angular: Vector3::read(r)?,
        })
    }
}

/// `geometry_msgs/msg/TwistWithCovariance`: `Twist twist`, `float64[36] covariance`
/// (row-major 6x6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Row-major 6x6 covariance.
    pub covariance: [f64; 36],
}

impl CdrMessage for TwistWithCovariance {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/TwistWithCovariance";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            twist: Twist::read(r)?,
            covariance: r.f64_array("TwistWithCovariance.covariance")?,
        })
    }
}

/// `geometry_msgs/msg/TwistWithCovarianceStamped`: `std_msgs/Header header`,
/// `TwistWithCovariance twist`.
#[derive(Clone, Debug, PartialEq)]
pub struct TwistWithCovarianceStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The twist and its covariance.
    pub twist: TwistWithCovariance,
}

impl CdrMessage for TwistWithCovarianceStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/TwistWithCovarianceStamped";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            twist: TwistWithCovariance::read(r)?,
        })
    }
}

/// `geometry_msgs/msg/Transform`: `Vector3 translation`, `Quaternion rotation`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Transform {
    /// The translation.
    pub translation: Vector3,
    /// The rotation.
    pub rotation: Quaternion,
}

impl CdrMessage for Transform {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/Transform";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            translation: Vector3::read(r)?,
            rotation: Quaternion::read(r)?,
        })
    }
}

/// `geometry_msgs/msg/TransformStamped`: `std_msgs/Header header`, `string child_frame_id`,
/// `Transform transform` (the pose of `child_frame_id` in `header.frame_id`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TransformStamped {
    /// Stamp and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The transform.
    pub transform: Transform,
}

impl CdrMessage for TransformStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/TransformStamped";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            child_frame_id: r.string("TransformStamped.child_frame_id")?,
            transform: Transform::read(r)?,
        })
    }
}

/// `tf2_msgs/msg/TFMessage`: `geometry_msgs/TransformStamped[] transforms`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl CdrMessage for TfMessage {
    const TYPE_NAME: &'static str = "tf2_msgs/msg/TFMessage";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        // Header, a child frame's length and seven float64s at the least.
        let n = r.seq_len("TFMessage.transforms", HEADER_MIN + 4 + 56)?;
        let transforms = (0..n)
            .map(|_| TransformStamped::read(r))
            .collect::<Result<_>>()?;
        Ok(Self { transforms })
    }
}

/// `nav_msgs/msg/Odometry`: `std_msgs/Header header`, `string child_frame_id`,
/// `geometry_msgs/PoseWithCovariance pose` (in `header.frame_id`),
/// `geometry_msgs/TwistWithCovariance twist` (in `child_frame_id`).
#[derive(Clone, Debug, PartialEq)]
pub struct Odometry {
    /// Stamp and the pose's frame.
    pub header: Header,
    /// The twist's frame.
    pub child_frame_id: String,
    /// The pose and its covariance.
    pub pose: PoseWithCovariance,
    /// The twist and its covariance.
    pub twist: TwistWithCovariance,
}

impl CdrMessage for Odometry {
    const TYPE_NAME: &'static str = "nav_msgs/msg/Odometry";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            child_frame_id: r.string("Odometry.child_frame_id")?,
            pose: PoseWithCovariance::read(r)?,
            twist: TwistWithCovariance::read(r)?,
        })
    }
}

/// `marine_acoustic_msgs/msg/Dvl` (apl-ocean-engineering/marine_msgs), the report of Water
/// Linked's ROS 2 driver: `std_msgs/Header header`, `uint8 velocity_mode`, `uint8 dvl_type`,
/// `geometry_msgs/Vector3 velocity`, `float64[9] velocity_covar`, `float64 altitude`,
/// `float64 course_gnd`, `float64 speed_gnd`, `uint8 num_good_beams`, `float32 sound_speed`,
/// `bool beam_ranges_valid`, `bool beam_velocities_valid`,
/// `geometry_msgs/Vector3[4] beam_unit_vec`, `float64[4] range`, `float32[4] range_covar`,
/// `float32[4] beam_quality`, `float32[4] beam_velocity`, `float32[4] beam_velocity_covar`.
/// (The message's constants, such as the mode and type codes, are not serialised.)
#[derive(Clone, Debug, PartialEq)]
pub struct Dvl {
    /// Stamp (the time of validity, for Water Linked's driver) and frame.
    pub header: Header,
    /// Bottom track, water track or both (the message's `DVL_MODE_*` codes).
    pub velocity_mode: u8,
    /// The kind of DVL (the message's `DVL_TYPE_*` codes).
    pub dvl_type: u8,
    /// The velocity, m/s.
    pub velocity: Vector3,
    /// Row-major 3x3 covariance of the velocity.
    pub velocity_covar: [f64; 9],
    /// Altitude above the bottom, m.
    pub altitude: f64,
    /// Course over ground.
    pub course_gnd: f64,
    /// Speed over ground.
    pub speed_gnd: f64,
    /// How many beams were good.
    pub num_good_beams: u8,
    /// Speed of sound, m/s.
    pub sound_speed: f32,
    /// Whether the beam ranges are valid.
    pub beam_ranges_valid: bool,
    /// Whether the beam velocities are valid (Water Linked: the velocity is valid).
    pub beam_velocities_valid: bool,
    /// Unit vector of each beam.
    pub beam_unit_vec: [Vector3; 4],
    /// Range along each beam, m.
    pub range: [f64; 4],
    /// Variance of each range.
    pub range_covar: [f32; 4],
    /// Quality of each beam.
    pub beam_quality: [f32; 4],
    /// Velocity along each beam, m/s.
    pub beam_velocity: [f32; 4],
    /// Variance of each beam velocity.
    pub beam_velocity_covar: [f32; 4],
}

impl CdrMessage for Dvl {
    const TYPE_NAME: &'static str = "marine_acoustic_msgs/msg/Dvl";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        let header = Header::read(r)?;
        let velocity_mode = r.u8("Dvl.velocity_mode")?;
        let dvl_type = r.u8("Dvl.dvl_type")?;
        let velocity = Vector3::read(r)?;
        let velocity_covar = r.f64_array("Dvl.velocity_covar")?;
        let altitude = r.f64("Dvl.altitude")?;
        let course_gnd = r.f64("Dvl.course_gnd")?;
        let speed_gnd = r.f64("Dvl.speed_gnd")?;
        let num_good_beams = r.u8("Dvl.num_good_beams")?;
        let sound_speed = r.f32("Dvl.sound_speed")?;
        let beam_ranges_valid = r.bool("Dvl.beam_ranges_valid")?;
        let beam_velocities_valid = r.bool("Dvl.beam_velocities_valid")?;
        let mut beam_unit_vec = [Vector3::default(); 4];
        for v in &mut beam_unit_vec {
            *v = Vector3::read(r)?;
        }
        Ok(Self {
            header,
            velocity_mode,
            dvl_type,
            velocity,
            velocity_covar,
            altitude,
            course_gnd,
            speed_gnd,
            num_good_beams,
            sound_speed,
            beam_ranges_valid,
            beam_velocities_valid,
            beam_unit_vec,
            range: r.f64_array("Dvl.range")?,
            range_covar: r.f32_array("Dvl.range_covar")?,
            beam_quality: r.f32_array("Dvl.beam_quality")?,
            beam_velocity: r.f32_array("Dvl.beam_velocity")?,
            beam_velocity_covar: r.f32_array("Dvl.beam_velocity_covar")?,
        })
    }
}

/// `sensor_msgs/msg/Image`: `std_msgs/Header header`, `uint32 height`, `uint32 width`,
/// `string encoding`, `uint8 is_bigendian`, `uint32 step`, `uint8[] data`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Image {
    /// Stamp (of the exposure) and camera frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono8`, `bgr8`, `rgb8`, `mono16`, ...).
    pub encoding: String,
    /// Whether multi-byte pixels are big-endian (as sent: any nonzero value means yes).
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels, `step * height` bytes in a well-formed message.
    pub data: Vec<u8>,
}

impl CdrMessage for Image {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/Image";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(ImageView::read(r)?.to_image())
    }
}

impl Image {
    /// The image as an [`ImageView`] borrowing its pixels.
    pub fn view(&self) -> ImageView<'_> {
        ImageView {
            header: self.header.clone(),
            height: self.height,
            width: self.width,
            encoding: self.encoding.clone(),
            is_bigendian: self.is_bigendian,
            step: self.step,
            data: &self.data,
        }
    }
}

/// A `sensor_msgs/Image` whose pixels are borrowed from the serialised message, so that
/// converting an image does not copy megabytes first. The fields are those of [`Image`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ImageView<'a> {
    /// Stamp (of the exposure) and camera frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono8`, `bgr8`, `rgb8`, `mono16`, ...).
    pub encoding: String,
    /// Whether multi-byte pixels are big-endian (as sent: any nonzero value means yes).
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels, `step * height` bytes in a well-formed message.
    pub data: &'a [u8],
}

impl<'a> ImageView<'a> {
    /// Reads the fields of a `sensor_msgs/Image` from `r`.
    pub fn read(r: &mut CdrReader<'a>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            height: r.u32("Image.height")?,
            width: r.u32("Image.width")?,
            encoding: r.string("Image.encoding")?,
            is_bigendian: r.u8("Image.is_bigendian")?,
            step: r.u32("Image.step")?,
            data: r.byte_seq("Image.data")?,
        })
    }

    /// Decodes one whole `sensor_msgs/Image` serialised as `ser`, borrowing its pixels.
    pub fn decode(data: &'a [u8], ser: Serialization) -> Result<Self> {
        let mut r = CdrReader::with_serialization(data, ser)?;
        let m = Self::read(&mut r)?;
        r.finish(Image::TYPE_NAME)?;
        Ok(m)
    }

    /// The image with its pixels copied.
    pub fn to_image(&self) -> Image {
        Image {
            header: self.header.clone(),
            height: self.height,
            width: self.width,
            encoding: self.encoding.clone(),
            is_bigendian: self.is_bigendian,
            step: self.step,
            data: self.data.to_vec(),
        }
    }
}

/// `sensor_msgs/msg/CompressedImage`: `std_msgs/Header header`, `string format`,
/// `uint8[] data`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CompressedImage {
    /// Stamp and camera frame.
    pub header: Header,
    /// The format (`jpeg`, `png`, or image_transport's `bgr8; jpeg compressed bgr8`).
    pub format: String,
    /// The compressed image file.
    pub data: Vec<u8>,
}

impl CdrMessage for CompressedImage {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/CompressedImage";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(CompressedImageView::read(r)?.to_compressed_image())
    }
}

impl CompressedImage {
    /// The image as a [`CompressedImageView`] borrowing its bytes.
    pub fn view(&self) -> CompressedImageView<'_> {
        CompressedImageView {
            header: self.header.clone(),
            format: self.format.clone(),
            data: &self.data,
        }
    }
}

/// A `sensor_msgs/CompressedImage` whose file bytes are borrowed from the serialised message.
/// The fields are those of [`CompressedImage`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CompressedImageView<'a> {
    /// Stamp and camera frame.
    pub header: Header,
    /// The format (`jpeg`, `png`, or image_transport's `bgr8; jpeg compressed bgr8`).
    pub format: String,
    /// The compressed image file.
    pub data: &'a [u8],
}

impl<'a> CompressedImageView<'a> {
    /// Reads the fields of a `sensor_msgs/CompressedImage` from `r`.
    pub fn read(r: &mut CdrReader<'a>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            format: r.string("CompressedImage.format")?,
            data: r.byte_seq("CompressedImage.data")?,
        })
    }

    /// Decodes one whole `sensor_msgs/CompressedImage` serialised as `ser`, borrowing its
    /// bytes.
    pub fn decode(data: &'a [u8], ser: Serialization) -> Result<Self> {
        let mut r = CdrReader::with_serialization(data, ser)?;
        let m = Self::read(&mut r)?;
        r.finish(CompressedImage::TYPE_NAME)?;
        Ok(m)
    }

    /// The image with its bytes copied.
    pub fn to_compressed_image(&self) -> CompressedImage {
        CompressedImage {
            header: self.header.clone(),
            format: self.format.clone(),
            data: self.data.to_vec(),
        }
    }
}

/// `sensor_msgs/msg/RegionOfInterest`: `uint32 x_offset`, `uint32 y_offset`, `uint32 height`,
/// `uint32 width`, `bool do_rectify`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RegionOfInterest {
    /// Leftmost column.
    pub x_offset: u32,
    /// Topmost row.
    pub y_offset: u32,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Whether the region is to be rectified.
    pub do_rectify: bool,
}

impl CdrMessage for RegionOfInterest {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/RegionOfInterest";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            x_offset: r.u32("RegionOfInterest.x_offset")?,
            y_offset: r.u32("RegionOfInterest.y_offset")?,
            height: r.u32("RegionOfInterest.height")?,
            width: r.u32("RegionOfInterest.width")?,
            do_rectify: r.bool("RegionOfInterest.do_rectify")?,
        })
    }
}

/// `sensor_msgs/msg/CameraInfo`: `std_msgs/Header header`, `uint32 height`, `uint32 width`,
/// `string distortion_model`, `float64[] d`, `float64[9] k`, `float64[9] r`,
/// `float64[12] p`, `uint32 binning_x`, `uint32 binning_y`, `RegionOfInterest roi`. ROS 1
/// names the four matrices `D`, `K`, `R`, `P`, with the same layout.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraInfo {
    /// Stamp and camera frame.
    pub header: Header,
    /// Rows of the calibrated image.
    pub height: u32,
    /// Columns of the calibrated image.
    pub width: u32,
    /// The distortion model (`plumb_bob`, `rational_polynomial`, `equidistant`).
    pub distortion_model: String,
    /// Distortion coefficients (k1, k2, t1, t2, k3 for `plumb_bob`).
    pub d: Vec<f64>,
    /// Row-major 3x3 intrinsic matrix.
    pub k: [f64; 9],
    /// Row-major 3x3 rectification rotation (stereo).
    pub r: [f64; 9],
    /// Row-major 3x4 projection matrix.
    pub p: [f64; 12],
    /// Horizontal binning (0 or 1: none).
    pub binning_x: u32,
    /// Vertical binning (0 or 1: none).
    pub binning_y: u32,
    /// The region of interest (all zeros: the whole image).
    pub roi: RegionOfInterest,
}

impl CdrMessage for CameraInfo {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/CameraInfo";
    fn read(r: &mut CdrReader<'_>) -> Result<Self> {
        Ok(Self {
            header: Header::read(r)?,
            height: r.u32("CameraInfo.height")?,
            width: r.u32("CameraInfo.width")?,
            distortion_model: r.string("CameraInfo.distortion_model")?,
            d: r.f64_seq("CameraInfo.d")?,
            k: r.f64_array("CameraInfo.k")?,
            r: r.f64_array("CameraInfo.r")?,
            p: r.f64_array("CameraInfo.p")?,
            binning_x: r.u32("CameraInfo.binning_x")?,
            binning_y: r.u32("CameraInfo.binning_y")?,
            roi: RegionOfInterest::read(r)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_kinds() {
        assert!(CdrReader::new(&[0, 1, 0, 0]).is_ok());
        assert!(CdrReader::new(&[0, 0, 0, 0]).unwrap().is_big_endian());
        for h in [[0u8, 3, 0, 0], [0, 7, 0, 0], [1, 1, 0, 0]] {
            assert!(CdrReader::new(&h).is_err());
        }
        let e = CdrReader::new(&[0, 1]).unwrap_err().to_string();
        assert!(e.contains("byte 0"), "{e}");
    }

    #[test]
    fn alignment_and_big_endian() {
        // Payload offsets: u8 at 0, pad to 4, u32 at 4, u8 at 8, pad to 16, f64 at 16.
        let pad = [0u8; 7];
        let le = [
            &[0u8, 1, 0, 0, 7, 0, 0, 0][..],
            &5u32.to_le_bytes(),
            &[9],
            &pad,
            &2.5f64.to_le_bytes(),
        ]
        .concat();
        let be = [
            &[0u8, 0, 0, 0, 7, 0, 0, 0][..],
            &5u32.to_be_bytes(),
            &[9],
            &pad,
            &2.5f64.to_be_bytes(),
        ]
        .concat();
        for m in [le, be] {
            let mut r = CdrReader::new(&m).unwrap();
            assert_eq!(r.u8("a").unwrap(), 7);
            assert_eq!(r.u32("b").unwrap(), 5);
            assert_eq!(r.u8("c").unwrap(), 9);
            assert_eq!(r.offset(), 13);
            assert_eq!(r.f64("d").unwrap(), 2.5);
            assert_eq!(r.remaining(), 0);
            // Cut inside the padding before the f64.
            let mut r = CdrReader::new(&m[..15]).unwrap();
            r.u8("a").unwrap();
            r.u32("b").unwrap();
            r.u8("c").unwrap();
            let e = r.f64("d").unwrap_err().to_string();
            assert!(e.contains("d at byte 13"), "{e}");
        }
    }

    #[test]
    fn bogus_lengths_are_errors() {
        // A string and a sequence claiming 4 GB.
        let m = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff, b'a', 0];
        let e = StringMsg::decode(&m).unwrap_err().to_string();
        assert!(e.contains("String.data") && e.contains("byte 8"), "{e}");
        let mut r = CdrReader::new(&m).unwrap();
        let e = r.seq_len("seq", 8).unwrap_err().to_string();
        assert!(e.contains("seq at byte 4"), "{e}");
        // No NUL, and too many trailing bytes.
        assert!(StringMsg::decode(&[0, 1, 0, 0, 1, 0, 0, 0, b'a']).is_err());
        let ok = [0, 1, 0, 0, 2, 0, 0, 0, b'a', 0, 0, 0];
        assert_eq!(StringMsg::decode(&ok).unwrap().data, "a");
        assert!(StringMsg::decode(&[ok.as_slice(), &[0, 0]].concat()).is_err());
    }
    /// A ROS 1 `Header`: seq, sec, nsec, a string without NUL.
    fn ros1_header(seq: u32, sec: u32, nsec: u32, frame: &str) -> Vec<u8> {
        [
            &seq.to_le_bytes()[..],
            &sec.to_le_bytes(),
            &nsec.to_le_bytes(),
            &(frame.len() as u32).to_le_bytes(),
            frame.as_bytes(),
        ]
        .concat()
    }

    #[test]
    fn ros1_is_packed_with_seq_and_unsigned_seconds() {
        // Seconds past 2038 (beyond i32) stay positive.
        let m = ros1_header(7, 3_000_000_000, 5, "cam");
        let h: Header = decode(&m, Serialization::Ros1).unwrap();
        assert_eq!(h.seq, 7);
        assert_eq!(h.stamp.sec, 3_000_000_000);
        assert_eq!(h.stamp.as_nanos(), 3_000_000_000_000_000_005);
        assert_eq!(h.frame_id, "cam");
        // No alignment: a u8 then an f64 right after it.
        let m = [&[9u8][..], &2.5f64.to_le_bytes()].concat();
        let mut r = CdrReader::ros1(&m);
        assert_eq!(r.u8("a").unwrap(), 9);
        assert_eq!(r.f64("b").unwrap(), 2.5);
        r.finish("x").unwrap();
        // Any byte after the last field is an error, with the offset counted from byte 0.
        let m = [ros1_header(1, 2, 3, "").as_slice(), &[0]].concat();
        let e = decode::<Header>(&m, Serialization::Ros1)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("ROS 1 message: ") && e.contains("at byte 16"),
            "{e}"
        );
        // A CDR stamp with a negative second stays negative.
        let m = [&[0u8, 1, 0, 0][..], &(-2i32).to_le_bytes(), &[0; 8]].concat();
        let h = Header::decode(&m).unwrap();
        assert_eq!((h.seq, h.stamp.sec), (0, -2));
        assert_eq!(h.stamp.as_nanos(), -2_000_000_000);
    }

    #[test]
    fn ros1_strings_have_no_nul() {
        let m = [&3u32.to_le_bytes()[..], b"abc"].concat();
        assert_eq!(
            decode::<StringMsg>(&m, Serialization::Ros1).unwrap().data,
            "abc"
        );
        // The CDR reading of the same bytes misses its NUL.
        let cdr = [&[0u8, 1, 0, 0][..], &m].concat();
        assert!(StringMsg::decode(&cdr).is_err());
        let bad = [&2u32.to_le_bytes()[..], &[0xff, 0xfe]].concat();
        let e = decode::<StringMsg>(&bad, Serialization::Ros1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("String.data at byte 4") && e.contains("UTF-8"),
            "{e}"
        );
    }

    #[test]
    fn decode_header_reads_only_the_header() {
        // A header followed by bytes that are no valid rest of anything.
        let m = [ros1_header(3, 10, 20, "cam0").as_slice(), &[0xff; 9]].concat();
        let h = decode_header(&m, Serialization::Ros1).unwrap();
        assert_eq!((h.seq, h.stamp.sec, h.stamp.nanosec), (3, 10, 20));
        assert!(decode_header(&m[..10], Serialization::Ros1).is_err());
        let cdr = [
            0, 1, 0, 0, 10, 0, 0, 0, 20, 0, 0, 0, 1, 0, 0, 0, 0, 0xff, 0xff,
        ];
        let h = decode_header(&cdr, Serialization::Cdr).unwrap();
        assert_eq!((h.seq, h.stamp.sec, h.frame_id.as_str()), (0, 10, ""));
    }
}
