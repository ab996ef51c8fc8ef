#!/usr/bin/env python3
"""Two builds of the module in one process, their kNN calls alternating (the order flipped every
call), on the fixture scan (64 x 2048, random predictions): the fairest comparison of two
versions on a noisy machine. Checks that both give the same classes first.

Build each version's module with `cargo build --release -p kitti2pgm-py` and copy
`target/release/libkitti2pgm_py.so` aside, then:

Usage: ab_unproject.py OLD.so NEW.so [CALLS]   (default 1500 calls a side)
Prints each side's best and median (ms) and new / old.
"""

import importlib.machinery
import importlib.util
import pathlib
import sys
import time

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[3]


def load(path):
    loader = importlib.machinery.ExtensionFileLoader("kitti2pgm", path)
    spec = importlib.util.spec_from_file_location("kitti2pgm", path, loader=loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    old, new = load(sys.argv[1]), load(sys.argv[2])
    calls = int(sys.argv[3]) if len(sys.argv) == 4 else 1500
    pts = new.read_scan(str(REPO / "fixtures/semantickitti/sequences/00/velodyne/000000.bin"))
    m = new.project(pts, cols=2048, fov_deg=360)
    pred = np.random.default_rng(0).integers(1, 20, (64, 2048)).astype(np.uint8)
    cell_range = np.ascontiguousarray(m["map"][..., 4])
    args = (pred, m["row"], m["col"], pts, cell_range)
    if not (old.unproject(*args, method="knn") == new.unproject(*args, method="knn")).all():
        sys.exit("the two builds disagree")
    times = {"old": [], "new": []}
    for i in range(calls):
        pair = (("old", old), ("new", new)) if i % 2 == 0 else (("new", new), ("old", old))
        for name, module in pair:
            t0 = time.perf_counter()
            module.unproject(*args, method="knn")
            times[name].append(time.perf_counter() - t0)
    o, n = (np.array(times[k]) * 1e3 for k in ("old", "new"))
    print(
        f"old best {o.min():.3f} median {np.median(o):.3f} ms; new best {n.min():.3f} "
        f"median {np.median(n):.3f} ms; new/old best {n.min() / o.min():.3f} "
        f"median {np.median(n) / np.median(o):.3f}"
    )


if __name__ == "__main__":
    main()
