"""kitti2pgm infer on your own sensor: a model trained on VLP-16 point shards run on a ROS 2 bag
of that sensor (streamed) and on the bag unpacked, a replay file, the model's predictions as
pre-labels that check, convert and score read, and the same classes from Python (arrays, and the
trainer's PyTorch network)."""

import json
import pathlib
import shutil
import subprocess

import numpy as np
import pytest
from kitti2pgm_train.cli import main

REPO = pathlib.Path(__file__).resolve().parents[3]
FIX = REPO / "fixtures"
BAG = FIX / "own_lidar_bag"
SCAN = FIX / "own_lidar" / "sequences" / "00" / "velodyne" / "000000.pcd"


def _bin(path, *args, check=True):
    r = subprocess.run([path, "--no-progress", *map(str, args)], capture_output=True, text=True)
    if check:
        assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def vlp16(tmp_path_factory, kitti2pgm_path):
    """A small model trained on the VLP-16 scan labelled from its SUSTechPOINTS boxes (point
    shards, 16 x 1024 maps): its run and its ONNX export."""
    tmp = tmp_path_factory.mktemp("vlp16")
    root = tmp / "boxed"
    shutil.copytree(FIX / "own_lidar", root)
    _bin(kitti2pgm_path, "label", root, "--boxes", FIX / "own_boxes")
    _bin(kitti2pgm_path, "convert", root, "--out", tmp / "pts", "--sensor", "vlp16", "--all-frames",
         "--cols", "1024", "--format", "points")
    run = tmp / "run"
    assert main(["train", "--shards", str(tmp / "pts" / "points"), "--out", str(run), "--model", "squeezeseg",
                 "--input", "xyzdi", "--width-mult", "0.25", "--batch", "1", "--steps", "6", "--lr", "0.05",
                 "--no-flip", "--device", "cpu", "--log-every", "50", "--workers", "0"]) == 0
    onnx = tmp / "vlp16.onnx"
    assert main(["export", "--run", str(run), "--out", str(onnx)]) == 0
    return run, onnx


@pytest.fixture(scope="module")
def kitti_model(tmp_path_factory, lidar_only):
    """A model of KITTI's 64-beam maps (one training step on the raw fixture's shards)."""
    tmp = tmp_path_factory.mktemp("kitti")
    assert main(["train", "--shards", str(lidar_only / "shards"), "--out", str(tmp / "run"), "--model",
                 "squeezeseg", "--input", "xyzdi", "--width-mult", "0.25", "--batch", "3", "--steps", "1",
                 "--no-flip", "--device", "cpu", "--log-every", "50", "--workers", "0"]) == 0
    assert main(["export", "--run", str(tmp / "run"), "--out", str(tmp / "kitti.onnx")]) == 0
    return tmp / "kitti.onnx"


def _labels(root: pathlib.Path):
    return {str(f.relative_to(root)): f.read_bytes() for f in sorted(root.rglob("*.label"))}


def test_bag_equals_its_unpacked_folder_and_replays(vlp16, tmp_path, kitti2pgm_path):
    from mcap.reader import make_reader

    _, onnx = vlp16
    s = json.loads(_bin(kitti2pgm_path, "infer", "--model", onnx, BAG, "--topic", "/velodyne_points",
                        "--out", tmp_path / "bag", "--viz", tmp_path / "replay.mcap", "--json").stdout)
    assert s["frames"] == 2 and s["failures"] == [] and s["points"] == 2 * 14831
    assert sum(n > 0 for _, n in s["classes"]) >= 2, "one class only: the comparison would be empty"
    _bin(kitti2pgm_path, "unpack", BAG, "--topic", "/velodyne_points", "--out", tmp_path / "unpacked")
    _bin(kitti2pgm_path, "infer", "--model", onnx, tmp_path / "unpacked", "--out", tmp_path / "folder")
    bag, folder = _labels(tmp_path / "bag"), _labels(tmp_path / "folder")
    assert sorted(bag) == ["sequences/00/predictions/000000.label", "sequences/00/predictions/000001.label"]
    assert bag == folder
    # The replay: each scan's points coloured by class at the bag's header stamps.
    with open(tmp_path / "replay.mcap", "rb") as f:
        times = [m.log_time for _, c, m in make_reader(f).iter_messages(topics=["/kitti2pgm/viz/points"])]
    first = json.loads((tmp_path / "unpacked" / "sequences" / "00" / "unpack.json").read_text())["first_stamp"]
    sec, nsec = first.split(".")
    assert times[0] == int(sec) * 10**9 + int(nsec) and len(times) == 2 and times[1] > times[0]


def test_other_sensors_and_bad_topics_are_refused(vlp16, kitti_model, tmp_path, kitti2pgm_path):
    _, onnx = vlp16
    out = tmp_path / "out"
    # A KITTI model given the VLP-16 bag: both maps named, nothing written.
    r = _bin(kitti2pgm_path, "infer", "--model", kitti_model, BAG, "--topic", "/velodyne_points", "--out", out,
             check=False)
    assert r.returncode == 1 and "16-beam scan" in r.stderr and "64-beam maps" in r.stderr, r.stderr
    # The VLP-16 model given a KITTI HDL-64E scan: its points fit no VLP-16 beam.
    kitti = FIX / "raw" / "2011_09_26" / "2011_09_26_drive_0001_sync" / "velodyne_points" / "data" / "0000000000.bin"
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, kitti, "--out", out, check=False)
    assert r.returncode == 1 and "fit no beam of VLP-16" in r.stderr and "16 x 1024" in r.stderr, r.stderr
    # A topic that is not a point cloud, and none at all: usage errors listing the clouds.
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, BAG, "--topic", "/rosout_text", "--out", out, check=False)
    assert r.returncode == 2 and "std_msgs/msg/String, not sensor_msgs/msg/PointCloud2" in r.stderr, r.stderr
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, BAG, "--out", out, check=False)
    assert r.returncode == 2 and "/velodyne_points (2 messages)" in r.stderr, r.stderr
    # Nothing to write; a replay file over the input.
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, BAG, "--topic", "/velodyne_points", check=False)
    assert r.returncode == 2, r.stderr
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, BAG, "--topic", "/velodyne_points", "--out", out,
             "--viz", BAG / "replay.mcap", check=False)
    assert r.returncode == 2 and "the output is inside" in r.stderr, r.stderr
    assert not out.exists() and not (BAG / "replay.mcap").exists()


def test_as_labels_check_convert_score(vlp16, tmp_path, kitti2pgm_path):
    _, onnx = vlp16
    root = tmp_path / "mine"
    shutil.copytree(FIX / "own_lidar", root)
    _bin(kitti2pgm_path, "infer", "--model", onnx, root, "--out", tmp_path / "pred", "--as-labels", root)
    label = root / "sequences" / "00" / "labels" / "000000.label"
    record = json.loads((root / "sequences" / "00" / "model_labels.json").read_text())
    assert record["complete"] and record["class_map"]["name"] == "sustechpoints"
    assert record["digest"] == kitti2pgm_model_digest(onnx) and list(record["frames"]) == ["000000"]
    # The labels are the predictions (raw ids of the model's class map, as score reads them).
    assert label.read_bytes() == (tmp_path / "pred" / "sequences" / "00" / "predictions" / "000000.label").read_bytes()

    def findings():
        rep = json.loads(_bin(kitti2pgm_path, "check", root, "--only", "model-labels", "--json").stdout)
        return [(f["severity"], f["message"]) for f in rep["findings"]]

    [(sev, msg)] = findings()
    assert sev == "warning" and "1 of 1 label files are as the model wrote them" in msg and "000000" in msg
    # convert reads them with the recorded class map; score against them is the model itself.
    s = _bin(kitti2pgm_path, "convert", root, "--out", tmp_path / "maps", "--sensor", "vlp16", "--all-frames",
             "--cols", "1024").stdout
    assert "frames converted               1" in s, s
    rep = json.loads(_bin(kitti2pgm_path, "score", "--gt", root, "--raw", root, "--points", "--pred",
                          tmp_path / "pred", "--json").stdout)
    assert rep["accuracy"] == 1.0, rep["accuracy"]
    # An annotator corrects 100 points: check stops reporting the frame as unedited, and score
    # measures the change per class.
    a = np.fromfile(label, dtype="<u4")
    changed = np.flatnonzero(a != 1)[:100]
    a[changed] = 1
    a.tofile(label)
    [(sev, msg)] = findings()
    assert sev == "note" and "were edited since" in msg
    rep = json.loads(_bin(kitti2pgm_path, "score", "--gt", root, "--raw", root, "--points", "--pred",
                          tmp_path / "pred", "--json").stdout)
    assert rep["accuracy"] == pytest.approx(1 - 100 / a.size)
    # Labels that are there are never replaced: an earlier run's without --overwrite, edited ones
    # not even with it, and a dataset's own never.
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, root, "--as-labels", root, check=False)
    assert r.returncode == 2 and "--overwrite" in r.stderr, r.stderr
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, root, "--as-labels", root, "--overwrite", check=False)
    assert r.returncode == 2 and "were edited since" in r.stderr, r.stderr
    assert np.array_equal(np.fromfile(label, dtype="<u4"), a)
    sk = FIX / "semantickitti"
    r = _bin(kitti2pgm_path, "infer", "--model", onnx, sk, "--out", tmp_path / "sk", "--as-labels", sk, check=False)
    assert r.returncode == 2 and "never writes there" in r.stderr, r.stderr
    # Back to the model's labels: --overwrite replaces an unedited run's.
    label.write_bytes((tmp_path / "pred" / "sequences" / "00" / "predictions" / "000000.label").read_bytes())
    _bin(kitti2pgm_path, "infer", "--model", onnx, root, "--as-labels", root, "--overwrite")
    [(sev, _)] = findings()
    assert sev == "warning"
    # An interrupted run (its record says so): every reader refuses the sequence, and --overwrite
    # starts it again.
    marker = root / "sequences" / "00" / "model_labels.json"
    marker.write_text(marker.read_text().replace('"complete": true', '"complete": false'))
    for args in (["check", root], ["convert", root, "--out", tmp_path / "maps2", "--sensor", "vlp16"],
                 ["infer", "--model", onnx, root, "--as-labels", root]):
        r = _bin(kitti2pgm_path, *args, check=False)
        assert r.returncode != 0 and "unfinished infer --as-labels run" in r.stderr, (args, r.stderr)
    _bin(kitti2pgm_path, "infer", "--model", onnx, root, "--as-labels", root, "--overwrite")
    assert json.loads(marker.read_text())["complete"]
    [(sev, _)] = findings()
    assert sev == "warning"


def kitti2pgm_model_digest(path):
    import kitti2pgm

    return kitti2pgm.Model(path).digest


def test_python_arrays_and_the_pytorch_run_give_the_cli_classes(vlp16, tmp_path, kitti2pgm_path):
    import kitti2pgm

    run, onnx = vlp16
    _bin(kitti2pgm_path, "infer", "--model", onnx, SCAN, "--out", tmp_path / "cli", "--maps")
    cli = np.fromfile(tmp_path / "cli" / "000000.label", dtype="<u4")
    model = kitti2pgm.Model(onnx)
    cloud = kitti2pgm.read_cloud(SCAN)
    r = model.predict(cloud["points"], ring=cloud["ring"].astype(np.uint16))
    classes = r["classes"].astype(np.int64)
    assert np.array_equal(np.where(classes < 0, 0xFFFF, classes), cli)
    assert np.array_equal(r["map"], np.load(tmp_path / "cli" / "maps" / "000000.npy"))
    with pytest.raises(ValueError, match=r"points must be a float32 array of shape \(N, 4\)"):
        model.predict(cloud["points"][:, :3])
    with pytest.raises(ValueError, match="ring must be"):
        model.predict(cloud["points"], ring=cloud["ring"][:5].astype(np.uint16))
    # Another engine's output is checked: integers, one a cell.
    with pytest.raises(ValueError, match="runner must return"):
        model.predict(cloud["points"], runner=lambda x: np.zeros(x.shape[1:3], dtype=np.float32))
    with pytest.raises(ValueError, match="runner must return"):
        model.predict(cloud["points"], runner=lambda x: np.zeros((3, 3), dtype=np.int64))
    # The trainer's PyTorch network on the CPU, through the same projection and kNN.
    assert main(["predict", "--run", str(run), str(SCAN), "--out", str(tmp_path / "torch"), "--device", "cpu"]) == 0
    torch_labels = np.fromfile(tmp_path / "torch" / "000000.label", dtype="<u4")
    assert (torch_labels == cli).mean() >= 0.9999


# Peak memory is measured from a small Python process: Linux keeps a process's peak across
# exec, so a child of the test process (torch loaded) would start at the test's own size.
PEAK = ("import os, sys; out = os.open(sys.argv[1], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644); "
        "pid = os.fork()\nif pid == 0: os.dup2(out, 1); os.execv(sys.argv[2], sys.argv[2:])\n"
        "_, status, usage = os.wait4(pid, 0); print(os.waitstatus_to_exitcode(status), usage.ru_maxrss)")


def _peak_mib(args, out: pathlib.Path):
    """Runs the CLI (its stdout to `out`) and returns its peak resident memory, MiB."""
    r = subprocess.run(["python3", "-c", PEAK, str(out), *args], capture_output=True, text=True)
    code, kib = r.stdout.split()
    assert code == "0", r.stderr
    return int(kib) / 1024


def test_a_bag_runs_in_flat_memory(vlp16, tmp_path, kitti2pgm_path):
    """infer streams a bag: 192 scans (about 88 MiB) cost no more memory than 48 (both three or
    more times the 16 scans it holds at a time on two threads), within the run-to-run spread
    (about 6 MiB here)."""
    import importlib.util

    pytest.importorskip("rosbags")
    from rosbags.typesys import Stores, get_typestore

    spec = importlib.util.spec_from_file_location("make_bag", FIX / "make_bag.py")
    assert spec and spec.loader
    mb = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mb)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    pts = mb.read_pcd(FIX / "lidars" / "velodyne" / "vlp16_1673400472138016708.pcd")
    _, onnx = vlp16
    peaks = []
    for n in (48, 192):
        bag = tmp_path / f"bag{n}"
        msgs = [("/v", "sensor_msgs/msg/PointCloud2", mb.pointcloud2(ts, pts, i, "v"), i, True) for i in range(n)]
        mb.write_bag(bag, msgs, ts)
        peaks.append(_peak_mib([kitti2pgm_path, "--no-progress", "--threads", "2", "infer", "--model", str(onnx),
                                str(bag), "--topic", "/v", "--out", str(tmp_path / f"o{n}"), "--json"],
                               tmp_path / f"s{n}.json"))
        assert json.loads((tmp_path / f"s{n}.json").read_text())["frames"] == n
    assert sum(f.stat().st_size for f in (tmp_path / "bag192").iterdir()) > 80 * 2**20
    assert peaks[1] < peaks[0] + 16, peaks
