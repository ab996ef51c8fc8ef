"""Point shards -> network inputs on the fly: 3D augmentation, then the ring-exact projection of
the native module (``import kitti2pgm``), in the DataLoader workers.

``convert --format points`` writes each scan's points with their laser rings, labels and colours.
Here every sample is augmented in 3D (``--augment rotate,scale,jitter,drop,flip``) and projected
by ``kitti2pgm.project``, the converter's own projection: rows stay the rings of the original scan
order (a rotation about z shifts columns, it never moves a point to another row). A sample's
augmentation is a pure function of the run's seed, the step and the sample's position in the batch,
so runs are reproducible and ``--resume`` sees the same samples. Without augmentation a sample is
exactly the map ``convert`` writes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np
from kitti2pgm_data import ShardDataset, ShardReader, read_metadata

from .data import FrameSet, Normaliser, make_item
from .models import INPUTS

AUGMENTS = ("rotate", "scale", "jitter", "drop", "flip")


@dataclass(frozen=True)
class Augmentation:
    """Which 3D augmentations are drawn per sample, and their ranges."""

    rotate_deg: float = 0.0            # uniform in [-rotate_deg, rotate_deg] about z
    scale: Tuple[float, float] = (1.0, 1.0)  # uniform scale factor
    jitter_m: float = 0.0              # bell-shaped noise on x, y, z (standard deviation, metres; bounded)
    drop: float = 0.0                  # probability of dropping each point
    flip: bool = False                 # asked for by name; the mirror itself is the sampler's flip

    @classmethod
    def parse(cls, names: str, rotate_deg: float = 180.0, scale: Tuple[float, float] = (0.95, 1.05),
              jitter_m: float = 0.01, drop: float = 0.1) -> "Augmentation":
        """From ``--augment rotate,scale,jitter,drop,flip`` (any subset; empty = none)."""
        chosen = [n.strip() for n in names.split(",") if n.strip()]
        unknown = sorted(set(chosen) - set(AUGMENTS))
        if unknown:
            raise ValueError(f"--augment: unknown {unknown}; choose from {','.join(AUGMENTS)}")
        if not 0.0 <= drop < 1.0 or jitter_m < 0 or not 0 < scale[0] <= scale[1]:
            raise ValueError("--augment ranges: drop in [0, 1), jitter >= 0, 0 < scale low <= high")
        on = set(chosen)
        return cls(rotate_deg=rotate_deg if "rotate" in on else 0.0,
                   scale=(scale[0], scale[1]) if "scale" in on else (1.0, 1.0),
                   jitter_m=jitter_m if "jitter" in on else 0.0,
                   drop=drop if "drop" in on else 0.0,
                   flip="flip" in on)

    def draw(self, seed: int, key: Optional[Tuple[int, int]], flip: bool) -> Dict[str, Any]:
        """The keyword arguments of ``kitti2pgm.project`` for one sample; ``key`` = (step,
        position in the batch); no key = no augmentation (validation, prediction)."""
        if key is None:
            return {}
        rng = np.random.default_rng([seed, 7_000_003, int(key[0]), int(key[1])])
        rotate = float(rng.uniform(-self.rotate_deg, self.rotate_deg)) if self.rotate_deg else 0.0
        lo, hi = self.scale
        scale = float(rng.uniform(lo, hi)) if hi > lo else float(lo)
        return {"rotate_deg": rotate, "scale": scale, "flip": bool(flip),
                "jitter": self.jitter_m, "drop": self.drop, "seed": int(rng.integers(0, 2**63 - 1))}


def shard_kind(path: str) -> str:
    """"maps" or "points"."""
    with ShardReader(path) as r:
        return r.kind


class PointFrameSet:
    """Frames of point shards, projected (and augmented) per sample; the interface of
    ``FrameSet`` (``item``, ``channels``, ``height``, ``width``)."""

    def __init__(self, paths: Sequence[str], inputs: str, norm: Normaliser,
                 augment: Augmentation = Augmentation(), seed: int = 0, map_args: Optional[dict] = None):
        import kitti2pgm  # the native module: pip install ./tools/kitti2pgm_py

        self.project = kitti2pgm.project
        self.ds = ShardDataset(paths)
        self.groups = INPUTS[inputs]
        self.norm, self.augment, self.seed = norm, augment, seed
        map_params = read_metadata(paths[0])["params"]["map"]
        spec = map_params["spec"]
        self.map_args = map_args or {
            "rows": spec["rows"], "cols": spec["cols"], "fov_deg": spec["fov"], "fov_up_deg": spec["fov_up"],
            "fov_down_deg": spec["fov_down"], "row_mode": spec["row_mode"]}
        if map_args is None and map_params.get("sensor"):
            # Another sensor's shards: each point's ring is its beam row, of this many beams.
            self.map_args["beams"] = map_params["sensor"]["beams"]
        first = self.sample(0)
        self.channels = [c for c in first["channels"] if c != "label"]
        missing = sorted({c for g in self.groups for c in g} - set(self.channels))
        if missing:
            raise ValueError(f"input {inputs!r} needs channels {missing}; the point shards have {self.channels} "
                             "(convert with --rgb for colour inputs)")
        self.index = {c: i for i, c in enumerate(first["channels"])}
        self.height, self.width = first["map"].shape[:2]

    def __len__(self) -> int:
        return len(self.ds)

    def sample(self, i: int, flip: bool = False, key=None) -> dict:
        """Frame ``i`` projected with the augmentation of ``key`` (none without a key)."""
        f = self.ds[i]
        kw = dict(self.map_args)
        kw.update(self.augment.draw(self.seed, key, flip))
        if f["rgb"] is not None:
            kw.update(rgb=f["rgb"], rgb_valid=f["rgb_valid"].astype(bool))
        m = self.project(f["points"], rings=f["ring"], labels=f["label"], instance=f["instance"], point_cells=False,
                         **kw)
        m["id"] = f["id"]
        return m

    def item(self, i: int, flip: bool = False, key=None) -> dict:
        m = self.sample(i, flip, key)
        # A mirror is done in 3D (y is already negated in the map): no column flip here.
        return make_item(self, m["id"], m["map"], m["mask"], m["label"].astype(np.int64), 1.0)


def open_frames(paths: Sequence[str], inputs: str, norm: Normaliser, augment: Augmentation = Augmentation(),
                seed: int = 0):
    """``FrameSet`` for map shards, ``PointFrameSet`` for point shards (augmentation applies to
    point shards only)."""
    if shard_kind(paths[0]) == "points":
        return PointFrameSet(paths, inputs, norm, augment, seed)
    if augment not in (Augmentation(), Augmentation(flip=True)):
        raise ValueError("--augment rotate/scale/jitter/drop needs point shards (convert --format points); "
                         f"{paths[0]} holds maps")
    return FrameSet(paths, inputs, norm)
