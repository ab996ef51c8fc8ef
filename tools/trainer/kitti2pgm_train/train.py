"""The training loop.

A run directory holds ``config.json`` (every argument, the git commit, the kitti2pgm version, the
conversion parameters and class map read from the shards, the normalisation and the class weights
actually used), ``log.csv`` (step, loss, learning rate, frames/s) and ``checkpoint.pt`` (written
atomically every ``--checkpoint-every`` steps and at the end). A run directory is never
overwritten: ``--resume`` continues the run found there, and ends with the same weights as an
uninterrupted run (same seed, same batches, deterministic kernels on CPU).
"""

from __future__ import annotations

import csv
import json
import os
import time
from dataclasses import dataclass

import torch
from kitti2pgm_data import class_map, read_metadata

from . import __version__
from .common import Progress, atomic_save, dist_info, git_commit, lr_at, masked_loss, pick_device, say, seed_everything
from .config import TrainConfig
from .data import (
    DeviceFrames,
    FrameSet,
    Normaliser,
    StepBatches,
    TorchFrames,
    check_same_map,
    class_weights,
    collate,
    find_shards,
    load_stats,
)
from .evaluate import predict
from .metrics import Confusion
from .models import SegNet
from .onthefly import Augmentation, PointFrameSet, open_frames


def resolve_flag(value, device: torch.device) -> bool:
    """An on/off speed option: as given, else on for CUDA and off elsewhere."""
    return device.type == "cuda" if value is None else bool(value)


def use_device_data(mode: str, data: FrameSet, device: torch.device) -> bool:
    """Whether the split is loaded onto the device (``--data-on-gpu``): ``on``, ``off``, or
    ``auto`` = on a CUDA device when it takes at most half of the free memory."""
    if isinstance(data, PointFrameSet):
        return False  # projected per sample, in the workers
    if mode in ("on", "off"):
        return mode == "on"
    if device.type != "cuda":
        return False
    free, _total = torch.cuda.mem_get_info(device)
    return DeviceFrames.bytes_needed(data) <= free // 2


@dataclass
class TrainData:
    """The dataset role: the train frames and what was read with them."""

    paths: list
    meta: dict
    classes: dict
    norm: Normaliser
    weights: list
    data: FrameSet


def load_train_data(cfg: TrainConfig) -> TrainData:
    """The train shards, their class map and metadata, the normalisation and class weights."""
    stats = load_stats(cfg.stats)
    norm = Normaliser.from_stats(stats)
    paths = find_shards(cfg.train_shards) if cfg.train_shards else find_shards(cfg.shards, "train")
    classes = class_map(paths[0])
    low, high = cfg.scale_range
    augment = Augmentation.parse(cfg.augment, cfg.rotate_deg, (low, high), cfg.jitter, cfg.drop)
    return TrainData(paths=paths, meta=read_metadata(paths[0]), classes=classes, norm=norm,
                     weights=class_weights(stats, cfg.class_weights, classes),
                     data=open_frames(paths, cfg.input, norm, augment, cfg.seed))


def build_model(cfg: TrainConfig, n_classes: int, device, channels_last: bool, dist) -> torch.nn.Module:
    """The model role: the network on its device (wrapped for several processes)."""
    model: torch.nn.Module = SegNet(cfg.model, cfg.input, n_classes, width_mult=cfg.width_mult,
                                    dropout=cfg.dropout, crf=cfg.crf).to(device)
    if channels_last:
        model = model.to(memory_format=torch.channels_last)
    rank, world, local_rank = dist
    if world > 1:
        ids = [local_rank] if device.type == "cuda" else None
        model = torch.nn.parallel.DistributedDataParallel(model, device_ids=ids)
    return model


def open_run_dir(cfg: TrainConfig, rank: int) -> bool:
    """Checks the run directory: a new run, or ``--resume`` of one with a checkpoint. Returns
    whether to resume (a run that stopped before its first checkpoint starts again)."""
    run, ckpt = cfg.out, os.path.join(cfg.out, "checkpoint.pt")
    started = os.path.exists(os.path.join(run, "config.json"))
    resume = cfg.resume
    if started and not os.path.exists(ckpt):
        if rank == 0:
            say(f"{run}: the run there stopped before its first checkpoint; starting it again")
            for name in ("config.json", "log.csv", "val.csv"):
                if os.path.exists(os.path.join(run, name)):
                    os.remove(os.path.join(run, name))
        started, resume = False, False
    if started and not resume:
        raise FileExistsError(f"{run} already holds a run: pass --resume to continue it, or choose another --out")
    if resume and not started:
        raise FileNotFoundError(f"{ckpt}: no run to resume in {run}")
    return resume


def write_config(cfg: TrainConfig, td: TrainData, world: int, speed: dict) -> None:
    """``config.json``: the configuration and everything the run was made from."""
    config = {
        "args": cfg.to_dict(), "git_commit": git_commit(), "trainer_version": __version__,
        "kitti2pgm_version": td.meta["version"], "shard_params": td.meta["params"], "class_map": td.classes,
        "train_shards": td.paths, "frames": len(td.data), "channels": td.data.channels,
        "normalisation": {"source": td.norm.source, "mean": td.norm.mean, "std": td.norm.std},
        "class_weights": td.weights, "world_size": world,
        "on_the_fly": isinstance(td.data, PointFrameSet),
        "augmentation": vars(td.data.augment) if isinstance(td.data, PointFrameSet) else None,
        "speed": speed,
    }
    with open(os.path.join(cfg.out, "config.json"), "w") as f:
        json.dump(config, f, indent=2)


def batch_stream(cfg: TrainConfig, data: FrameSet, device, on_device: bool, start: int, dist):
    """The batches of steps ``start`` to ``cfg.steps``, the same whatever the workers."""
    rank, world, _ = dist
    sampler = StepBatches(len(data), cfg.batch, start, cfg.steps, cfg.seed, cfg.flip, rank, world)
    if on_device:
        resident = DeviceFrames(data, device)
        return (resident.batch(keys) for keys in sampler)
    return iter(torch.utils.data.DataLoader(
        TorchFrames(data),
        batch_sampler=sampler,
        collate_fn=collate,
        num_workers=cfg.workers,
        pin_memory=device.type == "cuda",
        prefetch_factor=4 if cfg.workers > 0 else None,
        persistent_workers=cfg.workers > 0,
        # Its own generator: the loader's worker seed must not consume the global RNG that
        # dropout draws from, or a resumed run would diverge.
        generator=torch.Generator().manual_seed(cfg.seed),
    ))


class Logs:
    """The task's records: ``log.csv``, ``val.csv`` and TensorBoard (rank 0 only)."""

    def __init__(self, cfg: TrainConfig, classes: dict, rank: int, validating: bool):
        self.log = self.val = self.tb = None
        if rank != 0:
            return
        self.log, self.writer = self._csv(os.path.join(cfg.out, "log.csv"),
                                          ["step", "loss", "lr", "frames_per_s", "data_wait_share"])
        if validating:
            self.val, self.val_writer = self._csv(os.path.join(cfg.out, "val.csv"),
                                                  ["step", "miou"] + [c["name"] for c in classes["classes"]])
        if cfg.tensorboard:
            from torch.utils.tensorboard import SummaryWriter
            self.tb = SummaryWriter(os.path.join(cfg.out, "tensorboard"))

    @staticmethod
    def _csv(path: str, header: list):
        new = not os.path.exists(path)
        f = open(path, "a", newline="")
        w = csv.writer(f)
        if new:
            w.writerow(header)
        return f, w

    def step(self, done: int, loss: float, lr: float, fps: float, wait_share: float) -> None:
        self.writer.writerow([done, f"{loss:.6f}", f"{lr:.6g}", f"{fps:.2f}", f"{wait_share:.4f}"])
        assert self.log is not None, "rank 0 logs"
        self.log.flush()
        if self.tb:
            self.tb.add_scalar("loss", loss, done)
            self.tb.add_scalar("lr", lr, done)

    def validation(self, done: int, conf: Confusion) -> None:
        miou = conf.miou()
        ious = (conf.iou(c) for c in range(conf.k))
        self.val_writer.writerow([done, f"{miou:.6f}"] + ["" if v is None else f"{v:.6f}" for v in ious])
        assert self.val is not None, "rank 0 validates"
        self.val.flush()
        if self.tb:
            self.tb.add_scalar("val/miou", miou, done)

    def close(self) -> None:
        for f in (self.log, self.val):
            if f:
                f.close()


def validate(net, val_data: FrameSet, classes: dict, device, batch: int) -> Confusion:
    """The val frames predicted by ``net`` (left in training mode afterwards)."""
    net.eval()
    conf = Confusion(classes)
    for _ in predict(net, val_data, device, batch, conf):
        pass
    net.train()
    return conf


def train_step(forward, opt, batch: dict, lr: float, weight, device, memory, amp: bool) -> float:
    """One SGD step on a batch at learning rate ``lr``; returns the loss."""
    for g in opt.param_groups:
        g["lr"] = lr
    inputs = [x.to(device, non_blocking=True).contiguous(memory_format=memory) for x in batch["inputs"]]
    mask, label = batch["mask"].to(device, non_blocking=True), batch["label"].to(device, non_blocking=True)
    with torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=amp):
        logits = forward(inputs, mask=mask, xyz=batch["xyz"].to(device))
    # The loss in float32 whatever the forward pass ran in.
    loss = masked_loss(logits.float(), label, mask, weight)
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()
    return loss.detach().item()


def _start_processes(cfg: TrainConfig):
    """(rank, world, local rank) and this process's device; joins the process group when there
    are several processes (torchrun)."""
    dist = dist_info()
    if dist[1] > 1:
        torch.distributed.init_process_group("nccl" if torch.cuda.is_available() and cfg.device != "cpu" else "gloo")
    return dist, pick_device(cfg.device, dist[2])


def _restore(ckpt_path: str, net, opt, device) -> dict:
    """Loads the checkpoint into the model and the optimiser, restores the RNG; returns it."""
    ck = torch.load(ckpt_path, map_location=device, weights_only=False)
    net.load_state_dict(ck["model"])
    opt.load_state_dict(ck["optimizer"])
    torch.set_rng_state(ck["torch_rng"])
    return ck


def _validation_frames(cfg: TrainConfig, td):
    """The validation frames: ``cfg.val_shards``, or the val split of the training shards."""
    paths = find_shards(cfg.val_shards or cfg.shards, None if cfg.val_shards else "val")
    return open_frames(paths, cfg.input, td.norm)


def train(cfg: TrainConfig) -> dict:
    """Trains as ``cfg`` says (a new run, or ``cfg.resume``); returns the last step and loss."""
    dist, device = _start_processes(cfg)
    rank, world, _ = dist
    run, ckpt_path = cfg.out, os.path.join(cfg.out, "checkpoint.pt")
    if cfg.tensorboard:
        import importlib.util
        if importlib.util.find_spec("tensorboard") is None:
            raise ModuleNotFoundError("no tensorboard", name="tensorboard")
    resume = open_run_dir(cfg, rank)
    if world > 1:
        torch.distributed.barrier()  # every rank has checked the run directory before rank 0 writes it
    os.makedirs(run, exist_ok=True)
    if device.type == "cpu":
        torch.use_deterministic_algorithms(True)
    seed_everything(cfg.seed + rank)
    td = load_train_data(cfg)
    amp, channels_last = resolve_flag(cfg.amp, device), resolve_flag(cfg.channels_last, device)
    on_device = use_device_data(cfg.data_on_gpu, td.data, device)
    model = build_model(cfg, len(td.classes["classes"]), device, channels_last, dist)
    net: torch.nn.Module = model.module if world > 1 else model  # type: ignore[assignment]
    opt = torch.optim.SGD(model.parameters(), lr=cfg.lr, momentum=cfg.momentum, weight_decay=cfg.weight_decay)
    start, best, ck = 0, float("-inf"), None
    if resume:
        with open(os.path.join(run, "config.json")) as f:
            check_same_map(td.paths, json.load(f)["shard_params"], run)
        ck = _restore(ckpt_path, net, opt, device)
        start = ck["step"]
    elif rank == 0:
        write_config(cfg, td, world, {"amp_bf16": amp, "channels_last": channels_last, "compile": cfg.compile,
                                      "data_on_device": on_device})
    weight = torch.tensor(td.weights, dtype=torch.float32, device=device)
    val_data = _validation_frames(cfg, td) if cfg.val_every and rank == 0 else None
    if val_data is not None and ck:
        best = ck.get("best_miou", best)
    logs = Logs(cfg, td.classes, rank, val_data is not None)
    model.train()
    if rank == 0:
        say(f"training {cfg.model} ({cfg.input}) on {len(td.data)} frames of {len(td.paths)} shard(s), "
            f"{len(td.classes['classes'])} classes, device {device}{' x ' + str(world) if world > 1 else ''}; "
            f"steps {start}..{cfg.steps} of {cfg.batch} frames; run in {run}")
    progress = Progress(cfg.steps, "training", start) if rank == 0 else None
    batches = batch_stream(cfg, td.data, device, on_device, start, dist)
    forward = torch.compile(model) if cfg.compile else model
    memory = torch.channels_last if channels_last else torch.contiguous_format
    t_last, frames_since, wait = time.perf_counter(), 0, 0.0
    loss_value, done = float("nan"), start
    for step in range(start, cfg.steps):
        t_wait = time.perf_counter()
        batch = next(batches, None)
        if batch is None:
            break
        wait += time.perf_counter() - t_wait
        lr = lr_at(step, cfg.lr, cfg.lr_halve_every)
        loss_value = train_step(forward, opt, batch, lr, weight, device, memory, amp)
        frames_since += len(batch["id"]) * world
        done = step + 1
        if rank == 0 and (done % cfg.log_every == 0 or done == cfg.steps):
            now = time.perf_counter()
            elapsed = max(now - t_last, 1e-9)
            logs.step(done, loss_value, lr, frames_since / elapsed, wait / elapsed)
            if progress:
                progress.line(done, f"loss {loss_value:.4f}, {frames_since / elapsed:.1f} frames/s, lr {lr:.3g}")
            t_last, frames_since, wait = now, 0, 0.0
        if progress:
            progress.update(done, f"loss {loss_value:.4f}")
        if val_data is not None and (done % cfg.val_every == 0 or done == cfg.steps):
            conf = validate(net, val_data, td.classes, device, cfg.batch)
            logs.validation(done, conf)
            if conf.miou() > best:
                best = conf.miou()
                atomic_save({"model": net.state_dict(), "step": done, "miou": best}, os.path.join(run, "best.pt"))
        if rank == 0 and (done % cfg.checkpoint_every == 0 or done == cfg.steps):
            atomic_save({"model": net.state_dict(), "optimizer": opt.state_dict(), "step": done,
                         "torch_rng": torch.get_rng_state(), "args": cfg.to_dict(), "best_miou": best}, ckpt_path)
        if cfg.stop_after and done - start >= cfg.stop_after:
            break  # a deliberate interruption (tests of --resume)
    if progress:
        progress.close()
    logs.close()
    if world > 1:
        torch.distributed.destroy_process_group()
    return {"step": done, "loss": loss_value}
