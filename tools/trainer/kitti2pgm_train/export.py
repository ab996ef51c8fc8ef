"""Export a trained run for deployment: ONNX (opened by onnxruntime, TensorRT, ...) and
TorchScript, with the normalisation inside the graph.

The exported model takes the raw channels exactly as a kitti2pgm shard stores them (a
1 x H x W x C float32 tensor, C = the run's channels, e.g. x y z intensity range r g b), builds
the mask (range > 0), selects and normalises each input group with the run's constants, and
returns the predicted class of every cell (1 x H x W int64) and the logits (1 x K x H x W).

The ONNX file records what feeding it needs, in one metadata entry that ``kitti2pgm infer``
and ``kitti2pgm.Model`` read: the map parameters of the run's shards (map, sensor model and
pose, colour, class map), the input's channels and that the normalisation is inside the graph.
The native module builds the entry (``kitti2pgm.model_metadata``): kitti2pgm decides its key
and checks its content.
"""

from __future__ import annotations

import contextlib
import os
from typing import List, Optional

import torch
import torch.nn as nn

from .config import TrainConfig
from .evaluate import load_run
from .models import INPUTS


class Deployable(nn.Module):
    """A trained network behind its input preparation: raw shard channels in, labels out."""

    def __init__(self, model: nn.Module, channels: List[str], inputs: str, mean: dict, std: dict):
        super().__init__()
        self.model = model
        index = {c: i for i, c in enumerate(channels)}
        self.groups = [list(g) for g in INPUTS[inputs]]
        for g in self.groups:
            self.register_buffer(f"idx_{len(self._buffers)}", torch.tensor([index[c] for c in g]))
        self.mean = nn.ParameterList([nn.Parameter(torch.tensor([float(mean[c]) for c in g]), requires_grad=False)
                                      for g in self.groups])
        self.std = nn.ParameterList([nn.Parameter(torch.tensor([float(std[c]) for c in g]), requires_grad=False)
                                     for g in self.groups])
        self.range_index = index["range"]
        self.xyz_index = [index["x"], index["y"], index["z"]]

    def forward(self, tensor: torch.Tensor):
        t = tensor.permute(0, 3, 1, 2)
        mask = t[:, self.range_index] > 0
        xs = []
        for k, idx in enumerate(self._buffers.values()):
            assert idx is not None
            v = t.index_select(1, idx)
            xs.append((v - self.mean[k].view(1, -1, 1, 1)) / self.std[k].view(1, -1, 1, 1) * mask.unsqueeze(1))
        xyz = t[:, self.xyz_index]
        logits = self.model(xs, mask=mask, xyz=xyz)
        return logits.argmax(1), logits


def deployable(run: str) -> tuple:
    """The run's best (or last) model wrapped for deployment, an example input and the run's
    config."""
    model, config, norm = load_run(run, torch.device("cpu"))
    spec = config["shard_params"]["map"]["spec"]
    channels = config["channels"]
    net = Deployable(model, channels, TrainConfig.from_saved(config["args"]).input, norm.mean, norm.std).eval()
    example = torch.zeros(1, spec["rows"], spec["cols"], len(channels))
    return net, example, config


def model_record(config: dict) -> str:
    """The record of a run (its shards' map, its channels, what made it): the metadata value
    that tells kitti2pgm how to feed the run's network, built and checked by the native module."""
    import json

    import kitti2pgm  # the native module (tools/install.sh)

    args = TrainConfig.from_saved(config["args"])
    _, value = kitti2pgm.model_metadata(
        json.dumps(config["shard_params"]["map"]), list(config["channels"]),
        f"kitti2pgm_train {config.get('trainer_version', '?')}: {args.model} {args.input}")
    return value


def record_map(path: str, config: dict) -> None:
    """Adds the metadata entry that tells kitti2pgm how to feed the model at ``path`` (an ONNX
    file, rewritten in place)."""
    import kitti2pgm
    import onnx

    key, value = kitti2pgm.MODEL_METADATA_KEY, model_record(config)
    m = onnx.load(path)
    for old in [p for p in m.metadata_props if p.key == key]:
        m.metadata_props.remove(old)
    m.metadata_props.add(key=key, value=value)
    onnx.save(m, path)


@contextlib.contextmanager
def _atomic(path: str):
    """A temporary name beside ``path``, renamed to ``path`` when the block succeeds and removed
    (with any side file an exporter wrote beside it) when it fails."""
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        for leftover in (tmp, tmp + ".data"):
            if os.path.exists(leftover):
                os.remove(leftover)


def export(run: str, onnx_path: Optional[str] = None, torchscript_path: Optional[str] = None) -> dict:
    """Writes the ONNX and/or TorchScript file (atomically); returns their paths."""
    net, example, config = deployable(run)
    out = {}
    with torch.no_grad():
        if onnx_path:
            # One self-contained file: the weights inside the graph (external_data=False), so
            # that the file loads wherever it is copied (the models are far below ONNX's 2 GB).
            with _atomic(onnx_path) as tmp:
                torch.onnx.export(net, (example,), tmp, input_names=["tensor"], output_names=["labels", "logits"],
                                  dynamo=True, external_data=False, verbose=False)
                record_map(tmp, config)
            out["onnx"] = onnx_path
        if torchscript_path:
            with _atomic(torchscript_path) as tmp:
                torch.jit.save(torch.jit.trace(net, (example,)), tmp)
            out["torchscript"] = torchscript_path
    return out
