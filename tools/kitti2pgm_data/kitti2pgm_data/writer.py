"""Writing prediction shards: ``kitti2pgm.Frame`` messages carrying a predicted label map on
the prediction topic, which ``kitti2pgm score --pred`` reads.

The schema (the ``FileDescriptorSet`` of ``kitti2pgm.Frame``), the field numbers, the topic name
and the class map all come from a ground-truth shard, so the prediction shard is as
self-describing as the input and this package holds no copy of them.
"""

from __future__ import annotations

import os
from typing import Dict, Iterable, Optional

import numpy as np
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from .reader import PathLike, ShardError, class_map, read_metadata
from .schema import FRAME_SCHEMA, FrameSchema, encode_varint


def _field_bytes(number: int, data: bytes) -> bytes:
    return encode_varint(number << 3 | 2) + encode_varint(len(data)) + data


def _field_uint(number: int, v: int) -> bytes:
    return encode_varint(number << 3) + encode_varint(int(v))


def encode_prediction(schema: FrameSchema, frame_id: str, label: np.ndarray, drive: str = "",
                      frame_index: int = 0, split: str = "") -> bytes:
    """A ``kitti2pgm.Frame`` message (field numbers from ``schema``) holding an H x W predicted
    label map of class ids."""
    label = np.ascontiguousarray(label, dtype=np.uint8)
    if label.ndim != 2:
        raise ValueError(f"a label map is H x W, got shape {label.shape}")
    h, w = label.shape
    n = schema.number
    return b"".join([
        _field_bytes(n("id"), frame_id.encode()),
        _field_bytes(n("drive"), drive.encode()),
        _field_uint(n("frame_index"), frame_index),
        _field_uint(n("height"), h),
        _field_uint(n("width"), w),
        _field_bytes(n("label"), label.tobytes()),
        _field_bytes(n("split"), split.encode()),
    ])


def frame_schema(shard: PathLike) -> bytes:
    """The ``kitti2pgm.Frame`` schema data of a shard."""
    with open(shard, "rb") as f:
        summary = make_reader(f).get_summary()
    for s in (summary.schemas.values() if summary else []):
        if s.name == FRAME_SCHEMA:
            return s.data
    raise ShardError(f"{os.fspath(shard)}: no {FRAME_SCHEMA} schema")


def write_predictions(path: PathLike, predictions: Iterable[Dict], schema_from: PathLike,
                      metadata: Optional[Dict[str, str]] = None) -> int:
    """Writes a prediction shard (atomically: temporary name, then rename). Each item of
    ``predictions`` has ``id``, ``label`` (H x W) and optionally ``drive``, ``frame_index``,
    ``split``. Returns the number of frames written."""
    path = os.fspath(path)
    schema_data = frame_schema(schema_from)
    schema = FrameSchema(schema_data)
    topic = read_metadata(schema_from).get("prediction_topic")
    if not topic:
        raise ShardError(f"{os.fspath(schema_from)}: its metadata names no prediction_topic "
                         "(written by an older kitti2pgm?)")
    classes = len(class_map(schema_from)["classes"])
    tmp = os.path.join(os.path.dirname(path) or ".", f".tmp-{os.getpid()}-{os.path.basename(path)}")
    n = 0
    try:
        with open(tmp, "wb") as f:
            w = Writer(f, chunk_size=1 << 16, compression=CompressionType.ZSTD)
            w.start(profile="kitti2pgm", library="kitti2pgm_data")
            sid = w.register_schema(name=FRAME_SCHEMA, encoding="protobuf", data=schema_data)
            cid = w.register_channel(topic=topic, message_encoding="protobuf", schema_id=sid)
            for p in predictions:
                label = np.asarray(p["label"])
                if label.size and int(label.max()) >= classes:
                    raise ValueError(f"prediction for {p['id']}: class id {int(label.max())}, "
                                     f"the map has {classes} classes")
                data = encode_prediction(schema, p["id"], label, p.get("drive", ""), p.get("frame_index", 0),
                                         p.get("split", ""))
                w.add_message(channel_id=cid, log_time=n, publish_time=n, data=data, sequence=n)
                n += 1
            w.add_metadata("kitti2pgm_predictions", dict(metadata or {}))
            w.finish()
        os.replace(tmp, path)
    finally:
        # Nothing half-written is left behind, under the final name or the temporary one.
        if os.path.exists(tmp):
            os.remove(tmp)
    return n
