#!/usr/bin/env python3
"""Reading one frame at random: ShardReader (and ShardDataset) against np.load of its .npy.

Usage: read_bench.py CONVERTED_DIR [--repeat N]
CONVERTED_DIR holds lidar_2d/*.npy and shards/*.mcap of the same frames (convert --format
npy,mcap). Times are medians over N random frames (page cache warm: every file is read once
first), measured in one run, and printed with their ratio.
"""
import glob
import os
import statistics
import sys
import time

import numpy as np
from kitti2pgm_data import ShardDataset


def main():
    d = sys.argv[1]
    repeat = int(sys.argv[sys.argv.index("--repeat") + 1]) if "--repeat" in sys.argv else 2000
    shards = sorted(glob.glob(os.path.join(d, "shards", "*.mcap")))
    ds = ShardDataset(shards)  # chunk CRCs checked (the default)
    fast = ShardDataset(shards, validate_crc=False)
    ids = [ds[i]["id"] for i in range(len(ds))]  # warms the page cache and opens the shards
    [fast[i] for i in range(len(fast))]
    npys = [os.path.join(d, "lidar_2d", f"{i}.npy") for i in ids]
    for p in npys:
        np.load(p)
    rng = np.random.default_rng(0)
    order = rng.integers(0, len(ds), repeat)
    t_npy, t_shard, t_fast = [], [], []
    for i in order:
        t0 = time.perf_counter()
        a = np.load(npys[i])
        t1 = time.perf_counter()
        f = ds[int(i)]
        t2 = time.perf_counter()
        fast[int(i)]
        t3 = time.perf_counter()
        t_npy.append(t1 - t0)
        t_shard.append(t2 - t1)
        t_fast.append(t3 - t2)
    assert a.shape[:2] == f["tensor"].shape[:2]
    m_npy, m_shard, m_fast = (statistics.median(t) * 1e3 for t in (t_npy, t_shard, t_fast))
    print(f"{len(ds)} frames in {len(shards)} shards, {repeat} random reads")
    print(f"np.load(.npy)                          median {m_npy:.3f} ms")
    print(f"ShardDataset[i] (CRCs checked)         median {m_shard:.3f} ms   ratio shard/npy {m_shard / m_npy:.2f}")
    print(f"ShardDataset[i] (validate_crc=False)   median {m_fast:.3f} ms   ratio shard/npy {m_fast / m_npy:.2f}")


if __name__ == "__main__":
    main()
