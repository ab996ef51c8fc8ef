"""A training run's configuration: one typed object, built from the command line, saved in the
run's ``config.json`` (under ``args``) and read back by ``evaluate``, ``export`` and
``--resume``. Its defaults are the command line's (``cli.py`` takes them from here)."""

from __future__ import annotations

import argparse
from dataclasses import MISSING, asdict, dataclass, field, fields
from typing import List, Optional, Sequence


def _check_bounds(cfg, at_least_1: Sequence[str] = (), at_least_0: Sequence[str] = ()) -> None:
    """Refuses an option below its bound (NaN too), named as on the command line."""
    for names, bound, words in ((at_least_1, 1, "at least 1"), (at_least_0, 0, "0 or more")):
        for name in names:
            value = getattr(cfg, name)
            if not value >= bound:
                raise ValueError(f"--{name.replace('_', '-')} must be {words}, not {value}")


@dataclass
class TrainConfig:
    """Everything ``train`` is told. Field names are the ``train`` options' (dashes as
    underscores)."""

    # Data.
    shards: str
    out: str
    train_shards: Optional[str] = None
    val_shards: Optional[str] = None
    stats: Optional[str] = None
    class_weights: str = "sqrt"
    workers: int = 2
    data_on_gpu: str = "auto"
    # Model.
    model: str = "squeezeseg"
    input: str = "xyzdi"
    width_mult: float = 1.0
    dropout: float = 0.5
    crf: bool = False
    # Optimisation (the paper's schedule).
    steps: int = 50_000
    batch: int = 32
    lr: float = 0.01
    momentum: float = 0.9
    weight_decay: float = 1e-4
    lr_halve_every: int = 10_000
    seed: int = 0
    # Augmentation.
    flip: bool = True
    augment: str = ""
    rotate_deg: float = 180.0
    scale_range: List[float] = field(default_factory=lambda: [0.95, 1.05])
    jitter: float = 0.01
    drop: float = 0.1
    # Device and speed.
    device: str = "auto"
    amp: Optional[bool] = None
    channels_last: Optional[bool] = None
    compile: bool = False
    # Run bookkeeping.
    resume: bool = False
    log_every: int = 50
    val_every: int = 0
    checkpoint_every: int = 1000
    tensorboard: bool = False
    stop_after: int = 0

    def __post_init__(self):
        # SqueezeSeg's own weights are the class map's reference weights.
        if self.class_weights == "squeezeseg":
            self.class_weights = "reference"
        _check_bounds(self, at_least_1=("steps", "batch", "log_every", "checkpoint_every"),
                      at_least_0=("workers", "val_every", "stop_after", "lr_halve_every"))

    @classmethod
    def from_args(cls, ns: argparse.Namespace) -> "TrainConfig":
        """From the parsed ``train`` options."""
        return cls(**{f.name: getattr(ns, f.name) for f in fields(cls)})

    @classmethod
    def from_saved(cls, saved: dict) -> "TrainConfig":
        """From a run's ``config.json`` ``args`` (keys of other versions ignored)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in saved.items() if k in names})

    def to_dict(self) -> dict:
        """What ``config.json`` and the checkpoints store."""
        return asdict(self)

    @staticmethod
    def defaults() -> dict:
        """The options' defaults (every field but the required ``shards`` and ``out``)."""
        out = {}
        for f in fields(TrainConfig):
            if f.default is not MISSING:
                out[f.name] = f.default
            elif f.default_factory is not MISSING:
                out[f.name] = f.default_factory()
        return out


@dataclass
class EvalConfig:
    """Everything ``evaluate`` is told (the ``evaluate`` options, dashes as underscores)."""

    run: str
    shards: str
    val_shards: Optional[str] = None
    predictions: Optional[str] = None
    format: str = "npy"
    batch: int = 8
    device: str = "auto"
    timing_frames: int = 10
    # Timed passes stop once they have taken this long (at least 3 of them): a CPU's forward of
    # hundreds of ms is timed in about a second, a GPU's still over every frame.
    timing_seconds: float = 1.0
    json: bool = False
    onnx: Optional[str] = None
    # Per point (the native module carries each prediction back to its scan).
    points: bool = False
    raw: Optional[str] = None
    unproject: str = "knn"
    point_predictions: Optional[str] = None
    knn_k: int = 5
    knn_window: int = 5
    knn_sigma: float = 1.0
    knn_cutoff: float = 1.0
    knn_wrap: bool = False

    def __post_init__(self):
        if self.points and not self.raw:
            raise ValueError("--points needs --raw: the dataset root holding the scans")
        _check_bounds(self, at_least_1=("batch",), at_least_0=("timing_frames", "timing_seconds"))

    @classmethod
    def each_from_args(cls, ns: argparse.Namespace) -> List["EvalConfig"]:
        """From the parsed ``evaluate`` options: one configuration a ``--run`` (repeatable)."""
        runs = ns.run if isinstance(ns.run, list) else [ns.run]
        return [cls(**{f.name: run if f.name == "run" else getattr(ns, f.name) for f in fields(cls)})
                for run in runs]

    @classmethod
    def from_args(cls, ns: argparse.Namespace) -> "EvalConfig":
        """From the parsed ``evaluate`` options of one run."""
        configs = cls.each_from_args(ns)
        if len(configs) != 1:
            raise ValueError(f"{len(configs)} runs given where one is evaluated")
        return configs[0]

    @staticmethod
    def defaults() -> dict:
        """The options' defaults (every field but the required ``run`` and ``shards``)."""
        return {f.name: f.default for f in fields(EvalConfig) if f.default is not MISSING}
