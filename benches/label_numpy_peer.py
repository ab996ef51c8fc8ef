#!/usr/bin/env python3
"""Benchmark peer for `kitti2pgm label` (issue 46): points in rotated boxes, as users write it.

label_numpy_peer.py scene SCENE --frames N --boxes B [--seed S]
    Writes a SUSTechPOINTS scene (SCENE/label/<frame6>.json, SCENE/lidar/) of N frames with B
    boxes each around the VLP-16 scan's points (centres within 25 m, 0.5-6 m sizes, turned about
    z and a little about x and y; types Car, Pedestrian, Truck, BicycleRider), seeded.
label_numpy_peer.py label ROOT SCENE OUT [--workers N]
    Labels every ROOT/sequences/00/velodyne/<frame6>.pcd (binary PCD) by the boxes of
    SCENE/label/<frame6>.json: numpy reads the scan, each box's rotation is built from its Euler
    angles (Rx * Ry * Rz, SUSTechPOINTS' convention), the points are taken into the box's frame
    (one vectorised matrix product a box) and tested against its half extents; boxes are
    applied largest first so that the smallest holding a point wins (kitti2pgm's rule); the
    class (SUSTechPOINTS' map) and instance are written as OUT/<frame6>.label (u32, class |
    instance << 16). Parallel over scans with a process pool. Prints scans/s on its last line.
"""
import argparse
import glob
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from pcd_numpy_peer import read_pcd  # the PCD reader of the conversion peer, beside this file

CLASSES = {"Car": 1, "Truck": 2, "Pedestrian": 4, "BicycleRider": 5}


def make_scene(args):
    rng = np.random.default_rng(args.seed)
    os.makedirs(os.path.join(args.scene, "label"), exist_ok=True)
    os.makedirs(os.path.join(args.scene, "lidar"), exist_ok=True)
    types = list(CLASSES)
    for f in range(args.frames):
        objs = []
        for i in range(args.boxes):
            r, a = rng.uniform(2, 25), rng.uniform(-np.pi, np.pi)
            centre = [r * np.cos(a), r * np.sin(a), rng.uniform(-1.5, 0.5)]
            size = list(rng.uniform(0.5, 6.0, 3))
            rot = [rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(-np.pi, np.pi)]
            xyz = lambda v: {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])}  # noqa: E731
            objs.append({"obj_type": types[i % len(types)], "obj_id": str(i),
                         "psr": {"position": xyz(centre), "scale": xyz(size), "rotation": xyz(rot)}})
        with open(os.path.join(args.scene, "label", f"{f:06d}.json"), "w") as out:
            json.dump(objs, out)


def rotation(x, y, z):
    sx, cx, sy, cy, sz, cz = np.sin(x), np.cos(x), np.sin(y), np.cos(y), np.sin(z), np.cos(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rx @ ry @ rz


def label(job):
    scan, boxes_file, out = job
    a = read_pcd(scan)
    pts = np.stack([a["x"], a["y"], a["z"]], 1).astype(np.float32)
    with open(boxes_file) as f:
        objs = json.load(f)
    boxes = []
    for i, o in enumerate(objs):
        p = o["psr"]
        c = np.array([p["position"][k] for k in "xyz"], np.float32)
        s = np.array([p["scale"][k] for k in "xyz"], np.float32)
        r = rotation(*(p["rotation"][k] for k in "xyz")).astype(np.float32)
        boxes.append((float(np.prod(s)), i, c, s / 2, r, CLASSES.get(o["obj_type"], 0)))
    boxes.sort(key=lambda b: (-b[0], -b[1]))  # largest first: the smallest is written last
    cls = np.zeros(len(pts), np.uint32)
    inst = np.zeros(len(pts), np.uint32)
    for _, i, c, half, r, k in boxes:
        if k == 0:
            continue
        q = (pts - c) @ r  # the points in the box's frame
        inside = np.all(np.abs(q) <= half, axis=1)
        cls[inside] = k
        inst[inside] = i + 1
    (cls | inst << 16).astype("<u4").tofile(out)
    return 1


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("scene")
    s.add_argument("scene")
    s.add_argument("--frames", type=int, default=300)
    s.add_argument("--boxes", type=int, default=30)
    s.add_argument("--seed", type=int, default=1)
    lab = sub.add_parser("label")
    lab.add_argument("root")
    lab.add_argument("scene")
    lab.add_argument("out")
    lab.add_argument("--workers", type=int, default=os.cpu_count())
    args = ap.parse_args()
    if args.cmd == "scene":
        make_scene(args)
        return
    os.makedirs(args.out, exist_ok=True)
    scans = sorted(glob.glob(os.path.join(args.root, "sequences/00/velodyne/*.pcd")))
    jobs = []
    for scan in scans:
        stem = os.path.basename(scan)[:-4]
        jobs.append((scan, os.path.join(args.scene, "label", stem + ".json"), os.path.join(args.out, stem + ".label")))
    t = time.time()
    with ProcessPoolExecutor(args.workers) as pool:
        n = sum(pool.map(label, jobs, chunksize=8))
    dt = time.time() - t
    print(f"{n} scans in {dt:.3f} s: {n / dt:.1f} scans/s", file=sys.stderr)


if __name__ == "__main__":
    main()
