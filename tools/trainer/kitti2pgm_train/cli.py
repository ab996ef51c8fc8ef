"""``python -m kitti2pgm_train``: train, evaluate (and predict) from kitti2pgm shards.

    python -m kitti2pgm_train train --shards out/shards --model squeezeseg --input xyzdi+dirgb \\
        --stats stats.json --out runs/ss-mid
    python -m kitti2pgm_train evaluate --run runs/ss-mid --shards out/shards
    kitti2pgm score --gt out --pred runs/ss-mid/predictions --imageset out/ImageSet/val.txt

Without a subcommand, ``train`` is assumed (``python -m kitti2pgm_train --shards DIR ...``).
"""

from __future__ import annotations

import argparse
import json
import sys

from .config import EvalConfig, TrainConfig
from .names import INPUTS, MODELS


class _Help(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """The description as written, every option with its default."""


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kitti2pgm_train", description=__doc__, formatter_class=_Help)
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="train a model (the paper's schedule by default)", formatter_class=_Help,
                       description="Train SqueezeSeg or PointSeg from kitti2pgm shards. Progress goes to stderr "
                                   "(a line every --log-every steps; a live line on a terminal), the log to "
                                   "<out>/log.csv.")
    t.add_argument("--shards", required=True,
                   help="shards folder (train-*.mcap, val-*.mcap) or a convert output folder; map shards (OUT/shards) "
                        "or point shards (OUT/points: projected on the fly, see --augment)")
    t.add_argument("--train-shards", help="explicit train shards (glob) instead of <shards>/train-*.mcap")
    t.add_argument("--model", choices=sorted(MODELS))
    t.add_argument("--input", choices=sorted(INPUTS),
                   help="xyzdi (LiDAR), xyzdirgb (early fusion), xyzdi+dirgb (mid fusion)")
    t.add_argument("--out", required=True, help="run directory (never overwritten; see --resume)")
    t.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    t.add_argument("--stats", help="kitti2pgm stats --json output: normalisation and class weights")
    t.add_argument("--class-weights", choices=["sqrt", "inverse", "reference", "squeezeseg", "uniform"],
                   help="with --stats: sqrt or plain inverse frequency; reference = the class map's own weights "
                        "(SqueezeSeg's [1/15, 1, 10, 10] for the paper's map; used without --stats; squeezeseg is "
                        "an alias); uniform = no weighting")
    t.add_argument("--steps", type=int, help="training steps (the paper's schedule)")
    t.add_argument("--batch", type=int, help="frames per step (per process with torchrun)")
    t.add_argument("--lr", type=float, help="SGD learning rate at step 0")
    t.add_argument("--momentum", type=float, help="SGD momentum")
    t.add_argument("--weight-decay", type=float, help="SGD weight decay")
    t.add_argument("--lr-halve-every", type=int, help="halve the learning rate every N steps")
    t.add_argument("--no-flip", dest="flip", action="store_false", help="no random left-right flip")
    t.add_argument("--augment",
                   help="with point shards (convert --format points): 3D augmentation per sample before the "
                        "ring-exact projection (native module kitti2pgm), any of rotate,scale,jitter,drop,flip "
                        "(flip: the random mirror, done in 3D); seeded by --seed, the step and the sample")
    t.add_argument("--rotate-deg", type=float, help="--augment rotate: uniform in [-D, D] about z")
    t.add_argument("--scale-range", type=float, nargs=2, metavar=("LOW", "HIGH"),
                   help="--augment scale: uniform factor")
    t.add_argument("--jitter", type=float,
                   help="--augment jitter: standard deviation of the bell-shaped, bounded (3.46 x) noise on x, y, z, "
                        "metres")
    t.add_argument("--drop", type=float, help="--augment drop: probability of dropping a point")
    t.add_argument("--dropout", type=float, help="dropout before the classifier")
    t.add_argument("--crf", action="store_true", help="SqueezeSeg's recurrent CRF on the logits")
    t.add_argument("--width-mult", type=float, help="channel width multiplier (1 = the paper's)")
    t.add_argument("--seed", type=int, help="seed of the weights, batches and augmentation")
    t.add_argument("--workers", type=int,
                   help="DataLoader worker processes reading the shards (0 = in the training process)")
    t.add_argument("--device", help="auto, cpu or cuda")
    t.add_argument("--amp", action=argparse.BooleanOptionalAction,
                   help="bf16 autocast of the forward pass (default: on with CUDA, off on CPU)")
    t.add_argument("--channels-last", action=argparse.BooleanOptionalAction,
                   help="channels-last memory format (default: on with CUDA)")
    t.add_argument("--compile", action="store_true", help="torch.compile the model")
    t.add_argument("--data-on-gpu", choices=["auto", "on", "off"],
                   help="load the decoded train split onto the device once and batch, flip and normalise there "
                        "(auto: on CUDA when it takes at most half the free memory; on also works on CPU); "
                        "otherwise DataLoader workers with pinned memory and prefetching")
    t.add_argument("--log-every", type=int, help="a log.csv row and a progress line every N steps")
    t.add_argument("--val-every", type=int,
                   help="every N steps, predict the val shards, log the IoUs to val.csv (and TensorBoard) and keep "
                        "the best model in best.pt (which evaluate then uses)")
    t.add_argument("--val-shards", help="explicit val shards (glob) instead of <shards>/val-*.mcap")
    t.add_argument("--checkpoint-every", type=int, help="checkpoint.pt written every N steps")
    t.add_argument("--tensorboard", action="store_true", help="also log to <out>/tensorboard")
    t.add_argument("--stop-after", type=int, help=argparse.SUPPRESS)
    # One copy of the defaults: the typed configuration's.
    t.set_defaults(**TrainConfig.defaults())
    e = sub.add_parser("evaluate", help="predict the val shards, write predictions/<id>.npy, print IoUs",
                       formatter_class=_Help)
    e.add_argument("--run", required=True, action="append",
                   help="the run directory (train --out); repeated, each run in turn on the same shards, in one "
                        "process (--json then prints a list, each result with its run)")
    e.add_argument("--shards", required=True, help="shards folder (val-*.mcap is used)")
    e.add_argument("--val-shards", help="explicit shards (glob) instead of <shards>/val-*.mcap")
    e.add_argument("--predictions", help="where to write the .npy maps (default <run>/predictions)")
    e.add_argument("--format", choices=["npy", "mcap", "both"],
                   help="predictions as <id>.npy maps, as one prediction shard <run>/predictions.mcap, or both")
    e.add_argument("--batch", type=int, help="frames per forward pass")
    e.add_argument("--device", help="auto, cpu or cuda")
    e.add_argument("--timing-frames", type=int,
                   help="forward passes (batch 1) timed for inference ms/frame, after two warm-ups; 0: none")
    e.add_argument("--timing-seconds", type=float,
                   help="stop timing once the timed passes took this long (at least 3 of them)")
    e.add_argument("--json", action="store_true", help="print the results as JSON")
    e.add_argument("--onnx", help="also time this exported model (onnxruntime, CPU) per frame")
    e.add_argument("--points", action="store_true",
                   help="also carry each prediction back to every point of its scan (native module), score it "
                        "per point (3D, beside the 2D figures) and write the per-point predictions as kitti2pgm "
                        "unproject does (SemanticKITTI: raw ids in sequences/<NN>/predictions/); needs --raw")
    e.add_argument("--raw", help="with --points: the dataset root holding the scans")
    e.add_argument("--unproject", choices=["cell", "knn"],
                   help="with --points: a point's class from its cell, or RangeNet++'s kNN post-processing")
    e.add_argument("--point-predictions", help="with --points: where (default <run>/point_predictions)")
    e.add_argument("--knn-k", type=int, help="kNN: neighbours that vote")
    e.add_argument("--knn-window", type=int, help="kNN: search window side, cells (odd)")
    e.add_argument("--knn-sigma", type=float, help="kNN: Gaussian standard deviation, cells")
    e.add_argument("--knn-cutoff", type=float, help="kNN: farther neighbours vote for nobody, metres")
    e.add_argument("--knn-wrap", action="store_true", help="kNN: window across the 360-degree seam")
    e.set_defaults(**EvalConfig.defaults())
    x = sub.add_parser("export", help="export a run as ONNX and/or TorchScript, normalisation inside",
                       formatter_class=_Help)
    x.add_argument("--run", required=True, help="the run directory (train --out)")
    x.add_argument("--out", help="the .onnx file to write")
    x.add_argument("--torchscript", help="the TorchScript .pt file to write")
    r = sub.add_parser("predict", help="run a run's network (PyTorch, GPU when present) on scan files or folders, "
                                       "projected and carried back as kitti2pgm infer does",
                       formatter_class=_Help)
    r.add_argument("--run", required=True, help="the run directory (train --out)")
    r.add_argument("inputs", nargs="+", metavar="INPUT", help="scan files (.bin, .pcd, .pcd.bin) or folders of them")
    r.add_argument("--out", required=True, help="OUT/<stem>.label per scan (uint32 class ids, 0xffff: outside "
                                                "the map), as kitti2pgm infer writes a scan file's")
    r.add_argument("--device", default="auto", help="auto, cpu or cuda")
    r.add_argument("--method", choices=["knn", "cell"], default="knn",
                   help="a point's class: RangeNet++'s kNN, or its cell's")
    r.add_argument("--json", action="store_true", help="print the summary as JSON")
    return p


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0].startswith("--") and argv[0] not in ("--help", "-h"):
        argv = ["train"] + argv
    args = parser().parse_args(argv)
    from kitti2pgm_data import ShardError
    try:
        if args.command == "train":
            from .train import train
            r = train(TrainConfig.from_args(args))
            last = f"last loss {r['loss']:.4f}" if r["loss"] == r["loss"] else "no step left to train"  # NaN: none
            print(f"trained to step {r['step']}, {last}; run in {args.out}")
        elif args.command == "export":
            if not args.out and not args.torchscript:
                raise ValueError("export: give --out model.onnx and/or --torchscript model.pt")
            from .export import export
            for kind, path in export(args.run, args.out, args.torchscript).items():
                print(f"{kind}: {path}")
        elif args.command == "predict":
            from .predict import predict
            r = predict(args.run, args.inputs, args.out, args.device, args.method)
            if args.json:
                print(json.dumps(r, indent=2))
            else:
                total = max(1, sum(r["classes"].values()))
                print(f"{r['scans']} scans, {r['points']} points ({r['not_predicted']} outside the map) on "
                      f"{r['device']}; labels in {r['out']}")
                for name, n in r["classes"].items():
                    print(f"  {name:<16} {n:>10} {100 * n / total:7.3f}%")
        else:
            _evaluate(args)
    except (FileExistsError, FileNotFoundError, ValueError, ShardError, MissingExtra) as e:
        print(f"kitti2pgm_train: error: {e}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as e:
        print(f"kitti2pgm_train: error: {missing_extra(e)}", file=sys.stderr)
        return 1
    return 0


def _evaluate(args: argparse.Namespace) -> None:
    """``evaluate``: each ``--run`` in turn (one Python and torch start for all of them)."""
    from .evaluate import evaluate
    configs = EvalConfig.each_from_args(args)
    several = len(configs) > 1
    if several:
        named = [f"--{o.replace('_', '-')}" for o in ("predictions", "point_predictions", "onnx") if getattr(args, o)]
        if named:
            raise ValueError(f"evaluate: {', '.join(named)} name one run's files: give one --run")
    results = []
    for config in configs:
        r = evaluate(config)
        if args.json:
            results.append({"run": config.run, **r} if several else r)
            continue
        if several:
            print(f"run {config.run}:")
        _print_eval(r)
    if args.json:
        print(json.dumps(results if several else results[0], indent=2))


def _print_eval(r: dict) -> None:
    """An evaluation's table, per cell and (with --points) per point, and its timing."""
    import torch

    from .metrics import Confusion
    c = Confusion(r["class_map"])
    c.m = torch.tensor(r["confusion"])
    print(f"{r['frames']} frames; predictions in {r['predictions'] or r['prediction_shard']}")
    print(c.table())
    if "points" in r:
        p = Confusion(r["class_map"])
        p.m = torch.tensor(r["points"]["confusion"])
        print(f"per point ({r['points']['unproject']}, {r['points']['points']} points, "
              f"{r['points']['not_predicted']} outside the map): mIoU {p.miou():.4f} "
              f"(per cell {c.miou():.4f}); predictions in {r['points']['predictions']}")
    times = r["inference_ms_per_frame"].items()
    print("inference ms/frame: " + ", ".join(f"{k} {v:.1f}" for k, v in times if v))


class MissingExtra(Exception):
    """An optional package a command needs is not installed."""


# Optional packages and the extra of kitti2pgm-train that installs them.
EXTRAS = {"onnx": "export", "onnxscript": "export", "onnxruntime": "export", "tensorboard": "tensorboard",
          "kitti2pgm": None}


def missing_extra(e: ModuleNotFoundError) -> str:
    """What to install for a missing module, in words."""
    name = (e.name or "").split(".")[0]
    if name == "kitti2pgm":
        return "point shards need the native module: pip install ./tools/kitti2pgm_py (or tools/install.sh)"
    extra = EXTRAS.get(name)
    if extra:
        return f"this needs {name}: pip install 'kitti2pgm-train[{extra}]' (or -e 'tools/trainer[{extra}]')"
    return f"{e} (is the trainer installed? tools/install.sh)"
