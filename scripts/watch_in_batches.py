#!/usr/bin/env python3
"""Feeds a stereo image folder (sample_data/stereo's layout: cam0/, cam1/, target.yaml,
dvl.jsonl) without its camchain into a folder watched by `dvlcal watch`, in batches of frames:
each batch's images are written under hidden names and renamed into place together with the DVL
log cut at the same share of its reports, and the next batch is written once the watch has
printed an update for the last one. Then the log is touched TOUCH times, an update apart.

    python3 scripts/watch_in_batches.py DVLCAL SRC DIR UPDATES.json BATCH TOUCH

starts `DVLCAL watch DIR --json --interval 0.5 --until-idle 4 --no-progress --out DIR.yaml`
after the first batch, with the updates in UPDATES.json and its standard error in DIR.err, and
says on its standard error when each batch was written and how long the watch took to end after
its last update (the idle time and the final calibration).
"""

import os
import shutil
import subprocess
import sys
import time

dvlcal, src, dst, out = sys.argv[1:5]
batch, touch = int(sys.argv[5]), int(sys.argv[6])
names = sorted(os.listdir(os.path.join(src, "cam0")))
lines = open(os.path.join(src, "dvl.jsonl")).read().splitlines(True)
for cam in ("cam0", "cam1"):
    os.makedirs(os.path.join(dst, cam), exist_ok=True)
shutil.copy(os.path.join(src, "target.yaml"), dst)


def updates():
    try:
        with open(out) as f:
            return sum(1 for _ in f)
    except OSError:
        return 0


watch, k, start = None, 0, 0
while start < len(names):
    end = min(start + batch, len(names))
    if len(names) - end < batch // 2:
        end = len(names)
    for n in names[start:end]:
        for cam in ("cam0", "cam1"):
            shutil.copy(os.path.join(src, cam, n), os.path.join(dst, cam, "." + n))
    for n in names[start:end]:
        for cam in ("cam0", "cam1"):
            os.rename(os.path.join(dst, cam, "." + n), os.path.join(dst, cam, n))
    m = round(len(lines) * end / len(names))
    with open(os.path.join(dst, "dvl.jsonl.tmp"), "w") as f:
        f.writelines(lines[:m])
    os.rename(os.path.join(dst, "dvl.jsonl.tmp"), os.path.join(dst, "dvl.jsonl"))
    k += 1
    if watch is None:
        watch = subprocess.Popen(
            [dvlcal, "watch", dst, "--json", "--interval", "0.5", "--until-idle", "4",
             "--no-progress", "--out", dst + ".yaml"],
            stdout=open(out, "w"), stderr=open(dst + ".err", "w"))
    print(f"batch {k}: {end} frames, {m} DVL lines", file=sys.stderr, flush=True)
    while updates() < k:
        time.sleep(0.2)
    start = end
for _ in range(touch):
    time.sleep(1.5)
    os.utime(os.path.join(dst, "dvl.jsonl"))
    k += 1
    while updates() < k:
        time.sleep(0.2)
t_end = time.time()
watch.wait()
print(f"watch ended {time.time() - t_end:.1f} s after its last update (idle 4 s, then the "
      f"final calibration), exit status {watch.returncode}", file=sys.stderr)
