#!/usr/bin/env python3
"""Benchmarks of the native module, each a ratio measured in one process on the same real scans.

    python tools/kitti2pgm_py/bench/bench_project.py [--repeat 20]

1. ``kitti2pgm.project`` against the numpy projection of ``../shared/bench/semantickitti_numpy_baseline.py``
   (its ``convert`` without the file I/O: the same lines on arrays already in memory), 64 x 2048
   over 360 degrees with labels, on the SemanticKITTI scans of ``../shared`` (else the fixture's);
   one thread (the default), ``threads=2`` (two threads inside the call), and ``point_cells=False``
   (no per-point row and col: the trainer's call).
2. Two threads calling ``project`` at once against one (the GIL is released while Rust works).
3. DataLoader frames/s with one worker: point shards projected on the fly with
   ``--augment rotate,scale,jitter,drop,flip`` against precomputed map shards of the same frames,
   both lz4-compressed (the default), then both uncompressed.
"""

import argparse
import glob
import os
import pathlib
import subprocess
import sys
import tempfile
import threading
import time

import kitti2pgm
import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[3]
SHARED = REPO.parent / "shared"
H, UP, DOWN = 64, np.radians(3.0), np.radians(-25.0)


def peer_project(pts, lab, width):
    """semantickitti_numpy_baseline.convert, from its arrays on (no np.fromfile, no np.save)."""
    depth = np.linalg.norm(pts[:, :3], axis=1)
    keep = depth > 0
    pts, lab, depth = pts[keep], lab[keep], depth[keep]
    yaw = -np.arctan2(pts[:, 1], pts[:, 0])
    pitch = np.arcsin(pts[:, 2] / depth)
    u = np.clip(np.floor(0.5 * (yaw / np.pi + 1.0) * width), 0, width - 1).astype(np.int64)
    v = np.clip(np.floor((1.0 - (pitch - DOWN) / (UP - DOWN)) * H), 0, H - 1).astype(np.int64)
    order = np.argsort(depth)[::-1]
    grid = np.zeros((H, width, 6), np.float32)
    grid[v[order], u[order], :4] = pts[order]
    grid[v[order], u[order], 4] = depth[order]
    grid[v[order], u[order], 5] = lab[order]
    return grid


def best(f, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times), float(np.median(times))


def scans():
    root = SHARED / "semantickitti" if (SHARED / "semantickitti").is_dir() else REPO / "fixtures" / "semantickitti"
    ds = kitti2pgm.Dataset(root)
    lut = np.zeros(1 << 16, np.float32)
    for k, v in ds.class_map["learning_map"].items():
        lut[int(k)] = v
    out = []
    for fid in ds.frames:
        seq, frame = fid.split("_")
        raw = np.fromfile(root / "sequences" / seq / "velodyne" / f"{frame}.bin", np.float32).reshape(-1, 4)
        lab = lut[np.fromfile(root / "sequences" / seq / "labels" / f"{frame}.label", np.uint32) & 0xFFFF]
        f = ds.load(fid)
        out.append((fid, raw, lab, f["points"], f["label"]))
    return root, out


def bench_project(repeat):
    root, data = scans()
    print(f"1. project vs the numpy peer, 64 x 2048 over 360 deg, {len(data)} scans of {root}")
    tot_peer = tot_ours = tot_two = tot_bare = 0.0
    for fid, raw, lab, pts, labels in data:
        def ours(threads, point_cells=True, pts=pts, labels=labels):
            return kitti2pgm.project(pts, labels=labels, cols=2048, fov_deg=360.0, threads=threads,
                                     point_cells=point_cells)
        peer, _ = best(lambda raw=raw, lab=lab: peer_project(raw, lab, 2048), repeat)
        one, _ = best(lambda: ours(1), repeat)
        two, _ = best(lambda: ours(2), repeat)
        bare, _ = best(lambda: ours(1, point_cells=False), repeat)
        tot_peer += peer
        tot_ours += one
        tot_two += two
        tot_bare += bare
        print(f"   {fid}: {len(raw)} points, numpy {peer * 1e3:.2f} ms, kitti2pgm {one * 1e3:.2f} ms: "
              f"{peer / one:.1f}x; threads=2 {two * 1e3:.2f} ms: {peer / two:.1f}x; "
              f"point_cells=False {bare * 1e3:.2f} ms: {peer / bare:.1f}x")
    print(f"   all: {tot_peer / tot_ours:.1f}x faster on one thread, {tot_peer / tot_two:.1f}x with threads=2, "
          f"{tot_peer / tot_bare:.1f}x with point_cells=False (the trainer's call) "
          f"(best of {repeat}; {os.cpu_count()} cores)")
    fid, raw, lab, pts, labels = data[0]

    def run(n_threads, calls):
        def work():
            for _ in range(calls):
                kitti2pgm.project(pts, labels=labels, cols=2048, fov_deg=360.0)
        ts = [threading.Thread(target=work) for _ in range(n_threads)]
        t = time.perf_counter()
        for x in ts:
            x.start()
        for x in ts:
            x.join()
        return n_threads * calls / (time.perf_counter() - t)
    one, two = run(1, 4 * repeat), run(2, 4 * repeat)
    print(f"2. threads: {one:.0f} scans/s on 1 thread, {two:.0f} on 2: {two / one:.2f}x ({os.cpu_count()} cores)")


def bench_loader(steps):
    import torch
    from kitti2pgm_train.data import FrameSet, Normaliser, StepBatches, TorchFrames, collate
    from kitti2pgm_train.onthefly import Augmentation, open_frames

    exe = REPO / "target" / "release" / "kitti2pgm"
    if not exe.exists():
        exe = REPO / "target" / "debug" / "kitti2pgm"
    raw = SHARED / "kitti" / "raw" if (SHARED / "kitti" / "raw").is_dir() else REPO / "fixtures" / "raw"
    for compression in ("lz4", "none"):
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run([str(exe), "--no-progress", "convert", str(raw), "--out", tmp, "--format", "mcap,points",
                            "--compression", compression], check=True, capture_output=True)
            norm = Normaliser.from_stats(None)
            maps = FrameSet(sorted(glob.glob(os.path.join(tmp, "shards", "train-*.mcap"))), "xyzdi", norm)
            aug = Augmentation.parse("rotate,scale,jitter,drop,flip")
            points = open_frames(sorted(glob.glob(os.path.join(tmp, "points", "train-*.mcap"))), "xyzdi", norm, aug, 0)
            print(f"3. DataLoader, 1 worker, batch 8, {len(maps)} frames of {raw} (64 x 512), {steps} batches, "
                  f"--compression {compression}")
            rates = {}
            for name, fs in [("map shards", maps), ("point shards + augmentation", points),
                             ("map shards (again)", maps), ("point shards + augmentation (again)", points)]:
                loader = torch.utils.data.DataLoader(TorchFrames(fs),
                                                     batch_sampler=StepBatches(len(fs), 8, 0, steps + 2, 0, True),
                                                     collate_fn=collate, num_workers=1, prefetch_factor=2)
                it = iter(loader)
                next(it), next(it)  # worker start-up
                t = time.perf_counter()
                n = sum(len(b["id"]) for b in it)
                rates[name] = n / (time.perf_counter() - t)
                print(f"   {name}: {rates[name]:.1f} frames/s")
            m = max(rates["map shards"], rates["map shards (again)"])
            p = max(rates["point shards + augmentation"], rates["point shards + augmentation (again)"])
            print(f"   on the fly = {p / m:.2f} x the precomputed maps' rate (goal >= 0.5)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--steps", type=int, default=20)
    a = ap.parse_args()
    bench_project(a.repeat)
    bench_loader(a.steps)


if __name__ == "__main__":
    sys.exit(main())
