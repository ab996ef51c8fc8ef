"""Training and evaluation loops, checkpoints, logs.

A run directory holds ``config.json`` (every argument, the git commit, the kitti2pgm version and
parameters read from the shards, the normalisation and the class weights actually used),
``log.csv`` (step, loss, learning rate, frames/s), ``checkpoint.pt`` (written atomically every
``--checkpoint-every`` steps and at the end) and, after evaluation, ``predictions/<id>.npy``
(H x W uint8 label maps that ``kitti2pgm score`` reads) and ``eval.json``. A run directory is never
overwritten: ``--resume`` continues the run found there, and ends with the same weights as an
uninterrupted run (same seed, same batches, deterministic kernels on CPU).
"""

from __future__ import annotations

import csv
import json
import os
import random
import subprocess
import sys
import time
from typing import Optional

import numpy as np
import torch
import torch.nn.functional as F

from . import __version__
from .data import FrameSet, Normaliser, class_weights, collate, find_shards, load_stats
from .metrics import Confusion
from .models import SegNet


class Progress:
    """A one-line progress display on a terminal (stderr); silent otherwise."""

    def __init__(self, total: int, what: str):
        self.total, self.what, self.tty = total, what, sys.stderr.isatty()
        self.t0 = time.perf_counter()

    def update(self, done: int, extra: str = "") -> None:
        if self.tty:
            rate = done / max(time.perf_counter() - self.t0, 1e-9)
            sys.stderr.write(f"\r{self.what} {done}/{self.total} ({rate:.1f}/s) {extra}   ")
            sys.stderr.flush()

    def close(self) -> None:
        if self.tty:
            sys.stderr.write("\n")


def git_commit() -> Optional[str]:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=os.path.dirname(__file__)).stdout.strip()
    except Exception:
        return None


def dist_info():
    """(rank, world size, local rank) from torchrun's environment, (0, 1, 0) otherwise."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    return int(os.environ.get("RANK", "0")), world, int(os.environ.get("LOCAL_RANK", "0"))


def pick_device(name: str, local_rank: int) -> torch.device:
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda":
        return torch.device("cuda", local_rank)
    return torch.device(name)


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def atomic_save(obj, path: str) -> None:
    tmp = path + ".tmp"
    torch.save(obj, tmp)
    os.replace(tmp, path)


def masked_loss(logits, label, mask, weight):
    """Class-weighted cross entropy averaged over the valid cells (SqueezeSeg's loss)."""
    ce = F.cross_entropy(logits, label, weight=weight, reduction="none")
    m = mask.float()
    return (ce * m).sum() / m.sum().clamp(min=1.0)


def lr_at(step: int, lr: float, halve_every: int) -> float:
    return lr * (0.5 ** (step // halve_every)) if halve_every > 0 else lr


def train(args) -> dict:
    rank, world, local_rank = dist_info()
    if world > 1:
        torch.distributed.init_process_group("nccl" if torch.cuda.is_available() and args.device != "cpu" else "gloo")
    device = pick_device(args.device, local_rank)
    run = args.out
    ckpt_path = os.path.join(run, "checkpoint.pt")
    if os.path.exists(os.path.join(run, "config.json")) and not args.resume:
        raise FileExistsError(f"{run} already holds a run: pass --resume to continue it, or choose another --out")
    if args.resume and not os.path.exists(ckpt_path):
        raise FileNotFoundError(f"{ckpt_path}: no checkpoint to resume")
    if world > 1:
        torch.distributed.barrier()  # every rank has checked the run directory before rank 0 writes it
    os.makedirs(run, exist_ok=True)
    if device.type == "cpu":
        torch.use_deterministic_algorithms(True)
    seed_everything(args.seed + rank)
    stats = load_stats(args.stats)
    norm = Normaliser.from_stats(stats)
    weights = class_weights(stats, args.class_weights)
    train_paths = find_shards(args.shards, "train") if not args.train_shards else find_shards(args.train_shards)
    data = FrameSet(train_paths, args.input, norm)
    model = SegNet(args.model, args.input, width_mult=args.width_mult, dropout=args.dropout, crf=args.crf).to(device)
    if world > 1:
        model = torch.nn.parallel.DistributedDataParallel(model, device_ids=[local_rank] if device.type == "cuda" else None)
    opt = torch.optim.SGD(model.parameters(), lr=args.lr, momentum=args.momentum, weight_decay=args.weight_decay)
    start = 0
    if args.resume:
        ck = torch.load(ckpt_path, map_location=device, weights_only=False)
        (model.module if world > 1 else model).load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        start = ck["step"]
        torch.set_rng_state(ck["torch_rng"])
    if rank == 0 and not args.resume:
        meta = {}
        try:
            from kitti2pgm_data import read_metadata
            meta = read_metadata(train_paths[0])
        except Exception:
            pass
        config = {
            "args": vars(args), "git_commit": git_commit(), "trainer_version": __version__,
            "kitti2pgm_version": meta.get("version"), "shard_params": meta.get("params"),
            "train_shards": train_paths, "frames": len(data), "channels": data.channels,
            "normalisation": {"source": norm.source, "mean": norm.mean, "std": norm.std},
            "class_weights": weights, "world_size": world,
        }
        with open(os.path.join(run, "config.json"), "w") as f:
            json.dump(config, f, indent=2)
    weight = torch.tensor(weights, dtype=torch.float32, device=device)
    log_path = os.path.join(run, "log.csv")
    new_log = not os.path.exists(log_path)
    log = open(log_path, "a", newline="") if rank == 0 else None
    writer = csv.writer(log) if log else None
    if writer and new_log:
        writer.writerow(["step", "loss", "lr", "frames_per_s"])
    tb = None
    if rank == 0 and args.tensorboard:
        from torch.utils.tensorboard import SummaryWriter
        tb = SummaryWriter(os.path.join(run, "tensorboard"))
    model.train()
    progress = Progress(args.steps, "training") if rank == 0 else None
    t_last, frames_since = time.perf_counter(), 0
    loss_value = float("nan")
    from .data import StepBatches, TorchFrames
    loader = torch.utils.data.DataLoader(
        TorchFrames(data),
        batch_sampler=StepBatches(len(data), args.batch, start, args.steps, args.seed, args.flip, rank, world),
        collate_fn=collate,
        num_workers=args.workers,
        pin_memory=device.type == "cuda",
        # Its own generator: the loader's worker seed must not consume the global RNG that
        # dropout draws from, or a resumed run would diverge.
        generator=torch.Generator().manual_seed(args.seed),
    )
    done = start
    for step, batch in zip(range(start, args.steps), loader):
        lr = lr_at(step, args.lr, args.lr_halve_every)
        for g in opt.param_groups:
            g["lr"] = lr
        idx = batch["id"]
        inputs = [x.to(device, non_blocking=True) for x in batch["inputs"]]
        mask, label = batch["mask"].to(device, non_blocking=True), batch["label"].to(device, non_blocking=True)
        logits = model(inputs, mask=mask, xyz=batch["xyz"].to(device))
        loss = masked_loss(logits, label, mask, weight)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        loss_value = loss.detach().item()
        frames_since += len(idx) * world
        done = step + 1
        if rank == 0 and (done % args.log_every == 0 or done == args.steps):
            now = time.perf_counter()
            fps = frames_since / max(now - t_last, 1e-9)
            writer.writerow([done, f"{loss_value:.6f}", f"{lr:.6g}", f"{fps:.2f}"])
            log.flush()
            if tb:
                tb.add_scalar("loss", loss_value, done)
                tb.add_scalar("lr", lr, done)
            t_last, frames_since = now, 0
        if progress:
            progress.update(done, f"loss {loss_value:.4f}")
        if rank == 0 and (done % args.checkpoint_every == 0 or done == args.steps):
            atomic_save({"model": (model.module if world > 1 else model).state_dict(), "optimizer": opt.state_dict(),
                         "step": done, "torch_rng": torch.get_rng_state(), "args": vars(args)}, ckpt_path)
        if args.stop_after and done - start >= args.stop_after:
            break  # a deliberate interruption (tests of --resume)
    if progress:
        progress.close()
    if log:
        log.close()
    if world > 1:
        torch.distributed.destroy_process_group()
    return {"step": done, "loss": loss_value}


def load_run(run: str, device: torch.device):
    with open(os.path.join(run, "config.json")) as f:
        config = json.load(f)
    a = config["args"]
    model = SegNet(a["model"], a["input"], width_mult=a["width_mult"], dropout=a["dropout"], crf=a["crf"])
    ck = torch.load(os.path.join(run, "checkpoint.pt"), map_location=device, weights_only=False)
    model.load_state_dict(ck["model"])
    norm = Normaliser(config["normalisation"]["mean"], config["normalisation"]["std"], config["normalisation"]["source"])
    return model.to(device).eval(), config, norm


@torch.no_grad()
def evaluate(args) -> dict:
    """Predicts every frame of the val shards, writes ``predictions/<id>.npy`` and the IoU table."""
    device = pick_device(args.device, 0)
    model, config, norm = load_run(args.run, device)
    paths = find_shards(args.shards, "val") if not args.val_shards else find_shards(args.val_shards)
    data = FrameSet(paths, config["args"]["input"], norm)
    out = args.predictions or os.path.join(args.run, "predictions")
    write_npy = args.format in ("npy", "both")
    if write_npy:
        os.makedirs(out, exist_ok=True)
    conf = Confusion()
    progress = Progress(len(data), "evaluating")

    def predictions():
        for start in range(0, len(data), args.batch):
            batch = collate([data.item(i) for i in range(start, min(start + args.batch, len(data)))])
            mask = batch["mask"].to(device)
            logits = model([x.to(device) for x in batch["inputs"]], mask=mask, xyz=batch["xyz"].to(device))
            pred = logits.argmax(1)
            conf.add(pred, batch["label"].to(device), mask)
            for fid, p in zip(batch["id"], pred.to(torch.uint8).cpu().numpy()):
                if write_npy:
                    tmp = os.path.join(out, f".{fid}.tmp.npy")
                    np.save(tmp, p)
                    os.replace(tmp, os.path.join(out, f"{fid}.npy"))
                yield {"id": fid, "label": p}
            progress.update(min(start + args.batch, len(data)))

    shard_out = None
    if args.format in ("mcap", "both"):
        from kitti2pgm_data import write_predictions
        shard_out = os.path.join(args.run, "predictions.mcap")
        write_predictions(shard_out, predictions(), schema_from=paths[0],
                          metadata={"run": os.path.abspath(args.run), "model": config["args"]["model"],
                                    "input": config["args"]["input"]})
    else:
        for _ in predictions():
            pass
    progress.close()
    timing = inference_time(model, data, device, args.timing_frames)
    result = {"frames": len(data), "predictions": out if write_npy else None, "prediction_shard": shard_out,
              **conf.as_dict(), "inference_ms_per_frame": timing}
    with open(os.path.join(args.run, "eval.json"), "w") as f:
        json.dump(result, f, indent=2)
    return result


@torch.no_grad()
def inference_time(model, data: FrameSet, device: torch.device, frames: int) -> dict:
    """Median forward time of one frame (batch 1) on the CPU and, when present, the GPU."""
    out = {}
    item = collate([data.item(0)])
    devices = [torch.device("cpu")] + ([torch.device("cuda")] if torch.cuda.is_available() else [])
    for d in devices:
        m = model.to(d)
        xs = [x.to(d) for x in item["inputs"]]
        mask, xyz = item["mask"].to(d), item["xyz"].to(d)
        times = []
        for k in range(frames + 2):
            if d.type == "cuda":
                torch.cuda.synchronize()
            t = time.perf_counter()
            m(xs, mask=mask, xyz=xyz)
            if d.type == "cuda":
                torch.cuda.synchronize()
            if k >= 2:  # two warm-up passes
                times.append((time.perf_counter() - t) * 1e3)
        out[d.type] = float(np.median(times)) if times else None
    model.to(device)
    return out
