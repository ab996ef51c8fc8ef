"""IoU exactly as ``kitti2pgm score`` (cell protocol): one confusion matrix over all valid cells,
IoU = TP / (TP + FP + FN), mIoU over car, pedestrian, cyclist, a class absent from truth and
prediction left out of the mean."""

from __future__ import annotations

from typing import Dict, Optional

import torch

CLASSES = ["background", "car", "pedestrian", "cyclist"]


class Confusion:
    def __init__(self, k: int = 4):
        self.k = k
        self.m = torch.zeros(k, k, dtype=torch.int64)

    def add(self, pred: torch.Tensor, label: torch.Tensor, mask: torch.Tensor) -> None:
        """Adds the valid cells of a batch (pred, label: N x H x W ints; mask: N x H x W bool)."""
        p, t = pred[mask].to(torch.int64).cpu(), label[mask].to(torch.int64).cpu()
        self.m += torch.bincount(t * self.k + p, minlength=self.k * self.k).view(self.k, self.k)

    def iou(self, c: int) -> Optional[float]:
        tp = int(self.m[c, c])
        fp = int(self.m[:, c].sum()) - tp
        fn = int(self.m[c, :].sum()) - tp
        d = tp + fp + fn
        return tp / d if d else None

    def miou(self) -> float:
        v = [x for x in (self.iou(c) for c in range(1, self.k)) if x is not None]
        return sum(v) / len(v) if v else 0.0

    def as_dict(self) -> Dict[str, object]:
        return {"iou": {CLASSES[c]: self.iou(c) for c in range(self.k)}, "miou": self.miou(),
                "confusion": self.m.tolist()}

    def table(self) -> str:
        f = lambda v: "-" if v is None else f"{v:.4f}"  # noqa: E731
        rows = [f"{'class':<12} {'IoU':>8}"] + [f"{CLASSES[c]:<12} {f(self.iou(c)):>8}" for c in range(self.k)]
        rows.append(f"mIoU (car, pedestrian, cyclist): {self.miou():.4f}")
        return "\n".join(rows)
