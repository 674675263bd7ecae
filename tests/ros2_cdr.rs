//! The CDR decoder of ROS 2 messages against fixtures written by rosbags, an independent
//! implementation (tests/fixtures/cdr, made by scripts/make_cdr_fixtures.py): every field
//! decodes to the value set there, every truncated fixture is an error, and no bytes (random,
//! or fixtures mutated) make a decoder panic. Case counts are kept small for `cargo test`;
//! raise them with `DVL_FUZZ_CASES=...` for a longer run.

use std::path::PathBuf;

use dvlcal::io::bag::cdr::*;
use proptest::prelude::*;

fn cases(n: u32) -> u32 {
    std::env::var("DVL_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(n)
}

fn fixture(name: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/cdr")
        .join(format!("{name}.cdr"));
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Every fixture with the decoder of its type; the decoder's result is reduced to whether it
/// succeeded, so that one list drives the truncation and fuzz tests.
type Decode = fn(&[u8]) -> Result<(), dvlcal::Error>;

fn ok<T>(r: dvlcal::error::Result<T>) -> Result<(), dvlcal::Error> {
    r.map(|_| ())
}

const ALL: &[(&str, Decode)] = &[
    ("header", |b| ok(Header::decode(b))),
    ("header_be", |b| ok(Header::decode(b))),
    ("string", |b| ok(StringMsg::decode(b))),
    ("vector3", |b| ok(Vector3::decode(b))),
    ("quaternion", |b| ok(Quaternion::decode(b))),
    ("pose", |b| ok(Pose::decode(b))),
    ("pose_stamped", |b| ok(PoseStamped::decode(b))),
    ("pose_with_covariance_stamped", |b| {
        ok(PoseWithCovarianceStamped::decode(b))
    }),
    ("twist_with_covariance_stamped", |b| {
        ok(TwistWithCovarianceStamped::decode(b))
    }),
    ("transform_stamped", |b| ok(TransformStamped::decode(b))),
    ("tf_message", |b| ok(TfMessage::decode(b))),
    ("odometry", |b| ok(Odometry::decode(b))),
    ("dvl", |b| ok(Dvl::decode(b))),
    ("image", |b| ok(Image::decode(b))),
    ("compressed_image", |b| ok(CompressedImage::decode(b))),
    ("camera_info", |b| ok(CameraInfo::decode(b))),
];

fn cov(base: f64) -> [f64; 36] {
    std::array::from_fn(|i| base + i as f64)
}

fn q() -> Quaternion {
    Quaternion {
        x: 0.1,
        y: 0.2,
        z: 0.3,
        w: 0.9273618495495704,
    }
}

fn header(sec: i64, nanosec: u32, frame: &str) -> Header {
    Header {
        seq: 0,
        stamp: Time { sec, nanosec },
        frame_id: frame.into(),
    }
}

fn v3(x: f64, y: f64, z: f64) -> Vector3 {
    Vector3 { x, y, z }
}

#[test]
fn header_and_string() {
    let h = Header::decode(&fixture("header")).unwrap();
    assert_eq!(h, header(1_700_000_000, 123_456_789, "camera"));
    assert!((h.stamp.as_secs_f64() - 1_700_000_000.0 - 0.123_456_789).abs() < 1e-6);
    assert_eq!(Header::decode(&fixture("header_be")).unwrap(), h);
    assert!(
        CdrReader::new(&fixture("header_be"))
            .unwrap()
            .is_big_endian()
    );
    assert_eq!(
        StringMsg::decode(&fixture("string")).unwrap().data,
        "héllo dvl"
    );
}

#[test]
fn geometry() {
    assert_eq!(
        Vector3::decode(&fixture("vector3")).unwrap(),
        v3(1.5, -2.25, 3.125)
    );
    assert_eq!(Quaternion::decode(&fixture("quaternion")).unwrap(), q());
    let p = Pose::decode(&fixture("pose")).unwrap();
    assert_eq!((p.position.x, p.position.y, p.position.z), (4.0, 5.0, 6.0));
    assert_eq!(p.orientation, q());
    let ps = PoseStamped::decode(&fixture("pose_stamped")).unwrap();
    assert_eq!(ps.header, header(12, 34, "map"));
    assert_eq!(
        (ps.pose.position.x, ps.pose.position.y, ps.pose.position.z),
        (-1.0, 0.5, 2.0)
    );
    let pc = PoseWithCovarianceStamped::decode(&fixture("pose_with_covariance_stamped")).unwrap();
    assert_eq!(pc.header, header(1_700_000_001, 500, "odom"));
    assert_eq!(pc.pose.pose.position.z, 3.0);
    assert_eq!(pc.pose.covariance, cov(0.5));
    let tc = TwistWithCovarianceStamped::decode(&fixture("twist_with_covariance_stamped")).unwrap();
    assert_eq!(tc.header, header(1_700_000_002, 7, "dvl"));
    assert_eq!(tc.twist.twist.linear, v3(0.25, -0.5, 0.125));
    assert_eq!(tc.twist.twist.angular, v3(0.01, 0.02, -0.03));
    assert_eq!(tc.twist.covariance, cov(100.0));
}

#[test]
fn transforms() {
    let t = TransformStamped::decode(&fixture("transform_stamped")).unwrap();
    assert_eq!(t.header, header(100, 5, "base_link"));
    assert_eq!(t.child_frame_id, "dvl_link");
    assert_eq!(t.transform.translation, v3(0.1, 0.2, -0.3));
    assert_eq!(t.transform.rotation, Quaternion::default());
    let tf = TfMessage::decode(&fixture("tf_message")).unwrap();
    assert_eq!(tf.transforms.len(), 2);
    assert_eq!(tf.transforms[0].header, header(200, 5, "base_link"));
    assert_eq!(tf.transforms[0].child_frame_id, "cam0");
    assert_eq!(tf.transforms[0].transform.translation, v3(1.0, 0.0, 0.0));
    assert_eq!(tf.transforms[1].header, header(201, 5, "cam0"));
    assert_eq!(tf.transforms[1].child_frame_id, "cam1");
    assert_eq!(tf.transforms[1].transform.translation, v3(0.12, 0.0, 0.0));
    let r = tf.transforms[1].transform.rotation;
    assert_eq!((r.x, r.y, r.z, r.w), (0.5, 0.5, 0.5, 0.5));
}

#[test]
fn odometry() {
    let o = Odometry::decode(&fixture("odometry")).unwrap();
    assert_eq!(o.header, header(1_700_000_003, 999_999_999, "odom"));
    assert_eq!(o.child_frame_id, "dvl");
    assert_eq!(o.pose.pose.orientation, q());
    assert_eq!(o.pose.covariance, cov(0.5));
    assert_eq!(o.twist.twist.linear, v3(0.25, -0.5, 0.125));
    assert_eq!(o.twist.covariance, cov(100.0));
}

#[test]
fn dvl() {
    let d = Dvl::decode(&fixture("dvl")).unwrap();
    assert_eq!(d.header, header(1_700_000_004, 250_000_000, "dvl_link"));
    assert_eq!((d.velocity_mode, d.dvl_type), (1, 2));
    assert_eq!(d.velocity, v3(0.3, -0.1, 0.05));
    let c: [f64; 9] = std::array::from_fn(|i| 1e-4 * (i + 1) as f64);
    assert_eq!(d.velocity_covar, c);
    assert_eq!((d.altitude, d.course_gnd, d.speed_gnd), (2.75, 0.5, 0.3162));
    assert_eq!(d.num_good_beams, 4);
    assert_eq!(d.sound_speed, 1500.5);
    assert!(d.beam_ranges_valid);
    assert!(!d.beam_velocities_valid);
    assert_eq!(
        d.beam_unit_vec,
        [
            v3(0.6, 0.0, 0.8),
            v3(0.0, 0.6, 0.8),
            v3(-0.6, 0.0, 0.8),
            v3(0.0, -0.6, 0.8)
        ]
    );
    assert_eq!(d.range, [3.0, 3.25, 3.5, 3.75]);
    assert_eq!(d.range_covar, [0.5, 0.25, 0.125, 0.0625]);
    assert_eq!(d.beam_quality, [1.0, 2.0, 3.0, 4.0]);
    assert_eq!(d.beam_velocity, [0.25, -0.25, 0.5, -0.5]);
    assert_eq!(d.beam_velocity_covar, [0.001, 0.002, 0.003, 0.004]);
}

#[test]
fn images() {
    let i = Image::decode(&fixture("image")).unwrap();
    assert_eq!(i.header, header(1_700_000_005, 1, "cam0"));
    assert_eq!((i.height, i.width, i.step), (2, 3, 3));
    assert_eq!(i.encoding, "mono8");
    assert_eq!(i.is_bigendian, 0);
    assert_eq!(i.data, [0, 1, 2, 253, 254, 255]);
    let c = CompressedImage::decode(&fixture("compressed_image")).unwrap();
    assert_eq!(c.header, header(1_700_000_006, 2, "cam1"));
    assert_eq!(c.format, "jpeg");
    assert_eq!(c.data, [0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 0xFF, 0xD9]);
    let ci = CameraInfo::decode(&fixture("camera_info")).unwrap();
    assert_eq!(ci.header, header(1_700_000_007, 3, "cam0"));
    assert_eq!((ci.height, ci.width), (480, 640));
    assert_eq!(ci.distortion_model, "plumb_bob");
    assert_eq!(ci.d, [-0.25, 0.1, 0.001, -0.002, 0.0]);
    assert_eq!(ci.k, [500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0, 1.0]);
    assert_eq!(ci.r, [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    assert_eq!(
        ci.p,
        [
            500.0, 0.0, 320.0, -60.0, 0.0, 501.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0
        ]
    );
    assert_eq!((ci.binning_x, ci.binning_y), (1, 2));
    assert_eq!(
        ci.roi,
        RegionOfInterest {
            x_offset: 10,
            y_offset: 20,
            height: 400,
            width: 600,
            do_rectify: true
        }
    );
}

/// Every fixture decodes, and every shorter prefix of it is an error that names a byte offset
/// within the prefix.
#[test]
fn every_truncation_is_an_error() {
    for &(name, decode) in ALL {
        let b = fixture(name);
        decode(&b).unwrap_or_else(|e| panic!("{name}: {e}"));
        for n in 0..b.len() {
            let e = decode(&b[..n])
                .err()
                .unwrap_or_else(|| panic!("{name} cut to {n} bytes decoded"))
                .to_string();
            let at: usize = e
                .split("at byte ")
                .nth(1)
                .and_then(|s| s.split(':').next())
                .and_then(|s| s.parse().ok())
                .unwrap_or_else(|| panic!("{name} cut to {n}: no offset in {e:?}"));
            assert!(at <= n, "{name} cut to {n}: offset {at} past the end: {e}");
        }
    }
}

/// A message of one type decoded as every other type never panics, and where the layouts
/// differ enough it fails.
#[test]
fn wrong_types_do_not_panic() {
    for &(name, _) in ALL {
        let b = fixture(name);
        for &(_, decode) in ALL {
            let _ = decode(&b);
        }
    }
    // A Dvl is not an Odometry, and an Image is not a CameraInfo.
    assert!(Odometry::decode(&fixture("dvl")).is_err());
    assert!(CameraInfo::decode(&fixture("image")).is_err());
}

fn mutate(s: &[u8], edits: &[(usize, u8, u8)]) -> Vec<u8> {
    let mut b = s.to_vec();
    for &(pos, op, byte) in edits {
        let i = pos % (b.len() + 1);
        match op % 4 {
            0 if i < b.len() => b[i] = byte,
            1 => b.insert(i, byte),
            2 if i < b.len() => {
                b.remove(i);
            }
            _ => b.truncate(i),
        }
    }
    b
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(256)))]

    #[test]
    fn random_bytes_never_panic(
        body in prop::collection::vec(any::<u8>(), 0..400),
        le in any::<bool>(),
    ) {
        // With a valid header half the time, so that the decoders get past it.
        let msg = if le { [&[0u8, 1, 0, 0][..], &body].concat() } else { body };
        for &(_, decode) in ALL {
            let _ = decode(&msg);
        }
    }

    #[test]
    fn mutated_fixtures_never_panic(
        which in 0..ALL.len(),
        edits in prop::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..6),
    ) {
        let b = mutate(&fixture(ALL[which].0), &edits);
        for &(_, decode) in ALL {
            let _ = decode(&b);
        }
    }

    #[test]
    fn huge_words_never_panic(which in 0..ALL.len(), pos in any::<usize>()) {
        // 0xffffffff over any aligned word: where it is a length or count (4 G), it must fail
        // before allocating.
        let mut b = fixture(ALL[which].0);
        let words = (b.len() - 4) / 4;
        prop_assume!(words > 0);
        let at = 4 + 4 * (pos % words);
        b[at..at + 4].copy_from_slice(&[0xff; 4]);
        let _ = (ALL[which].1)(&b);
    }
}
