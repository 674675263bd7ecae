#!/usr/bin/env python3
"""Writes a large ROS 2 MCAP bag for reader benchmarks, with rosbags (PyPI): about N GB of raw
mono8 stereo Image messages (752x480, /cam0/image_raw and /cam1/image_raw, 20 Hz) and
marine_acoustic_msgs/Dvl on /dvl/velocity_report (10 Hz). Such bags are made at benchmark time
and never committed.

    python3 -m venv /tmp/rbs && /tmp/rbs/bin/pip install rosbags numpy pillow
    /tmp/rbs/bin/python scripts/make_bench_bag.py --gb 5                     # -> /tmp/dvlcal_bench_5gb/
    /tmp/rbs/bin/python scripts/make_bench_bag.py --gb 1 --out /tmp/b1 --compression zstd
    /tmp/rbs/bin/python scripts/make_bench_bag.py --jpeg-sample --out /tmp/dvlcal-bench/stereo_jpeg

--jpeg-sample writes instead all 251 stereo frames of sample_data/stereo as
sensor_msgs/CompressedImage (the JPEG files' bytes unchanged) on /cam0/image_raw/compressed and
/cam1/image_raw/compressed, with header stamps from the file names, and every velocity report of
its dvl.jsonl as Dvl: the same images as the folder, for comparing the two readers' throughput.

The images loop over --frames distinct frames of sample_data/stereo (decoded once with Pillow,
the only image data held in memory), while the stamps advance by 50 ms per stereo pair and never
repeat; the DVL loops over the velocity reports of sample_data/stereo/dvl.jsonl with stamps
advancing by 100 ms. Record times are the stamps plus a seeded latency of 15-45 ms, as in
scripts/make_sample_bags.py. Chunks are rosbags' (1 MiB; uncompressed, or zstd at rosbags' level
with --compression zstd). The bag stops at the first stereo pair that brings the serialized
message bytes to N * 10^9 or more.

On a 2-core machine with 60 MB of resident memory: 1 GB in about 5 s uncompressed (about 25 s
with --compression zstd, 0.49 GB on disk), 5 GB in about 45 s.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from make_sample_bags import (  # noqa: E402  (the typestore with Dvl and the message builders)
    DVL,
    STEREO,
    TS2,
    compressed_msg,
    dvl_msg,
    image_msg,
    jpeg_path,
    tov_ns,
    latency_ns,
    mono8,
    read_reports,
)
from rosbags.rosbag2 import Writer  # noqa: E402
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin  # noqa: E402

T0_NS = 1_700_000_000_000_000_000
IMAGE_PERIOD_NS = 50_000_000  # 20 Hz
DVL_PERIOD_NS = 100_000_000  # 10 Hz
DVL_OFFSET_NS = 25_000_000  # DVL stamps between the image stamps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gb", type=float, help="serialized message bytes to write, in 10^9 bytes")
    ap.add_argument("--jpeg-sample", action="store_true", help="the whole sample_data/stereo as CompressedImage")
    ap.add_argument("--out", type=Path, help="bag folder to create (default /tmp/dvlcal_bench_<N>gb)")
    ap.add_argument("--compression", choices=("none", "zstd"), default="none")
    ap.add_argument("--frames", type=int, default=8, help="distinct stereo frames to loop over (memory: 0.72 MB each)")
    ap.add_argument("--force", action="store_true", help="replace --out if it exists")
    args = ap.parse_args()
    if args.jpeg_sample:
        out = args.out or Path("/tmp/dvlcal-bench/stereo_jpeg")
        if out.exists():
            if not args.force:
                raise SystemExit(f"{out} exists; pass --force to replace it")
            shutil.rmtree(out)
        jpeg_sample(out)
        return
    if args.gb is None:
        raise SystemExit("give --gb N or --jpeg-sample")
    out = args.out or Path(f"/tmp/dvlcal_bench_{args.gb:g}gb")
    if out.exists():
        if not args.force:
            raise SystemExit(f"{out} exists; pass --force to replace it")
        shutil.rmtree(out)
    budget = int(args.gb * 1e9)

    stamps = sorted(int(p.stem) for p in (STEREO / "cam0").glob("*.jpg"))
    picked = [stamps[i * len(stamps) // args.frames] for i in range(args.frames)]
    pixels = [{cam: mono8(cam, t) for cam in ("cam0", "cam1")} for t in picked]
    reports = [rep for _, rep in read_reports(STEREO / "dvl.jsonl")]

    writer = Writer(out, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP)
    if args.compression == "zstd":
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    start = time.monotonic()
    written = images = dvls = 0
    with writer:
        conns = {
            "cam0": writer.add_connection("/cam0/image_raw", "sensor_msgs/msg/Image", typestore=TS2),
            "cam1": writer.add_connection("/cam1/image_raw", "sensor_msgs/msg/Image", typestore=TS2),
            "dvl": writer.add_connection("/dvl/velocity_report", DVL, typestore=TS2),
        }
        block = 0
        while written < budget:
            # One 100 ms block: two stereo pairs and one DVL report, written in record-time order
            # (latencies are at most 45 ms, so blocks never overlap in record time).
            msgs = []
            for k in range(2):
                if written >= budget:
                    break
                pair = 2 * block + k
                t = T0_NS + pair * IMAGE_PERIOD_NS
                for cam in ("cam0", "cam1"):
                    data = TS2.serialize_cdr(image_msg(t, cam, pixels[pair % args.frames][cam]), "sensor_msgs/msg/Image")
                    msgs.append((t + latency_ns(cam, t), cam, data))
                    written += len(data)
                images += 2
            t = T0_NS + block * DVL_PERIOD_NS + DVL_OFFSET_NS
            data = TS2.serialize_cdr(dvl_msg(reports[block % len(reports)], stamp_ns=t), DVL)
            msgs.append((t + latency_ns("/dvl/velocity_report", t), "dvl", data))
            written += len(data)
            dvls += 1
            for rec, key, data in sorted(msgs, key=lambda m: (m[0], m[1])):
                writer.write(conns[key], rec, data)
            block += 1
            if block % 1000 == 0:
                print(f"  {written / 1e9:.2f} GB, {time.monotonic() - start:.0f} s", file=sys.stderr)
    elapsed = time.monotonic() - start
    size = sum(p.stat().st_size for p in out.iterdir())
    print(
        f"{out}: {images} images, {dvls} Dvl, {written / 1e9:.3f} GB of messages, {size / 1e9:.3f} GB on disk "
        f"({args.compression}), {elapsed:.1f} s ({written / 1e6 / elapsed:.0f} MB/s)"
    )


def jpeg_sample(out: Path) -> None:
    """All of sample_data/stereo as CompressedImage (JPEG bytes unchanged) plus its DVL log."""
    out.parent.mkdir(parents=True, exist_ok=True)
    stamps = sorted(int(p.stem) for p in (STEREO / "cam0").glob("*.jpg"))
    msgs = []
    for t in stamps:
        for cam in ("cam0", "cam1"):
            jpeg = jpeg_path(cam, t).read_bytes()
            data = TS2.serialize_cdr(compressed_msg(t, cam, jpeg), "sensor_msgs/msg/CompressedImage")
            msgs.append((t + latency_ns(cam, t), cam, data))
    for _, rep in read_reports(STEREO / "dvl.jsonl"):
        t = tov_ns(rep)
        data = TS2.serialize_cdr(dvl_msg(rep), DVL)
        msgs.append((t + latency_ns("/dvl/velocity_report", t), "dvl", data))
    writer = Writer(out, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP)
    with writer:
        conns = {
            "cam0": writer.add_connection("/cam0/image_raw/compressed", "sensor_msgs/msg/CompressedImage", typestore=TS2),
            "cam1": writer.add_connection("/cam1/image_raw/compressed", "sensor_msgs/msg/CompressedImage", typestore=TS2),
            "dvl": writer.add_connection("/dvl/velocity_report", DVL, typestore=TS2),
        }
        for rec, key, data in sorted(msgs, key=lambda m: (m[0], m[1])):
            writer.write(conns[key], rec, data)
    size = sum(p.stat().st_size for p in out.iterdir())
    print(f"{out}: {len(stamps)} stereo JPEG frames, {size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
