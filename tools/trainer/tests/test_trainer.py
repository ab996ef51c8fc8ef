"""The trainer on CPU: shapes, a real learning check on real frames, score agreement, resume."""

import json
import os
import shutil

import numpy as np
import pytest
import torch
from kitti2pgm_train.cli import main
from kitti2pgm_train.data import FrameSet, Normaliser
from kitti2pgm_train.models import INPUTS, MODELS, SegNet

RAW = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "fixtures", "raw")


@pytest.mark.parametrize("model", sorted(MODELS))
@pytest.mark.parametrize("inputs", sorted(INPUTS))
def test_output_shapes(model, inputs):
    net = SegNet(model, inputs, 4, width_mult=0.25).eval()
    xs = [torch.randn(2, len(g), 64, 64) for g in INPUTS[inputs]]
    with torch.no_grad():
        y = net(xs)
    assert y.shape == (2, 4, 64, 64)
    assert len(net.encoders) == len(INPUTS[inputs])


def test_crf_keeps_shapes_and_changes_logits():
    net = SegNet("squeezeseg", "xyzdi", 4, width_mult=0.25, crf=True).eval()
    x = torch.randn(1, 5, 64, 64)
    mask = torch.ones(1, 64, 64, dtype=torch.bool)
    xyz = torch.randn(1, 3, 64, 64)
    with torch.no_grad():
        plain = net.decoder(*net.encoders[0](x))
        y = net([x], mask=mask, xyz=xyz)
    assert y.shape == plain.shape and not torch.allclose(y, plain)


def test_paper_sized_squeezeseg():
    n = sum(p.numel() for p in SegNet("squeezeseg", "xyzdi", 4).parameters())
    assert 0.8e6 < n < 1.1e6, n  # SqueezeSeg has about 0.9-1 million parameters


def test_inputs_flip_and_normalisation(converted):
    fs = FrameSet(sorted((converted / "shards").glob("*.mcap")), "xyzdi+dirgb", Normaliser.from_stats(None))
    a, b = fs.item(0), fs.item(0, flip=True)
    assert [x.shape for x in a["inputs"]] == [(5, 64, 256), (5, 64, 256)]
    assert torch.equal(a["label"].flip(-1), b["label"]) and torch.equal(a["mask"].flip(-1), b["mask"])
    # Empty cells are exactly zero; y is negated before normalisation when flipped.
    assert torch.all(a["inputs"][0][:, ~a["mask"]] == 0)
    m, s = fs.norm.mean["y"], fs.norm.std["y"]
    y_raw = a["inputs"][0][1] * s + m
    y_flip = b["inputs"][0][1].flip(-1) * s + m
    valid = a["mask"]
    assert torch.allclose(y_flip[valid], -y_raw[valid], atol=1e-4)


def test_colour_inputs_need_colour_shards(lidar_only):
    with pytest.raises(ValueError, match="convert with --rgb"):
        FrameSet(sorted((lidar_only / "shards").glob("*.mcap")), "xyzdirgb", Normaliser.from_stats(None))


def _train(out, shards, steps, extra=()):
    args = ["train", "--shards", str(shards), "--out", str(out), "--model", "squeezeseg", "--input", "xyzdi",
            "--width-mult", "0.25", "--batch", "3", "--steps", str(steps), "--lr", "0.05", "--no-flip",
            "--dropout", "0", "--class-weights", "uniform", "--device", "cpu", "--log-every", "50", "--workers", "0",
            *extra]
    assert main(args) == 0


@pytest.mark.long(17)
def test_overfits_real_frames_and_agrees_with_kitti2pgm_score(converted, tmp_path, kitti2pgm):
    """A real learning check: on the three real fixture frames, 150 steps take the car IoU from
    near zero to high (measured 0.71 on the development machine, 0.74 after 300 steps; the
    threshold leaves room for other CPUs' arithmetic)."""
    run = tmp_path / "run"
    shards = converted / "shards"
    _train(run, shards, 150)
    assert main(["evaluate", "--run", str(run), "--shards", str(shards), "--val-shards", str(shards / "train-*.mcap"),
                 "--device", "cpu", "--timing-frames", "1", "--format", "both"]) == 0
    ev = json.loads((run / "eval.json").read_text())
    assert ev["frames"] == 3
    assert ev["iou"]["car"] >= 0.6, ev["iou"]
    assert ev["inference_ms_per_frame"]["cpu"] > 0
    # The trainer's IoUs are kitti2pgm score's on the same predictions.
    r = kitti2pgm("score", "--gt", str(converted), "--pred", str(run / "predictions"), "--json")
    score = json.loads(r.stdout)
    assert score["confusion"]["m"] == ev["confusion"]
    for c in ("background", "car", "pedestrian", "cyclist"):
        assert score["classes"][c]["iou"] == ev["iou"][c]
    assert score["miou"] == ev["miou"]
    # The prediction shard scores the same.
    r = kitti2pgm("score", "--gt", str(converted), "--pred", str(run / "predictions.mcap"), "--json")
    assert json.loads(r.stdout)["confusion"] == score["confusion"]
    # After a single step the same network is far from it: the IoU was learnt.
    run0 = tmp_path / "run0"
    _train(run0, shards, 1)
    assert main(["evaluate", "--run", str(run0), "--shards", str(shards), "--val-shards", str(shards / "train-*.mcap"),
                 "--device", "cpu", "--timing-frames", "1"]) == 0
    ev0 = json.loads((run0 / "eval.json").read_text())
    assert (ev0["iou"]["car"] or 0.0) < ev["iou"]["car"] - 0.3, (ev0["iou"], ev["iou"])
    config = json.loads((run / "config.json").read_text())
    assert config["git_commit"] is None or len(config["git_commit"]) == 40
    assert config["kitti2pgm_version"] and config["class_weights"] == [1.0, 1.0, 1.0, 1.0]
    log = (run / "log.csv").read_text().splitlines()
    assert log[0] == "step,loss,lr,frames_per_s,data_wait_share" and len(log) == 4
    first, last = float(log[1].split(",")[1]), float(log[-1].split(",")[1])
    assert last < first


def test_resume_gives_the_uninterrupted_result(converted, tmp_path):
    shards = converted / "shards"
    # Two DataLoader workers and dropout: the batches and the RNG must still line up.
    extra = ["--checkpoint-every", "2", "--dropout", "0.5", "--workers", "2"]
    straight, resumed = tmp_path / "straight", tmp_path / "resumed"
    _train(straight, shards, 6, extra)
    _train(resumed, shards, 6, extra + ["--stop-after", "3"])
    ck = torch.load(resumed / "checkpoint.pt", weights_only=False)
    assert ck["step"] == 3 or ck["step"] == 2  # stopped mid-run
    with pytest.raises(FileExistsError):
        from kitti2pgm_train.config import TrainConfig
        from kitti2pgm_train.train import train
        train(TrainConfig(shards=str(shards), out=str(resumed)))
    _train(resumed, shards, 6, extra + ["--resume"])
    a = torch.load(straight / "checkpoint.pt", weights_only=False)["model"]
    b = torch.load(resumed / "checkpoint.pt", weights_only=False)["model"]
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


def test_evaluate_refuses_shards_of_another_map(lidar_only, tmp_path, kitti2pgm, capsys):
    """(Issue 26) A run trained on 64 x 256 over 90 degrees reports no IoU on shards of 64 x 1024
    over 120 degrees: both maps are named."""
    run = tmp_path / "run"
    _train(run, lidar_only / "shards", 1)
    other = tmp_path / "other"
    kitti2pgm("convert", str(RAW), "--out", str(other), "--format", "mcap", "--cols", "1024", "--fov-deg", "120")
    args = ["evaluate", "--run", str(run), "--shards", str(other / "shards"), "--val-shards",
            str(other / "shards" / "train-*.mcap"), "--device", "cpu", "--timing-frames", "1"]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "its map is 64 x 1024 over 120 deg" in err and "trained on 64 x 256 over 90 deg" in err, err
    assert not (run / "eval.json").exists()


def test_several_runs_evaluate_in_one_process(lidar_only, tmp_path, capsys):
    """evaluate --run A --run B: each run as if alone (its own predictions and eval.json), --json a
    list of the results with their runs; a file option that names one run's files is refused."""
    one, two = tmp_path / "one", tmp_path / "two"
    _train(one, lidar_only / "shards", 1)
    _train(two, lidar_only / "shards", 2)
    # A finished run resumed (reproduce.sh after an interruption before its evaluation).
    capsys.readouterr()
    _train(two, lidar_only / "shards", 2, ["--resume"])
    assert "trained to step 2, no step left to train" in capsys.readouterr().out
    common = ["--shards", str(lidar_only / "shards"), "--val-shards", str(lidar_only / "shards" / "train-*.mcap"),
              "--device", "cpu", "--timing-frames", "0", "--json"]
    assert main(["evaluate", "--run", str(two), *common]) == 0
    alone = json.loads(capsys.readouterr().out)
    assert main(["evaluate", "--run", str(one), "--run", str(two), *common]) == 0
    both = json.loads(capsys.readouterr().out)
    assert [r["run"] for r in both] == [str(one), str(two)]
    assert both[1]["confusion"] == alone["confusion"] and both[1]["frames"] == alone["frames"] == 3
    for run, r in zip((one, two), both):
        assert json.loads((run / "eval.json").read_text())["confusion"] == r["confusion"]
        assert sorted(p.name for p in (run / "predictions").iterdir()) == sorted(
            p.name for p in (two / "predictions").iterdir())
    assert main(["evaluate", "--run", str(one), "--run", str(two), *common, "--predictions", str(tmp_path / "p")]) == 1
    assert "--predictions name one run's files: give one --run" in capsys.readouterr().err


def test_errors_are_clear(converted, tmp_path, capsys):
    assert main(["train", "--shards", str(tmp_path), "--out", str(tmp_path / "r")]) == 1
    assert "no train shard" in capsys.readouterr().err
    bad = tmp_path / "stats.json"
    bad.write_text("{}")
    r2 = tmp_path / "r2"
    assert main(["train", "--shards", str(converted / "shards"), "--out", str(r2), "--stats", str(bad)]) == 1
    assert "not a kitti2pgm stats" in capsys.readouterr().err


def test_help_is_fast_and_shows_every_default():
    """--help needs no torch (it took ~12 s) and states each default."""
    import subprocess
    import sys

    code = ("import sys; from kitti2pgm_train.cli import parser; h = parser()._subparsers._group_actions[0]"
            ".choices['train'].format_help(); print('torch' in sys.modules); print(h)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.startswith("False"), "torch imported for --help"
    out = " ".join(out.split())  # argparse wraps lines
    for want in ["--steps STEPS", "(default: 50000)", "--batch BATCH", "(default: 32)", "--lr LR", "(default: 0.01)"]:
        assert want in out, want


def test_progress_is_reported_and_a_run_that_died_early_can_be_reused(converted, tmp_path, capsys):
    run = tmp_path / "run"
    shards = converted / "shards"
    # A run that stopped before its first checkpoint (config.json written, no checkpoint.pt).
    run.mkdir()
    (run / "config.json").write_text("{}")
    (run / "log.csv").write_text("step,loss\n")
    _train(run, shards, 4, ["--log-every", "2"])
    err = capsys.readouterr().err
    assert "stopped before its first checkpoint; starting it again" in err
    assert "training squeezeseg (xyzdi) on 3 frames" in err, err
    assert "training 2/4" in err and "training 4/4" in err and "frames/s" in err, err
    assert (run / "checkpoint.pt").exists()
    # --resume of a folder without a run names it.
    assert main(["train", "--shards", str(shards), "--out", str(tmp_path / "empty"), "--resume"]) == 1
    assert "no run to resume" in capsys.readouterr().err


def test_a_missing_extra_is_named(converted, tmp_path, capsys):
    import importlib.util

    if importlib.util.find_spec("tensorboard") is not None:
        pytest.skip("tensorboard is installed here: its absence cannot be shown")
    assert main(["train", "--shards", str(converted / "shards"), "--out", str(tmp_path / "r"), "--tensorboard",
                 "--steps", "1", "--device", "cpu", "--workers", "0"]) == 1
    err = capsys.readouterr().err
    assert "pip install 'kitti2pgm-train[tensorboard]'" in err, err
    assert not (tmp_path / "r").exists(), "nothing written before the check"


def test_stats_drive_normalisation_and_weights(converted, tmp_path, kitti2pgm):
    stats = tmp_path / "stats.json"
    stats.write_text(kitti2pgm("stats", str(converted), "--json").stdout)
    run = tmp_path / "run"
    _train(run, converted / "shards", 1, ["--stats", str(stats), "--class-weights", "sqrt"])
    config = json.loads((run / "config.json").read_text())
    s = json.loads(stats.read_text())
    assert config["normalisation"]["source"].startswith("kitti2pgm stats")
    assert config["normalisation"]["mean"]["range"] == s["normalisation"]["mean"][4]
    # The stats' sqrt weights (0 for the absent pedestrian class falls back to SqueezeSeg's 10).
    w = s["class_weights"]["sqrt_inverse_frequency"]
    assert config["class_weights"] == [w[0], w[1], 10.0, w[3]]


@pytest.mark.long(8)
def test_torchrun_two_processes(converted, tmp_path):
    """DistributedDataParallel through torchrun (two CPU processes, gloo)."""
    import subprocess
    import sys
    run = tmp_path / "ddp"
    r = subprocess.run([sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
                        "-m", "kitti2pgm_train", "train", "--shards", str(converted / "shards"), "--out", str(run),
                        "--width-mult", "0.25", "--batch", "1", "--steps", "2", "--device", "cpu", "--log-every", "1"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert json.loads((run / "config.json").read_text())["world_size"] == 2
    assert (run / "checkpoint.pt").exists()
    assert len((run / "log.csv").read_text().splitlines()) == 3


def test_device_resident_batches_equal_the_worker_batches(converted):
    """--data-on-gpu builds, on the device (here the CPU), exactly the worker path's batches."""
    from kitti2pgm_train.data import DeviceFrames, collate

    fs = FrameSet(sorted((converted / "shards").glob("*.mcap")), "xyzdi+dirgb", Normaliser.from_stats(None))
    keys = [(0, False), (1, True), (2, True), (0, True)]
    a = DeviceFrames(fs, torch.device("cpu")).batch(keys)
    b = collate([fs.item(i, flip=f) for i, f in keys])
    assert a["id"] == b["id"]
    for x, y in zip(a["inputs"], b["inputs"]):
        assert torch.equal(x, y)
    for k in ("xyz", "mask", "label"):
        assert torch.equal(a[k], b[k]), k


def test_amp_and_device_data_on_cpu(converted, tmp_path):
    """bf16 autocast and the device-resident data path train on CPU; the config records them."""
    run = tmp_path / "amp"
    _train(run, converted / "shards", 3, ["--amp", "--data-on-gpu", "on", "--channels-last"])
    config = json.loads((run / "config.json").read_text())
    assert config["speed"] == {"amp_bf16": True, "channels_last": True, "compile": False, "data_on_device": True}
    log = (run / "log.csv").read_text().splitlines()
    loss = float(log[-1].split(",")[1])
    assert np.isfinite(loss)


def test_validation_keeps_the_best_model(converted, tmp_path):
    run = tmp_path / "val"
    shards = converted / "shards"
    _train(run, shards, 4, ["--val-every", "2", "--val-shards", str(shards / "train-*.mcap")])
    rows = (run / "val.csv").read_text().splitlines()
    assert rows[0].startswith("step,miou,background,car") and len(rows) == 3
    best = torch.load(run / "best.pt", weights_only=False)
    assert best["miou"] == max(float(r.split(",")[1]) for r in rows[1:])


def test_exported_models_label_like_pytorch(converted, tmp_path):
    """ONNX (onnxruntime) and TorchScript give PyTorch's labels on the real frames, from the raw
    shard channels (the normalisation is inside the graph)."""
    import onnxruntime
    from kitti2pgm_train.evaluate import load_run, predict
    from kitti2pgm_train.export import export

    run = tmp_path / "exp"
    shards = converted / "shards"
    _train(run, shards, 2, ["--input", "xyzdi"])
    out = tmp_path / "export"
    out.mkdir()
    paths = export(str(run), str(out / "m.onnx"), str(out / "m.pt"))
    # One self-contained file each (no side .data file, no temporary left): the ONNX model
    # copied alone into another folder loads there.
    assert sorted(p.name for p in out.iterdir()) == ["m.onnx", "m.pt"]
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.copy(out / "m.onnx", elsewhere / "model.onnx")
    model, config, norm = load_run(str(run), torch.device("cpu"))
    fs = FrameSet(sorted(shards.glob("*.mcap")), "xyzdi", norm)
    want = dict(predict(model, fs, torch.device("cpu"), 1))
    session = onnxruntime.InferenceSession(str(elsewhere / "model.onnx"), providers=["CPUExecutionProvider"])
    scripted = torch.jit.load(paths["torchscript"])
    for i in range(len(fs)):
        f = fs.ds[i]
        x = np.ascontiguousarray(np.asarray(f["tensor"])[None], dtype=np.float32)
        labels = session.run(None, {session.get_inputs()[0].name: x})[0][0]
        assert np.array_equal(labels, want[f["id"]]), f["id"]
        ts = scripted(torch.tensor(x))[0][0].numpy()
        assert np.array_equal(ts, want[f["id"]]), f["id"]


def test_twenty_semantickitti_classes_train_and_score_like_kitti2pgm(tmp_path, kitti2pgm):
    """SemanticKITTI shards (20 classes from their metadata) train, evaluate, and the trainer's
    table equals kitti2pgm score's (the benchmark's mIoU rule: absent classes count 0)."""
    from pathlib import Path

    repo = Path(__file__).resolve().parents[3]
    data = tmp_path / "sk"
    kitti2pgm("convert", str(repo / "fixtures/semantickitti"), "--out", str(data), "--format", "npy,mcap",
              "--cols", "256")
    shards = data / "shards"
    run = tmp_path / "run"
    _train(run, shards, 3, [])
    config = json.loads((run / "config.json").read_text())
    assert len(config["class_map"]["classes"]) == 20 and config["class_weights"][0] == 0.0
    assert main(["evaluate", "--run", str(run), "--shards", str(shards), "--val-shards", str(shards / "train-*.mcap"),
                 "--device", "cpu", "--json", "--timing-frames", "0"]) == 0
    ev = json.loads((run / "eval.json").read_text())
    assert len(ev["iou"]) == 20
    score = json.loads(kitti2pgm("score", "--gt", str(data), "--pred", str(run / "predictions"), "--json").stdout)
    assert score["confusion"]["m"] == ev["confusion"]
    assert score["miou"] == ev["miou"]
    for name, iou in ev["iou"].items():
        assert score["classes"][name]["iou"] == iou, name


def test_evaluate_per_point_equals_kitti2pgm_score(converted, tmp_path, kitti2pgm):
    """evaluate --points --unproject knn: the 3D figures beside the 2D ones, equal to
    kitti2pgm score --unproject knn on the same predictions; the per-point predictions are
    written in convert's layout, and on SemanticKITTI in the benchmark's (raw ids), which
    kitti2pgm score reads with the benchmark's protocol to the same matrix."""
    from pathlib import Path

    repo = Path(__file__).resolve().parents[3]
    run = tmp_path / "run"
    shards = converted / "shards"
    _train(run, shards, 3)
    assert main(["evaluate", "--run", str(run), "--shards", str(shards), "--val-shards", str(shards / "train-*.mcap"),
                 "--device", "cpu", "--timing-frames", "0", "--points", "--raw", str(repo / "fixtures/raw")]) == 0
    ev = json.loads((run / "eval.json").read_text())
    pts = ev["points"]
    assert pts["unproject"] == "knn" and pts["points"] > 300_000 and pts["not_predicted"] > 100_000
    s = json.loads(kitti2pgm("score", "--gt", str(converted), "--pred", str(run / "predictions"), "--raw",
                             str(repo / "fixtures/raw"), "--unproject", "knn", "--json").stdout)
    assert pts["confusion"] == s["points"]["confusion"]["m"]
    assert ev["confusion"] == s["cells"]["confusion"]["m"]
    assert abs(pts["miou"] - s["points"]["miou"]) < 1e-9
    written = sorted(p.name for p in (run / "point_predictions/labels/2011_09_26_drive_0001_sync").iterdir())
    assert written == ["0000000000.label", "0000000045.label"]
    # SemanticKITTI: raw ids in the benchmark's layout, scored by kitti2pgm against the dataset.
    data = tmp_path / "sk"
    kitti2pgm("convert", str(repo / "fixtures/semantickitti"), "--out", str(data), "--format", "npy,mcap",
              "--cols", "256")
    sk_run = tmp_path / "sk_run"
    _train(sk_run, data / "shards", 2)
    assert main(["evaluate", "--run", str(sk_run), "--shards", str(data / "shards"), "--device", "cpu",
                 "--val-shards", str(data / "shards" / "train-*.mcap"),
                 "--timing-frames", "0", "--points", "--raw", str(repo / "fixtures/semantickitti")]) == 0
    ev = json.loads((sk_run / "eval.json").read_text())
    bench = json.loads(kitti2pgm("score", "--gt", str(repo / "fixtures/semantickitti"), "--pred",
                                 str(sk_run / "point_predictions"), "--json").stdout)
    assert ev["points"]["confusion"] == bench["confusion"]["m"]
    assert abs(ev["points"]["miou"] - bench["miou"]) < 1e-9


def test_the_configuration_is_typed_and_has_one_set_of_defaults(tmp_path):
    from kitti2pgm_train.cli import parser
    from kitti2pgm_train.config import TrainConfig
    ns = parser().parse_args(["train", "--shards", "s", "--out", "o"])
    cfg = TrainConfig.from_args(ns)
    # The command line's defaults are the configuration's.
    assert cfg == TrainConfig(shards="s", out="o")
    assert cfg.steps == 50_000 and cfg.flip and cfg.amp is None and cfg.scale_range == [0.95, 1.05]
    ns = parser().parse_args(["train", "--shards", "s", "--out", "o", "--no-flip", "--class-weights", "squeezeseg",
                              "--amp", "--scale-range", "0.9", "1.1"])
    cfg = TrainConfig.from_args(ns)
    assert (cfg.flip, cfg.class_weights, cfg.amp, cfg.scale_range) == (False, "reference", True, [0.9, 1.1])
    # Saved and read back whole; keys of other versions are ignored.
    assert TrainConfig.from_saved({**cfg.to_dict(), "command": "train"}) == cfg
    for bad in ({"steps": 0}, {"log_every": 0}, {"workers": -1}):
        with pytest.raises(ValueError, match="must be"):
            TrainConfig(shards="s", out="o", **bad)
    from kitti2pgm_train.config import EvalConfig
    ev = EvalConfig.from_args(parser().parse_args(["evaluate", "--run", "r", "--shards", "s"]))
    assert ev == EvalConfig(run="r", shards="s") and ev.knn_k == 5 and ev.format == "npy"
    two = parser().parse_args(["evaluate", "--run", "a", "--run", "b", "--shards", "s"])
    assert EvalConfig.each_from_args(two) == [EvalConfig(run="a", shards="s"), EvalConfig(run="b", shards="s")]
    with pytest.raises(ValueError, match="2 runs given where one is evaluated"):
        EvalConfig.from_args(two)
    with pytest.raises(ValueError, match="--points needs --raw"):
        EvalConfig(run="r", shards="s", points=True)
    for bad in ({"timing_frames": -1}, {"timing_seconds": -0.5}, {"timing_seconds": float("nan")}):
        with pytest.raises(ValueError, match="must be 0 or more"):
            EvalConfig(run="r", shards="s", **bad)


def test_timed_passes_stop_at_the_count_or_the_time_budget(monkeypatch):
    """The inference timing: two warm-ups, then every frame asked for while they are quick, at
    least 3 once they took the budget (a slow CPU), none at all for 0 frames."""
    from kitti2pgm_train import evaluate

    clock = [0.0]
    monkeypatch.setattr(evaluate.time, "perf_counter", lambda: clock[0])

    def passes(ms, frames, seconds):
        calls = []

        def run():
            calls.append(1)
            clock[0] += ms / 1e3

        median = evaluate.timed_passes(run, frames, seconds)
        return len(calls), None if median is None else round(median, 6)

    assert passes(5, 10, 1.0) == (12, 5.0)  # quick: all 10 timed, after 2 warm-ups
    assert passes(200, 10, 1.0) == (7, 200.0)  # 5 x 200 ms reach the 1 s budget
    assert passes(900, 10, 1.0) == (5, 900.0)  # at least 3 timed, however slow
    assert passes(900, 2, 1.0) == (4, 900.0)  # never more than asked for
    assert passes(900, 10, 0.0) == (5, 900.0)
    assert passes(5, 0, 1.0) == (0, None)  # none asked for: nothing run


def test_own_boxes_label_convert_train_unproject_and_score(tmp_path, kitti2pgm):
    """Issue 46 end to end: the SUSTechPOINTS boxes of fixtures/own_boxes around the real VLP-16
    scan -> `label` -> `convert` (the recorded class map) -> train a few steps -> `unproject`
    (kNN) -> `score` on the labelled root (per point); the scores equal a numpy count of the
    label files themselves."""
    from pathlib import Path

    repo = Path(__file__).resolve().parents[3]
    root = tmp_path / "root"
    shutil.copytree(repo / "fixtures/own_lidar", root)
    kitti2pgm("label", str(root), "--boxes", str(repo / "fixtures/own_boxes"))
    data = tmp_path / "data"
    kitti2pgm("convert", str(root), "--out", str(data), "--sensor", "vlp16", "--all-frames", "--cols", "512",
              "--format", "npy,mcap")
    shards = data / "shards"
    run = tmp_path / "run"
    _train(run, shards, 3, [])
    config = json.loads((run / "config.json").read_text())
    assert config["class_map"]["name"] == "sustechpoints"
    assert main(["evaluate", "--run", str(run), "--shards", str(shards), "--val-shards", str(shards / "*.mcap"),
                 "--device", "cpu", "--timing-frames", "0"]) == 0
    up = tmp_path / "up"
    kitti2pgm("unproject", "--gt", str(data), "--pred", str(run / "predictions"), "--raw", str(root), "--out", str(up))
    score = json.loads(kitti2pgm("score", "--gt", str(root), "--pred", str(up), "--json").stdout)
    truth = np.fromfile(root / "sequences/00/labels/000000.label", "<u4") & 0xFFFF
    pred = np.fromfile(up / "sequences/00/predictions/000000.label", "<u4") & 0xFFFF
    names = [c["name"] for c in config["class_map"]["classes"]]
    assert len(truth) == len(pred) == 14831
    ious = []
    for c, name in enumerate(names):
        tp = int(((truth == c) & (pred == c)).sum())
        fp = int(((truth != c) & (pred == c)).sum())
        fn = int(((truth == c) & (pred != c)).sum())
        if tp + fp + fn == 0:
            continue
        iou = tp / (tp + fp + fn)
        assert abs(score["classes"][name]["iou"] - iou) < 1e-12, name
        if c != 0:
            ious.append(iou)
    assert abs(score["miou"] - sum(ious) / len(ious)) < 1e-12
