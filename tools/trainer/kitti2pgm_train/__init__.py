"""Companion trainer of kitti2pgm: SqueezeSeg and PointSeg on Polar Grid Maps read from shards.

Modules by role (after lidar-bonnetal): ``data`` (shards -> normalised input tensors, flip
augmentation), ``models`` (SqueezeSeg, PointSeg, fusion variants, chosen from a registry),
``metrics`` (IoU exactly as ``kitti2pgm score``, for any class map), ``train`` (the training loop,
checkpoints, logs), ``evaluate`` (predictions, IoU, inference time), ``common`` (what both share)
and ``cli`` (the ``python -m kitti2pgm_train`` entry point). The class map, and so the number of
classes, comes from the shards' metadata.
"""

__version__ = "0.1.0"
