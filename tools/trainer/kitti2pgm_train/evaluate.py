"""Evaluation: predictions for the val shards (``predictions/<id>.npy`` H x W uint8 label maps
and/or a prediction shard, both read by ``kitti2pgm score``), the IoU table in ``eval.json`` and
the inference time per frame."""

from __future__ import annotations

import json
import os
import time
from typing import List, Optional

import numpy as np
import torch

from .common import Progress, pick_device
from .config import EvalConfig, TrainConfig
from .data import FrameSet, Normaliser, check_same_map, collate, find_shards
from .metrics import Confusion
from .models import SegNet
from .onthefly import open_frames


def load_run(run: str, device: torch.device):
    """The run's model (its best checkpoint when it kept one, else the last), config and
    normalisation."""
    with open(os.path.join(run, "config.json")) as f:
        config = json.load(f)
    a = TrainConfig.from_saved(config["args"])
    model = SegNet(a.model, a.input, len(config["class_map"]["classes"]), width_mult=a.width_mult,
                   dropout=a.dropout, crf=a.crf)
    which = "best.pt" if os.path.exists(os.path.join(run, "best.pt")) else "checkpoint.pt"
    ck = torch.load(os.path.join(run, which), map_location=device, weights_only=False)
    model.load_state_dict(ck["model"])
    n = config["normalisation"]
    norm = Normaliser(n["mean"], n["std"], n["source"])
    return model.to(device).eval(), config, norm


@torch.no_grad()
def predict(model, data: FrameSet, device: torch.device, batch: int, conf: Optional[Confusion] = None):
    """Yields (frame id, H x W uint8 predicted labels) for every frame of ``data``, in order,
    adding each batch's valid cells to ``conf`` when given. The model is in eval mode."""
    for start in range(0, len(data), batch):
        b = collate([data.item(i) for i in range(start, min(start + batch, len(data)))])
        mask = b["mask"].to(device)
        logits = model([x.to(device) for x in b["inputs"]], mask=mask, xyz=b["xyz"].to(device))
        pred = logits.argmax(1)
        if conf is not None:
            conf.add(pred, b["label"].to(device), mask)
        yield from zip(b["id"], pred.to(torch.uint8).cpu().numpy())


@torch.no_grad()
def evaluate(args: EvalConfig) -> dict:
    """Predicts every frame of the val shards, writes ``predictions/<id>.npy`` and the IoU table."""
    device = pick_device(args.device, 0)
    model, config, norm = load_run(args.run, device)
    paths = find_shards(args.shards, "val") if not args.val_shards else find_shards(args.val_shards)
    trained = TrainConfig.from_saved(config["args"])
    check_same_map(paths, config["shard_params"], args.run)
    data = open_frames(paths, trained.input, norm)
    out = args.predictions or os.path.join(args.run, "predictions")
    write_npy = args.format in ("npy", "both")
    if write_npy:
        os.makedirs(out, exist_ok=True)
    conf = Confusion(config["class_map"])
    progress = Progress(len(data), "evaluating")
    points = None
    if args.points:
        from kitti2pgm_data import read_metadata

        from .points import PointEvaluation
        if args.raw is None:
            raise ValueError("--points needs --raw: the dataset root holding the scans")
        spec = read_metadata(paths[0])["params"]["map"]["spec"]
        knn = dict(k=args.knn_k, window=args.knn_window, sigma=args.knn_sigma, cutoff=args.knn_cutoff,
                   wrap_columns=args.knn_wrap)
        points = PointEvaluation(args.raw, spec, config["class_map"], args.unproject, knn,
                                 args.point_predictions or os.path.join(args.run, "point_predictions"))

    def predictions():
        for k, (fid, p) in enumerate(predict(model, data, device, args.batch, conf)):
            if points is not None:
                points.add(fid, p)
            if write_npy:
                tmp = os.path.join(out, f".{fid}.tmp.npy")
                np.save(tmp, p)
                os.replace(tmp, os.path.join(out, f"{fid}.npy"))
            yield {"id": fid, "label": p}
            progress.update(k + 1)

    shard_out = None
    if args.format in ("mcap", "both"):
        from kitti2pgm_data import write_predictions
        shard_out = os.path.join(args.run, "predictions.mcap")
        write_predictions(shard_out, predictions(), schema_from=paths[0],
                          metadata={"run": os.path.abspath(args.run), "model": trained.model,
                                    "input": trained.input})
    else:
        for _ in predictions():
            pass
    progress.close()
    timing = inference_time(model, data, device, args.timing_frames, args.timing_seconds)
    if args.onnx:
        timing["onnxruntime_cpu"] = onnx_time(args.onnx, data, args.timing_frames, args.timing_seconds)
    result = {"frames": len(data), "class_map": config["class_map"], "predictions": out if write_npy else None,
              "prediction_shard": shard_out,
              **conf.as_dict(), "inference_ms_per_frame": timing}
    if points is not None:
        # The 3D figures beside the 2D ones: every point of the scans, by the method.
        result["points"] = {"unproject": args.unproject, "predictions": points.out, "points": points.points,
                            "not_predicted": points.not_predicted, **points.conf.as_dict()}
    with open(os.path.join(args.run, "eval.json"), "w") as f:
        json.dump(result, f, indent=2)
    return result


def timed_passes(run, frames: int, seconds: float) -> Optional[float]:
    """Median time of ``run()`` in ms: two warm-up calls, then ``frames`` timed ones, or fewer
    (at least 3) once the timed ones took ``seconds``; None when ``frames`` is 0."""
    if frames <= 0:
        return None
    times: List[float] = []
    for _ in range(2):
        run()
    while len(times) < frames and (len(times) < 3 or sum(times) < seconds * 1e3):
        t = time.perf_counter()
        run()
        times.append((time.perf_counter() - t) * 1e3)
    return float(np.median(times))


@torch.no_grad()
def inference_time(model, data: FrameSet, device: torch.device, frames: int, seconds: float) -> dict:
    """Median forward time of one frame (batch 1) on the CPU and, when present, the GPU."""
    item = collate([data.item(0)])
    devices = [torch.device("cpu")] + ([torch.device("cuda")] if torch.cuda.is_available() else [])
    out = {d.type: timed_passes(_forward(model.to(d), item, d), frames, seconds) for d in devices}
    model.to(device)
    return out


def _forward(model, item: dict, d: torch.device):
    """One forward pass of a collated ``item`` on ``d``, finished when it returns."""
    xs = [x.to(d) for x in item["inputs"]]
    mask, xyz = item["mask"].to(d), item["xyz"].to(d)

    def run():
        model(xs, mask=mask, xyz=xyz)
        if d.type == "cuda":
            torch.cuda.synchronize()

    return run


def onnx_time(path: str, data: FrameSet, frames: int, seconds: float) -> Optional[float]:
    """Median onnxruntime (CPU) time of one frame of an exported model, ms."""
    import onnxruntime

    session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])
    f = data.ds[0]
    x = np.ascontiguousarray(np.asarray(f["tensor"])[None], dtype=np.float32)
    name = session.get_inputs()[0].name
    return timed_passes(lambda: session.run(None, {name: x}), frames, seconds)
