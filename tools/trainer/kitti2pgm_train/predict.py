"""``predict --run DIR INPUT``: a run's PyTorch network on new scans, on the GPU when there is one.

Everything but the network is kitti2pgm's own code, as ``kitti2pgm infer`` runs the run's
exported ONNX model: the native module reads each scan, projects it with the map recorded for
the run (the record the export writes, built by the same function), and carries the map's
classes back to every point (RangeNet++'s kNN by default). Only the engine differs, so on the
CPU the classes equal the ONNX model's (up to ties between two classes' scores).

Written per scan, as ``kitti2pgm infer`` writes a lone scan file: ``OUT/<stem>.label``, one
little-endian uint32 per point of the file, its class id (0xffff: outside the map). A folder of
scans keeps its sub-folders under OUT.
"""

from __future__ import annotations

import os
from typing import Dict, List, Optional, Tuple

import numpy as np
import torch

from .common import pick_device

# What a scan file is called (kitti2pgm reads these).
SCAN_SUFFIXES = (".pcd.bin", ".pcd", ".bin")
NOT_PREDICTED = 0xFFFF


def _stem(name: str) -> str:
    for s in SCAN_SUFFIXES:
        if name.endswith(s):
            return name[: -len(s)]
    return os.path.splitext(name)[0]


def scans(inputs: List[str]) -> List[Tuple[str, str]]:
    """(scan file, its output name without suffix) for every INPUT: a file as itself (its stem),
    a folder as every scan file under it (its path relative to the folder). Two scans with one
    output name are an error."""
    out: List[Tuple[str, str]] = []
    for i in inputs:
        if os.path.isfile(i):
            out.append((i, _stem(os.path.basename(i))))
        elif os.path.isdir(i):
            found = []
            for d, _, files in os.walk(i):
                for f in files:
                    if f.endswith(SCAN_SUFFIXES) and not f.startswith("."):
                        p = os.path.join(d, f)
                        found.append((p, _stem(os.path.relpath(p, i))))
            if not found:
                raise ValueError(f"{i}: no scan file (.bin, .pcd, .pcd.bin) in it")
            out.extend(sorted(found))
        else:
            raise FileNotFoundError(f"{i}: no such file or folder")
    names: Dict[str, str] = {}
    for p, n in out:
        if n in names:
            raise ValueError(f"{p} and {names[n]} would both be written as {n}.label")
        names[n] = p
    return out


def _write_label(path: str, classes: np.ndarray) -> None:
    entries = np.where(classes < 0, NOT_PREDICTED, classes.astype(np.int64)).astype("<u4")
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        entries.tofile(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def predict(run: str, inputs: List[str], out: str, device: str = "auto", method: str = "knn",
            progress: Optional[object] = None) -> dict:
    """Runs the run's network on every scan of ``inputs`` into ``out``; returns a summary."""
    import kitti2pgm

    from .export import deployable, model_record

    files = scans(inputs)
    out_abs = os.path.abspath(out)
    for p, _ in files:
        if os.path.abspath(p).startswith(out_abs + os.sep):
            raise ValueError(f"{out}: the output would hold the input {p}")
    dev = pick_device(device, 0)
    net, _, config = deployable(run)
    net = net.to(dev)
    model = kitti2pgm.Model.from_record(model_record(config), name=f"{run} (PyTorch)")

    @torch.no_grad()
    def runner(x: np.ndarray) -> np.ndarray:
        labels, _ = net(torch.from_numpy(x).to(dev))
        return labels.cpu().numpy()

    classes = [c["name"] for c in config["class_map"]["classes"]]
    counts = np.zeros(len(classes), dtype=np.int64)
    points = missing = 0
    for p, name in files:
        r = model.predict_file(p, method=method, runner=runner)
        c = r["classes"]
        _write_label(os.path.join(out, name + ".label"), c)
        points += len(c)
        missing += int((c < 0).sum())
        counts += np.bincount(c[c >= 0].astype(np.int64), minlength=len(classes))[: len(classes)]
    return {"run": run, "device": str(dev), "method": method, "scans": len(files), "points": points,
            "not_predicted": missing, "classes": dict(zip(classes, counts.tolist())), "out": out}
