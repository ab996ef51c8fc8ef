#!/usr/bin/env python3
"""Benchmark peer for another sensor's PCD scans: what users write today (issue 27).

pcd_numpy_peer.py ROOT OUT_DIR --rows H --fov-up DEG --fov-down DEG [--width 1024] [--workers N]

Reads every ROOT/sequences/*/velodyne/*.pcd (binary PCD) with numpy (the header parsed, the
records as a structured array), projects the points to an H x W range image by elevation bins
between --fov-up and --fov-down (the answer users get: "change fov_up / fov_down and the image
height"), columns by azimuth over 360 degrees, the nearest point kept per cell, and saves float32
H x W x 6 arrays (x, y, z, intensity, range, label 0) as OUT_DIR/<seq>_<frame>.npy. Vectorised
numpy, parallel over scans with a process pool. Prints scans/s on its last line.
"""
import argparse
import glob
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def read_pcd(path):
    with open(path, "rb") as f:
        raw = f.read()
    head, _, body = raw.partition(b"DATA binary\n")
    h = dict(line.split(None, 1) for line in head.decode().splitlines() if line and not line.startswith("#"))
    names, sizes, types = h["FIELDS"].split(), h["SIZE"].split(), h["TYPE"].split()
    dtype = np.dtype([(n, f"<{t.lower()}{s}") for n, s, t in zip(names, sizes, types)])
    return np.frombuffer(body, dtype=dtype, count=int(h["POINTS"]))


def convert(job):
    scan, out, rows, width, up, down = job
    a = read_pcd(scan)
    pts = np.stack([a["x"], a["y"], a["z"]], 1).astype(np.float32)
    inten = a["intensity"].astype(np.float32) if "intensity" in a.dtype.names else np.zeros(len(a), np.float32)
    depth = np.linalg.norm(pts, axis=1)
    keep = np.isfinite(depth) & (depth > 0)
    pts, inten, depth = pts[keep], inten[keep], depth[keep]
    yaw = -np.arctan2(pts[:, 1], pts[:, 0])
    pitch = np.arcsin(pts[:, 2] / depth)
    u = np.clip(np.floor(0.5 * (yaw / np.pi + 1.0) * width), 0, width - 1).astype(np.int64)
    v = np.clip(np.floor((1.0 - (pitch - down) / (up - down)) * rows), 0, rows - 1).astype(np.int64)
    order = np.argsort(depth)[::-1]  # far first, so the nearest point is written last
    grid = np.zeros((rows, width, 6), np.float32)
    grid[v[order], u[order], :3] = pts[order]
    grid[v[order], u[order], 3] = inten[order]
    grid[v[order], u[order], 4] = depth[order]
    np.save(out, grid)
    return 1


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("root")
    ap.add_argument("out")
    ap.add_argument("--rows", type=int, required=True)
    ap.add_argument("--fov-up", type=float, required=True)
    ap.add_argument("--fov-down", type=float, required=True)
    ap.add_argument("--width", type=int, default=1024)
    ap.add_argument("--workers", type=int, default=1)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    up, down = np.radians(a.fov_up), np.radians(a.fov_down)
    jobs = []
    for scan in sorted(glob.glob(os.path.join(a.root, "sequences", "*", "velodyne", "*.pcd"))):
        seq = scan.split(os.sep)[-3]
        frame = os.path.basename(scan)[:-4]
        jobs.append((scan, os.path.join(a.out, f"{seq}_{frame}.npy"), a.rows, a.width, up, down))
    t = time.perf_counter()
    if a.workers > 1:
        with ProcessPoolExecutor(a.workers) as ex:
            n = sum(ex.map(convert, jobs, chunksize=4))
    else:
        n = sum(map(convert, jobs))
    dt = time.perf_counter() - t
    print(f"{n} scans in {dt:.2f} s: {n / dt:.1f} scans/s")


if __name__ == "__main__":
    sys.exit(main())
