#!/usr/bin/env python3
"""Writes the bag fixtures of tests/ros2_bag.rs into tests/fixtures/bags/ with implementations
independent of dvlcal's readers: rosbags (PyPI) for ROS 2 bags in both storages and for ROS 1
bags, and foxglove's `mcap` writer (PyPI) for the MCAP variants rosbags does not write (lz4
chunks, messages outside chunks, chunk CRCs).

    python3 -m venv /tmp/rb && /tmp/rb/bin/pip install rosbags mcap
    /tmp/rb/bin/python scripts/make_bag_fixtures.py

The output is deterministic for given package versions (the writers record their names and
versions in the files). Every bag holds the same messages: four topics of different types
(std_msgs String, geometry_msgs PoseStamped, a small mono8 sensor_msgs Image, and the custom
marine_acoustic_msgs Dvl registered from its .msg text) at known record times, in chunks small
enough that each bag has several. `expected.json` lists every message in record order with its
topic, type, record time and serialised bytes (hex), once as CDR (ROS 2 bags) and once in ROS 1
serialisation (ROS 1 bags), so the tests compare bytes rather than re-decoding them.

Files written:
- mcap_zstd/            ROS 2 bag folder, MCAP with zstd chunks (rosbags)
- none.mcap             bare MCAP, uncompressed chunks (rosbags)
- lz4.mcap              bare MCAP, lz4 (frame) chunks with CRCs (mcap)
- unchunked.mcap        bare MCAP, messages outside chunks (mcap)
- sqlite/               ROS 2 bag folder, sqlite3 storage (rosbags)
- bare.db3              the same database as a bare file
- split_mcap/           one bag in two MCAP files named by a hand-written metadata.yaml
- split_sqlite/         the same in two sqlite3 files
- ros1_none.bag, ros1_bz2.bag, ros1_lz4.bag   ROS 1 bags (rosbags)
- expected.json         the messages, as described above
"""

import json
import shutil
from importlib.metadata import version
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

OUT = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "bags"

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
STRING = "std_msgs/msg/String"
POSE = "geometry_msgs/msg/PoseStamped"
IMAGE = "sensor_msgs/msg/Image"

# Topics in the order they are first written. The DVL topic is added after the first
# messages, so its channel is declared inside a later chunk than the others.
TOPICS = [
    ("/chatter", STRING),
    ("/pose", POSE),
    ("/cam0/image_raw", IMAGE),
    ("/dvl/velocity_report", DVL),
]

T0_NS = 1_700_000_000_000_000_000
STEP_NS = 50_000_000
STEPS = 12
# Messages per forced chunk of the rosbags MCAP writer (its own threshold is 1 MiB).
PER_CHUNK = 7


def typestore(store):
    ts = get_typestore(store)
    ts.register(get_types_from_msg(DVL_MSG, DVL))
    return ts


TS2 = typestore(Stores.ROS2_HUMBLE)
TS1 = typestore(Stores.ROS1_NOETIC)


def messages(ts):
    """(topic, type, log_time_ns, message) in record order."""
    T = ts.types

    def header(ns, frame):
        stamp = T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        if "seq" in T["std_msgs/msg/Header"].__dataclass_fields__:
            return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def vec(x, y, z):
        return T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    out = []
    for k in range(STEPS):
        t = T0_NS + k * STEP_NS
        # The stamp is 20 ms before the record time, as a recorder sees it.
        stamp = t - 20_000_000
        if k % 3 == 0:
            out.append(("/chatter", STRING, t, T[STRING](data=f"hello {k}")))
        pose = T[POSE](
            header=header(stamp, "map"),
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=0.5 * k, y=-0.25 * k, z=1.0),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        out.append(("/pose", POSE, t, pose))
        if k >= 2:
            dvl = T[DVL](
                header=header(stamp, "dvl_link"),
                velocity_mode=1,
                dvl_type=2,
                velocity=vec(0.1 * k, -0.05, 0.01),
                velocity_covar=np.array([1e-4 * (i + 1) for i in range(9)], dtype=np.float64),
                altitude=2.5 + 0.01 * k,
                course_gnd=0.5,
                speed_gnd=0.1 * k,
                num_good_beams=4,
                sound_speed=1500.0,
                beam_ranges_valid=True,
                beam_velocities_valid=k != 5,
                beam_unit_vec=[vec(0.6, 0.0, 0.8), vec(0.0, 0.6, 0.8), vec(-0.6, 0.0, 0.8), vec(0.0, -0.6, 0.8)],
                range=np.array([3.0, 3.25, 3.5, 3.75], dtype=np.float64),
                range_covar=np.array([0.5, 0.25, 0.125, 0.0625], dtype=np.float32),
                beam_quality=np.array([1.0, 2.0, 3.0, 4.0], dtype=np.float32),
                beam_velocity=np.array([0.25, -0.25, 0.5, -0.5], dtype=np.float32),
                beam_velocity_covar=np.array([0.001, 0.002, 0.003, 0.004], dtype=np.float32),
            )
            # The same record time as the pose: ties keep their record order.
            out.append(("/dvl/velocity_report", DVL, t, dvl))
        if k % 2 == 1:
            img = T[IMAGE](
                header=header(stamp, "cam0"),
                height=4,
                width=8,
                encoding="mono8",
                is_bigendian=0,
                step=8,
                data=np.array([(k * 7 + i) % 256 for i in range(32)], dtype=np.uint8),
            )
            out.append(("/cam0/image_raw", IMAGE, t + 1_000_000, img))
    return out


MSGS2 = [(topic, tp, t, bytes(TS2.serialize_cdr(m, tp))) for topic, tp, t, m in messages(TS2)]
MSGS1 = [(topic, tp, t, bytes(TS1.serialize_ros1(m, tp))) for topic, tp, t, m in messages(TS1)]


def write_rosbags2(path, storage, compress, msgs=MSGS2):
    """A ROS 2 bag folder written by rosbags; MCAP chunks are closed every PER_CHUNK messages."""
    w = Ros2Writer(path, version=9, storage_plugin=storage)
    if compress:
        w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    w.open()
    conns = {}
    written = 0
    for topic, tp, t, data in msgs:
        if topic not in conns:
            conns[topic] = w.add_connection(topic, tp, typestore=TS2)
        w.write(conns[topic], t, data)
        written += 1
        if storage == StoragePlugin.MCAP and written % PER_CHUNK == 0:
            w.storage.close_chunk()
    w.close()


def write_mcap(path, compression, chunked):
    """A bare MCAP file written by foxglove's writer, with chunk CRCs."""
    with path.open("wb") as f:
        w = McapWriter(f, chunk_size=700, compression=compression, use_chunking=chunked)
        w.start(profile="ros2", library=f"mcap-{version('mcap')}")
        channels = {}
        for seq, (topic, tp, t, data) in enumerate(MSGS2):
            if topic not in channels:
                msgdef, _ = TS2.generate_msgdef(tp, ros_version=2)
                sid = w.register_schema(name=tp, encoding="ros2msg", data=msgdef.encode())
                channels[topic] = w.register_channel(
                    topic=topic,
                    message_encoding="cdr",
                    schema_id=sid,
                    metadata={"offered_qos_profiles": ""},
                )
            w.add_message(channels[topic], log_time=t, data=data, publish_time=t, sequence=seq)
        w.finish()


def write_ros1(path, fmt):
    w = Ros1Writer(path)
    if fmt is not None:
        w.set_compression(fmt)
    w.chunk_threshold = 1024
    w.open()
    conns = {}
    for topic, tp, t, data in MSGS1:
        if topic not in conns:
            conns[topic] = w.add_connection(topic, tp, typestore=TS1)
        w.write(conns[topic], t, data)
    w.close()


def split(name, storage, ext):
    """One bag in two storage files: the first and second half of the messages, each written
    as a bag of its own, moved into one folder under a metadata.yaml that lists both."""
    half = len(MSGS2) // 2
    parts = [MSGS2[:half], MSGS2[half:]]
    folder = OUT / name
    folder.mkdir()
    files = []
    for i, msgs in enumerate(parts):
        tmp = OUT / f"_{name}_{i}"
        write_rosbags2(tmp, storage, False, msgs)
        f = f"{name}_{i}.{ext}"
        shutil.move(tmp / f"{tmp.name}.{ext}", folder / f)
        shutil.rmtree(tmp)
        files.append((f, msgs))
    counts = {}
    for topic, tp, _, _ in MSGS2:
        counts.setdefault((topic, tp), 0)
        counts[(topic, tp)] += 1
    lines = [
        "rosbag2_bagfile_information:",
        "  version: 9",
        f"  storage_identifier: {storage.name.lower()}",
        "  relative_file_paths:",
        *[f"  - {f}" for f, _ in files],
        f"  message_count: {len(MSGS2)}",
        "  topics_with_message_count:",
    ]
    for (topic, tp), n in counts.items():
        lines += [
            "  - topic_metadata:",
            f"      name: {topic}",
            f"      type: {tp}",
            "      serialization_format: cdr",
            "      offered_qos_profiles: []",
            f"    message_count: {n}",
        ]
    lines += ["  files:"]
    for f, msgs in files:
        lines += [f"  - path: {f}", f"    message_count: {len(msgs)}"]
    (folder / "metadata.yaml").write_text("\n".join(lines) + "\n")


def expected(msgs):
    return [{"topic": topic, "type": tp, "log_time_ns": t, "data": data.hex()} for topic, tp, t, data in msgs]


def main():
    # Everything is written anew except the folder's README.
    OUT.mkdir(parents=True, exist_ok=True)
    for p in OUT.iterdir():
        if p.is_dir():
            shutil.rmtree(p)
        elif p.name != "README.md":
            p.unlink()

    write_rosbags2(OUT / "mcap_zstd", StoragePlugin.MCAP, True)

    write_rosbags2(OUT / "_none", StoragePlugin.MCAP, False)
    shutil.move(OUT / "_none" / "_none.mcap", OUT / "none.mcap")
    shutil.rmtree(OUT / "_none")

    write_mcap(OUT / "lz4.mcap", CompressionType.LZ4, True)
    write_mcap(OUT / "unchunked.mcap", CompressionType.NONE, False)

    write_rosbags2(OUT / "sqlite", StoragePlugin.SQLITE3, False)
    shutil.copy(OUT / "sqlite" / "sqlite.db3", OUT / "bare.db3")

    split("split_mcap", StoragePlugin.MCAP, "mcap")
    split("split_sqlite", StoragePlugin.SQLITE3, "db3")

    write_ros1(OUT / "ros1_none.bag", None)
    write_ros1(OUT / "ros1_bz2.bag", Ros1Writer.CompressionFormat.BZ2)
    write_ros1(OUT / "ros1_lz4.bag", Ros1Writer.CompressionFormat.LZ4)

    (OUT / "expected.json").write_text(
        json.dumps({"cdr": expected(MSGS2), "ros1": expected(MSGS1)}, indent=1) + "\n"
    )
    print(f"rosbags {version('rosbags')}, mcap {version('mcap')}: wrote {OUT}")
    for p in sorted(OUT.rglob("*")):
        if p.is_file() and p.name != "README.md":
            print(f"  {p.relative_to(OUT)}: {p.stat().st_size} bytes")


if __name__ == "__main__":
    main()
