#!/usr/bin/env python3
"""Writes the message fixtures of tests/ros2_cdr.rs and tests/ros_messages.rs with rosbags
(PyPI), an implementation independent of dvlcal's decoder, and Pillow for the compressed
images:

- tests/fixtures/cdr/NAME.cdr: one little-endian CDR message per type (plus a big-endian
  Header), with the field values the tests assert;
- tests/fixtures/cdr/ros1/NAME.ros1: the same messages in ROS 1 serialisation (every Header
  with seq = 7), plus a Header stamped after 2038;
- tests/fixtures/cdr/images/: sensor_msgs/Image messages of a known 6x4 colour scene in every
  encoding dvlcal converts (and a few it does not), CompressedImage messages holding a PNG and
  a JPEG of a known 16x8 scene, each as NAME.cdr and NAME.ros1, and the scenes' RGB pixels;
- fuzz/corpus/ros_msg/: all of the above, the seeds of the ros_msg fuzz target.

Everything is deterministic: the same package versions write the same bytes.

    python3 -m venv /tmp/rb && /tmp/rb/bin/pip install rosbags pillow
    /tmp/rb/bin/python scripts/make_cdr_fixtures.py
"""

import io
import shutil
from importlib.metadata import version
from pathlib import Path

import numpy as np
from PIL import Image as PilImage
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "fixtures" / "cdr"
OUT_ROS1 = OUT / "ros1"
OUT_IMAGES = OUT / "images"
CORPUS = ROOT / "fuzz" / "corpus" / "ros_msg"

# marine_acoustic_msgs/msg/Dvl (apl-ocean-engineering/marine_msgs), fields only. The package
# exists in ROS 2 only; the ROS 1 fixture serialises the same field list.
DVL_MSG = """
std_msgs/Header header
uint8 velocity_mode
uint8 dvl_type
geometry_msgs/Vector3 velocity
float64[9] velocity_covar
float64 altitude
float64 course_gnd
float64 speed_gnd
uint8 num_good_beams
float32 sound_speed
bool beam_ranges_valid
bool beam_velocities_valid
geometry_msgs/Vector3[4] beam_unit_vec
float64[4] range
float32[4] range_covar
float32[4] beam_quality
float32[4] beam_velocity
float32[4] beam_velocity_covar
"""

# tf2_msgs/TFMessage, missing from rosbags' ROS 1 type store.
TF_MSG = "geometry_msgs/TransformStamped[] transforms\n"

# The seq of every ROS 1 Header.
SEQ = 7

ts2 = get_typestore(Stores.ROS2_HUMBLE)
ts2.register(get_types_from_msg(DVL_MSG, "marine_acoustic_msgs/msg/Dvl"))
ts1 = get_typestore(Stores.ROS1_NOETIC)
ts1.register(get_types_from_msg(DVL_MSG, "marine_acoustic_msgs/msg/Dvl"))
ts1.register(get_types_from_msg(TF_MSG, "tf2_msgs/msg/TFMessage"))


def messages(ts, ros1):
    """Every fixture message, built with the type store `ts` (ROS 1 when `ros1`)."""
    T = ts.types

    def header(sec, nanosec, frame):
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
        if ros1:
            return T["std_msgs/msg/Header"](seq=SEQ, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def vec(x, y, z):
        return T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    def quat(x, y, z, w):
        return T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)

    def pose(px, py, pz, q):
        return T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=px, y=py, z=pz), orientation=q)

    def cov(base):
        return np.array([base + i for i in range(36)], dtype=np.float64)

    def transform(sec, parent, child, t, q):
        return T["geometry_msgs/msg/TransformStamped"](
            header=header(sec, 5, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](translation=vec(*t), rotation=quat(*q)),
        )

    def f64(v):
        return np.array(v, dtype=np.float64)

    def f32(v):
        return np.array(v, dtype=np.float32)

    def u8(v):
        return np.array(v, dtype=np.uint8)

    q = quat(0.1, 0.2, 0.3, 0.9273618495495704)
    pwc = T["geometry_msgs/msg/PoseWithCovariance"](pose=pose(1.0, 2.0, 3.0, q), covariance=cov(0.5))
    twc = T["geometry_msgs/msg/TwistWithCovariance"](
        twist=T["geometry_msgs/msg/Twist"](linear=vec(0.25, -0.5, 0.125), angular=vec(0.01, 0.02, -0.03)),
        covariance=cov(100.0),
    )
    # ROS 1 names CameraInfo's matrices D K R P, ROS 2 d k r p.
    dkrp = ["D", "K", "R", "P"] if ros1 else ["d", "k", "r", "p"]
    camera_info = dict(
        header=header(1700000007, 3, "cam0"),
        height=480,
        width=640,
        distortion_model="plumb_bob",
        binning_x=1,
        binning_y=2,
        roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=10, y_offset=20, height=400, width=600, do_rectify=True),
    )
    for key, value in zip(
        dkrp,
        [
            f64([-0.25, 0.1, 0.001, -0.002, 0.0]),
            f64([500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0, 1.0]),
            f64([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            f64([500.0, 0.0, 320.0, -60.0, 0.0, 501.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
        ],
    ):
        camera_info[key] = value

    return {
        "header": ("std_msgs/msg/Header", header(1700000000, 123456789, "camera")),
        "string": ("std_msgs/msg/String", T["std_msgs/msg/String"](data="héllo dvl")),
        "vector3": ("geometry_msgs/msg/Vector3", vec(1.5, -2.25, 3.125)),
        "quaternion": ("geometry_msgs/msg/Quaternion", q),
        "pose": ("geometry_msgs/msg/Pose", pose(4.0, 5.0, 6.0, q)),
        "pose_stamped": (
            "geometry_msgs/msg/PoseStamped",
            T["geometry_msgs/msg/PoseStamped"](header=header(12, 34, "map"), pose=pose(-1.0, 0.5, 2.0, q)),
        ),
        "pose_with_covariance_stamped": (
            "geometry_msgs/msg/PoseWithCovarianceStamped",
            T["geometry_msgs/msg/PoseWithCovarianceStamped"](header=header(1700000001, 500, "odom"), pose=pwc),
        ),
        "twist_with_covariance_stamped": (
            "geometry_msgs/msg/TwistWithCovarianceStamped",
            T["geometry_msgs/msg/TwistWithCovarianceStamped"](header=header(1700000002, 7, "dvl"), twist=twc),
        ),
        "transform_stamped": (
            "geometry_msgs/msg/TransformStamped",
            transform(100, "base_link", "dvl_link", (0.1, 0.2, -0.3), (0.0, 0.0, 0.0, 1.0)),
        ),
        "tf_message": (
            "tf2_msgs/msg/TFMessage",
            T["tf2_msgs/msg/TFMessage"](
                transforms=[
                    transform(200, "base_link", "cam0", (1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
                    transform(201, "cam0", "cam1", (0.12, 0.0, 0.0), (0.5, 0.5, 0.5, 0.5)),
                ]
            ),
        ),
        "odometry": (
            "nav_msgs/msg/Odometry",
            T["nav_msgs/msg/Odometry"](header=header(1700000003, 999999999, "odom"), child_frame_id="dvl", pose=pwc, twist=twc),
        ),
        "dvl": (
            "marine_acoustic_msgs/msg/Dvl",
            T["marine_acoustic_msgs/msg/Dvl"](
                header=header(1700000004, 250000000, "dvl_link"),
                velocity_mode=1,
                dvl_type=2,
                velocity=vec(0.3, -0.1, 0.05),
                velocity_covar=f64([1e-4 * (i + 1) for i in range(9)]),
                altitude=2.75,
                course_gnd=0.5,
                speed_gnd=0.3162,
                num_good_beams=4,
                sound_speed=1500.5,
                beam_ranges_valid=True,
                beam_velocities_valid=False,
                beam_unit_vec=[vec(0.6, 0.0, 0.8), vec(0.0, 0.6, 0.8), vec(-0.6, 0.0, 0.8), vec(0.0, -0.6, 0.8)],
                range=f64([3.0, 3.25, 3.5, 3.75]),
                range_covar=f32([0.5, 0.25, 0.125, 0.0625]),
                beam_quality=f32([1.0, 2.0, 3.0, 4.0]),
                beam_velocity=f32([0.25, -0.25, 0.5, -0.5]),
                beam_velocity_covar=f32([0.001, 0.002, 0.003, 0.004]),
            ),
        ),
        "image": (
            "sensor_msgs/msg/Image",
            T["sensor_msgs/msg/Image"](
                header=header(1700000005, 1, "cam0"),
                height=2,
                width=3,
                encoding="mono8",
                is_bigendian=0,
                step=3,
                data=u8([0, 1, 2, 253, 254, 255]),
            ),
        ),
        "compressed_image": (
            "sensor_msgs/msg/CompressedImage",
            T["sensor_msgs/msg/CompressedImage"](
                header=header(1700000006, 2, "cam1"),
                format="jpeg",
                data=u8([0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 0xFF, 0xD9]),
            ),
        ),
        "camera_info": ("sensor_msgs/msg/CameraInfo", T["sensor_msgs/msg/CameraInfo"](**camera_info)),
    }


# The raw-image scene: 6x4 pixels, each channel linear in x and y, so that a bilinear demosaic
# recovers the interior exactly.
W, H = 6, 4


def scene_rgb():
    """The 6x4 scene as an H x W x 3 uint8 array."""
    y, x = np.mgrid[0:H, 0:W]
    r = 20 + 40 * x + 5 * y
    g = 200 - 30 * x + 12 * y
    b = 30 + 10 * x + 25 * y
    return np.stack([r, g, b], axis=-1).astype(np.uint8)


# Colour of each position of the top-left 2x2 block of each Bayer pattern (0 R, 1 G, 2 B).
BAYER = {"rggb": (0, 1, 1, 2), "bggr": (2, 1, 1, 0), "gbrg": (1, 2, 0, 1), "grbg": (1, 0, 2, 1)}


def raw_images():
    """(name, encoding, is_bigendian, bytes per pixel, pixel rows as H x (W*bpp) uint8, row
    padding in bytes) of every raw Image fixture."""
    rgb = scene_rgb()
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    alpha = (255 - 10 * np.arange(W))[None, :].repeat(H, axis=0).astype(np.uint8)
    # mono16: the value R*256 + G, so the high byte is R.
    v16 = r.astype(np.uint16) * 256 + g.astype(np.uint16)
    out = [
        ("mono8", "mono8", 0, 1, r, 0),
        ("mono8_padded", "mono8", 0, 1, r, 2),
        ("8uc1", "8UC1", 0, 1, r, 0),
        ("mono16", "mono16", 0, 2, v16.astype("<u2").view(np.uint8).reshape(H, 2 * W), 0),
        ("mono16_be", "mono16", 1, 2, v16.astype(">u2").view(np.uint8).reshape(H, 2 * W), 0),
        ("rgb8", "rgb8", 0, 3, rgb.reshape(H, 3 * W), 0),
        ("bgr8", "bgr8", 0, 3, rgb[..., ::-1].reshape(H, 3 * W), 0),
        ("bgr8_padded", "bgr8", 0, 3, rgb[..., ::-1].reshape(H, 3 * W), 6),
        ("rgba8", "rgba8", 0, 4, np.dstack([rgb, alpha]).reshape(H, 4 * W), 0),
        ("bgra8", "bgra8", 0, 4, np.dstack([rgb[..., ::-1], alpha]).reshape(H, 4 * W), 0),
    ]
    y, x = np.mgrid[0:H, 0:W]
    for name, pattern in BAYER.items():
        channel = np.array(pattern)[(y % 2) * 2 + x % 2]
        mosaic = np.take_along_axis(rgb, channel[..., None], axis=-1)[..., 0]
        out.append((f"bayer_{name}8", f"bayer_{name}8", 0, 1, mosaic, 0))
    # Encodings dvlcal does not convert, with consistent sizes.
    out.append(("unsupported_32fc1", "32FC1", 0, 4, np.zeros((H, 4 * W), np.uint8), 0))
    out.append(("unsupported_yuv422", "yuv422", 0, 2, np.zeros((H, 2 * W), np.uint8), 0))
    out.append(("unsupported_16uc3", "16UC3", 0, 6, np.zeros((H, 6 * W), np.uint8), 0))
    return out


# The compressed-image scene: 16x8, smooth, so that a JPEG stays close to it.
CW, CH = 16, 8


def compressed_scene():
    y, x = np.mgrid[0:CH, 0:CW]
    r = 10 + 14 * x
    g = 240 - 9 * x - 10 * y
    b = 40 + 20 * y
    return np.stack([r, g, b], axis=-1).astype(np.uint8)


def compressed_files():
    """(name, format, file bytes) of the CompressedImage fixtures."""
    img = PilImage.fromarray(compressed_scene(), "RGB")
    png = io.BytesIO()
    img.save(png, format="PNG")
    jpeg = io.BytesIO()
    img.save(jpeg, format="JPEG", quality=95, subsampling=0)
    # compressed_depth_image_transport: a 12-byte configuration header, then a 16-bit PNG.
    depth = io.BytesIO()
    PilImage.fromarray(np.full((CH, CW), 1000, np.uint16)).save(depth, format="PNG")
    return [
        ("png", "rgb8; png compressed rgb8", png.getvalue()),
        ("jpeg", "bgr8; jpeg compressed bgr8", jpeg.getvalue()),
        ("compressed_depth", "16UC1; compressedDepth png", bytes(12) + depth.getvalue()),
    ]


def image_messages(ts, ros1):
    """The image fixtures as messages of the type store `ts`."""
    T = ts.types

    def header(nanosec):
        stamp = T["builtin_interfaces/msg/Time"](sec=1700000100, nanosec=nanosec)
        if ros1:
            return T["std_msgs/msg/Header"](seq=SEQ, stamp=stamp, frame_id="cam0")
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id="cam0")

    out = {}
    for i, (name, encoding, bigendian, bpp, rows, pad) in enumerate(raw_images()):
        padded = np.hstack([rows, np.full((H, pad), 0xEE, np.uint8)])
        out[name] = (
            "sensor_msgs/msg/Image",
            T["sensor_msgs/msg/Image"](
                header=header(i),
                height=H,
                width=W,
                encoding=encoding,
                is_bigendian=bigendian,
                step=W * bpp + pad,
                data=padded.reshape(-1).copy(),
            ),
        )
    for i, (name, fmt, data) in enumerate(compressed_files()):
        out[name] = (
            "sensor_msgs/msg/CompressedImage",
            T["sensor_msgs/msg/CompressedImage"](
                header=header(100 + i), format=fmt, data=np.frombuffer(data, dtype=np.uint8).copy()
            ),
        )
    return out


def write(path, data):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(bytes(data))


def main():
    n = 0
    msgs2 = messages(ts2, ros1=False)
    for name, (typename, msg) in msgs2.items():
        write(OUT / f"{name}.cdr", ts2.serialize_cdr(msg, typename))
        n += 1
    # The same header, big-endian.
    typename, msg = msgs2["header"]
    write(OUT / "header_be.cdr", ts2.serialize_cdr(msg, typename, little_endian=False))
    n += 1

    for name, (typename, msg) in messages(ts1, ros1=True).items():
        write(OUT_ROS1 / f"{name}.ros1", ts1.serialize_ros1(msg, typename))
        n += 1
    # A ROS 1 stamp after 2038: second 3000000000 as an unsigned 32-bit number. rosbags holds
    # ROS 1 seconds as int32, whose two's complement -1294967296 has the same four bytes.
    T = ts1.types
    late = T["std_msgs/msg/Header"](
        seq=SEQ, stamp=T["builtin_interfaces/msg/Time"](sec=3000000000 - 2**32, nanosec=5), frame_id="late"
    )
    write(OUT_ROS1 / "header_2038.ros1", ts1.serialize_ros1(late, "std_msgs/msg/Header"))
    n += 1

    for ts, ros1, ext in [(ts2, False, "cdr"), (ts1, True, "ros1")]:
        for name, (typename, msg) in image_messages(ts, ros1).items():
            data = ts.serialize_ros1(msg, typename) if ros1 else ts.serialize_cdr(msg, typename)
            write(OUT_IMAGES / f"{name}.{ext}", data)
            n += 1
    write(OUT_IMAGES / "scene.rgb", scene_rgb().tobytes())
    write(OUT_IMAGES / "compressed_scene.rgb", compressed_scene().tobytes())
    n += 2

    # The fuzz seeds: every message fixture, flat.
    if CORPUS.exists():
        shutil.rmtree(CORPUS)
    CORPUS.mkdir(parents=True)
    for sub, prefix in [(OUT, ""), (OUT_ROS1, "ros1_"), (OUT_IMAGES, "image_")]:
        for f in sorted(sub.iterdir()):
            if f.suffix in (".cdr", ".ros1"):
                shutil.copyfile(f, CORPUS / f"{prefix}{f.name}")
    print(
        f"rosbags {version('rosbags')}, pillow {version('pillow')}, numpy {version('numpy')}: "
        f"wrote {n} files under {OUT} and the seeds in {CORPUS}"
    )


if __name__ == "__main__":
    main()
