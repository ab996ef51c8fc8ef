"""What training and evaluation share: progress display, devices, distributed set-up, seeding,
atomic checkpoints, the loss."""

from __future__ import annotations

import os
import random
import subprocess
import sys
import time
from typing import Optional

import numpy as np
import torch
import torch.nn.functional as F


def say(message: str) -> None:
    """A line for the person running the trainer (stderr)."""
    print(f"kitti2pgm_train: {message}", file=sys.stderr, flush=True)


class Progress:
    """Progress on stderr: a live line with rate and ETA on a terminal, and a plain line at each
    log step elsewhere (a log file, a CI job). ``start`` is where a resumed run begins, so that
    the rate counts this run's work only."""

    def __init__(self, total: int, what: str, start: int = 0):
        self.total, self.what, self.tty = total, what, sys.stderr.isatty()
        self.start, self.t0 = start, time.perf_counter()

    def _status(self, done: int) -> str:
        rate = (done - self.start) / max(time.perf_counter() - self.t0, 1e-9)
        eta = (self.total - done) / rate if rate > 0 else 0.0
        h, rest = divmod(int(eta), 3600)
        return f"{self.what} {done}/{self.total} ({rate:.1f} steps/s, ETA {h}:{rest // 60:02}:{rest % 60:02})"

    def update(self, done: int, extra: str = "") -> None:
        """The live line (terminal only)."""
        if self.tty:
            sys.stderr.write(f"\r{self._status(done)} {extra}   ")
            sys.stderr.flush()

    def line(self, done: int, extra: str = "") -> None:
        """A plain line, where there is no live one."""
        if not self.tty:
            print(f"{self._status(done)} {extra}", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.tty:
            sys.stderr.write("\n")


def git_commit() -> Optional[str]:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=os.path.dirname(__file__)).stdout.strip()
    except Exception:
        return None


def dist_info():
    """(rank, world size, local rank) from torchrun's environment, (0, 1, 0) otherwise."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    return int(os.environ.get("RANK", "0")), world, int(os.environ.get("LOCAL_RANK", "0"))


def pick_device(name: str, local_rank: int) -> torch.device:
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda":
        return torch.device("cuda", local_rank)
    return torch.device(name)


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def atomic_save(obj, path: str) -> None:
    tmp = path + ".tmp"
    torch.save(obj, tmp)
    os.replace(tmp, path)


def masked_loss(logits, label, mask, weight):
    """Class-weighted cross entropy averaged over the valid cells (SqueezeSeg's loss)."""
    ce = F.cross_entropy(logits, label, weight=weight, reduction="none")
    m = mask.float()
    return (ce * m).sum() / m.sum().clamp(min=1.0)


def lr_at(step: int, lr: float, halve_every: int) -> float:
    return lr * (0.5 ** (step // halve_every)) if halve_every > 0 else lr


