"""Shard reading: chunk indexes, chunk decompression, and the ``kitti2pgm.Frame`` message.

The frame message is protobuf (its FileDescriptorSet is the channel's schema, so generic tools
decode it too). Its fields are a handful of scalars, strings and byte arrays, so it is parsed
here from the protobuf wire format directly, which keeps the package free of a protobuf
dependency and lets the arrays be zero-copy views of the decompressed chunk.
"""

from __future__ import annotations

import mmap
import os
import struct
import zlib
from typing import Dict, Iterable, Iterator, List, Optional, Union

import numpy as np
from mcap.reader import NonSeekingReader, make_reader

FRAME_TOPIC = "/kitti2pgm/frame"
_OP_CHUNK = 0x06
_OP_MESSAGE = 0x05
METADATA_NAME = "kitti2pgm"

PathLike = Union[str, "os.PathLike[str]"]


class ShardError(Exception):
    """A shard that cannot be read; the message names the shard and the frame."""


# Field numbers of kitti2pgm.Frame (docs/shard-format.md).
_SCALARS = {3: "frame_index", 4: "timestamp_ns", 5: "height", 6: "width"}
_STRINGS = {1: "id", 2: "drive", 13: "split"}
_BYTES = {8: "tensor", 9: "label", 10: "instance", 11: "mask", 12: "rgb_valid"}


def _varint(buf: memoryview, pos: int):
    result = shift = 0
    while True:
        b = buf[pos]
        pos += 1
        result |= (b & 0x7F) << shift
        if b < 0x80:
            return result, pos
        shift += 7


def decode_frame(data: Union[bytes, memoryview]) -> Dict[str, object]:
    """Decodes one ``kitti2pgm.Frame`` message into a dict of numpy arrays and scalars."""
    buf = memoryview(data)
    fields: Dict[str, object] = {"frame_index": 0, "timestamp_ns": 0, "height": 0, "width": 0,
                                 "id": "", "drive": "", "split": ""}
    raw: Dict[str, memoryview] = {}
    channels: List[str] = []
    pos, end = 0, len(buf)
    while pos < end:
        key, pos = _varint(buf, pos)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, pos = _varint(buf, pos)
            if number in _SCALARS:
                fields[_SCALARS[number]] = value
        elif wire == 2:
            n, pos = _varint(buf, pos)
            chunk = buf[pos:pos + n]
            if len(chunk) != n:
                raise ValueError("truncated frame message")
            pos += n
            if number in _STRINGS:
                fields[_STRINGS[number]] = bytes(chunk).decode()
            elif number == 7:
                channels.append(bytes(chunk).decode())
            elif number in _BYTES:
                raw[_BYTES[number]] = chunk
        elif wire == 1:
            pos += 8
        elif wire == 5:
            pos += 4
        else:
            raise ValueError(f"unsupported protobuf wire type {wire}")
    h, w = int(fields["height"]), int(fields["width"])
    c = len(channels)

    def arr(name: str, dtype: str, shape) -> np.ndarray:
        b = raw.get(name, memoryview(b""))
        need = int(np.prod(shape)) * np.dtype(dtype).itemsize
        if len(b) != need:
            raise ValueError(f"{name} has {len(b)} bytes, expected {need}")
        return np.frombuffer(b, dtype=dtype).reshape(shape)

    def optional(name: str, dtype: str, shape):
        # Absent in prediction messages, which carry the label map only.
        return arr(name, dtype, shape) if len(raw.get(name, b"")) else None

    fields["channels"] = channels
    fields["tensor"] = arr("tensor", "<f4", (h, w, c)) if c else optional("tensor", "<f4", (h, w, c))
    fields["label"] = arr("label", "u1", (h, w))
    fields["instance"] = optional("instance", "<u2", (h, w))
    fields["mask"] = optional("mask", "u1", (h, w))
    fields["rgb_valid"] = optional("rgb_valid", "u1", (h, w))
    return fields


class ShardReader:
    """Random access to the frames of one shard.

    Opening reads the summary (chunk indexes, channels, statistics) only; ``reader[i]`` then
    reads and decompresses the one chunk that holds frame ``i`` (frames are in frame-id order).
    An uncompressed shard is read without any copy: the arrays are views of the mapped file.
    ``validate_crc`` checks each chunk's CRC (costs a pass over the data).
    """

    def __init__(self, path: PathLike, validate_crc: bool = False):
        self.path = os.fspath(path)
        self.validate_crc = validate_crc
        try:
            self._file = open(self.path, "rb")
            self._map = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError) as e:
            raise ShardError(f"{self.path}: cannot open: {e}") from e
        try:
            summary = make_reader(self._file).get_summary()
        except Exception as e:  # mcap raises several types for a truncated file
            raise ShardError(f"{self.path}: unreadable summary (truncated or unfinished shard?): {e}") from e
        if summary is None:
            raise ShardError(f"{self.path}: no summary section: the shard was not finished")
        frame_channels = {cid for cid, ch in summary.channels.items() if ch.topic == FRAME_TOPIC}
        if not frame_channels:
            raise ShardError(f"{self.path}: no {FRAME_TOPIC} channel")
        self._frame_channels = frame_channels
        chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        # Every frame message is alone in its chunk (the writer's chunk size is below one frame).
        self._chunks = [c for c in chunks if frame_channels & set(c.message_index_offsets)]
        self._summary = summary

    def __len__(self) -> int:
        return len(self._chunks)

    def close(self) -> None:
        self._map.close()
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _frame_data(self, index) -> memoryview:
        """The frame message bytes of one chunk (parsed by hand from the MCAP spec's Chunk and
        Message layouts, so that an uncompressed chunk is never copied)."""
        start, length = index.chunk_start_offset, index.chunk_length
        m = self._map
        if start + length > len(m) or m[start] != _OP_CHUNK:
            raise ValueError(f"no chunk record at byte {start} (truncated or corrupted shard?)")
        pos = start + 9
        _t0, _t1, usize, ucrc, clen = struct.unpack_from("<QQQIi", m, pos)
        pos += 8 + 8 + 8 + 4 + 4
        compression = bytes(m[pos:pos + clen]).decode()
        pos += clen
        (rlen,) = struct.unpack_from("<Q", m, pos)
        pos += 8
        payload = memoryview(m)[pos:pos + rlen]
        if len(payload) != rlen:
            raise ValueError("chunk records run past the end of the file")
        if compression == "":
            data = payload
        elif compression == "lz4":
            import lz4.frame  # installed with mcap, which needs it too

            data = memoryview(lz4.frame.decompress(payload))
        elif compression == "zstd":
            import zstandard  # installed with mcap, which needs it too

            data = memoryview(zstandard.ZstdDecompressor().decompress(payload, max_output_size=usize))
        else:
            raise ValueError(f"unsupported chunk compression {compression!r}")
        if len(data) != usize:
            raise ValueError(f"chunk decompressed to {len(data)} bytes, expected {usize}")
        if self.validate_crc and ucrc != 0 and zlib.crc32(data) != ucrc:
            raise ValueError("chunk CRC mismatch (corrupted shard)")
        found = None
        p, end = 0, len(data)
        while p < end:
            op = data[p]
            (n,) = struct.unpack_from("<Q", data, p + 1)
            body = data[p + 9:p + 9 + n]
            if op == _OP_MESSAGE:
                (channel,) = struct.unpack_from("<H", body, 0)
                if channel in self._frame_channels:
                    if found is not None:
                        raise ValueError("more than one frame in the chunk")
                    found = body[22:]
            p += 9 + n
        if found is None:
            raise ValueError("no frame message in the chunk")
        return found

    def __getitem__(self, i: int) -> Dict[str, object]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"{self.path}: frame {i} of {len(self)}")
        try:
            return decode_frame(self._frame_data(self._chunks[i]))
        except Exception as e:
            raise ShardError(f"{self.path}: frame #{i}: {e}") from e

    def __iter__(self) -> Iterator[Dict[str, object]]:
        for i in range(len(self)):
            yield self[i]

    def metadata(self) -> Dict[str, str]:
        return read_metadata(self.path)


def read_metadata(path: PathLike) -> Dict[str, str]:
    """The shard's ``kitti2pgm`` metadata record (version, params, drives, frames, failed, split)."""
    with open(path, "rb") as f:
        for m in make_reader(f).iter_metadata():
            if m.name == METADATA_NAME:
                return dict(m.metadata)
    raise ShardError(f"{os.fspath(path)}: no {METADATA_NAME} metadata record")


def iter_frames(paths: Union[PathLike, Iterable[PathLike]]) -> Iterator[Dict[str, object]]:
    """Yields every frame of the shards, shard by shard, in frame-id order.

    Streams the file from the start, so it also reads a shard whose summary was lost: the frames
    before a corrupted or truncated point are yielded, then ``ShardError`` names the shard and the
    frame that could not be read.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    for path in paths:
        path = os.fspath(path)
        n = 0
        last: Optional[str] = None
        try:
            with open(path, "rb") as f:
                # Stream from the start (never from the summary), so that a shard whose end is
                # lost still gives its first frames.
                reader = NonSeekingReader(f)
                for _schema, channel, message in reader.iter_messages(topics=[FRAME_TOPIC], log_time_order=False):
                    frame = decode_frame(message.data)
                    yield frame
                    n += 1
                    last = str(frame["id"])
        except ShardError:
            raise
        except Exception as e:
            after = f" after frame {last}" if last else ""
            raise ShardError(f"{path}: frame #{n}{after}: corrupted or truncated: {e}") from e
