#!/usr/bin/env python3
"""Packs the bag recording and the poses sample as the ROS bags users record, with rosbags (PyPI),
a pure-Python writer independent of dvlcal's bag readers, and writes the small bag fixtures of the
tests.

    python3 -m venv /tmp/rbs && /tmp/rbs/bin/pip install rosbags numpy pillow
    dvlcal simulate --images --jpeg-quality 85 --seed 31 --duration 13 \
        --camchain sample_data/bags/recording/camchain.yaml --board-distance 1.0 --out /tmp/bag_recording
    /tmp/rbs/bin/python scripts/make_sample_bags.py --recording /tmp/bag_recording   # writes everything below
    /tmp/rbs/bin/python scripts/make_sample_bags.py --summary  # prints what the bags hold

The bag recording is a rendered stereo recording of its own (376x240 cameras, 131 frames at 10 Hz,
13 s), so that the bags hold every frame and calibrate, while costing a fraction of the image
folders: its JPEG files are kept only inside the bags. Reads the recording (cam0/ cam1/
<t_ns>.jpg, camchain.yaml, target.yaml, dvl.jsonl, truth/) and sample_data/poses/ (poses.txt,
dvl.jsonl) and writes, replacing earlier output:

  sample_data/bags/recording/        the recording's camchain.yaml, target.yaml, dvl.jsonl and
                                     truth (calibration.yaml, poses.txt, poses_board.txt, twist.csv)
  sample_data/bags/stereo_mcap/      ROS 2 bag, MCAP storage, zstd chunks: mono8 Image (the JPEGs
                                     decoded) and CameraInfo of both cameras, the three topics of
                                     Water Linked's ROS 2 driver (Dvl, Odometry,
                                     PoseWithCovarianceStamped)
  sample_data/bags/stereo_sqlite3/   ROS 2 bag, sqlite3 storage: CompressedImage (the JPEG files
                                     unchanged) of both cameras, Odometry of the DVL
  sample_data/bags/stereo_ros1.bag   ROS 1 bag, lz4 chunks: CompressedImage (the JPEG files
                                     unchanged) of both cameras and the A50 JSON lines verbatim as
                                     std_msgs/String (Water Linked's ROS 1 driver)
  sample_data/bags/poses_mcap.mcap   bare MCAP file, lz4 chunks: PoseStamped from poses/poses.txt
                                     and Dvl from poses/dvl.jsonl
  tests/fixtures/bag_cases/*         small bags of the cases a bag reader must get right

Every frame and every DVL report is kept in every bag.

Times: header stamps are exact (image: the integer ns of the file name; DVL: time_of_validity;
poses: the TUM time split from its decimal text). The record (log) time of every message is its
header stamp plus a latency of 15-45 ms drawn from a generator seeded with (SEED, source, stamp),
so the same message has the same record time in every bag, and a reader that takes record times
instead of header stamps is off by about 30 ms. The JSON strings of the ROS 1 bag are recorded at
time_of_transmission plus such a latency. Messages are written in record-time order, as a
recorder writes them.

Deterministic: the same rosbags, zstd and lz4 versions write the same bytes on every run (no wall
clock, no random seed from the system; temporary folders carry the final names, since rosbags
writes the storage file name into the bag's metadata).
"""

from __future__ import annotations

import argparse
import json
import math
import random
import shutil
import sys
import tempfile
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Callable, Iterable

import lz4.frame
import numpy as np
from PIL import Image
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from ruamel.yaml import YAML

ROOT = Path(__file__).resolve().parent.parent
# The rendered stereo frames read: sample_data/stereo for scripts/make_bench_bag.py, the bag
# recording given with --recording for the sample bags.
STEREO = ROOT / "sample_data" / "stereo"
POSES = ROOT / "sample_data" / "poses"
BAGS = ROOT / "sample_data" / "bags"
RECORDING = BAGS / "recording"
TRUTH_FILES = ("calibration.yaml", "poses.txt", "poses_board.txt", "twist.csv")
CASES = ROOT / "tests" / "fixtures" / "bag_cases"

SEED = 11
LATENCY_NS = (15_000_000, 45_000_000)
SIZE_BUDGET = 25_000_000  # bytes, all of sample_data/bags
CASE_BUDGET = 200_000  # bytes, each file of tests/fixtures/bag_cases

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
DVL = "marine_acoustic_msgs/msg/Dvl"
DVL_MODE_BOTTOM = 1
DVL_TYPE_PISTON = 0
# The A50 beam directions the Water Linked ROS 2 driver fills in (22.5 deg off z, 45 deg about z).
_A, _C = 0.6532814824381883, 0.38268343236508984
A50_BEAMS = [(-_A, _A, _C), (-_A, -_A, _C), (_A, -_A, _C), (_A, _A, _C)]

TS2 = get_typestore(Stores.ROS2_HUMBLE)
TS2.register(get_types_from_msg(DVL_MSG, DVL))
T2 = TS2.types
TS1 = get_typestore(Stores.ROS1_NOETIC)
T1 = TS1.types


# ----------------------------------------------------------------------------- inputs


def latency_ns(source: str, stamp_ns: int) -> int:
    """Recorder latency of one message, the same for the same (source, stamp) in every bag."""
    return random.Random(f"{SEED}/{source}/{stamp_ns}").randint(*LATENCY_NS)


def split_decimal_time(text: str) -> tuple[int, int]:
    """'1700000000.1' -> (1700000000, 100000000), from the digits, never through a float."""
    whole, _, frac = text.strip().partition(".")
    if not whole.isdigit() or (frac and not frac.isdigit()) or len(frac) > 9:
        raise ValueError(f"not a time with at most 9 decimals: {text!r}")
    return int(whole), int(frac.ljust(9, "0"))


def frame_stamps() -> list[int]:
    """Stamps (ns) of the recording's frames, the same for cam0 and cam1."""
    stamps0 = sorted(int(p.stem) for p in (STEREO / "cam0").glob("*.jpg"))
    stamps1 = sorted(int(p.stem) for p in (STEREO / "cam1").glob("*.jpg"))
    if stamps0 != stamps1 or not stamps0:
        raise SystemExit("cam0 and cam1 must hold the same stamps")
    return stamps0


def jpeg_path(cam: str, stamp_ns: int) -> Path:
    return STEREO / cam / f"{stamp_ns}.jpg"


def mono8(cam: str, stamp_ns: int) -> np.ndarray:
    with Image.open(jpeg_path(cam, stamp_ns)) as im:
        return np.asarray(im.convert("L"), dtype=np.uint8)


def read_reports(path: Path) -> list[tuple[str, dict]]:
    """(line verbatim, parsed) of every velocity report of an A50 json_v3 log."""
    out = []
    for line in path.read_text().splitlines():
        if line.strip():
            rep = json.loads(line)
            if rep.get("type") == "velocity":
                out.append((line, rep))
    return out


def read_tum(path: Path) -> list[tuple[int, int, list[float]]]:
    """(sec, nanosec, [x y z qx qy qz qw]) of every line of a TUM file."""
    out = []
    for line in path.read_text().splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            f = line.split()
            sec, nsec = split_decimal_time(f[0])
            out.append((sec, nsec, [float(v) for v in f[1:8]]))
    return out


def camchain() -> dict:
    return YAML(typ="safe").load((STEREO / "camchain.yaml").read_text())


# ----------------------------------------------------------------------------- messages


def ns(sec: int, nsec: int) -> int:
    return sec * 1_000_000_000 + nsec


def header(stamp_ns: int, frame: str, ros1_seq: int | None = None):
    sec, nsec = divmod(stamp_ns, 1_000_000_000)
    if ros1_seq is not None:
        return T1["std_msgs/msg/Header"](
            seq=ros1_seq, stamp=T1["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame
        )
    return T2["std_msgs/msg/Header"](stamp=T2["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame)


def vec(x: float, y: float, z: float):
    return T2["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))


def pose(p: list[float]):
    """geometry_msgs/Pose from [x y z qx qy qz qw]."""
    return T2["geometry_msgs/msg/Pose"](
        position=T2["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
        orientation=T2["geometry_msgs/msg/Quaternion"](x=p[3], y=p[4], z=p[5], w=p[6]),
    )


def image_msg(stamp_ns: int, frame: str, px: np.ndarray, encoding: str = "mono8", ros1_seq: int | None = None):
    T = T1 if ros1_seq is not None else T2
    height, width = px.shape[:2]
    raw = np.ascontiguousarray(px).view(np.uint8).reshape(-1)
    return T["sensor_msgs/msg/Image"](
        header=header(stamp_ns, frame, ros1_seq),
        height=height,
        width=width,
        encoding=encoding,
        is_bigendian=0,
        step=raw.size // height,
        data=raw,
    )


def camera_info_msg(stamp_ns: int, frame: str, cam: dict):
    fu, fv, pu, pv = (float(v) for v in cam["intrinsics"])
    k1, k2, p1, p2 = (float(v) for v in cam["distortion_coeffs"])
    width, height = cam["resolution"]
    return T2["sensor_msgs/msg/CameraInfo"](
        header=header(stamp_ns, frame),
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=np.array([k1, k2, p1, p2, 0.0]),
        k=np.array([fu, 0.0, pu, 0.0, fv, pv, 0.0, 0.0, 1.0]),
        r=np.eye(3).reshape(-1),
        p=np.array([fu, 0.0, pu, 0.0, 0.0, fv, pv, 0.0, 0.0, 0.0, 1.0, 0.0]),
        binning_x=0,
        binning_y=0,
        roi=T2["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def compressed_msg(stamp_ns: int, frame: str, jpeg: bytes, ros1_seq: int | None = None):
    T = T1 if ros1_seq is not None else T2
    return T["sensor_msgs/msg/CompressedImage"](
        header=header(stamp_ns, frame, ros1_seq), format="jpeg", data=np.frombuffer(jpeg, dtype=np.uint8)
    )


def tov_ns(rep: dict) -> int:
    return int(rep["time_of_validity"]) * 1000


def tot_ns(rep: dict) -> int:
    return int(rep["time_of_transmission"]) * 1000


def covariance3(rep: dict) -> np.ndarray:
    return np.array(rep["covariance"], dtype=np.float64).reshape(3, 3)


def dvl_msg(rep: dict, frame: str = "dvl", stamp_ns: int | None = None, velocity=None):
    """marine_acoustic_msgs/Dvl as waterlinked_dvl_driver fills it from a velocity report."""
    vx, vy, vz = velocity if velocity is not None else (rep["vx"], rep["vy"], rep["vz"])
    beams = rep["transducers"]
    return T2[DVL](
        header=header(tov_ns(rep) if stamp_ns is None else stamp_ns, frame),
        velocity_mode=DVL_MODE_BOTTOM,
        dvl_type=DVL_TYPE_PISTON,
        velocity=vec(vx, vy, vz),
        velocity_covar=covariance3(rep).reshape(-1),
        altitude=float(rep["altitude"]),
        course_gnd=math.atan2(vy, vx),
        speed_gnd=math.hypot(vx, vy),
        num_good_beams=sum(1 for b in beams if b["beam_valid"]),
        sound_speed=0.0,
        beam_ranges_valid=True,
        beam_velocities_valid=bool(rep["velocity_valid"]),
        beam_unit_vec=[vec(*u) for u in A50_BEAMS],
        range=np.array([b["distance"] for b in beams], dtype=np.float64),
        range_covar=np.zeros(4, dtype=np.float32),
        beam_quality=np.array([b["rssi"] for b in beams], dtype=np.float32),
        beam_velocity=np.array([b["velocity"] for b in beams], dtype=np.float32),
        beam_velocity_covar=np.zeros(4, dtype=np.float32),
    )


@dataclass
class DeadReckoning:
    """A plausible dead-reckoned position: the velocities integrated in the DVL frame."""

    position: np.ndarray
    std: float
    last_ns: int | None = None

    @classmethod
    def start(cls) -> "DeadReckoning":
        return cls(np.zeros(3), 0.0)

    def update(self, rep: dict) -> None:
        t = tov_ns(rep)
        if self.last_ns is not None and rep["velocity_valid"]:
            dt = (t - self.last_ns) * 1e-9
            v = np.array([rep["vx"], rep["vy"], rep["vz"]])
            self.position = self.position + v * dt
            self.std += 0.01 * float(np.linalg.norm(v)) * dt  # 1 % of the distance travelled
        self.last_ns = t

    def pose_with_covariance(self):
        cov = np.zeros(36)
        cov[[0, 7, 14]] = self.std
        cov[[21, 28, 35]] = -1.0  # the driver: orientation covariance unknown
        return T2["geometry_msgs/msg/PoseWithCovariance"](
            pose=pose([*self.position.tolist(), 0.0, 0.0, 0.0, 1.0]), covariance=cov
        )


def twist_cov(rep: dict) -> np.ndarray:
    cov = np.zeros((6, 6))
    cov[:3, :3] = covariance3(rep)
    return cov.reshape(-1)


def odom_msg(rep: dict, dr: DeadReckoning, stamp_ns: int | None = None, frame: str = "dvl"):
    """nav_msgs/Odometry as waterlinked_dvl_driver publishes it on ~/odom for a velocity report."""
    return T2["nav_msgs/msg/Odometry"](
        header=header(tov_ns(rep) if stamp_ns is None else stamp_ns, frame),
        child_frame_id="",
        pose=dr.pose_with_covariance(),
        twist=T2["geometry_msgs/msg/TwistWithCovariance"](
            twist=T2["geometry_msgs/msg/Twist"](linear=vec(rep["vx"], rep["vy"], rep["vz"]), angular=vec(0, 0, 0)),
            covariance=twist_cov(rep),
        ),
    )


def dead_reckoning_msg(rep: dict, dr: DeadReckoning):
    return T2["geometry_msgs/msg/PoseWithCovarianceStamped"](header=header(tov_ns(rep), "dvl"), pose=dr.pose_with_covariance())


def pose_stamped_msg(stamp_ns: int, frame: str, p: list[float]):
    return T2["geometry_msgs/msg/PoseStamped"](header=header(stamp_ns, frame), pose=pose(p))


# ----------------------------------------------------------------------------- writing


@dataclass
class Entry:
    """One message to write: record time, topic, type and a function making the message."""

    record_ns: int
    topic: str
    msgtype: str
    make: Callable[[], object]


def chunked_mcap(compression: str, level: int, chunk_bytes: int) -> type:
    """rosbags' MCAP storage with the chunk compression, level and size of a recorder preset
    (rosbags itself writes zstd at its default level into 1 MiB chunks)."""

    class ChunkedMcap(McapWriter):
        def __init__(self, path, mode):
            super().__init__(path, mode)
            self.flushing = False
            if mode == CompressionMode.STORAGE:
                self.compression = compression
                if compression == "lz4":
                    self.compressor = lambda b: lz4.frame.compress(b, compression_level=level)
                else:
                    from backports import zstd  # rosbags' own zstd dependency (Python < 3.14)

                    self.compressor = lambda b: zstd.compress(b, level=level)

        def close_chunk(self):  # rosbags calls this past 1 MiB: only close at chunk_bytes
            if self.flushing or self.chunk.bio.tell() >= chunk_bytes:
                super().close_chunk()

        def write(self, connection, timestamp, data):
            super().write(connection, timestamp, data)
            if self.chunk.bio.tell() >= chunk_bytes:
                super().close_chunk()

        def close(self, version, metadata):
            self.flushing = True
            super().close(version, metadata)

    return ChunkedMcap


def write_ros2(
    dest: Path,
    entries: Iterable[Entry],
    storage: str,
    compression: str = "",
    level: int = 0,
    chunk_bytes: int = 1 << 20,
    bare: bool = False,
) -> None:
    """A ROS 2 bag folder at dest, or with bare=True the single storage file dest (.mcap/.db3)."""
    entries = sorted(entries, key=lambda e: (e.record_ns, e.topic))
    remove(dest)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / dest.stem if bare else dest
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(folder, version=Writer2.VERSION_LATEST, storage_plugin=plugin)
        if storage == "mcap":
            writer.STORAGE_PLUGINS = {**Writer2.STORAGE_PLUGINS, StoragePlugin.MCAP: chunked_mcap(compression, level, chunk_bytes)}
            if compression:
                writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        conns = {}
        with writer:
            for e in entries:
                if e.topic not in conns:
                    conns[e.topic] = writer.add_connection(e.topic, e.msgtype, typestore=TS2)
                writer.write(conns[e.topic], e.record_ns, bytes(TS2.serialize_cdr(e.make(), e.msgtype)))
        if bare:
            shutil.move(str(folder / f"{dest.stem}{dest.suffix}"), dest)


def remove(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()


# ----------------------------------------------------------------------------- sample bags


def dvl_driver_entries(reports, topics=("dvl", "odom", "dead_reckoning")) -> list[Entry]:
    """The messages of Water Linked's ROS 2 driver, one per topic and velocity report."""
    dr = DeadReckoning.start()
    out = []
    for _, rep in reports:
        dr.update(rep)
        t = tov_ns(rep)
        snapshot = DeadReckoning(dr.position.copy(), dr.std, dr.last_ns)
        if "dvl" in topics:
            out.append(Entry(t + latency_ns("/dvl/velocity_report", t), "/dvl/velocity_report", DVL, lambda r=rep: dvl_msg(r)))
        if "odom" in topics:
            out.append(Entry(t + latency_ns("/dvl/odom", t), "/dvl/odom", "nav_msgs/msg/Odometry", lambda r=rep, d=snapshot: odom_msg(r, d)))
        if "dead_reckoning" in topics:
            out.append(
                Entry(
                    t + latency_ns("/dvl/dead_reckoning_report", t),
                    "/dvl/dead_reckoning_report",
                    "geometry_msgs/msg/PoseWithCovarianceStamped",
                    lambda r=rep, d=snapshot: dead_reckoning_msg(r, d),
                )
            )
    return out


def make_stereo_mcap(frames: list[int], reports) -> None:
    chain = camchain()
    entries = []
    for cam in ("cam0", "cam1"):
        for t in frames:
            entries.append(Entry(t + latency_ns(cam, t), f"/{cam}/image_raw", "sensor_msgs/msg/Image", lambda c=cam, t=t: image_msg(t, c, mono8(c, t))))
            entries.append(
                Entry(
                    t + latency_ns(f"{cam}/camera_info", t),
                    f"/{cam}/camera_info",
                    "sensor_msgs/msg/CameraInfo",
                    lambda c=cam, t=t: camera_info_msg(t, c, chain[c]),
                )
            )
    entries += dvl_driver_entries(reports)
    # The MCAP storage preset zstd_small of rosbag2: high zstd level, 4 MiB chunks.
    write_ros2(BAGS / "stereo_mcap", entries, "mcap", "zstd", level=19, chunk_bytes=4 << 20)


def make_stereo_sqlite3(frames: list[int], reports) -> None:
    entries = []
    for cam, side in (("cam0", "left"), ("cam1", "right")):
        for t in frames:
            entries.append(
                Entry(
                    t + latency_ns(cam, t),
                    f"/stereo/{side}/image_raw/compressed",
                    "sensor_msgs/msg/CompressedImage",
                    lambda c=cam, s=side, t=t: compressed_msg(t, f"stereo_{s}", jpeg_path(c, t).read_bytes()),
                )
            )
    entries += dvl_driver_entries(reports, topics=("odom",))
    write_ros2(BAGS / "stereo_sqlite3", entries, "sqlite3")


def make_poses_mcap(poses, reports) -> None:
    entries = []
    for sec, nsec, p in poses:
        t = ns(sec, nsec)
        entries.append(Entry(t + latency_ns("/mocap/rig/pose", t), "/mocap/rig/pose", "geometry_msgs/msg/PoseStamped", lambda t=t, p=p: pose_stamped_msg(t, "world", p)))
    entries += dvl_driver_entries(reports, topics=("dvl",))
    # 128 KiB chunks: a few lz4 chunks (the whole file is 0.3 MB before compression).
    write_ros2(BAGS / "poses_mcap.mcap", entries, "mcap", "lz4", level=0, chunk_bytes=128 << 10, bare=True)


def make_stereo_ros1(frames: list[int], reports) -> None:
    dest = BAGS / "stereo_ros1.bag"
    remove(dest)
    entries = []
    for cam in ("cam0", "cam1"):
        for seq, t in enumerate(frames):
            entries.append(
                Entry(
                    t + latency_ns(cam, t),
                    f"/{cam}/image_raw/compressed",
                    "sensor_msgs/msg/CompressedImage",
                    lambda c=cam, t=t, s=seq: compressed_msg(t, c, jpeg_path(c, t).read_bytes(), ros1_seq=s),
                )
            )
    for line, rep in reports:
        t = tot_ns(rep)
        entries.append(Entry(t + latency_ns("/dvl/json_data", t), "/dvl/json_data", "std_msgs/msg/String", lambda s=line: T1["std_msgs/msg/String"](data=s)))
    entries.sort(key=lambda e: (e.record_ns, e.topic))
    writer = Writer1(dest)
    writer.set_compression(Writer1.CompressionFormat.LZ4)
    writer.compressor = lambda b: lz4.frame.compress(b, compression_level=9)  # LZ4HC, same frame format
    callers = {"/cam0/image_raw/compressed": "/stereo_camera", "/cam1/image_raw/compressed": "/stereo_camera", "/dvl/json_data": "/dvl_a50"}
    conns = {}
    with writer:
        for e in entries:
            if e.topic not in conns:
                conns[e.topic] = writer.add_connection(e.topic, e.msgtype, typestore=TS1, callerid=callers[e.topic], latching=0)
            writer.write(conns[e.topic], e.record_ns, bytes(TS1.serialize_ros1(e.make(), e.msgtype)))


def copy_recording() -> None:
    """The small files of the recording a user needs beside the bags: cameras, board, DVL log, truth."""
    remove(RECORDING)
    (RECORDING / "truth").mkdir(parents=True)
    for name in ("camchain.yaml", "target.yaml", "dvl.jsonl"):
        shutil.copyfile(STEREO / name, RECORDING / name)
    for name in TRUTH_FILES:
        shutil.copyfile(STEREO / "truth" / name, RECORDING / "truth" / name)


def make_sample_bags() -> None:
    BAGS.mkdir(parents=True, exist_ok=True)
    remove(BAGS / "frames.txt")
    frames = frame_stamps()
    copy_recording()
    stereo_reports = read_reports(STEREO / "dvl.jsonl")
    make_stereo_mcap(frames, stereo_reports)
    make_stereo_sqlite3(frames, stereo_reports)
    make_poses_mcap(read_tum(POSES / "poses.txt"), read_reports(POSES / "dvl.jsonl"))
    make_stereo_ros1(frames, stereo_reports)
    total = sum(p.stat().st_size for p in BAGS.rglob("*") if p.is_file())
    for p in sorted(BAGS.rglob("*")):
        if p.is_file():
            print(f"{p.stat().st_size:>12,}  {p.relative_to(ROOT)}")
    print(f"{total:>12,}  total of {BAGS.relative_to(ROOT)} ({len(frames)} frames per camera)")
    if total >= SIZE_BUDGET:
        raise SystemExit(f"sample_data/bags is {total:,} bytes, over the budget of {SIZE_BUDGET:,}")


# ----------------------------------------------------------------------------- test cases


def make_cases() -> None:
    CASES.mkdir(parents=True, exist_ok=True)
    reports = read_reports(POSES / "dvl.jsonl")
    poses = read_tum(POSES / "poses.txt")

    # zero_stamps.mcap: a driver that leaves header.stamp at 0; only record times order the DVL.
    entries = []
    dr = DeadReckoning.start()
    for _, rep in reports[:5]:
        dr.update(rep)
        t = tov_ns(rep)
        entries.append(Entry(t + latency_ns("/dvl/odom", t), "/dvl/odom", "nav_msgs/msg/Odometry", lambda r=rep, d=DeadReckoning(dr.position.copy(), dr.std): odom_msg(r, d, stamp_ns=0)))
    for sec, nsec, p in poses[:5]:
        t = ns(sec, nsec)
        entries.append(Entry(t + latency_ns("/mocap/rig/pose", t), "/mocap/rig/pose", "geometry_msgs/msg/PoseStamped", lambda t=t, p=p: pose_stamped_msg(t, "world", p)))
    write_ros2(CASES / "zero_stamps.mcap", entries, "mcap", bare=True)

    # two_dvl.mcap: two DVLs; b is mounted rolled by 180 deg (y, z negated) and its clock 50 ms later.
    entries = []
    for _, rep in reports[:10]:
        t = tov_ns(rep)
        entries.append(Entry(t + latency_ns("/dvl_a/velocity_report", t), "/dvl_a/velocity_report", DVL, lambda r=rep: dvl_msg(r, "dvl_a")))
        tb = t + 50_000_000
        vb = (rep["vx"], -rep["vy"], -rep["vz"])
        entries.append(Entry(tb + latency_ns("/dvl_b/velocity_report", tb), "/dvl_b/velocity_report", DVL, lambda r=rep, tb=tb, vb=vb: dvl_msg(r, "dvl_b", stamp_ns=tb, velocity=vb)))
    write_ros2(CASES / "two_dvl.mcap", entries, "mcap", bare=True)

    # tf_poses.mcap: poses only as /tf, two rigs; rig_b is rig_a moved by +1 m along world x.
    entries = []
    for sec, nsec, p in poses[:20]:
        t = ns(sec, nsec)
        for child, dx in (("rig_a", 0.0), ("rig_b", 1.0)):
            q = [p[0] + dx, *p[1:]]
            entries.append(Entry(t + latency_ns(f"/tf/{child}", t), "/tf", "tf2_msgs/msg/TFMessage", lambda t=t, c=child, q=q: tf_msg(t, "world", c, q)))
    for _, rep in reports[:20]:
        t = tov_ns(rep)
        entries.append(Entry(t + latency_ns("/dvl/velocity_report", t), "/dvl/velocity_report", DVL, lambda r=rep: dvl_msg(r)))
    write_ros2(CASES / "tf_poses.mcap", entries, "mcap", "zstd", level=3, bare=True)

    # bad_encoding.mcap: images a mono8 reader must reject (32FC1, yuv422) between mono8 ones.
    t0 = ns(*poses[0][:2])
    rng = np.random.default_rng(SEED)
    kinds = ["mono8", "32FC1", "mono8", "yuv422", "32FC1", "yuv422", "mono8"]
    entries = []
    for i, kind in enumerate(kinds):
        t = t0 + i * 100_000_000
        if kind == "mono8":
            px = rng.integers(0, 256, size=(3, 4), dtype=np.uint8)
        elif kind == "32FC1":
            px = rng.random((3, 4), dtype=np.float32)  # step 16
        else:
            px = rng.integers(0, 256, size=(2, 8), dtype=np.uint8)  # 4x2 pixels, 2 bytes each
        entries.append(Entry(t + latency_ns("/cam0/image_raw", t), "/cam0/image_raw", "sensor_msgs/msg/Image", lambda t=t, px=px, k=kind: bad_image(t, px, k)))
    write_ros2(CASES / "bad_encoding.mcap", entries, "mcap", "zstd", level=3, bare=True)

    # twist.db3: a bare sqlite3 storage file with the DVL as TwistWithCovarianceStamped.
    entries = []
    for _, rep in reports[:20]:
        t = tov_ns(rep)
        entries.append(Entry(t + latency_ns("/dvl/twist", t), "/dvl/twist", "geometry_msgs/msg/TwistWithCovarianceStamped", lambda r=rep: twist_msg(r)))
    write_ros2(CASES / "twist.db3", entries, "sqlite3", bare=True)

    # pose_cov.mcap: two pose candidates of the same rig (and a DVL): a reader must be told which.
    entries = []
    for sec, nsec, p in poses[:20]:
        t = ns(sec, nsec)
        entries.append(Entry(t + latency_ns("/vio/pose", t), "/vio/pose", "geometry_msgs/msg/PoseWithCovarianceStamped", lambda t=t, p=p: pose_cov_msg(t, p)))
        entries.append(Entry(t + latency_ns("/vio/odom", t), "/vio/odom", "nav_msgs/msg/Odometry", lambda t=t, p=p: vio_odom_msg(t, p)))
    for _, rep in reports[:20]:
        t = tov_ns(rep)
        entries.append(Entry(t + latency_ns("/dvl/velocity_report", t), "/dvl/velocity_report", DVL, lambda r=rep: dvl_msg(r)))
    write_ros2(CASES / "pose_cov.mcap", entries, "mcap", "zstd", level=3, bare=True)

    for p in sorted(CASES.iterdir()):
        print(f"{p.stat().st_size:>12,}  {p.relative_to(ROOT)}")
        if p.suffix != ".md" and p.stat().st_size >= CASE_BUDGET:
            raise SystemExit(f"{p} is over {CASE_BUDGET:,} bytes")


def tf_msg(stamp_ns: int, parent: str, child: str, p: list[float]):
    return T2["tf2_msgs/msg/TFMessage"](
        transforms=[
            T2["geometry_msgs/msg/TransformStamped"](
                header=header(stamp_ns, parent),
                child_frame_id=child,
                transform=T2["geometry_msgs/msg/Transform"](
                    translation=vec(*p[:3]),
                    rotation=T2["geometry_msgs/msg/Quaternion"](x=p[3], y=p[4], z=p[5], w=p[6]),
                ),
            )
        ]
    )


def bad_image(stamp_ns: int, px: np.ndarray, kind: str):
    msg = image_msg(stamp_ns, "cam0", px, encoding=kind)
    if kind == "yuv422":
        msg.width = px.shape[1] // 2
    return msg


def twist_msg(rep: dict):
    return T2["geometry_msgs/msg/TwistWithCovarianceStamped"](
        header=header(tov_ns(rep), "dvl"),
        twist=T2["geometry_msgs/msg/TwistWithCovariance"](
            twist=T2["geometry_msgs/msg/Twist"](linear=vec(rep["vx"], rep["vy"], rep["vz"]), angular=vec(0, 0, 0)),
            covariance=twist_cov(rep),
        ),
    )


def pose_cov(p: list[float]):
    cov = np.zeros(36)
    cov[[0, 7, 14]] = 4e-6  # (2 mm)^2
    cov[[21, 28, 35]] = 4e-6  # (2 mrad)^2
    return T2["geometry_msgs/msg/PoseWithCovariance"](pose=pose(p), covariance=cov)


def pose_cov_msg(stamp_ns: int, p: list[float]):
    return T2["geometry_msgs/msg/PoseWithCovarianceStamped"](header=header(stamp_ns, "world"), pose=pose_cov(p))


def vio_odom_msg(stamp_ns: int, p: list[float]):
    return T2["nav_msgs/msg/Odometry"](
        header=header(stamp_ns, "world"),
        child_frame_id="rig",
        pose=pose_cov(p),
        twist=T2["geometry_msgs/msg/TwistWithCovariance"](
            twist=T2["geometry_msgs/msg/Twist"](linear=vec(0, 0, 0), angular=vec(0, 0, 0)), covariance=np.zeros(36)
        ),
    )


# ----------------------------------------------------------------------------- summary


def summarize(path: Path) -> None:
    """Topics, types, counts, header-stamp and record-time spans of one bag, read back with rosbags."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path], default_typestore=TS2) as reader:
        print(f"## {path.relative_to(ROOT)}")
        for conn in sorted(reader.connections, key=lambda c: c.topic):
            recs, stamps = [], []
            for c, rec, raw in reader.messages(connections=[conn]):
                recs.append(rec)
                msg = reader.deserialize(raw, c.msgtype)
                h = getattr(msg, "header", None)
                if h is None and hasattr(msg, "transforms"):
                    h = msg.transforms[0].header
                if h is not None:
                    stamps.append(ns(h.stamp.sec, h.stamp.nanosec))
            span = f"stamps {min(stamps)}..{max(stamps)}" if stamps else "no header"
            print(f"- {conn.topic} {conn.msgtype} x{len(recs)}: {span}; record {min(recs)}..{max(recs)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--summary", action="store_true", help="print the contents of the written bags instead of writing")
    ap.add_argument("--recording", type=Path, help="the rendered bag recording (dvlcal simulate --images --out DIR)")
    args = ap.parse_args()
    if args.summary:
        for p in [*sorted(BAGS.glob("*.bag")), *sorted(BAGS.glob("*.mcap")), *sorted(d for d in BAGS.iterdir() if (d / "metadata.yaml").is_file()), *sorted(CASES.glob("*.mcap")), *sorted(CASES.glob("*.db3"))]:
            summarize(p)
        return
    if args.recording is None:
        raise SystemExit("give --recording DIR: the rendered bag recording (see the top of this script)")
    global STEREO
    STEREO = args.recording
    print(f"rosbags {version('rosbags')}, lz4 {version('lz4')}, backports.zstd {version('backports.zstd')}", file=sys.stderr)
    make_sample_bags()
    make_cases()


if __name__ == "__main__":
    main()
