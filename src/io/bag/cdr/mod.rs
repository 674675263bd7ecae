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
//!
//! [`Error::Input`]: crate::error::Error::Input

mod declare;
mod header;
mod messages;
mod reader;

pub use header::{Header, Time, decode_header};
pub use messages::{
    CameraInfo, CompressedImage, CompressedImageView, Dvl, Image, ImageView, Imu, Odometry, Point,
    Pose, PoseStamped, PoseWithCovariance, PoseWithCovarianceStamped, Quaternion, RegionOfInterest,
    StringMsg, TfMessage, Transform, TransformStamped, Twist, TwistWithCovariance,
    TwistWithCovarianceStamped, Vector3,
};
pub use reader::{CdrMessage, CdrReader, ENCAPSULATION_LEN, decode};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::bag::Serialization;

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
