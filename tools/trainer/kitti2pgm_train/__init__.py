"""Companion trainer of kitti2pgm: SqueezeSeg and PointSeg on Polar Grid Maps read from shards.

Modules by role (after lidar-bonnetal): ``data`` (shards -> normalised input tensors, flip
augmentation), ``models`` (SqueezeSeg, PointSeg, fusion variants, chosen from a registry),
``metrics`` (IoU exactly as ``kitti2pgm score``), ``task`` (train / evaluate loops, checkpoints)
and ``cli`` (the ``python -m kitti2pgm_train`` entry point).
"""

__version__ = "0.1.0"
