"""kitti2pgm infer on the trainer's exported models: ONNX Runtime's own labels on the same maps,
unproject's per-point classes, the map recorded in the file, and bad models refused."""

import json
import pathlib
import subprocess

import numpy as np
import pytest
from kitti2pgm_train.cli import main

REPO = pathlib.Path(__file__).resolve().parents[3]
RAW = REPO / "fixtures" / "raw"


def _export(tmp: pathlib.Path, shards: pathlib.Path, inputs: str, steps: int) -> pathlib.Path:
    """A small model trained `steps` steps on the shards (a high rate: its labels are mixed),
    exported to ONNX."""
    run = tmp / f"run-{inputs}"
    assert main(["train", "--shards", str(shards), "--out", str(run), "--model", "squeezeseg", "--input", inputs,
                 "--width-mult", "0.25", "--batch", "3", "--steps", str(steps), "--lr", "0.05", "--no-flip",
                 "--device", "cpu", "--log-every", "50", "--workers", "0"]) == 0
    out = tmp / f"{inputs}.onnx"
    assert main(["export", "--run", str(run), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def rgb_model(converted, tmp_path_factory):
    return _export(tmp_path_factory.mktemp("infer"), converted / "shards", "xyzdi+dirgb", 6)


def _infer(kitti2pgm_path, *args, check=True):
    r = subprocess.run([kitti2pgm_path, "--no-progress", "infer", *map(str, args)], capture_output=True, text=True)
    if check:
        assert r.returncode == 0, r.stderr
    return r


def test_infer_labels_like_onnxruntime_and_unproject(rgb_model, converted, tmp_path, kitti2pgm_path):
    """The map classes equal ONNX Runtime's on the conversion's own maps, and the per-point
    classes equal `kitti2pgm unproject --method knn` applied to those maps, point for point."""
    import onnxruntime

    out = tmp_path / "out"
    s = json.loads(_infer(kitti2pgm_path, "--model", rgb_model, RAW, "--out", out, "--maps", "--json").stdout)
    assert s["frames"] == 3 and s["failures"] == [] and s["points"] > 300_000
    assert s["seconds"]["model"] > 0 and s["digest"].startswith("xxh3-128:")
    session = onnxruntime.InferenceSession(str(rgb_model), providers=["CPUExecutionProvider"])
    classes = set()
    for npy in sorted((converted / "lidar_2d").glob("*.npy")):
        a = np.load(npy)  # x y z intensity range label r g b
        x = np.ascontiguousarray(np.concatenate([a[..., :5], a[..., 6:]], -1)[None], dtype=np.float32)
        want = session.run(None, {"tensor": x})[0][0]
        got = np.load(out / "maps" / npy.name)
        assert got.shape == want.shape == (64, 256)
        assert (got == want).mean() >= 0.9999, npy.name
        classes |= set(np.unique(want).tolist())
    assert len(classes) >= 2, "the model predicts one class only: the comparison would be empty"
    ref = tmp_path / "ref"
    subprocess.run([kitti2pgm_path, "--no-progress", "unproject", "--gt", str(converted), "--pred", str(out / "maps"),
                    "--raw", str(RAW), "--out", str(ref), "--method", "knn"], check=True, capture_output=True)
    labels = sorted((out / "labels").rglob("*.label"))
    assert len(labels) == 3
    for f in labels:
        assert f.read_bytes() == (ref / f.relative_to(out)).read_bytes(), f
    # score reads them per point (0xffff outside the map: not predicted).
    rep = json.loads(subprocess.run([kitti2pgm_path, "--no-progress", "score", "--gt", str(converted), "--pred",
                                     str(out / "labels"), "--points", "--raw", str(RAW), "--json"],
                                    check=True, capture_output=True, text=True).stdout)
    assert rep["frames"] == 3 and rep["elements"] > 50_000, (rep["frames"], rep["elements"])


def test_python_model_predicts_like_the_cli(converted, lidar_only, tmp_path, kitti2pgm_path):
    """kitti2pgm.Model on one scan file: the CLI's classes, and the record the export wrote."""
    import kitti2pgm

    model_path = _export(tmp_path, lidar_only / "shards", "xyzdi", 2)
    scan = RAW / "2011_09_26" / "2011_09_26_drive_0001_sync" / "velodyne_points" / "data" / "0000000000.bin"
    _infer(kitti2pgm_path, "--model", model_path, scan, "--out", tmp_path / "one", "--maps")
    model = kitti2pgm.Model(model_path)
    assert model.spec["channels"] == ["x", "y", "z", "intensity", "range"]
    assert model.spec["map"]["spec"]["cols"] == 256 and model.spec["normalisation"] == "in_graph"
    r = model.predict_file(scan)
    cli = np.fromfile(tmp_path / "one" / "0000000000.label", dtype="<u4")
    assert r["classes"].shape == cli.shape
    classes = r["classes"].astype(np.int64)
    assert np.array_equal(np.where(classes < 0, 0xFFFF, classes), cli)
    assert np.array_equal(r["map"], np.load(tmp_path / "one" / "maps" / "0000000000.npy"))


def _rewrite_record(src: pathlib.Path, dst: pathlib.Path, change) -> None:
    import kitti2pgm
    import onnx

    m = onnx.load(str(src))
    entry = [p for p in m.metadata_props if p.key == kitti2pgm.MODEL_METADATA_KEY]
    assert len(entry) == 1
    value = change(json.loads(entry[0].value))
    m.metadata_props.remove(entry[0])
    if value is not None:
        m.metadata_props.add(key=kitti2pgm.MODEL_METADATA_KEY, value=json.dumps(value))
    onnx.save(m, str(dst))


def test_bad_models_and_outputs_are_refused(rgb_model, converted, tmp_path, kitti2pgm_path):
    out = tmp_path / "out"
    # Not a model at all.
    junk = tmp_path / "junk.onnx"
    junk.write_text("not a model")
    r = _infer(kitti2pgm_path, "--model", junk, RAW, "--out", out, check=False)
    assert r.returncode == 1 and "junk.onnx: not an ONNX model" in r.stderr, r.stderr
    # Someone else's model: no record; accepted with the map it was trained on.
    bare = tmp_path / "bare.onnx"
    _rewrite_record(rgb_model, bare, lambda v: None)
    r = _infer(kitti2pgm_path, "--model", bare, RAW, "--out", out, check=False)
    assert r.returncode == 2 and "records no kitti2pgm map" in r.stderr and "--map-from" in r.stderr, r.stderr
    _infer(kitti2pgm_path, "--model", bare, RAW, "--out", tmp_path / "given", "--map-from", converted)
    _infer(kitti2pgm_path, "--model", rgb_model, RAW, "--out", tmp_path / "recorded")
    for f in sorted((tmp_path / "recorded").rglob("*.label")):
        assert f.read_bytes() == (tmp_path / "given" / f.relative_to(tmp_path / "recorded")).read_bytes()
    # A record whose map disagrees with the graph's input: both shapes named.
    lying = tmp_path / "lying.onnx"

    def rows_32(v):
        v["map"]["spec"]["rows"] = 32
        return v

    _rewrite_record(rgb_model, lying, rows_32)
    r = _infer(kitti2pgm_path, "--model", lying, RAW, "--out", out, check=False)
    assert r.returncode == 1 and "[1, 64, 256, 8]" in r.stderr and "[1, 32, 256, 8]" in r.stderr, r.stderr
    # A KITTI model given another sensor's scans: refused, naming both.
    r = _infer(kitti2pgm_path, "--model", rgb_model, REPO / "fixtures" / "own_lidar", "--out", out, check=False)
    assert r.returncode == 1 and "16-beam scan" in r.stderr and "64-beam maps" in r.stderr, r.stderr
    # An output over the input, or over the model.
    r = _infer(kitti2pgm_path, "--model", rgb_model, RAW, "--out", RAW / "out", check=False)
    assert r.returncode == 2 and "the output is inside the dataset" in r.stderr, r.stderr
    r = _infer(kitti2pgm_path, "--model", rgb_model, RAW, "--out", rgb_model, check=False)
    assert r.returncode == 2 and "the model" in r.stderr, r.stderr
    # ONNX Runtime's library named where there is none.
    r = _infer(kitti2pgm_path, "--model", rgb_model, RAW, "--out", out, "--onnxruntime", tmp_path, check=False)
    assert r.returncode == 2 and "no ONNX Runtime library there" in r.stderr, r.stderr
    assert not out.exists()
