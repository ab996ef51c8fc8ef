"""The Python pipeline users write to run a segmentation model on scans: the same ONNX model
under onnxruntime, scans read with numpy, kitti2pgm's own Python `project` and `unproject`
(the kNN), one .label file per scan. The peer of `kitti2pgm infer` (benches/compare_infer.sh).

    python3 benches/infer_python_peer.py MODEL.onnx RAW_ROOT OUT [--threads N] [--engine-only MAPS]

--engine-only MAPS: only the engine, on the converted maps (MAPS/*.npy, the .npy layout: x y z
intensity range label ...): the floor `kitti2pgm infer` is measured against.
"""

import argparse
import glob
import json
import os
import time

import numpy as np
import onnxruntime


def session(model: str, threads: int):
    o = onnxruntime.SessionOptions()
    o.intra_op_num_threads = threads
    return onnxruntime.InferenceSession(model, o, providers=["CPUExecutionProvider"])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("raw")
    ap.add_argument("out")
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--engine-only", metavar="MAPS")
    a = ap.parse_args()
    s = session(a.model, a.threads)
    name = s.get_inputs()[0].name
    t0 = time.perf_counter()
    if a.engine_only:
        maps = sorted(glob.glob(os.path.join(a.engine_only, "*.npy")))
        inputs = [np.ascontiguousarray(np.load(f)[None, :, :, :5], dtype=np.float32) for f in maps]
        t0 = time.perf_counter()  # the maps are in memory: the model alone is timed
        for x in inputs:
            s.run(["labels"], {name: x})
        print(json.dumps({"frames": len(maps), "seconds": time.perf_counter() - t0}))
        return
    import kitti2pgm

    spec = json.loads(dict(s.get_modelmeta().custom_metadata_map)[kitti2pgm.MODEL_METADATA_KEY])
    m = spec["map"]["spec"]
    classes = spec["map"]["class_map"]["name"]
    scans = sorted(glob.glob(os.path.join(a.raw, "*", "*_sync", "velodyne_points", "data", "*.bin")))
    for path in scans:
        points = np.fromfile(path, dtype=np.float32).reshape(-1, 4)
        p = kitti2pgm.project(points, rows=m["rows"], cols=m["cols"], fov_deg=m["fov"], fov_up_deg=m["fov_up"],
                              fov_down_deg=m["fov_down"], row_mode=m["row_mode"])
        x = np.ascontiguousarray(p["map"][None, :, :, :5], dtype=np.float32)
        labels = s.run(["labels"], {name: x})[0][0].astype(np.uint8)
        per_point = kitti2pgm.unproject(labels, p["row"], p["col"], points, p["map"][..., 4],
                                        class_map=classes).astype(np.int64)
        drive = path.split(os.sep)[-4]
        dst = os.path.join(a.out, "labels", drive, os.path.basename(path)[:-4] + ".label")
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        np.where(per_point < 0, 0xFFFF, per_point).astype("<u4").tofile(dst)
    print(json.dumps({"frames": len(scans), "seconds": time.perf_counter() - t0}))


if __name__ == "__main__":
    main()
