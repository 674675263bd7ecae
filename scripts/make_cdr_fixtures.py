#!/usr/bin/env python3
"""Writes the CDR fixtures of tests/ros2_cdr.rs with rosbags (PyPI), an implementation
independent of dvlcal's decoder: one little-endian .cdr file per message type, plus a
big-endian Header, with the field values the tests assert.

    python3 -m venv /tmp/rb && /tmp/rb/bin/pip install rosbags
    /tmp/rb/bin/python scripts/make_cdr_fixtures.py
"""

from pathlib import Path

from importlib.metadata import version

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

OUT = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "cdr"

# marine_acoustic_msgs/msg/Dvl (apl-ocean-engineering/marine_msgs), fields only.
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

ts = get_typestore(Stores.ROS2_HUMBLE)
ts.register(get_types_from_msg(DVL_MSG, "marine_acoustic_msgs/msg/Dvl"))
T = ts.types


def header(sec, nanosec, frame):
    return T["std_msgs/msg/Header"](
        stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame
    )


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


q = quat(0.1, 0.2, 0.3, 0.9273618495495704)
pwc = T["geometry_msgs/msg/PoseWithCovariance"](pose=pose(1.0, 2.0, 3.0, q), covariance=cov(0.5))
twc = T["geometry_msgs/msg/TwistWithCovariance"](
    twist=T["geometry_msgs/msg/Twist"](linear=vec(0.25, -0.5, 0.125), angular=vec(0.01, 0.02, -0.03)),
    covariance=cov(100.0),
)

MESSAGES = {
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
            velocity_covar=np.array([1e-4 * (i + 1) for i in range(9)], dtype=np.float64),
            altitude=2.75,
            course_gnd=0.5,
            speed_gnd=0.3162,
            num_good_beams=4,
            sound_speed=1500.5,
            beam_ranges_valid=True,
            beam_velocities_valid=False,
            beam_unit_vec=[vec(0.6, 0.0, 0.8), vec(0.0, 0.6, 0.8), vec(-0.6, 0.0, 0.8), vec(0.0, -0.6, 0.8)],
            range=np.array([3.0, 3.25, 3.5, 3.75], dtype=np.float64),
            range_covar=np.array([0.5, 0.25, 0.125, 0.0625], dtype=np.float32),
            beam_quality=np.array([1.0, 2.0, 3.0, 4.0], dtype=np.float32),
            beam_velocity=np.array([0.25, -0.25, 0.5, -0.5], dtype=np.float32),
            beam_velocity_covar=np.array([0.001, 0.002, 0.003, 0.004], dtype=np.float32),
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
            data=np.array([0, 1, 2, 253, 254, 255], dtype=np.uint8),
        ),
    ),
    "compressed_image": (
        "sensor_msgs/msg/CompressedImage",
        T["sensor_msgs/msg/CompressedImage"](
            header=header(1700000006, 2, "cam1"),
            format="jpeg",
            data=np.array([0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 0xFF, 0xD9], dtype=np.uint8),
        ),
    ),
    "camera_info": (
        "sensor_msgs/msg/CameraInfo",
        T["sensor_msgs/msg/CameraInfo"](
            header=header(1700000007, 3, "cam0"),
            height=480,
            width=640,
            distortion_model="plumb_bob",
            d=np.array([-0.25, 0.1, 0.001, -0.002, 0.0], dtype=np.float64),
            k=np.array([500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0, 1.0], dtype=np.float64),
            r=np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], dtype=np.float64),
            p=np.array([500.0, 0.0, 320.0, -60.0, 0.0, 501.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0], dtype=np.float64),
            binning_x=1,
            binning_y=2,
            roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=10, y_offset=20, height=400, width=600, do_rectify=True),
        ),
    ),
}


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    for name, (typename, msg) in MESSAGES.items():
        (OUT / f"{name}.cdr").write_bytes(bytes(ts.serialize_cdr(msg, typename)))
    # The same header, big-endian.
    typename, msg = MESSAGES["header"]
    (OUT / "header_be.cdr").write_bytes(bytes(ts.serialize_cdr(msg, typename, little_endian=False)))
    print(f"rosbags {version('rosbags')}: wrote {len(MESSAGES) + 1} files to {OUT}")


if __name__ == "__main__":
    main()
