"""Shards -> network inputs: channel selection, normalisation, masks, flip augmentation, batches.

Frames come from ``kitti2pgm_data.ShardDataset``. Each input group of the model (``INPUTS``) is
built from the frame's channels by name, normalised with per-channel mean and standard deviation
(from ``kitti2pgm stats --json``, else SqueezeSeg's constants) and multiplied by the mask, so
empty cells are exactly 0 as in SqueezeSeg. The batch order is a pure function of the seed and the
step (one permutation per epoch), so a resumed run sees the same batches as an uninterrupted one.
"""

from __future__ import annotations

import glob
import json
import os
from typing import Dict, List, Optional, Sequence

import numpy as np
import torch
from kitti2pgm_data import ShardDataset, read_metadata

from .models import INPUTS

# SqueezeSeg's KITTI constants (x, y, z, intensity, range); colour has no published constants:
# 0.5 / 0.25 puts [0, 1] values around zero. Used when no stats file is given.
DEFAULT_MEAN = {"x": 10.88, "y": 0.23, "z": -1.04, "intensity": 0.21, "range": 12.12, "r": 0.5, "g": 0.5, "b": 0.5}
DEFAULT_STD = {"x": 11.47, "y": 6.91, "z": 0.86, "intensity": 0.16, "range": 12.32, "r": 0.25, "g": 0.25, "b": 0.25}
STATS_VERSION = 2


def find_shards(spec: str, split: Optional[str] = None) -> List[str]:
    """Shard paths from a folder (its ``<split>-*.mcap``), a glob or a file."""
    if os.path.isdir(spec):
        pattern = os.path.join(spec, f"{split}-*.mcap" if split else "*.mcap")
        paths = sorted(glob.glob(pattern))
        # A convert output folder: its map shards, else its point shards.
        for sub in ("shards", "points"):
            if not paths and os.path.isdir(os.path.join(spec, sub)):
                paths = sorted(glob.glob(os.path.join(spec, sub, f"{split}-*.mcap" if split else "*.mcap")))
    else:
        paths = sorted(glob.glob(spec))
    if not paths:
        raise FileNotFoundError(f"no {split + ' ' if split else ''}shard in {spec}")
    return paths


def describe_map(m: dict) -> str:
    """A map's shape in words: ``64 x 512 over 90 deg, rows rings``."""
    s = m["spec"]
    return f"{s['rows']} x {s['cols']} over {s['fov']:g} deg, rows {s['row_mode']}"


def describe_classes(m: dict) -> str:
    """A class map in words: its name and classes."""
    c = m["class_map"]
    return f"{c['name']} ({', '.join(k['name'] for k in c['classes'])})"


def check_same_map(paths: Sequence[str], recorded: dict, run: str) -> None:
    """Refuses shards whose map or class map is not the run's (``recorded``: the ``shard_params``
    of its ``config.json``), naming both: a network trained on one map scores garbage on
    another, and its outputs mean the classes it was trained on."""
    want = recorded["map"]
    for path in paths:
        here = read_metadata(path)["params"]["map"]
        if here["spec"] != want["spec"]:
            raise ValueError(f"{path}: its map is {describe_map(here)}, but {run} was trained on "
                             f"{describe_map(want)}; evaluate on shards converted with the run's map")
        if here["class_map"]["classes"] != want["class_map"]["classes"]:
            raise ValueError(f"{path}: its class map is {describe_classes(here)}, but {run} was trained on "
                             f"{describe_classes(want)}")


class Normaliser:
    """Per-channel mean and standard deviation, by channel name."""

    def __init__(self, mean: Dict[str, float], std: Dict[str, float], source: str):
        self.mean, self.std, self.source = mean, std, source

    @classmethod
    def from_stats(cls, stats: Optional[dict]) -> "Normaliser":
        if not stats:
            return cls(dict(DEFAULT_MEAN), dict(DEFAULT_STD), "SqueezeSeg defaults")
        n = stats["normalisation"]
        mean, std = dict(DEFAULT_MEAN), dict(DEFAULT_STD)
        for c, m, s in zip(n["channels"], n["mean"], n["std"]):
            mean[c], std[c] = float(m), float(s) if s > 0 else 1.0
        return cls(mean, std, f"kitti2pgm stats ({n['from_split']})")


def class_weights(stats: Optional[dict], mode: str, class_map: dict) -> List[float]:
    """Loss weights for the classes of ``class_map`` (the shards'): ``reference`` (the map's own,
    SqueezeSeg's [1/15, 1, 10, 10] for the paper's map), ``uniform`` (all 1; 0 for ignored
    classes), or from the stats file: ``sqrt`` (square root of inverse frequency) or ``inverse``.
    Without a stats file, ``reference`` (or ``uniform`` for a map without reference weights). A
    class absent from the stats keeps its reference weight (1 without one); ignored classes
    weigh 0."""
    n = len(class_map["classes"])
    ignore = set(class_map.get("ignore", []))
    uniform = [0.0 if k in ignore else 1.0 for k in range(n)]
    reference = class_map.get("reference_weights") or uniform
    if mode == "uniform":
        return uniform
    if mode == "reference" or not stats:
        return [float(v) for v in reference]
    if [c["name"] for c in stats["class_map"]["classes"]] != [c["name"] for c in class_map["classes"]]:
        raise ValueError("the stats file was made for other classes than the shards'")
    key = {"sqrt": "sqrt_inverse_frequency", "inverse": "inverse_frequency"}[mode]
    w = stats["class_weights"][key]
    return [0.0 if k in ignore else float(v) if v > 0 else float(reference[k]) for k, v in enumerate(w)]


def load_stats(path: Optional[str]) -> Optional[dict]:
    if not path:
        return None
    with open(path) as f:
        stats = json.load(f)
    if stats.get("version") != STATS_VERSION or "normalisation" not in stats:
        raise ValueError(f"{path}: not a kitti2pgm stats --json report (version {STATS_VERSION})")
    return stats


class FrameSet:
    """Frames of shards turned into the model's inputs."""

    def __init__(self, paths: Sequence[str], inputs: str, norm: Normaliser):
        self.ds = ShardDataset(paths)
        self.groups = INPUTS[inputs]
        self.norm = norm
        first = self.ds[0]
        self.channels = list(first["channels"])
        missing = sorted({c for g in self.groups for c in g} - set(self.channels))
        if missing:
            raise ValueError(f"input {inputs!r} needs channels {missing}; the shards have {self.channels} "
                             "(convert with --rgb for colour inputs)")
        self.index = {c: i for i, c in enumerate(self.channels)}
        self.height, self.width = first["tensor"].shape[:2]

    def __len__(self) -> int:
        return len(self.ds)

    def item(self, i: int, flip: bool = False, key=None) -> dict:
        f = self.ds[i]
        t = np.asarray(f["tensor"])
        mask = np.asarray(f["mask"]).astype(bool)
        label = np.asarray(f["label"]).astype(np.int64)
        if flip:
            # Mirror the columns (left <-> right) and negate y, as SqueezeSeg's augmentation.
            t, mask, label = t[:, ::-1], mask[:, ::-1], label[:, ::-1]
        return make_item(self, f["id"], t, mask, label, -1.0 if flip else 1.0)


def make_item(fs, fid: str, t: np.ndarray, mask: np.ndarray, label: np.ndarray, y_sign: float) -> dict:
    """The model's inputs from an H x W x C map ``t`` whose channels ``fs.index`` names: each
    input group normalised and masked (y times ``y_sign``), xyz, mask and label as tensors."""
    groups = []
    for g in fs.groups:
        x = np.stack([t[..., fs.index[c]] for c in g], 0).astype(np.float32)
        for k, c in enumerate(g):
            v = y_sign * x[k] if (y_sign != 1.0 and c == "y") else x[k]
            x[k] = (v - fs.norm.mean[c]) / fs.norm.std[c]
        groups.append(x * mask[None])
    xyz = np.stack([t[..., fs.index["x"]], t[..., fs.index["y"]] * y_sign, t[..., fs.index["z"]]], 0)
    return {
        "id": fid,
        "inputs": [torch.from_numpy(np.ascontiguousarray(g)) for g in groups],
        "xyz": torch.from_numpy(np.ascontiguousarray(xyz, dtype=np.float32)),
        "mask": torch.from_numpy(np.ascontiguousarray(mask)),
        "label": torch.from_numpy(np.ascontiguousarray(label)),
    }


class DeviceFrames:
    """The whole split decoded once into tensors on ``device`` (``--data-on-gpu``): batches are
    gathered, flipped and normalised there, with no worker and no copy from the host. The
    arithmetic is ``FrameSet.item``'s, in the same order on float32, so a batch is bit for bit
    the one the worker path builds for the same (frame, flip) keys (tested on CPU)."""

    def __init__(self, frames: FrameSet, device: torch.device):
        self.frames, self.device = frames, device
        ts, masks, labels, ids = [], [], [], []
        for i in range(len(frames)):
            f = frames.ds[i]
            ts.append(torch.from_numpy(np.ascontiguousarray(np.asarray(f["tensor"]).transpose(2, 0, 1))))
            masks.append(torch.from_numpy(np.asarray(f["mask"]).astype(bool)))
            labels.append(torch.from_numpy(np.asarray(f["label"]).astype(np.int64)))
            ids.append(f["id"])
        self.t = torch.stack(ts).to(device)          # N x C x H x W, raw channels
        self.mask = torch.stack(masks).to(device)    # N x H x W
        self.label = torch.stack(labels).to(device)  # N x H x W
        self.ids = ids

    @staticmethod
    def bytes_needed(frames: FrameSet) -> int:
        """Device memory the split takes (tensor float32, label int64, mask bool)."""
        c = len(frames.channels)
        return len(frames) * frames.height * frames.width * (4 * c + 8 + 1)

    def batch(self, keys: Sequence) -> dict:
        """The batch of ``keys`` [(frame index, flip)], as ``collate`` of ``FrameSet.item``."""
        fs = self.frames
        idx = torch.tensor([k[0] for k in keys], device=self.device)
        flip = torch.tensor([bool(k[1]) for k in keys], device=self.device)
        t, mask, label = self.t[idx], self.mask[idx], self.label[idx]
        fl = flip.view(-1, 1, 1)
        t = torch.where(fl.unsqueeze(1), t.flip(-1), t)
        mask = torch.where(fl, mask.flip(-1), mask)
        label = torch.where(fl, label.flip(-1), label)
        sign = torch.where(flip, -1.0, 1.0).view(-1, 1, 1)
        groups = []
        for g in fs.groups:
            planes = []
            for c in g:
                v = t[:, fs.index[c]]
                if c == "y":
                    v = v * sign
                planes.append((v - fs.norm.mean[c]) / fs.norm.std[c])
            groups.append(torch.stack(planes, 1) * mask.unsqueeze(1))
        xyz = torch.stack([t[:, fs.index["x"]], t[:, fs.index["y"]] * sign, t[:, fs.index["z"]]], 1)
        return {"id": [self.ids[k[0]] for k in keys], "inputs": groups, "xyz": xyz, "mask": mask, "label": label}


def collate(items: List[dict]) -> dict:
    return {
        "id": [it["id"] for it in items],
        "inputs": [torch.stack([it["inputs"][k] for it in items]) for k in range(len(items[0]["inputs"]))],
        "xyz": torch.stack([it["xyz"] for it in items]),
        "mask": torch.stack([it["mask"] for it in items]),
        "label": torch.stack([it["label"] for it in items]),
    }


def batch_indices(n: int, batch: int, step: int, seed: int, rank: int = 0, world: int = 1) -> List[int]:
    """The frame indices of one rank's part of global batch ``step``: a pure function of its
    arguments (the stream is one seeded permutation of the frames per epoch)."""
    per_step = batch * world
    start = step * per_step + rank * batch
    out = []
    for pos in range(start, start + batch):
        epoch, k = divmod(pos, n)
        out.append(int(np.random.default_rng([seed, epoch]).permutation(n)[k]))
    return out


def flips(step: int, seed: int, size: int) -> List[bool]:
    """Which items of a batch are mirrored (p = 0.5, seeded by step)."""
    return (np.random.default_rng([seed, 1_000_003, step]).random(size) < 0.5).tolist()


class StepBatches(torch.utils.data.Sampler):
    """The batches of steps ``start .. steps`` as lists of (frame index, flip, (step, position)),
    for a DataLoader with ``batch_sampler``: the same batches as the single-process loop, in any
    number of workers. The (step, position) key seeds a sample's 3D augmentation (point shards)."""

    def __init__(self, n: int, batch: int, start: int, steps: int, seed: int, flip: bool, rank: int = 0,
                 world: int = 1):
        self.n, self.batch, self.start, self.steps = n, batch, start, steps
        self.seed, self.flip, self.rank, self.world = seed, flip, rank, world

    def __len__(self) -> int:
        return max(self.steps - self.start, 0)

    def __iter__(self):
        for step in range(self.start, self.steps):
            idx = batch_indices(self.n, self.batch, step, self.seed, self.rank, self.world)
            fl = flips(step, self.seed, len(idx))
            yield [(i, f and self.flip, (step, k)) for k, (i, f) in enumerate(zip(idx, fl))]


class TorchFrames(torch.utils.data.Dataset):
    """``FrameSet`` as a torch Dataset indexed by (frame index, flip)."""

    def __init__(self, frames: FrameSet):
        self.frames = frames

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, key):
        i, flip, sample = key
        return self.frames.item(i, flip=flip, key=sample)
