"""Predictions carried back to every point (``evaluate --points``): each val frame's predicted map
reaches the points of its scan through ``kitti2pgm.unproject`` (cell, or RangeNet++'s kNN), the
points' own labels (the converter's) are the truth, and the per-point predictions are written by
the native module exactly as ``kitti2pgm unproject`` writes them (its layout and raw ids:
``kitti2pgm.write_point_predictions``)."""

from __future__ import annotations

import numpy as np
import torch

from .metrics import Confusion


class PointEvaluation:
    """Carries each predicted map back to its scan's points and counts them."""

    def __init__(self, raw: str, spec: dict, class_map: dict, method: str, knn: dict, out: str):
        import kitti2pgm  # the native module (tools/install.sh)

        self.k2 = kitti2pgm
        self.ds = kitti2pgm.Dataset(raw, class_map=class_map["name"])
        self.spec = dict(rows=spec["rows"], cols=spec["cols"], fov_deg=spec["fov"], fov_up_deg=spec["fov_up"],
                         fov_down_deg=spec["fov_down"], row_mode=spec["row_mode"])
        self.class_map, self.method, self.knn, self.out = class_map, method, knn, out
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
        self.conf.add(torch.from_numpy(cls[inside].astype(np.int64)),
                      torch.from_numpy(f["label"][inside].astype(np.int64)),
                      torch.ones(int(inside.sum()), dtype=torch.bool))
        # Every point of the .bin, in file order; dropped and outside points not predicted.
        full = np.full(f["file_len"], -1, np.int64)
        full[f["file_index"]] = cls
        _, missing = self.k2.write_point_predictions(self.out, fid, full, class_map=self.class_map["name"])
        self.not_predicted += missing
        self.points += len(full)
