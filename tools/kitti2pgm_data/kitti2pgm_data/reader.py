"""Shard reading: chunk indexes, chunk decompression, and the ``kitti2pgm.Frame`` message.

The frame message is protobuf (its FileDescriptorSet is the channel's schema, so generic tools
decode it too). Its fields are a handful of scalars, strings and byte arrays, so it is parsed
here from the protobuf wire format directly, with the field numbers read from the shard's own
schema (``schema.FrameSchema``); this keeps the package free of a protobuf dependency and lets
the arrays be zero-copy views of the decompressed chunk. Frames are found by their schema name,
``kitti2pgm.Frame``, on whatever topic they are.
"""

from __future__ import annotations

import json
import mmap
import os
import stat
import struct
import warnings
import zlib
from typing import Any, Dict, Iterable, Iterator, List, Optional, Union

import numpy as np
from mcap.opcode import Opcode
from mcap.reader import NonSeekingReader, make_reader

from .schema import FRAME_SCHEMA, POINTS_SCHEMA, FrameSchema, fields

# The MCAP spec's record layout: opcode (1 byte), content length (u64 little-endian), content.
_RECORD_HEAD = 1 + 8
# Chunk content before its compression string: message start and end time, uncompressed size
# (u64 each), uncompressed CRC (u32), compression string length (u32).
_CHUNK_HEAD = struct.Struct("<QQQII")
# Message content before its data: channel id (u16), sequence (u32), log and publish time (u64).
_MESSAGE_HEAD = struct.Struct("<HIQQ")
METADATA_NAME = "kitti2pgm"

PathLike = Union[str, "os.PathLike[str]"]


class ShardError(Exception):
    """A shard that cannot be read; the message names the shard and the frame."""


def open_regular(path: str):
    """Opens ``path`` for binary reading when it is a regular file (links followed); a link that
    leads nowhere, a folder, a FIFO (reading would wait forever) or a device is a ``ShardError``
    naming it, as the Rust reader refuses them."""
    try:
        st = os.stat(path)
    except OSError as e:
        kind = "a link that leads nowhere" if os.path.islink(path) else f"cannot open: {e}"
        raise ShardError(f"{path}: {kind}") from e
    if not stat.S_ISREG(st.st_mode):
        kind = ("a folder" if stat.S_ISDIR(st.st_mode) else "a named pipe (FIFO)" if stat.S_ISFIFO(st.st_mode)
                else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "not a file")
        raise ShardError(f"{path}: {kind}, not a regular file")
    return open(path, "rb")


# The arrays of a frame: dtype and whether the array has a third, channel axis.
_ARRAYS = {"tensor": ("<f4", True), "label": ("u1", False), "instance": ("<u2", False),
           "mask": ("u1", False), "rgb_valid": ("u1", False)}


def _fields(data: Union[bytes, memoryview], schema: FrameSchema):
    """The message's scalars, strings and string lists (absent ones at their protobuf defaults),
    and its byte fields as memoryviews of ``data``."""
    out: Dict[str, Any] = {}
    raw: Dict[str, memoryview] = {}
    lists: Dict[str, List[str]] = {}
    for number, _wire, value in fields(data):
        if number not in schema.by_number:
            continue  # a field this version does not know
        name, kind, repeated = schema.by_number[number]
        if kind == "string":
            text = bytes(value).decode()
            if repeated:
                lists.setdefault(name, []).append(text)
            else:
                out[name] = text
        elif kind == "bytes":
            raw[name] = value
        else:
            out[name] = value
    for name, (_num, kind, repeated) in schema.by_name.items():
        if repeated:
            out.setdefault(name, lists.get(name, []))
        elif kind == "string":
            out.setdefault(name, "")
        elif kind != "bytes":
            out.setdefault(name, 0)
    return out, raw


def decode_frame(data: Union[bytes, memoryview], schema: FrameSchema) -> Dict[str, Any]:
    """Decodes one ``kitti2pgm.Frame`` message, field numbers taken from ``schema`` (the shard's
    own), into a dict of scalars, strings and numpy arrays (views of ``data``, no copy)."""
    out, raw = _fields(data, schema)
    h, w = int(out["height"]), int(out["width"])
    c = len(out["channels"])
    for name, (dtype, has_channels) in _ARRAYS.items():
        shape = (h, w, c) if has_channels else (h, w)
        # Absent arrays (prediction messages carry the label map only; rgb_valid without colour).
        out[name] = _view(raw, name, dtype, shape, lambda need, name=name: name not in ("label", "tensor") or need == 0)
    return out


def _view(raw: Dict[str, memoryview], name: str, dtype: str, shape, optional) -> Optional[np.ndarray]:
    """Byte field ``name`` as a numpy view of ``shape``; None when it is empty and
    ``optional(bytes it would need)``; a ValueError when its size is wrong."""
    b = raw.get(name, memoryview(b""))
    need = int(np.prod(shape)) * np.dtype(dtype).itemsize
    if len(b) == 0 and optional(need):
        return None
    if len(b) != need:
        raise ValueError(f"{name} has {len(b)} bytes, expected {need}")
    return np.frombuffer(b, dtype=dtype).reshape(shape)


# The arrays of a point message: dtype and columns per point (None: one value per point).
_POINT_ARRAYS = {"points": ("<f4", 4), "ring": ("u1", None), "label": ("u1", None), "instance": ("<u2", None),
                 "rgb": ("<f4", 3), "rgb_valid": ("u1", None), "file_index": ("<u4", None)}
# Arrays a point message may leave empty: ring (no 64 rings found), rgb and rgb_valid (no colour),
# file_index (the scan dropped no point: the index is the position).
_POINT_OPTIONAL = {"ring", "rgb", "rgb_valid", "file_index"}


def decode_points(data: Union[bytes, memoryview], schema: FrameSchema) -> Dict[str, Any]:
    """Decodes one ``kitti2pgm.Points`` message (a point shard's frame) into a dict: id, drive,
    frame_index, timestamp_ns, split, count, and numpy views (no copy): points (N, 4) float32 x, y,
    z, intensity; ring (N,) uint8 or None; label (N,) uint8; instance (N,) uint16; rgb (N, 3)
    float32 and rgb_valid (N,) uint8, or None without colour; file_index (N,) uint32, or None when
    every point's index in its ``.bin`` is its position (the scan dropped no point)."""
    out, raw = _fields(data, schema)
    n = int(out["count"])
    for name, (dtype, cols) in _POINT_ARRAYS.items():
        shape = (n, cols) if cols else (n,)
        out[name] = _view(raw, name, dtype, shape, lambda need, name=name: name in _POINT_OPTIONAL and need > 0)
    return out


def _decoder(name: str):
    return decode_points if name == POINTS_SCHEMA else decode_frame


class ShardReader:
    """Random access to the frames of one shard (map shards: ``decode_frame`` dicts; point shards,
    ``convert --format points``: ``decode_points`` dicts; ``kind`` says which).

    Opening reads the summary (chunk indexes, channels, statistics) only; ``reader[i]`` then
    reads and decompresses the one chunk that holds frame ``i`` (frames are in frame-id order).
    An uncompressed shard is read without any copy: the arrays are views of the mapped file.
    Each chunk's CRC is checked (``validate_crc``, on by default as in the Rust reader: a
    flipped bit is a ``ShardError``, never a corrupted frame; ``False`` skips the pass over the
    data for shards already verified, e.g. by ``kitti2pgm inspect``).
    """

    def __init__(self, path: PathLike, validate_crc: bool = True):
        self.path = os.fspath(path)
        self.validate_crc = validate_crc
        try:
            self._file = open_regular(self.path)
            self._map = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError) as e:
            raise ShardError(f"{self.path}: cannot open: {e}") from e
        try:
            summary = make_reader(self._file).get_summary()
        except Exception as e:  # mcap raises several types for a truncated file
            raise ShardError(f"{self.path}: unreadable summary (truncated or unfinished shard?): {e}") from e
        if summary is None:
            raise ShardError(f"{self.path}: no summary section: the shard was not finished")
        frame_schemas = {sid: s for sid, s in summary.schemas.items() if s.name in (FRAME_SCHEMA, POINTS_SCHEMA)}
        frame_channels = {cid for cid, ch in summary.channels.items() if ch.schema_id in frame_schemas}
        if not frame_channels:
            raise ShardError(f"{self.path}: no channel of schema {FRAME_SCHEMA} or {POINTS_SCHEMA}")
        stored = next(iter(frame_schemas.values()))
        self.kind = "points" if stored.name == POINTS_SCHEMA else "maps"
        try:
            self.schema = FrameSchema(stored.data, stored.name)
        except Exception as e:
            raise ShardError(f"{self.path}: unreadable {stored.name} schema: {e}") from e
        self._decode = _decoder(stored.name)
        self._frame_channels = frame_channels
        chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        # Every frame message is alone in its chunk (the writer's chunk size is below one frame).
        self._chunks = [c for c in chunks if frame_channels & set(c.message_index_offsets)]
        self._summary = summary

    def __len__(self) -> int:
        return len(self._chunks)

    def close(self) -> None:
        try:
            self._map.close()
        except BufferError:
            # Frames (zero-copy views) or a pending exception's traceback still reference the
            # mapping: it is unmapped when the last of them goes.
            pass
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
        if start + length > len(m) or m[start] != Opcode.CHUNK:
            raise ValueError(f"no chunk record at byte {start} (truncated or corrupted shard?)")
        pos = start + _RECORD_HEAD
        _t0, _t1, usize, ucrc, clen = _CHUNK_HEAD.unpack_from(m, pos)
        pos += _CHUNK_HEAD.size
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
            body = data[p + _RECORD_HEAD:p + _RECORD_HEAD + n]
            if op == Opcode.MESSAGE:
                channel = _MESSAGE_HEAD.unpack_from(body, 0)[0]
                if channel in self._frame_channels:
                    if found is not None:
                        raise ValueError("more than one frame in the chunk")
                    found = body[_MESSAGE_HEAD.size:]
            p += _RECORD_HEAD + n
        if found is None:
            raise ValueError("no frame message in the chunk")
        return found

    def __getitem__(self, i: int) -> Dict[str, Any]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"{self.path}: frame {i} of {len(self)}")
        try:
            return self._decode(self._frame_data(self._chunks[i]), self.schema)
        except Exception as e:
            raise ShardError(f"{self.path}: frame #{i}: {e}") from e

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        for i in range(len(self)):
            yield self[i]

    def metadata(self) -> Dict[str, Any]:
        return read_metadata(self.path)


# Enum values as shards of earlier versions spelled them (Rust's identifiers), and their names
# today (the CLI's, the same in every file): read_metadata gives every shard's parameters in
# today's spelling, as the Rust reader does.
_OLD_NAMES = {"row_mode": {"Rings": "rings", "Elevation": "elevation"},
              "sampling": {"Nearest": "nearest", "Bilinear": "bilinear"},
              "compression": {"Lz4": "lz4", "Zstd": "zstd", "None": "none"},
              "absent_in_miou": {"LeftOut": "left_out", "Zero": "zero"}}


def _today(params: Any) -> Any:
    """``params`` with every enum value of the old spelling in today's."""
    if isinstance(params, dict):
        return {k: (_OLD_NAMES[k].get(v, v) if k in _OLD_NAMES and isinstance(v, str) else _today(v))
                for k, v in params.items()}
    if isinstance(params, list):
        return [_today(v) for v in params]
    return params


def read_metadata(path: PathLike) -> Dict[str, Any]:
    """The shard's ``kitti2pgm`` metadata record: ``version``, ``params`` (the conversion
    parameters, parsed from JSON: ``params["map"]["class_map"]`` is the class map), ``drives``,
    ``frames``, ``failed`` (lists), ``split``, ``frame_topic``, ``prediction_topic``. Raises
    ``ShardError`` naming the shard when the record is missing or malformed."""
    path = os.fspath(path)
    try:
        with open_regular(path) as f:
            records = [m for m in make_reader(f).iter_metadata() if m.name == METADATA_NAME]
    except Exception as e:
        raise ShardError(f"{path}: unreadable metadata (truncated or unfinished shard?): {e}") from e
    if not records:
        raise ShardError(f"{path}: no {METADATA_NAME} metadata record")
    md: Dict[str, Any] = dict(records[0].metadata)
    try:
        md["params"] = _today(json.loads(md["params"]))
        for key in ("drives", "frames", "failed"):
            md[key] = [x for x in md[key].split("\n") if x]
    except (KeyError, ValueError) as e:
        raise ShardError(f"{path}: malformed {METADATA_NAME} metadata record: {e!r}") from e
    return md


def class_map(path: PathLike) -> Dict[str, Any]:
    """The class map a shard was made with (names, colours, ignored ids, mIoU ids, reference
    weights), from its metadata."""
    try:
        return read_metadata(path)["params"]["map"]["class_map"]
    except (KeyError, TypeError) as e:
        raise ShardError(f"{os.fspath(path)}: no class map in the metadata: {e!r}") from e


def shard_paths(paths: Union[PathLike, Iterable[PathLike]]) -> List[str]:
    """One path (``str`` or ``Path``) or several, as a list of strings."""
    if isinstance(paths, (str, bytes, os.PathLike)):
        return [os.fspath(paths)]
    return [os.fspath(p) for p in paths]


def check_complete(paths: Iterable[PathLike], partial: bool = False) -> List[str]:
    """Checks that the shards come from finished conversions: the ``convert_summary.json`` of
    each shard's convert folder (``OUT`` of ``OUT/shards/x.mcap``), where there is one, must say
    ``"complete": true``. Raises ``ShardError`` naming the folder otherwise; with ``partial``,
    returns the problems instead (and warns), for reading an unfinished conversion on purpose.
    """
    problems = []
    folders = sorted({os.path.dirname(os.path.dirname(os.path.abspath(os.fspath(p)))) for p in paths})
    for folder in folders:
        summary = os.path.join(folder, "convert_summary.json")
        if not os.path.isfile(summary):
            continue
        try:
            with open(summary, encoding="utf-8") as f:
                s = json.load(f)
        except (OSError, ValueError) as e:
            raise ShardError(f"{summary}: unreadable conversion summary: {e}") from e
        if not s.get("complete", False):
            problems.append(f"the conversion into {folder} did not finish ({summary}: complete false): "
                            f"{s.get('frames_planned', '?')} frames were planned")
    if problems and not partial:
        raise ShardError(problems[0] + "; finish the conversion (run it again), or read what is there "
                         "on purpose (partial=True)")
    for p in problems:
        warnings.warn("PARTIAL: " + p, stacklevel=3)
    return problems


def iter_frames(paths: Union[PathLike, Iterable[PathLike]], validate_crc: bool = True,
                partial: bool = False) -> Iterator[Dict[str, Any]]:
    """Yields every frame of the shards (map or point shards), shard by shard, in frame-id order.

    Streams the file from the start, so it also reads a shard whose summary was lost: the frames
    before a corrupted or truncated point are yielded, then ``ShardError`` names the shard and the
    frame that could not be read. Chunk CRCs are checked (``validate_crc``). Shards of an
    unfinished conversion are refused unless ``partial`` (see ``check_complete``).
    """
    paths = shard_paths(paths)
    check_complete(paths, partial)
    for path in paths:
        path = os.fspath(path)
        n = 0
        last: Optional[str] = None
        try:
            with open_regular(path) as f:
                # Stream from the start (never from the summary), so that a shard whose end is
                # lost still gives its first frames.
                reader = NonSeekingReader(f, validate_crcs=validate_crc)
                schemas: Dict[int, FrameSchema] = {}
                for schema, _channel, message in reader.iter_messages(log_time_order=False):
                    if schema is None or schema.name not in (FRAME_SCHEMA, POINTS_SCHEMA):
                        continue
                    if schema.id not in schemas:
                        schemas[schema.id] = FrameSchema(schema.data, schema.name)
                    frame = _decoder(schema.name)(message.data, schemas[schema.id])
                    yield frame
                    n += 1
                    last = str(frame["id"])
        except ShardError:
            raise
        except Exception as e:
            after = f" after frame {last}" if last else ""
            raise ShardError(f"{path}: frame #{n}{after}: corrupted or truncated: {e}") from e
