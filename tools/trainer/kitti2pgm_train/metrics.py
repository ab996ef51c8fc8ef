"""IoU exactly as ``kitti2pgm score`` (cell protocol) for any class map: one confusion matrix over
all valid cells whose truth is not an ignored class, IoU = TP / (TP + FP + FN), mIoU over the
class map's ``miou`` classes (car, pedestrian, cyclist for the paper's map), a class absent from
truth and prediction left out of the mean."""

from __future__ import annotations

from typing import Any, Dict, Optional

import torch


class Confusion:
    """A confusion matrix over the classes of a class map (as stored in the shards' metadata)."""

    def __init__(self, class_map: dict):
        self.names = [c["name"] for c in class_map["classes"]]
        self.k = len(self.names)
        self.ignore = list(class_map.get("ignore", []))
        self.miou_ids = list(class_map["miou"])
        # SemanticKITTI's benchmark counts a class absent from truth and prediction as 0.
        self.absent_zero = class_map.get("absent_in_miou") == "zero"
        self.m = torch.zeros(self.k, self.k, dtype=torch.int64)

    def add(self, pred: torch.Tensor, label: torch.Tensor, mask: torch.Tensor) -> None:
        """Adds the valid cells of a batch (pred, label: N x H x W ints; mask: N x H x W bool)."""
        keep = mask.clone()
        for c in self.ignore:
            keep &= label != c
        p, t = pred[keep].to(torch.int64).cpu(), label[keep].to(torch.int64).cpu()
        self.m += torch.bincount(t * self.k + p, minlength=self.k * self.k).view(self.k, self.k)

    def iou(self, c: int) -> Optional[float]:
        tp = int(self.m[c, c])
        fp = int(self.m[:, c].sum()) - tp
        fn = int(self.m[c, :].sum()) - tp
        d = tp + fp + fn
        return tp / d if d else None

    def miou(self) -> float:
        ious = [self.iou(c) for c in self.miou_ids]
        v = [0.0 if x is None else x for x in ious] if self.absent_zero else [x for x in ious if x is not None]
        return sum(v) / len(v) if v else 0.0

    def as_dict(self) -> Dict[str, Any]:
        return {"iou": {self.names[c]: self.iou(c) for c in range(self.k)}, "miou": self.miou(),
                "confusion": self.m.tolist()}

    def table(self) -> str:
        f = lambda v: "-" if v is None else f"{v:.4f}"  # noqa: E731
        rows = [f"{'class':<12} {'IoU':>8}"] + [f"{self.names[c]:<12} {f(self.iou(c)):>8}" for c in range(self.k)]
        over = ", ".join(self.names[c] for c in self.miou_ids)
        rows.append(f"mIoU ({over}): {self.miou():.4f}")
        return "\n".join(rows)
