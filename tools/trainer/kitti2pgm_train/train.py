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

import torch

from kitti2pgm_data import class_map, read_metadata

from . import __version__
from .common import Progress, atomic_save, say, dist_info, git_commit, lr_at, masked_loss, pick_device, seed_everything
from .data import (DeviceFrames, FrameSet, Normaliser, StepBatches, TorchFrames, class_weights, collate, find_shards,
                   load_stats)
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


def train(args) -> dict:
    rank, world, local_rank = dist_info()
    if world > 1:
        torch.distributed.init_process_group("nccl" if torch.cuda.is_available() and args.device != "cpu" else "gloo")
    device = pick_device(args.device, local_rank)
    run = args.out
    ckpt_path = os.path.join(run, "checkpoint.pt")
    if args.tensorboard:
        import importlib.util
        if importlib.util.find_spec("tensorboard") is None:
            raise ModuleNotFoundError("no tensorboard", name="tensorboard")
    started = os.path.exists(os.path.join(run, "config.json"))
    if started and not os.path.exists(ckpt_path):
        # A run that stopped before its first checkpoint left nothing to continue: start it again.
        if rank == 0:
            say(f"{run}: the run there stopped before its first checkpoint; starting it again")
            for name in ("config.json", "log.csv", "val.csv"):
                if os.path.exists(os.path.join(run, name)):
                    os.remove(os.path.join(run, name))
        started, args.resume = False, False
    if started and not args.resume:
        raise FileExistsError(f"{run} already holds a run: pass --resume to continue it, or choose another --out")
    if args.resume and not started:
        raise FileNotFoundError(f"{ckpt_path}: no run to resume in {run}")
    if world > 1:
        torch.distributed.barrier()  # every rank has checked the run directory before rank 0 writes it
    os.makedirs(run, exist_ok=True)
    if device.type == "cpu":
        torch.use_deterministic_algorithms(True)
    seed_everything(args.seed + rank)
    stats = load_stats(args.stats)
    norm = Normaliser.from_stats(stats)
    train_paths = find_shards(args.shards, "train") if not args.train_shards else find_shards(args.train_shards)
    meta = read_metadata(train_paths[0])
    classes = class_map(train_paths[0])
    weights = class_weights(stats, args.class_weights, classes)
    augment = Augmentation.parse(args.augment, args.rotate_deg, tuple(args.scale_range), args.jitter, args.drop)
    data = open_frames(train_paths, args.input, norm, augment, args.seed)
    amp = resolve_flag(args.amp, device)
    channels_last = resolve_flag(args.channels_last, device)
    on_device = use_device_data(args.data_on_gpu, data, device)
    model = SegNet(args.model, args.input, len(classes["classes"]), width_mult=args.width_mult,
                   dropout=args.dropout, crf=args.crf).to(device)
    if channels_last:
        model = model.to(memory_format=torch.channels_last)
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
        config = {
            "args": vars(args), "git_commit": git_commit(), "trainer_version": __version__,
            "kitti2pgm_version": meta["version"], "shard_params": meta["params"], "class_map": classes,
            "train_shards": train_paths, "frames": len(data), "channels": data.channels,
            "normalisation": {"source": norm.source, "mean": norm.mean, "std": norm.std},
            "class_weights": weights, "world_size": world,
            "on_the_fly": isinstance(data, PointFrameSet),
            "augmentation": vars(augment) if isinstance(data, PointFrameSet) else None,
            "speed": {"amp_bf16": amp, "channels_last": channels_last, "compile": args.compile,
                      "data_on_device": on_device},
        }
        with open(os.path.join(run, "config.json"), "w") as f:
            json.dump(config, f, indent=2)
    weight = torch.tensor(weights, dtype=torch.float32, device=device)
    log_path = os.path.join(run, "log.csv")
    new_log = not os.path.exists(log_path)
    log = open(log_path, "a", newline="") if rank == 0 else None
    writer = csv.writer(log) if log else None
    if writer and new_log:
        writer.writerow(["step", "loss", "lr", "frames_per_s", "data_wait_share"])
    tb = None
    if rank == 0 and args.tensorboard:
        from torch.utils.tensorboard import SummaryWriter
        tb = SummaryWriter(os.path.join(run, "tensorboard"))
    model.train()
    if rank == 0:
        say(f"training {args.model} ({args.input}) on {len(data)} frames of {len(train_paths)} shard(s), "
            f"{len(classes['classes'])} classes, device {device}{' x ' + str(world) if world > 1 else ''}; "
            f"steps {start}..{args.steps} of {args.batch} frames; run in {run}")
    progress = Progress(args.steps, "training", start) if rank == 0 else None
    t_last, frames_since = time.perf_counter(), 0
    loss_value = float("nan")
    sampler = StepBatches(len(data), args.batch, start, args.steps, args.seed, args.flip, rank, world)
    if on_device:
        resident = DeviceFrames(data, device)
        batches = (resident.batch(keys) for keys in sampler)
    else:
        batches = iter(torch.utils.data.DataLoader(
            TorchFrames(data),
            batch_sampler=sampler,
            collate_fn=collate,
            num_workers=args.workers,
            pin_memory=device.type == "cuda",
            prefetch_factor=4 if args.workers > 0 else None,
            persistent_workers=args.workers > 0,
            # Its own generator: the loader's worker seed must not consume the global RNG that
            # dropout draws from, or a resumed run would diverge.
            generator=torch.Generator().manual_seed(args.seed),
        ))
    forward = torch.compile(model) if args.compile else model
    val_data, best = None, float("-inf")
    if args.val_every and rank == 0:
        val_paths = find_shards(args.val_shards or args.shards, None if args.val_shards else "val")
        val_data = open_frames(val_paths, args.input, norm)
        if args.resume:
            best = ck.get("best_miou", best)
    val_log = None
    if val_data is not None:
        val_path = os.path.join(run, "val.csv")
        new_val = not os.path.exists(val_path)
        val_log = open(val_path, "a", newline="")
        val_writer = csv.writer(val_log)
        if new_val:
            val_writer.writerow(["step", "miou"] + [c["name"] for c in classes["classes"]])
    done = start
    wait = 0.0  # seconds spent waiting for batches since the last log line
    for step in range(start, args.steps):
        t_wait = time.perf_counter()
        batch = next(batches, None)
        if batch is None:
            break
        wait += time.perf_counter() - t_wait
        lr = lr_at(step, args.lr, args.lr_halve_every)
        for g in opt.param_groups:
            g["lr"] = lr
        idx = batch["id"]
        memory = torch.channels_last if channels_last else torch.contiguous_format
        inputs = [x.to(device, non_blocking=True).contiguous(memory_format=memory) for x in batch["inputs"]]
        mask, label = batch["mask"].to(device, non_blocking=True), batch["label"].to(device, non_blocking=True)
        with torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=amp):
            logits = forward(inputs, mask=mask, xyz=batch["xyz"].to(device))
        # The loss in float32 whatever the forward pass ran in.
        loss = masked_loss(logits.float(), label, mask, weight)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        loss_value = loss.detach().item()
        frames_since += len(idx) * world
        done = step + 1
        if rank == 0 and (done % args.log_every == 0 or done == args.steps):
            now = time.perf_counter()
            fps = frames_since / max(now - t_last, 1e-9)
            share = wait / max(now - t_last, 1e-9)
            writer.writerow([done, f"{loss_value:.6f}", f"{lr:.6g}", f"{fps:.2f}", f"{share:.4f}"])
            log.flush()
            if tb:
                tb.add_scalar("loss", loss_value, done)
                tb.add_scalar("lr", lr, done)
            t_last, frames_since, wait = now, 0, 0.0
            if progress:
                progress.line(done, f"loss {loss_value:.4f}, {fps:.1f} frames/s, lr {lr:.3g}")
        if progress:
            progress.update(done, f"loss {loss_value:.4f}")
        if val_data is not None and (done % args.val_every == 0 or done == args.steps):
            net = model.module if world > 1 else model
            net.eval()
            conf = Confusion(classes)
            for _ in predict(net, val_data, device, args.batch, conf):
                pass
            net.train()
            miou = conf.miou()
            val_writer.writerow([done, f"{miou:.6f}"] + ["" if v is None else f"{v:.6f}" for v in
                                                          (conf.iou(c) for c in range(conf.k))])
            val_log.flush()
            if tb:
                tb.add_scalar("val/miou", miou, done)
            if miou > best:
                best = miou
                atomic_save({"model": net.state_dict(), "step": done, "miou": miou}, os.path.join(run, "best.pt"))
        if rank == 0 and (done % args.checkpoint_every == 0 or done == args.steps):
            atomic_save({"model": (model.module if world > 1 else model).state_dict(), "optimizer": opt.state_dict(),
                         "step": done, "torch_rng": torch.get_rng_state(), "args": vars(args),
                         "best_miou": best}, ckpt_path)
        if args.stop_after and done - start >= args.stop_after:
            break  # a deliberate interruption (tests of --resume)
    if progress:
        progress.close()
    if log:
        log.close()
    if val_log:
        val_log.close()
    if world > 1:
        torch.distributed.destroy_process_group()
    return {"step": done, "loss": loss_value}


