"""Read kitti2pgm MCAP training shards with mcap and numpy alone.

``iter_frames(paths)`` streams frames in order; ``ShardReader`` gives random access to one shard
through its chunk indexes (every frame is its own chunk); ``ShardDataset`` indexes several shards
as one PyTorch-style dataset (``__len__`` / ``__getitem__``, usable with a DataLoader).
"""

from .reader import (
    FRAME_TOPIC,
    ShardError,
    ShardReader,
    decode_frame,
    iter_frames,
    read_metadata,
)
from .dataset import ShardDataset
from .writer import PREDICTION_TOPIC, encode_prediction, write_predictions

__all__ = [
    "FRAME_TOPIC",
    "PREDICTION_TOPIC",
    "encode_prediction",
    "write_predictions",
    "ShardDataset",
    "ShardError",
    "ShardReader",
    "decode_frame",
    "iter_frames",
    "read_metadata",
]
__version__ = "0.1.0"
