//! The bounds-checked reader of one serialised message (CDR or ROS 1) and the trait of the
//! message types it decodes.

use crate::error::{Error, Result};
use crate::io::bag::Serialization;

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
