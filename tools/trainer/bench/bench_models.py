#!/usr/bin/env python3
"""Training throughput (frames/s) and inference time (ms/frame) of the six model/input
configurations at the paper's size (64 x 512 maps, full width), on the CPU and, when present,
the GPU. Synthetic inputs of the right shapes (speed does not depend on values).

Usage: bench_models.py [--batch 32] [--steps 5] [--device cpu|cuda|all] [--amp] [--channels-last]
                       [--compile]

--amp runs the forward pass in bf16 autocast, --channels-last uses that memory format and
--compile wraps the network in torch.compile, as the trainer's options of the same names.
"""
import argparse
import statistics
import time

import torch
from kitti2pgm_train.common import masked_loss
from kitti2pgm_train.models import INPUTS, MODELS, SegNet


def sync(d):
    if d.type == "cuda":
        torch.cuda.synchronize()


def bench(model, inputs, device, batch, steps, amp=False, channels_last=False, compile=False):
    net = SegNet(model, inputs, 4).to(device)  # the paper's 4 classes
    memory = torch.channels_last if channels_last else torch.contiguous_format
    net = net.to(memory_format=memory)
    run = torch.compile(net) if compile else net
    xs = [torch.randn(batch, len(g), 64, 512, device=device).contiguous(memory_format=memory) for g in INPUTS[inputs]]
    label = torch.randint(0, 4, (batch, 64, 512), device=device)
    mask = torch.ones(batch, 64, 512, dtype=torch.bool, device=device)
    w = torch.tensor([1 / 15, 1, 10, 10], device=device)
    opt = torch.optim.SGD(net.parameters(), lr=0.01, momentum=0.9)
    times = []
    for k in range(steps + 1):
        sync(device)
        t = time.perf_counter()
        with torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=amp):
            logits = run(xs)
        loss = masked_loss(logits.float(), label, mask, w)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sync(device)
        if k:
            times.append(time.perf_counter() - t)
    fps = batch / statistics.median(times)
    net.eval()
    one = [x[:1] for x in xs]
    inf = []
    with torch.no_grad():
        for k in range(steps + 2):
            sync(device)
            t = time.perf_counter()
            with torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=amp):
                run(one)
            sync(device)
            if k >= 2:
                inf.append((time.perf_counter() - t) * 1e3)
    return fps, statistics.median(inf), net, one


class _Flat(torch.nn.Module):
    """The network with one tensor argument per input group (what ONNX export takes)."""

    def __init__(self, net):
        super().__init__()
        self.net = net

    def forward(self, *xs):
        return self.net(list(xs))


def onnx_ms(net, one, steps):
    """Median onnxruntime (CPU) time of one frame of the exported network, ms."""
    import os
    import tempfile

    import onnxruntime

    path = os.path.join(tempfile.mkdtemp(), "m.onnx")
    with torch.no_grad():
        torch.onnx.export(_Flat(net.cpu().float()).eval(), tuple(x.cpu() for x in one), path, dynamo=True,
                          verbose=False)
    session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])
    feed = {i.name: x.cpu().numpy() for i, x in zip(session.get_inputs(), one)}
    times = []
    for k in range(steps + 2):
        t = time.perf_counter()
        session.run(None, feed)
        if k >= 2:
            times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--batch", type=int, default=32)
    p.add_argument("--steps", type=int, default=5)
    p.add_argument("--device", default="all")
    p.add_argument("--amp", action="store_true")
    p.add_argument("--channels-last", action="store_true")
    p.add_argument("--compile", action="store_true")
    p.add_argument("--onnx", action="store_true", help="also time the exported model (onnxruntime, CPU)")
    a = p.parse_args()
    devices = ["cpu", "cuda"] if a.device == "all" else [a.device]
    devices = [d for d in devices if d == "cpu" or torch.cuda.is_available()]
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, batch {a.batch}, amp {a.amp}, "
          f"channels_last {a.channels_last}, compile {a.compile}")
    print(f"{'device':<6} {'model':<11} {'input':<12} {'train frames/s':>15} {'inference ms/frame':>19}"
          + (f" {'onnxruntime ms/frame':>21}" if a.onnx else ""))
    for d in devices:
        for m in sorted(MODELS):
            for i in ["xyzdi", "xyzdirgb", "xyzdi+dirgb"]:
                fps, ms, net, one = bench(m, i, torch.device(d), a.batch, a.steps, a.amp, a.channels_last, a.compile)
                extra = f" {onnx_ms(net.eval(), one, a.steps):>21.1f}" if a.onnx else ""
                print(f"{d:<6} {m:<11} {i:<12} {fps:>15.1f} {ms:>19.1f}{extra}", flush=True)


if __name__ == "__main__":
    main()
