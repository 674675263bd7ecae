//! ROS 1 serialisation, images and camera info, against fixtures written by rosbags and
//! Pillow (tests/fixtures/cdr/ros1 and tests/fixtures/cdr/images, made by
//! scripts/make_cdr_fixtures.py):
//! - every ROS 1 fixture decodes to the same values as its CDR twin (tests/ros2_cdr.rs checks
//!   those against the values set in the script), with the `seq` the script set;
//! - the header alone is read from any stamped message in both serialisations;
//! - each image encoding gives the grey of a known colour scene; a Bayer mosaic of it gives
//!   the scene's grey inside the image; compressed PNG and JPEG give what the image files give;
//! - unsupported encodings, malformed sizes and odd camera models are errors that say why;
//! - truncated, random and mutated bytes are errors, never panics. Case counts are kept small
//!   for `cargo test`; raise them with `DVL_FUZZ_CASES=...`.

use std::fmt::Debug;
use std::path::{Path, PathBuf};

use dvlcal::io::bag::Serialization::{self, Cdr, Ros1};
use dvlcal::io::bag::cdr::*;
use dvlcal::io::bag::image::{
    SUPPORTED_ENCODINGS, compressed_to_gray, image_to_gray, message_to_gray,
};
use image::{DynamicImage, GrayImage, RgbImage};
use proptest::prelude::*;

/// The `seq` the script gives every ROS 1 header.
const SEQ: u32 = 7;

fn cases(n: u32) -> u32 {
    std::env::var("DVL_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(n)
}

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/cdr")
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The fixture `name` in serialisation `ser`.
fn fixture(name: &str, ser: Serialization) -> Vec<u8> {
    match ser {
        Cdr => read(&dir().join(format!("{name}.cdr"))),
        Ros1 => read(&dir().join("ros1").join(format!("{name}.ros1"))),
    }
}

/// The image fixture `name` in serialisation `ser`.
fn image_fixture(name: &str, ser: Serialization) -> Vec<u8> {
    let ext = match ser {
        Cdr => "cdr",
        Ros1 => "ros1",
    };
    read(&dir().join("images").join(format!("{name}.{ext}")))
}

/// Decodes fixture `name` as `M` from both serialisations; checks the ROS 1 headers' `seq`
/// (found by `headers`), clears it, and checks that both decodings are equal.
fn twin<M: CdrMessage + PartialEq + Debug>(name: &str, headers: fn(&mut M) -> Vec<&mut Header>) {
    let cdr: M = decode(&fixture(name, Cdr), Cdr).unwrap_or_else(|e| panic!("{name}: {e}"));
    let mut ros1: M =
        decode(&fixture(name, Ros1), Ros1).unwrap_or_else(|e| panic!("{name} (ROS 1): {e}"));
    for h in headers(&mut ros1) {
        assert_eq!(h.seq, SEQ, "{name}");
        h.seq = 0;
    }
    assert_eq!(ros1, cdr, "{name}");
}

#[test]
fn ros1_fixtures_decode_as_their_cdr_twins() {
    twin::<Header>("header", |m| vec![m]);
    twin::<StringMsg>("string", |_| vec![]);
    twin::<Vector3>("vector3", |_| vec![]);
    twin::<Quaternion>("quaternion", |_| vec![]);
    twin::<Pose>("pose", |_| vec![]);
    twin::<PoseStamped>("pose_stamped", |m| vec![&mut m.header]);
    twin::<PoseWithCovarianceStamped>("pose_with_covariance_stamped", |m| vec![&mut m.header]);
    twin::<TwistWithCovarianceStamped>("twist_with_covariance_stamped", |m| vec![&mut m.header]);
    twin::<TransformStamped>("transform_stamped", |m| vec![&mut m.header]);
    twin::<TfMessage>("tf_message", |m| {
        m.transforms.iter_mut().map(|t| &mut t.header).collect()
    });
    twin::<Odometry>("odometry", |m| vec![&mut m.header]);
    twin::<Dvl>("dvl", |m| vec![&mut m.header]);
    twin::<Image>("image", |m| vec![&mut m.header]);
    twin::<CompressedImage>("compressed_image", |m| vec![&mut m.header]);
    twin::<CameraInfo>("camera_info", |m| vec![&mut m.header]);
    // Spot checks that the twins are not both wrong in the same way.
    let s: StringMsg = decode(&fixture("string", Ros1), Ros1).unwrap();
    assert_eq!(s.data, "héllo dvl");
    let ci: CameraInfo = decode(&fixture("camera_info", Ros1), Ros1).unwrap();
    assert_eq!(ci.d, [-0.25, 0.1, 0.001, -0.002, 0.0]);
    assert_eq!(ci.k[4], 501.0);
}

#[test]
fn ros1_times_after_2038() {
    let h: Header = decode(&fixture("header_2038", Ros1), Ros1).unwrap();
    assert_eq!(h.seq, SEQ);
    assert_eq!((h.stamp.sec, h.stamp.nanosec), (3_000_000_000, 5));
    assert_eq!(h.stamp.as_nanos(), 3_000_000_000_000_000_005);
    assert_eq!(h.stamp.as_secs_f64(), 3_000_000_000.000_000_005);
    assert_eq!(h.frame_id, "late");
}

/// Decodes a whole message and returns its header.
type WholeHeader = fn(&[u8], Serialization) -> Header;

/// The stamped fixtures with the decoder of their whole header.
const STAMPED: &[(&str, WholeHeader)] = &[
    ("header", |b, s| decode::<Header>(b, s).unwrap()),
    ("pose_stamped", |b, s| {
        decode::<PoseStamped>(b, s).unwrap().header
    }),
    ("odometry", |b, s| decode::<Odometry>(b, s).unwrap().header),
    ("dvl", |b, s| decode::<Dvl>(b, s).unwrap().header),
    ("image", |b, s| decode::<Image>(b, s).unwrap().header),
    ("compressed_image", |b, s| {
        decode::<CompressedImage>(b, s).unwrap().header
    }),
    ("camera_info", |b, s| {
        decode::<CameraInfo>(b, s).unwrap().header
    }),
];

#[test]
fn the_header_alone() {
    for &(name, whole) in STAMPED {
        for ser in [Cdr, Ros1] {
            let b = fixture(name, ser);
            let h = decode_header(&b, ser).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(h, whole(&b, ser), "{name} {ser:?}");
        }
    }
    // The rest of the message is not looked at: a JPEG cut right after the header still gives
    // the stamp.
    for ser in [Cdr, Ros1] {
        let b = image_fixture("jpeg", ser);
        let full = decode_header(&b, ser).unwrap();
        let len = match ser {
            Cdr => 4 + 8 + 4 + 5,
            Ros1 => 4 + 8 + 4 + 4,
        };
        assert_eq!(decode_header(&b[..len], ser).unwrap(), full);
        assert_eq!(full.stamp.sec, 1_700_000_100);
        assert!(decode_header(&b[..len - 1], ser).is_err());
    }
}

/// Every ROS 1 fixture with its decoder, reduced to whether it succeeded.
type Decode = fn(&[u8]) -> Result<(), dvlcal::Error>;

fn ok<T>(r: dvlcal::error::Result<T>) -> Result<(), dvlcal::Error> {
    r.map(|_| ())
}

const ROS1: &[(&str, Decode)] = &[
    ("header", |b| ok(decode::<Header>(b, Ros1))),
    ("header_2038", |b| ok(decode::<Header>(b, Ros1))),
    ("string", |b| ok(decode::<StringMsg>(b, Ros1))),
    ("vector3", |b| ok(decode::<Vector3>(b, Ros1))),
    ("quaternion", |b| ok(decode::<Quaternion>(b, Ros1))),
    ("pose", |b| ok(decode::<Pose>(b, Ros1))),
    ("pose_stamped", |b| ok(decode::<PoseStamped>(b, Ros1))),
    ("pose_with_covariance_stamped", |b| {
        ok(decode::<PoseWithCovarianceStamped>(b, Ros1))
    }),
    ("twist_with_covariance_stamped", |b| {
        ok(decode::<TwistWithCovarianceStamped>(b, Ros1))
    }),
    ("transform_stamped", |b| {
        ok(decode::<TransformStamped>(b, Ros1))
    }),
    ("tf_message", |b| ok(decode::<TfMessage>(b, Ros1))),
    ("odometry", |b| ok(decode::<Odometry>(b, Ros1))),
    ("dvl", |b| ok(decode::<Dvl>(b, Ros1))),
    ("image", |b| ok(decode::<Image>(b, Ros1))),
    ("compressed_image", |b| {
        ok(decode::<CompressedImage>(b, Ros1))
    }),
    ("camera_info", |b| ok(decode::<CameraInfo>(b, Ros1))),
];

/// The byte offset an error message names.
fn offset_in(e: &str) -> usize {
    e.split("at byte ")
        .nth(1)
        .and_then(|s| s.split(':').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no offset in {e:?}"))
}

/// Every ROS 1 fixture decodes; every shorter prefix, and the fixture with one byte more, is
/// an error naming a byte offset within the bytes given.
#[test]
fn ros1_truncations_and_extra_bytes_are_errors() {
    for &(name, decode) in ROS1 {
        let b = fixture(name, Ros1);
        decode(&b).unwrap_or_else(|e| panic!("{name}: {e}"));
        for n in 0..b.len() {
            let e = decode(&b[..n])
                .err()
                .unwrap_or_else(|| panic!("{name} cut to {n} bytes decoded"))
                .to_string();
            assert!(e.starts_with("ROS 1 message: "), "{name}: {e}");
            assert!(offset_in(&e) <= n, "{name} cut to {n}: {e}");
        }
        let longer = [b.as_slice(), &[0]].concat();
        let e = decode(&longer).unwrap_err().to_string();
        assert_eq!(offset_in(&e), b.len(), "{name}: {e}");
    }
}

/// The grey the `image` crate makes of RGB pixels: what an image file of them gives.
fn crate_gray(w: u32, h: u32, rgb: Vec<u8>) -> GrayImage {
    DynamicImage::ImageRgb8(RgbImage::from_raw(w, h, rgb).unwrap()).into_luma8()
}

/// The 6x4 scene of the raw-image fixtures.
fn scene() -> Vec<u8> {
    read(&dir().join("images/scene.rgb"))
}

/// Converts image fixture `name` in both serialisations, checks they agree, and returns the
/// grey image.
fn gray_of(name: &str, type_name: &str) -> GrayImage {
    let cdr = message_to_gray(&image_fixture(name, Cdr), Cdr, type_name)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let ros1 = message_to_gray(&image_fixture(name, Ros1), Ros1, type_name)
        .unwrap_or_else(|e| panic!("{name} (ROS 1): {e}"));
    assert_eq!(cdr, ros1, "{name}");
    cdr
}

#[test]
fn every_encoding_gives_the_grey_of_the_scene() {
    let rgb = scene();
    assert_eq!(rgb.len(), 6 * 4 * 3);
    let red: Vec<u8> = rgb.chunks(3).map(|p| p[0]).collect();
    let grey = crate_gray(6, 4, rgb.clone());
    // The crate's grey is luma with the sRGB weights.
    for (g, p) in grey.as_raw().iter().zip(rgb.chunks(3)) {
        let l = 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]);
        assert!((f64::from(*g) - l).abs() <= 0.501, "{g} vs {l}");
    }
    // mono8 and 8UC1 hold R; mono16 holds R * 256 + G, whose high byte is R.
    for name in ["mono8", "mono8_padded", "8uc1", "mono16", "mono16_be"] {
        let g = gray_of(name, "sensor_msgs/Image");
        assert_eq!(g.dimensions(), (6, 4), "{name}");
        assert_eq!(g.as_raw(), &red, "{name}");
    }
    for name in ["rgb8", "bgr8", "bgr8_padded", "rgba8", "bgra8"] {
        assert_eq!(gray_of(name, "sensor_msgs/msg/Image"), grey, "{name}");
    }
    // The owned message converts as the borrowed one does.
    let m: Image = decode(&image_fixture("bgr8_padded", Cdr), Cdr).unwrap();
    assert_eq!(m.step, 24);
    assert_eq!(image_to_gray(&m).unwrap(), grey);
}

#[test]
fn bayer_gives_the_grey_of_the_scene() {
    let grey = crate_gray(6, 4, scene());
    for pattern in ["rggb", "bggr", "gbrg", "grbg"] {
        let name = format!("bayer_{pattern}8");
        let g = gray_of(&name, "sensor_msgs/Image");
        for y in 0..4 {
            for x in 0..6 {
                let (got, want) = (g.get_pixel(x, y)[0], grey.get_pixel(x, y)[0]);
                if (1..5).contains(&x) && (1..3).contains(&y) {
                    // Each channel is linear in x and y: bilinear interpolation is exact inside.
                    assert_eq!(got, want, "{name} at {x},{y}");
                } else {
                    // At the border the neighbourhood is one-sided: off by a step at most.
                    assert!(
                        got.abs_diff(want) <= 30,
                        "{name} at {x},{y}: {got} vs {want}"
                    );
                }
            }
        }
    }
}

#[test]
fn unsupported_encodings_are_errors() {
    for (name, enc) in [
        ("unsupported_32fc1", "32FC1"),
        ("unsupported_yuv422", "yuv422"),
        ("unsupported_16uc3", "16UC3"),
    ] {
        for ser in [Cdr, Ros1] {
            let e = message_to_gray(&image_fixture(name, ser), ser, "sensor_msgs/Image")
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("{enc:?}")), "{e}");
            for s in SUPPORTED_ENCODINGS {
                assert!(e.contains(s), "{e} lacks {s}");
            }
        }
    }
    let e = message_to_gray(&fixture("header", Cdr), Cdr, "std_msgs/msg/Header")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("std_msgs/Header") && e.contains("not images"),
        "{e}"
    );
}

#[test]
fn malformed_sizes_are_errors() {
    let good: Image = decode(&image_fixture("rgb8", Cdr), Cdr).unwrap();
    let err = |f: &dyn Fn(&mut Image)| {
        let mut m = good.clone();
        f(&mut m);
        image_to_gray(&m).unwrap_err().to_string()
    };
    assert!(err(&|m| m.step = 17).contains("less than the 18 bytes of a row"));
    assert!(err(&|m| m.data.truncate(71)).contains("needs 72 bytes"));
    assert!(err(&|m| m.step = 20).contains("needs 80 bytes"));
    assert!(err(&|m| m.height = 5).contains("needs 90 bytes"));
    assert!(err(&|m| m.width = 0).contains("without pixels"));
    assert!(err(&|m| m.height = 0).contains("without pixels"));
    assert!(err(&|m| m.width = 20_001).contains("larger than"));
    assert!(err(&|m| m.height = u32::MAX).contains("larger than"));
    assert!(err(&|m| m.step = u32::MAX).contains("needs"));
    // Extra bytes after the last row are accepted, as padding is.
    let mut m = good.clone();
    m.data.extend_from_slice(&[1, 2, 3]);
    assert_eq!(image_to_gray(&m).unwrap(), image_to_gray(&good).unwrap());
}

#[test]
fn compressed_images_decode_as_image_files() {
    let scene = read(&dir().join("images/compressed_scene.rgb"));
    let grey = crate_gray(16, 8, scene);
    for (name, format) in [
        ("png", "rgb8; png compressed rgb8"),
        ("jpeg", "bgr8; jpeg compressed bgr8"),
    ] {
        let g = gray_of(name, "sensor_msgs/CompressedImage");
        let m: CompressedImage = decode(&image_fixture(name, Ros1), Ros1).unwrap();
        assert_eq!(m.format, format);
        // The same bytes as an image file of a dataset folder.
        let file = dvlcal::io::image::decode_gray(&m.data, Path::new("frame")).unwrap();
        assert_eq!(g, file, "{name}");
        assert_eq!(compressed_to_gray(&m).unwrap(), g, "{name}");
        if name == "png" {
            assert_eq!(g, grey, "a PNG is lossless");
        } else {
            let worst = g
                .as_raw()
                .iter()
                .zip(grey.as_raw())
                .map(|(a, b)| a.abs_diff(*b))
                .max()
                .unwrap();
            assert!(worst <= 8, "the JPEG is {worst} grey levels off the scene");
        }
        // The format string does not matter, the bytes do.
        let mut other = m.clone();
        other.format = "whatever".into();
        assert_eq!(compressed_to_gray(&other).unwrap(), g);
    }
    let e = message_to_gray(
        &image_fixture("compressed_depth", Cdr),
        Cdr,
        "sensor_msgs/CompressedImage",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("compressedDepth") && e.contains("not supported"),
        "{e}"
    );
    // Bytes that are no image file, a JPEG cut short, a PNG cut short.
    let m: CompressedImage = decode(&image_fixture("jpeg", Cdr), Cdr).unwrap();
    let with = |data: &[u8]| CompressedImage {
        data: data.to_vec(),
        ..m.clone()
    };
    let e = compressed_to_gray(&with(b"GIF89a...."))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("neither a JPEG nor a PNG") && e.contains("47 49 46"),
        "{e}"
    );
    assert!(compressed_to_gray(&with(&[])).is_err());
    let cut = &m.data[..m.data.len() / 2];
    let e = compressed_to_gray(&with(cut)).unwrap_err().to_string();
    assert!(e.contains("cut short"), "{e}");
    let png: CompressedImage = decode(&image_fixture("png", Cdr), Cdr).unwrap();
    assert!(compressed_to_gray(&with(&png.data[..png.data.len() - 20])).is_err());
}

#[test]
fn camera_info_model() {
    for ser in [Cdr, Ros1] {
        let ci: CameraInfo = decode(&fixture("camera_info", ser), ser).unwrap();
        // The fixture is binned 1x2 with a region of interest: not a Kalibr camera.
        let e = ci.model().unwrap_err().to_string();
        assert!(e.contains("binning 1x2"), "{e}");
        let mut whole = ci.clone();
        whole.binning_y = 1;
        whole.roi = RegionOfInterest::default();
        let m = whole.model().unwrap();
        assert_eq!((m.width, m.height), (640, 480));
        assert_eq!((m.fu, m.fv, m.pu, m.pv), (500.0, 501.0, 320.0, 240.0));
        assert_eq!(m.distortion.kalibr_name(), "radtan");
        assert_eq!(m.distortion.coeffs(), [-0.25, 0.1, 0.001, -0.002]);
        let mut k3 = whole.clone();
        k3.d[4] = 0.01;
        let e = k3.model().unwrap_err().to_string();
        assert!(e.contains("Kalibr's radtan has 4 coefficients"), "{e}");
        let mut raw = whole.clone();
        raw.k = [0.0; 9];
        assert!(
            raw.model()
                .unwrap_err()
                .to_string()
                .contains("not calibrated")
        );
        let mut odd = whole;
        odd.distortion_model = "mei".into();
        assert!(odd.model().unwrap_err().to_string().contains("\"mei\""));
    }
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

/// The image fixtures the mutation test starts from.
const IMAGES: &[&str] = &[
    "mono8_padded",
    "mono16_be",
    "bgr8_padded",
    "rgba8",
    "bayer_grbg8",
    "png",
    "jpeg",
];

/// Everything the tests decode, on `b` in both serialisations; results are ignored.
fn decode_everything(b: &[u8]) {
    for ser in [Cdr, Ros1] {
        let _ = decode_header(b, ser);
        let _ = decode::<Header>(b, ser);
        let _ = decode::<TfMessage>(b, ser);
        let _ = decode::<Odometry>(b, ser);
        let _ = decode::<Dvl>(b, ser);
        let _ = decode::<PoseWithCovarianceStamped>(b, ser);
        let _ = decode::<CameraInfo>(b, ser).map(|c| c.model());
        let _ = message_to_gray(b, ser, "sensor_msgs/Image");
        let _ = message_to_gray(b, ser, "sensor_msgs/CompressedImage");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(256)))]

    #[test]
    fn random_bytes_never_panic(
        body in prop::collection::vec(any::<u8>(), 0..400),
        le in any::<bool>(),
    ) {
        let msg = if le { [&[0u8, 1, 0, 0][..], &body].concat() } else { body };
        decode_everything(&msg);
        for &(_, decode) in ROS1 {
            let _ = decode(&msg);
        }
    }

    #[test]
    fn mutated_ros1_fixtures_never_panic(
        which in 0..ROS1.len(),
        edits in prop::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..6),
    ) {
        let b = mutate(&fixture(ROS1[which].0, Ros1), &edits);
        for &(_, decode) in ROS1 {
            let _ = decode(&b);
        }
        decode_everything(&b);
    }

    #[test]
    fn mutated_images_never_panic(
        which in 0..IMAGES.len(),
        ros1 in any::<bool>(),
        edits in prop::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..6),
    ) {
        let ser = if ros1 { Ros1 } else { Cdr };
        let b = mutate(&image_fixture(IMAGES[which], ser), &edits);
        decode_everything(&b);
    }

    #[test]
    fn any_image_fields_never_panic(
        width in prop_oneof![0u32..10, any::<u32>()],
        height in prop_oneof![0u32..10, any::<u32>()],
        step in prop_oneof![0u32..50, any::<u32>()],
        enc in 0..SUPPORTED_ENCODINGS.len() + 1,
        big in any::<u8>(),
        data in prop::collection::vec(any::<u8>(), 0..300),
    ) {
        let m = Image {
            width,
            height,
            step,
            is_bigendian: big,
            encoding: SUPPORTED_ENCODINGS.get(enc).unwrap_or(&"16UC1").to_string(),
            data,
            ..Image::default()
        };
        if let Ok(g) = image_to_gray(&m) {
            prop_assert_eq!(g.dimensions(), (width, height));
        }
    }
}
