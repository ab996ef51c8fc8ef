"""Writing prediction shards: ``kitti2pgm.Frame`` messages carrying a predicted label map on
topic ``/kitti2pgm/prediction``, which ``kitti2pgm score --pred`` reads.

The schema (the ``FileDescriptorSet`` of ``kitti2pgm.Frame``) is copied from a ground-truth shard,
so the prediction shard is as self-describing as the input.
"""

from __future__ import annotations

import os
from typing import Dict, Iterable, Optional

import numpy as np
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from .reader import PathLike

PREDICTION_TOPIC = "/kitti2pgm/prediction"
FRAME_SCHEMA = "kitti2pgm.Frame"


def _varint(v: int) -> bytes:
    out = bytearray()
    while True:
        b = v & 0x7F
        v >>= 7
        if v:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def _field_bytes(number: int, data: bytes) -> bytes:
    return _varint(number << 3 | 2) + _varint(len(data)) + data


def _field_uint(number: int, v: int) -> bytes:
    return _varint(number << 3) + _varint(int(v))


def encode_prediction(frame_id: str, label: np.ndarray, drive: str = "", frame_index: int = 0, split: str = "") -> bytes:
    """A ``kitti2pgm.Frame`` message holding an H x W predicted label map (class ids 0-3)."""
    label = np.ascontiguousarray(label, dtype=np.uint8)
    if label.ndim != 2:
        raise ValueError(f"a label map is H x W, got shape {label.shape}")
    h, w = label.shape
    return b"".join([
        _field_bytes(1, frame_id.encode()),
        _field_bytes(2, drive.encode()),
        _field_uint(3, frame_index),
        _field_uint(5, h),
        _field_uint(6, w),
        _field_bytes(9, label.tobytes()),
        _field_bytes(13, split.encode()),
    ])


def frame_schema(shard: PathLike) -> bytes:
    """The ``kitti2pgm.Frame`` schema data of a shard."""
    with open(shard, "rb") as f:
        summary = make_reader(f).get_summary()
    for s in (summary.schemas.values() if summary else []):
        if s.name == FRAME_SCHEMA:
            return s.data
    raise ValueError(f"{os.fspath(shard)}: no {FRAME_SCHEMA} schema")


def write_predictions(path: PathLike, predictions: Iterable[Dict], schema_from: PathLike,
                      metadata: Optional[Dict[str, str]] = None) -> int:
    """Writes a prediction shard (atomically: temporary name, then rename). Each item of
    ``predictions`` has ``id``, ``label`` (H x W) and optionally ``drive``, ``frame_index``,
    ``split``. Returns the number of frames written."""
    path = os.fspath(path)
    tmp = os.path.join(os.path.dirname(path) or ".", f".tmp-{os.path.basename(path)}")
    n = 0
    with open(tmp, "wb") as f:
        w = Writer(f, chunk_size=1 << 16, compression=CompressionType.ZSTD)
        w.start(profile="kitti2pgm", library="kitti2pgm_data")
        sid = w.register_schema(name=FRAME_SCHEMA, encoding="protobuf", data=frame_schema(schema_from))
        cid = w.register_channel(topic=PREDICTION_TOPIC, message_encoding="protobuf", schema_id=sid)
        for p in predictions:
            data = encode_prediction(p["id"], p["label"], p.get("drive", ""), p.get("frame_index", 0), p.get("split", ""))
            w.add_message(channel_id=cid, log_time=n, publish_time=n, data=data, sequence=n)
            n += 1
        w.add_metadata("kitti2pgm_predictions", dict(metadata or {}))
        w.finish()
    os.replace(tmp, path)
    return n
