"""A random-access dataset over several shards (PyTorch-style, without depending on torch)."""

from __future__ import annotations

import bisect
import os
from typing import Callable, Dict, Iterable, List, Optional

import numpy as np

from .reader import PathLike, ShardReader


class ShardDataset:
    """Frames of several shards as one indexable dataset.

    ``len(ds)`` and ``ds[i]`` (random access, one chunk read per frame) make it usable with
    ``torch.utils.data.DataLoader`` directly (``shuffle=True`` shuffles by frame). Shards are opened
    lazily in each process, so the dataset can be handed to DataLoader workers. ``transform``, if
    given, is applied to each frame dict.
    """

    def __init__(self, paths: Iterable[PathLike], transform: Optional[Callable[[Dict], object]] = None):
        self.paths: List[str] = [os.fspath(p) for p in paths]
        if not self.paths:
            raise ValueError("no shard given")
        self.transform = transform
        self._lengths = []
        for p in self.paths:
            with ShardReader(p) as r:
                self._lengths.append(len(r))
        self._starts = np.concatenate([[0], np.cumsum(self._lengths)]).tolist()
        self._readers: Dict[int, ShardReader] = {}
        self._pid = os.getpid()

    def __len__(self) -> int:
        return int(self._starts[-1])

    def _reader(self, k: int) -> ShardReader:
        if os.getpid() != self._pid:  # a forked DataLoader worker: open its own files
            self._readers, self._pid = {}, os.getpid()
        r = self._readers.get(k)
        if r is None:
            r = self._readers[k] = ShardReader(self.paths[k])
        return r

    def locate(self, i: int):
        """(shard index, frame index in that shard) of global index ``i``."""
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"frame {i} of {len(self)}")
        k = bisect.bisect_right(self._starts, i) - 1
        return k, i - int(self._starts[k])

    def __getitem__(self, i: int):
        k, j = self.locate(i)
        frame = self._reader(k)[j]
        return self.transform(frame) if self.transform else frame

    def shuffled_indices(self, seed: int = 0) -> np.ndarray:
        """A permutation of the frame indices (numpy's PCG64 seeded with ``seed``)."""
        return np.random.default_rng(seed).permutation(len(self))

    def close(self) -> None:
        for r in self._readers.values():
            r.close()
        self._readers = {}

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_readers"] = {}
        return state
