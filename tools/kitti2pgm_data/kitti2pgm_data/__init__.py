"""Read kitti2pgm MCAP training shards with mcap and numpy alone.

``iter_frames(paths)`` streams frames in order (map shards, or point shards written by
``convert --format points``: each frame's points, rings, labels and colours); ``ShardReader`` gives random
access to one shard
through its chunk indexes (every frame is its own chunk); ``ShardDataset`` indexes several shards
as one PyTorch-style dataset (``__len__`` / ``__getitem__``, usable with a DataLoader).
``read_metadata`` and ``class_map`` give a shard's conversion parameters and classes;
``write_predictions`` writes a prediction shard that ``kitti2pgm score`` reads.
"""

from .dataset import ShardDataset
from .reader import (
    ShardError,
    ShardReader,
    class_map,
    decode_frame,
    decode_points,
    iter_frames,
    read_metadata,
)
from .schema import FRAME_SCHEMA, POINTS_SCHEMA, FrameSchema
from .writer import encode_prediction, write_predictions

__all__ = [
    "FRAME_SCHEMA",
    "POINTS_SCHEMA",
    "FrameSchema",
    "encode_prediction",
    "write_predictions",
    "ShardDataset",
    "ShardError",
    "ShardReader",
    "class_map",
    "decode_frame",
    "decode_points",
    "iter_frames",
    "read_metadata",
]
__version__ = "0.1.0"
