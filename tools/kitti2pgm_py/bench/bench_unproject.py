#!/usr/bin/env python3
"""RangeNet++'s kNN post-processing: kitti2pgm.unproject(method="knn") against the reference's
PyTorch formulation (unfold the range image and the argmax, topk, scatter-add vote; written here
from the algorithm), one thread each, the same inputs, 64 x 2048 maps of the SemanticKITTI scans.

Usage: bench_unproject.py [SCAN.bin ...] [--repeat N] [--warm N] [--floor] [--gaps]
(default: the fixture and shared scans)
Prints the medians and their ratio, measured in one run; checks the two agree point for point.
--warm N: also the best of N back-to-back kitti2pgm calls on each scan (a warm cache: the
benchmark's own calls each follow a PyTorch call).
--floor: also the floor, reading the call's input arrays (numpy sums over each) right after a
PyTorch call, as the benchmark's calls come (then another PyTorch call, so that the floor's read
warms nothing for kitti2pgm): the least any implementation's call takes here.
--gaps: also a kitti2pgm call after each kind of pause (median of --repeat calls on the first
scan): another kitti2pgm call (warm), busy Python loops of 1, 10 and 95 ms (touching no memory),
streaming a 16 MB array for 95 ms, and the PyTorch reference; which of them makes a call slow.
"""
import glob
import math
import pathlib
import statistics
import sys
import time

import kitti2pgm as k2
import numpy as np
import torch
import torch.nn.functional as F

REPO = pathlib.Path(__file__).resolve().parents[3]


def torch_knn(proj_range, unproj_range, proj_argmax, px, py, k=5, search=5, sigma=1.0, cutoff=1.0, nclasses=20):
    """The reference's steps in PyTorch (CPU)."""
    H, W = proj_range.shape
    pad = (search - 1) // 2
    unfold_r = F.unfold(proj_range[None, None], kernel_size=(search, search), padding=(pad, pad))
    idx = py * W + px
    r = unfold_r[:, :, idx]
    r[r < 0] = float("inf")
    r[:, (search * search - 1) // 2, :] = unproj_range
    d = torch.abs(r - unproj_range)
    x = torch.arange(search).repeat(search).view(search, search)
    xy = torch.stack([x, x.t()], dim=-1).float()
    mean, var = (search - 1) / 2.0, sigma ** 2
    g = (1.0 / (2.0 * math.pi * var)) * torch.exp(-torch.sum((xy - mean) ** 2, dim=-1) / (2 * var))
    g = (g / g.sum()).view(1, -1, 1)
    d = d * (1 - g)
    _, knn_idx = d.topk(k, dim=1, largest=False, sorted=False)
    unfold_a = F.unfold(proj_argmax[None, None].float(), kernel_size=(search, search), padding=(pad, pad)).long()
    a = torch.gather(unfold_a[:, :, idx], 1, knn_idx)
    if cutoff > 0:
        a[torch.gather(d, 1, knn_idx) > cutoff] = nclasses
    onehot = torch.zeros((1, nclasses + 1, len(idx)))
    onehot.scatter_add_(1, a, torch.ones_like(a, dtype=torch.float32))
    return onehot[:, 1:-1].argmax(dim=1)[0] + 1


def main():
    argv = sys.argv[1:]
    repeat, warm = 5, 0
    if "--repeat" in argv:
        i = argv.index("--repeat")
        repeat = int(argv[i + 1])
        argv = argv[:i] + argv[i + 2:]
    floor = "--floor" in argv
    gaps = "--gaps" in argv
    argv = [a for a in argv if a not in ("--floor", "--gaps")]
    if "--warm" in argv:
        i = argv.index("--warm")
        warm = int(argv[i + 1])
        argv = argv[:i] + argv[i + 2:]
    args = argv
    scans = args or sorted(glob.glob(str(REPO / "fixtures/semantickitti/sequences/*/velodyne/*.bin"))
                           + glob.glob(str(REPO / "../shared/semantickitti/sequences/*/velodyne/*.bin")))
    torch.set_num_threads(1)
    t_rust, t_torch, t_warm, t_floor, agree, total = [], [], [], [], 0, 0
    for path in scans:
        pts = k2.read_scan(path)
        m = k2.project(pts, cols=2048, fov_deg=360)
        rng = np.random.default_rng(0)
        pred = rng.integers(1, 20, (64, 2048)).astype(np.uint8)
        cell_range = np.ascontiguousarray(m["map"][..., 4])
        inside = m["row"] >= 0
        px = torch.from_numpy(m["col"][inside].astype(np.int64))
        py = torch.from_numpy(m["row"][inside].astype(np.int64))
        ur = torch.from_numpy(np.sqrt((pts[inside, :3] ** 2).sum(1)).astype(np.float32))
        pr = torch.from_numpy(np.where(m["mask"], cell_range, -1.0).astype(np.float32))
        pa = torch.from_numpy(pred.astype(np.int64))
        for _ in range(repeat):
            t0 = time.perf_counter()
            ours = k2.unproject(pred, m["row"], m["col"], pts, cell_range, method="knn")
            t1 = time.perf_counter()
            ref = torch_knn(pr, ur, pa, px, py)
            t2 = time.perf_counter()
            t_rust.append(t1 - t0)
            t_torch.append(t2 - t1)
        inputs = (pred, m["row"], m["col"], pts, cell_range)
        for _ in range(repeat if floor else 0):
            torch_knn(pr, ur, pa, px, py)
            t0 = time.perf_counter()
            for a in inputs:
                a.sum()
            t_floor.append(time.perf_counter() - t0)
            torch_knn(pr, ur, pa, px, py)
        for _ in range(warm):
            t0 = time.perf_counter()
            k2.unproject(pred, m["row"], m["col"], pts, cell_range, method="knn")
            t_warm.append(time.perf_counter() - t0)
        if gaps and path == scans[0]:
            args = (pred, m["row"], m["col"], pts, cell_range)
            gap_table = after_gaps(lambda args=args: k2.unproject(*args, method="knn"),
                                   lambda refs=(pr, ur, pa, px, py): torch_knn(*refs), repeat)
        agree += int((ours[inside] == ref.numpy()).sum())
        total += int(inside.sum())
    mr, mt = statistics.median(t_rust) * 1e3, statistics.median(t_torch) * 1e3
    print(f"{len(scans)} scans (64 x 2048, {total // len(scans)} points each), {repeat} runs each, 1 thread")
    print(f"PyTorch reference  median {mt:8.2f} ms/scan")
    print(f"kitti2pgm knn      median {mr:8.2f} ms/scan   speed-up {mt / mr:.0f}x")
    if t_floor:
        mf = statistics.median(t_floor) * 1e3
        print(f"floor: the inputs read  median {mf:8.2f} ms/scan   {mt / mf:.0f}x the reference's speed;"
              f" kitti2pgm takes {mr / mf:.1f}x its time")
    if t_warm:
        print(f"kitti2pgm knn      warm, best of {warm} calls a scan {min(t_warm) * 1e3:.2f} ms")
    print(f"agreement with torch.topk's tie order: {agree}/{total} points ({100 * agree / total:.3f}%)")
    if gaps:
        print(f"a kitti2pgm knn call after a pause (first scan, median of {repeat}):")
        for name, ms in gap_table:
            print(f"  {name:38s} {ms:6.2f} ms")


def after_gaps(call, reference, repeat):
    """Median time of `call` after each kind of pause."""
    def busy(seconds):
        t = time.perf_counter()
        while time.perf_counter() - t < seconds:
            pass
    big = np.ones(4 << 20, np.float32)

    def stream(seconds):
        t = time.perf_counter()
        while time.perf_counter() - t < seconds:
            big.sum()
    pauses = [("another kitti2pgm call (warm)", call), ("busy Python loop, 1 ms", lambda: busy(0.001)),
              ("busy Python loop, 10 ms", lambda: busy(0.010)), ("busy Python loop, 95 ms", lambda: busy(0.095)),
              ("streaming 16 MB, 95 ms", lambda: stream(0.095)), ("the PyTorch reference", reference)]
    table = []
    for name, pause in pauses:
        times = []
        for _ in range(max(repeat, 5)):
            pause()
            t0 = time.perf_counter()
            call()
            times.append(time.perf_counter() - t0)
        table.append((name, statistics.median(times) * 1e3))
    return table


if __name__ == "__main__":
    main()
