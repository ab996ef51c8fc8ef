#!/usr/bin/env python3
"""The I/O floor of a conversion: what any tool must do with the files, and nothing else.

    io_floor.py semantickitti ROOT OUT [--workers N]
    io_floor.py raw ROOT OUT [--workers N]

semantickitti: read every scan's .bin and .label, write one 64 x 2048 x 6 float32 .npy per scan
(the peer's and `convert --preset full`'s output size). raw: read every KITTI raw scan's .bin and
its camera-2 PNG file (not decoded: decoders differ, Pillow's is slower than kitti2pgm's), write
one 64 x 512 x 9 float32 .npy per frame (`convert --rgb`'s size). No projection, no labels, no
decoding: zeros are written. N processes share the files (default 1).

Prints the seconds the work took, timed once the processes are started (Python's start and the
pool's, about 0.25 s, are no part of a floor for a native tool). The ratio peer time / floor
time is the most any tool can be faster than the peer on that machine; docs/performance.md
reports it beside kitti2pgm's.
"""
import glob
import os
import sys
import time
from multiprocessing import Pool

import numpy as np


def scans(kind, root):
    """(scan, its labels or image, output name) of every frame."""
    if kind == "semantickitti":
        for b in sorted(glob.glob(os.path.join(root, "sequences", "*", "velodyne", "*.bin"))):
            seq = b.split(os.sep)[-3]
            label = os.path.join(os.path.dirname(os.path.dirname(b)), "labels", os.path.basename(b)[:-4] + ".label")
            yield b, label, f"{seq}_{os.path.basename(b)[:-4]}"
    else:
        for b in sorted(glob.glob(os.path.join(root, "20*", "*_sync", "velodyne_points", "data", "*.bin"))):
            drive = os.path.dirname(os.path.dirname(os.path.dirname(b)))
            png = os.path.join(drive, "image_02", "data", os.path.basename(b)[:-4] + ".png")
            yield b, png, f"{os.path.basename(drive)}_{os.path.basename(b)[:-4]}"


def work(job):
    kind, out, frames = job
    grid = np.zeros((64, 2048, 6) if kind == "semantickitti" else (64, 512, 9), np.float32)
    for scan, other, name in frames:
        np.fromfile(scan, np.float32)
        np.fromfile(other, np.uint8)
        np.save(os.path.join(out, name + ".npy"), grid)
    return len(frames)


def main():
    args = sys.argv[1:]
    workers = 1
    if "--workers" in args:
        i = args.index("--workers")
        workers = int(args[i + 1])
        args = args[:i] + args[i + 2:]
    if len(args) != 3 or args[0] not in ("semantickitti", "raw"):
        sys.exit(__doc__)
    kind, root, out = args
    frames = list(scans(kind, root))
    if not frames:
        sys.exit(f"{root}: no {kind} scans")
    os.makedirs(out, exist_ok=True)
    with Pool(workers) as pool:
        pool.map(abs, range(workers))  # the workers started before the clock
        start = time.perf_counter()
        pool.map(work, [(kind, out, frames[k::workers]) for k in range(workers)])
        print(f"{time.perf_counter() - start:.6f}")


if __name__ == "__main__":
    main()
