#!/usr/bin/env python3
"""Writes the IMU bag fixtures of tests/imu_bags.rs into tests/fixtures/imu_bags/ with rosbags
(PyPI), a pure-Python writer and serialiser independent of dvlcal's bag readers.

    python3 -m venv /tmp/rbs && /tmp/rbs/bin/pip install rosbags==0.11.9 numpy
    /tmp/rbs/bin/python scripts/make_imu_bag_fixtures.py

Deterministic: no clock, no randomness; the same rosbags version writes the same bytes.

The good bags hold one sensor_msgs/Imu topic, /vn100/data (a name without "imu": the type finds
it), N = 301 messages at 200 Hz, beside /imu/temperature (sensor_msgs/Temperature, 10 Hz: a
name with "imu" but another type). Message k (k = 0..N-1), with s = 0.005 k seconds:

    header.stamp     = T0_NS + 5_000_000 k ns          (T0_NS = 1712345678.123456789 s)
    record time      = stamp + 3 ms + 0.5 ms (k % 3)   (so header and record times differ)
    angular_velocity = ( 0.3 sin(2 pi 0.5 s),  0.2 cos(2 pi 0.25 s), -0.1 + 0.001 k )   rad/s
    linear_accel.    = ( 0.5 sin(2 pi s),     -0.25,                  9.80665 + 0.2 cos(pi s) )
    orientation      = rotation of 0.05 s rad about z
    covariances      = diag 1e-3 (orientation), 1e-6 (angular velocity), 4e-4 (acceleration)
    frame_id         = imu_link

Files written (replacing earlier output; README.md is kept):

  imu.bag            ROS 1 bag, lz4 chunks
  imu_sqlite/        ROS 2 bag folder, sqlite3 storage (metadata.yaml + imu_sqlite.db3)
  imu.mcap           bare ROS 2 MCAP file, zstd chunks
  big_endian.mcap    bare MCAP: the first 40 messages of /vn100/data, CDR big-endian
  two_imus.mcap      bare MCAP: /imu0/data and /imu1/data, 20 messages each (imu1's gyro x is
                     the formula's plus 1 rad/s)
  bad_imu.bag        ROS 1 bag, and
  bad_imu.mcap       bare MCAP: /imu/data, 60 messages of the formula at 200 Hz, except
                     (1-based message numbers on the topic):
                       10  cut to 100 bytes (does not decode)
                       20  angular_velocity.y = NaN
                       30  stamp 47.5 ms before message 29's (time goes backwards)
                       40  the stamp of message 39 (a repeated time stamp)
                       45  stamp zero (record time used instead)

The camera + DVL + IMU bag packs a recording that `dvlcal simulate` made (its numbers are the
simulator's, the packing is this script's and rosbags'; the binary is needed while the script
runs, not by the tests):

    dvlcal simulate --imu --duration 30 --imu-rate 100 --seed 21 --out TMP

  cam_dvl_imu.mcap   bare MCAP, zstd chunks: /mocap/rig/pose (geometry_msgs/PoseStamped, frame
                     world, header stamp = the TUM line's time exactly), /dvl/velocity_report
                     (marine_acoustic_msgs/Dvl as Water Linked's ROS 2 driver fills it from a
                     velocity report, header stamp = time_of_validity) and /imu/data
                     (sensor_msgs/Imu, header stamp = the CSV's ns, orientation unknown:
                     orientation_covariance[0] = -1); record times 2 ms after the stamps
  dvl_imu.mcap       the same without the pose topic: a DVL and an IMU, no camera data
  cam_dvl_imu_truth/ the recording's imu.yaml (Kalibr noise), truth/imu.yaml and
                     truth/calibration.yaml, copied as the simulator wrote them
"""

import argparse
import json
import math
import shutil
import subprocess
import tempfile
from importlib.metadata import version
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

OUT = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "imu_bags"

IMU = "sensor_msgs/msg/Imu"
TEMP = "sensor_msgs/msg/Temperature"
T0_NS = 1_712_345_678_123_456_789
STEP_NS = 5_000_000
N = 301
BAD_N = 60

TS2 = get_typestore(Stores.ROS2_HUMBLE)
TS1 = get_typestore(Stores.ROS1_NOETIC)

# marine_acoustic_msgs/msg/Dvl (apl-ocean-engineering/marine_msgs), fields only, as in
# scripts/make_sample_bags.py.
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
DVL = "marine_acoustic_msgs/msg/Dvl"
TS2.register(get_types_from_msg(DVL_MSG, DVL))
# The A50 beam directions the Water Linked ROS 2 driver fills in (22.5 deg off z, 45 deg about z).
_A, _C = 0.6532814824381883, 0.38268343236508984
A50_BEAMS = [(-_A, _A, _C), (-_A, -_A, _C), (_A, -_A, _C), (_A, _A, _C)]
SIM_ARGS = ["simulate", "--imu", "--duration", "30", "--imu-rate", "100", "--seed", "21"]
LATENCY_NS = 2_000_000


def gyro(k):
    s = 0.005 * k
    return (0.3 * math.sin(2 * math.pi * 0.5 * s), 0.2 * math.cos(2 * math.pi * 0.25 * s), -0.1 + 0.001 * k)


def accel(k):
    s = 0.005 * k
    return (0.5 * math.sin(2 * math.pi * s), -0.25, 9.80665 + 0.2 * math.cos(math.pi * s))


def record_ns(k):
    return T0_NS + STEP_NS * k + 3_000_000 + 500_000 * (k % 3)


def header(ts, ns, frame):
    T = ts.types
    stamp = T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    if "seq" in T["std_msgs/msg/Header"].__dataclass_fields__:
        return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
    return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)


def imu_msg(ts, k, stamp_ns, g=None, a=None):
    T = ts.types
    g = gyro(k) if g is None else g
    a = accel(k) if a is None else a
    half = 0.5 * 0.05 * 0.005 * k
    vec = T["geometry_msgs/msg/Vector3"]
    return T[IMU](
        header=header(ts, stamp_ns, "imu_link"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(half), w=math.cos(half)),
        orientation_covariance=np.diag([1e-3] * 3).reshape(9).astype(np.float64),
        angular_velocity=vec(x=g[0], y=g[1], z=g[2]),
        angular_velocity_covariance=np.diag([1e-6] * 3).reshape(9).astype(np.float64),
        linear_acceleration=vec(x=a[0], y=a[1], z=a[2]),
        linear_acceleration_covariance=np.diag([4e-4] * 3).reshape(9).astype(np.float64),
    )


def good(ts, ser):
    """(topic, type, record_ns, bytes) in record order: the Imu topic and the temperature."""
    out = []
    for k in range(N):
        out.append(("/vn100/data", IMU, record_ns(k), ser(imu_msg(ts, k, T0_NS + STEP_NS * k), IMU)))
        if k % 20 == 0:
            t = ts.types[TEMP](header=header(ts, T0_NS + STEP_NS * k, "imu_link"), temperature=21.5, variance=0.0)
            out.append(("/imu/temperature", TEMP, record_ns(k) + 100_000, ser(t, TEMP)))
    return out


def bad(ts, ser):
    """/imu/data with the damage listed in the module's text (k is 0-based: message k + 1)."""
    out = []
    for k in range(BAD_N):
        stamp = T0_NS + STEP_NS * k
        g = None
        if k + 1 == 20:
            g = (gyro(k)[0], float("nan"), gyro(k)[2])
        if k + 1 == 30:
            stamp = T0_NS + STEP_NS * (k - 1) - 47_500_000
        if k + 1 == 40:
            stamp = T0_NS + STEP_NS * (k - 1)
        if k + 1 == 45:
            stamp = 0
        data = bytes(ser(imu_msg(ts, k, stamp, g=g), IMU))
        if k + 1 == 10:
            data = data[:100]
        out.append(("/imu/data", IMU, record_ns(k), data))
    return out


def two(ts, ser):
    out = []
    for k in range(20):
        stamp = T0_NS + STEP_NS * k
        out.append(("/imu0/data", IMU, record_ns(k), ser(imu_msg(ts, k, stamp), IMU)))
        g = gyro(k)
        out.append(("/imu1/data", IMU, record_ns(k) + 1000, ser(imu_msg(ts, k, stamp, g=(g[0] + 1.0, g[1], g[2])), IMU)))
    return out


def cdr_le(m, t):
    return bytes(TS2.serialize_cdr(m, t))


def cdr_be(m, t):
    return bytes(TS2.serialize_cdr(m, t, little_endian=False))


def ros1(m, t):
    return bytes(TS1.serialize_ros1(m, t))


def write_ros2(folder, storage, msgs, compress=False):
    w = Ros2Writer(folder, version=9, storage_plugin=storage)
    if compress:
        w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    w.open()
    conns = {}
    for topic, tp, t, data in msgs:
        if topic not in conns:
            conns[topic] = w.add_connection(topic, tp, typestore=TS2)
        w.write(conns[topic], t, data)
    w.close()


def write_bare_mcap(name, msgs, compress=False):
    """A bare .mcap: written as a bag folder of the file's name, the file moved out."""
    stem = name.removesuffix(".mcap")
    folder = OUT / stem
    write_ros2(folder, StoragePlugin.MCAP, msgs, compress)
    shutil.move(folder / f"{stem}.mcap", OUT / name)
    shutil.rmtree(folder)


def write_ros1(path, msgs, fmt=None):
    w = Ros1Writer(path)
    if fmt is not None:
        w.set_compression(fmt)
    w.open()
    conns = {}
    for topic, tp, t, data in msgs:
        if topic not in conns:
            conns[topic] = w.add_connection(topic, tp, typestore=TS1)
        w.write(conns[topic], t, data)
    w.close()


def decimal_ns(text):
    """Integer nanoseconds of a decimal time stamp (exact: no float)."""
    whole, _, frac = text.partition(".")
    return int(whole) * 1_000_000_000 + int((frac + "000000000")[:9])


def sim_pose(ns, p):
    T = TS2.types
    return T["geometry_msgs/msg/PoseStamped"](
        header=header(TS2, ns, "world"),
        pose=T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
            orientation=T["geometry_msgs/msg/Quaternion"](x=p[3], y=p[4], z=p[5], w=p[6]),
        ),
    )


def sim_dvl(rep):
    """marine_acoustic_msgs/Dvl as waterlinked_dvl_driver fills it from a velocity report."""
    T = TS2.types
    vec = T["geometry_msgs/msg/Vector3"]
    vx, vy, vz = rep["vx"], rep["vy"], rep["vz"]
    beams = rep["transducers"]
    return T[DVL](
        header=header(TS2, int(rep["time_of_validity"]) * 1000, "dvl"),
        velocity_mode=1,
        dvl_type=0,
        velocity=vec(x=float(vx), y=float(vy), z=float(vz)),
        velocity_covar=np.array(rep["covariance"], dtype=np.float64).reshape(-1),
        altitude=float(rep["altitude"]),
        course_gnd=math.atan2(vy, vx),
        speed_gnd=math.hypot(vx, vy),
        num_good_beams=sum(1 for b in beams if b["beam_valid"]),
        sound_speed=0.0,
        beam_ranges_valid=True,
        beam_velocities_valid=bool(rep["velocity_valid"]),
        beam_unit_vec=[vec(x=u[0], y=u[1], z=u[2]) for u in A50_BEAMS],
        range=np.array([b["distance"] for b in beams], dtype=np.float64),
        range_covar=np.zeros(4, dtype=np.float32),
        beam_quality=np.array([b["rssi"] for b in beams], dtype=np.float32),
        beam_velocity=np.array([b["velocity"] for b in beams], dtype=np.float32),
        beam_velocity_covar=np.zeros(4, dtype=np.float32),
    )


def sim_imu(ns, v):
    T = TS2.types
    vec = T["geometry_msgs/msg/Vector3"]
    unknown = np.zeros(9, dtype=np.float64)
    unknown[0] = -1.0
    return T[IMU](
        header=header(TS2, ns, "imu"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=unknown,
        angular_velocity=vec(x=v[0], y=v[1], z=v[2]),
        angular_velocity_covariance=np.zeros(9, dtype=np.float64),
        linear_acceleration=vec(x=v[3], y=v[4], z=v[5]),
        linear_acceleration_covariance=np.zeros(9, dtype=np.float64),
    )


def cam_dvl_imu(dvlcal):
    """The simulated recording's poses, DVL reports and IMU samples, in record order."""
    with tempfile.TemporaryDirectory() as tmp:
        rec = Path(tmp) / "rec"
        subprocess.run([dvlcal, *SIM_ARGS, "--out", str(rec)], check=True, stdout=subprocess.DEVNULL)
        out = []
        for line in (rec / "poses.txt").read_text().splitlines():
            if line.strip() and not line.startswith("#"):
                f = line.split()
                ns = decimal_ns(f[0])
                msg = sim_pose(ns, [float(x) for x in f[1:8]])
                out.append(("/mocap/rig/pose", "geometry_msgs/msg/PoseStamped", ns + LATENCY_NS, cdr_le(msg, "geometry_msgs/msg/PoseStamped")))
        for line in (rec / "dvl.jsonl").read_text().splitlines():
            rep = json.loads(line) if line.strip() else {}
            if rep.get("type") == "velocity":
                ns = int(rep["time_of_validity"]) * 1000
                out.append(("/dvl/velocity_report", DVL, ns + LATENCY_NS, cdr_le(sim_dvl(rep), DVL)))
        for line in (rec / "imu0" / "data.csv").read_text().splitlines():
            if line.strip() and not line.startswith("#"):
                f = line.split(",")
                ns = int(f[0])
                out.append(("/imu/data", IMU, ns + LATENCY_NS, cdr_le(sim_imu(ns, [float(x) for x in f[1:7]]), IMU)))
        out.sort(key=lambda m: (m[2], m[0]))
        truth = OUT / "cam_dvl_imu_truth"
        (truth / "truth").mkdir(parents=True)
        shutil.copy(rec / "imu.yaml", truth / "imu.yaml")
        for name in ("imu.yaml", "calibration.yaml"):
            shutil.copy(rec / "truth" / name, truth / "truth" / name)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dvlcal", default=str(OUT.parent.parent.parent / "target" / "release" / "dvlcal"), help="the dvlcal binary that simulates the camera + DVL + IMU recording")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    for p in OUT.iterdir():
        if p.is_dir():
            shutil.rmtree(p)
        elif p.name != "README.md":
            p.unlink()

    write_ros1(OUT / "imu.bag", good(TS1, ros1), Ros1Writer.CompressionFormat.LZ4)
    write_ros2(OUT / "imu_sqlite", StoragePlugin.SQLITE3, good(TS2, cdr_le))
    write_bare_mcap("imu.mcap", good(TS2, cdr_le), compress=True)
    write_bare_mcap("big_endian.mcap", [m for m in good(TS2, cdr_be) if m[1] == IMU][:40])
    write_bare_mcap("two_imus.mcap", two(TS2, cdr_le))
    write_ros1(OUT / "bad_imu.bag", bad(TS1, ros1))
    write_bare_mcap("bad_imu.mcap", bad(TS2, cdr_le))
    recording = cam_dvl_imu(args.dvlcal)
    write_bare_mcap("cam_dvl_imu.mcap", recording, compress=True)
    write_bare_mcap("dvl_imu.mcap", [m for m in recording if m[0] != "/mocap/rig/pose"], compress=True)

    print(f"rosbags {version('rosbags')}: wrote {OUT}")
    total = 0
    for p in sorted(OUT.rglob("*")):
        if p.is_file() and p.name != "README.md":
            total += p.stat().st_size
            print(f"  {p.relative_to(OUT)}: {p.stat().st_size} bytes")
    print(f"  total: {total} bytes")


if __name__ == "__main__":
    main()
