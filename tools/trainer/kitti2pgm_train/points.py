"""Predictions carried back to every point (``evaluate --points``): each val frame's predicted map
reaches the points of its scan through ``kitti2pgm.unproject`` (cell, or RangeNet++'s kNN), the
points' own labels (the converter's) are the truth, and the per-point predictions are written
in the source's layout: SemanticKITTI ``sequences/<NN>/predictions/<frame6>.label`` (raw ids),
KITTI raw and object ``labels/<drive>/<frame>.label`` (class ids, 0xFFFF outside the map), as
``kitti2pgm unproject`` writes them."""

from __future__ import annotations

import os

import numpy as np
import torch

from .metrics import Confusion

NOT_PREDICTED = 0xFFFF


def prediction_path(out: str, fid: str) -> str:
    """Where a frame's per-point predictions go (``kitti2pgm unproject``'s layout)."""
    if len(fid) == 9 and fid[2] == "_":  # SemanticKITTI: <NN>_<frame6>
        return os.path.join(out, "sequences", fid[:2], "predictions", f"{fid[3:]}.label")
    if len(fid) == 6:  # the object set
        return os.path.join(out, "labels", "object", f"{fid}.label")
    date, drive, frame = fid[:10], fid[11:15], fid[16:]
    return os.path.join(out, "labels", f"{date}_drive_{drive}_sync", f"{frame}.label")


class PointEvaluation:
    """Carries each predicted map back to its scan's points and counts them."""

    def __init__(self, raw: str, spec: dict, class_map: dict, method: str, knn: dict, out: str):
        import kitti2pgm  # the native module (tools/install.sh)

        self.k2 = kitti2pgm
        self.ds = kitti2pgm.Dataset(raw, class_map=class_map["name"])
        self.spec = dict(rows=spec["rows"], cols=spec["cols"], fov_deg=spec["fov"], fov_up_deg=spec["fov_up"],
                         fov_down_deg=spec["fov_down"], row_mode=spec["row_mode"].lower())
        self.class_map, self.method, self.knn, self.out = class_map, method, knn, out
        self.inverse = class_map.get("learning_map_inv") or None
        self.conf = Confusion(class_map)
        self.not_predicted = 0
        self.points = 0

    def add(self, fid: str, pred: np.ndarray) -> None:
        f = self.ds[fid]
        pts = f["points"]
        m = self.k2.project(pts, **self.spec)
        cls = self.k2.unproject(pred, m["row"], m["col"], pts, m["map"][..., 4], method=self.method,
                                class_map=self.class_map["name"], **self.knn)
        inside = cls >= 0
        self.conf.add(torch.from_numpy(cls[inside].astype(np.int64)), torch.from_numpy(f["label"][inside].astype(np.int64)),
                      torch.ones(int(inside.sum()), dtype=torch.bool))
        # Every point of the .bin, in file order; dropped and outside points not predicted.
        full = np.full(f["file_len"], -1, np.int64)
        full[f["file_index"]] = cls
        if self.inverse:
            raw = np.where(full >= 0, np.asarray(self.inverse, np.int64)[np.maximum(full, 0)], 0)
        else:
            raw = np.where(full >= 0, full, NOT_PREDICTED)
        self.not_predicted += int((full < 0).sum())
        self.points += len(full)
        path = prediction_path(self.out, fid)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        tmp = os.path.join(os.path.dirname(path), f".tmp-{os.getpid()}-{os.path.basename(path)}")
        raw.astype("<u4").tofile(tmp)
        os.replace(tmp, path)
