"""The trainer's vocabulary without torch: the models and the input groups (so that ``--help``
and argument checking do not wait for torch to import)."""

from __future__ import annotations

from typing import Dict, Tuple

# Channel names of each input, in the order the tensor is built.
INPUTS: Dict[str, Tuple[Tuple[str, ...], ...]] = {
    "xyzdi": (("x", "y", "z", "intensity", "range"),),
    "xyzdirgb": (("x", "y", "z", "intensity", "range", "r", "g", "b"),),
    "xyzdi+dirgb": (("x", "y", "z", "intensity", "range"), ("range", "intensity", "r", "g", "b")),
}

# Model name -> display name.
MODELS = {"squeezeseg": "SqueezeSeg", "pointseg": "PointSeg"}
