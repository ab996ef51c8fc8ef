"""A random-access dataset over several shards (PyTorch-style, without depending on torch)."""

from __future__ import annotations

import bisect
import os
from typing import Callable, Dict, Iterable, List, Optional, Union

import numpy as np

from .reader import PathLike, ShardError, ShardReader, check_complete, read_metadata, shard_paths


class ShardDataset:
    """Frames of several shards as one indexable dataset.

    ``len(ds)`` and ``ds[i]`` (random access, one chunk read per frame) make it usable with
    ``torch.utils.data.DataLoader`` directly (``shuffle=True`` shuffles by frame). Shards are opened
    lazily in each process, so the dataset can be handed to DataLoader workers. ``transform``, if
    given, is applied to each frame dict.

    ``paths`` is one shard (``str`` or ``Path``) or several. The shards must be of one kind (maps
    or points), made with the same map parameters, of finished conversions (``partial=True``
    reads an unfinished one, with a warning), and hold each frame once; otherwise
    ``ShardError`` names the shard. Chunk CRCs are checked on every read (``validate_crc``).
    """

    def __init__(self, paths: Union[PathLike, Iterable[PathLike]],
                 transform: Optional[Callable[[Dict], object]] = None, partial: bool = False,
                 validate_crc: bool = True):
        self.paths: List[str] = shard_paths(paths)
        if not self.paths:
            raise ValueError("no shard given")
        self.transform = transform
        self.validate_crc = validate_crc
        self.partial = check_complete(self.paths, partial)
        self.metadata = self._check_consistent()
        self._lengths = []
        for p in self.paths:
            with ShardReader(p) as r:
                self._lengths.append(len(r))
        self._starts = np.concatenate([[0], np.cumsum(self._lengths)]).tolist()
        self._readers: Dict[int, ShardReader] = {}
        self._pid = os.getpid()

    def _check_consistent(self) -> Dict:
        """The first shard's metadata, after checking every shard against it."""
        first = None
        seen: Dict[str, str] = {}
        for p in self.paths:
            md = read_metadata(p)
            if first is None:
                first = md
            elif md.get("content", "maps") != first.get("content", "maps"):
                raise ShardError(f"{p}: holds {md.get('content', 'maps')}, {self.paths[0]} holds "
                                 f"{first.get('content', 'maps')}: one kind of shard at a time")
            elif md["params"]["map"] != first["params"]["map"]:
                spec, spec0 = md["params"]["map"].get("spec"), first["params"]["map"].get("spec")
                raise ShardError(f"{p}: made with other map parameters than {self.paths[0]} "
                                 f"({spec} vs {spec0}): shards of two conversions")
            for f in md["frames"]:
                if f in md["failed"]:
                    continue
                if f in seen:
                    raise ShardError(f"{p}: frame {f} is also in {seen[f]} (shards of two conversions?)")
                seen[f] = p
        assert first is not None, "ShardDataset has at least one shard"
        return first

    def __len__(self) -> int:
        return int(self._starts[-1])

    def _reader(self, k: int) -> ShardReader:
        if os.getpid() != self._pid:  # a forked DataLoader worker: open its own files
            self._readers, self._pid = {}, os.getpid()
        r = self._readers.get(k)
        if r is None:
            r = self._readers[k] = ShardReader(self.paths[k], validate_crc=self.validate_crc)
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
