"""kitti2pgm score against a SemanticKITTI root equals an independent numpy computation of the
benchmark's protocol (the SemanticKITTI API's evaluate_semantics.py), on perturbed predictions of
the real fixture scan."""

import json
import pathlib

import numpy as np
import yaml

REPO = pathlib.Path(__file__).resolve().parents[3]
SK = REPO / "fixtures" / "semantickitti"
YAML = REPO / "src" / "label" / "semantic-kitti.yaml"


def benchmark_iou(gt_raw, pred_raw, cfg):
    """evaluate_semantics.py, in numpy: labels through the learning map, a [pred, gt] confusion
    matrix, the ignored classes' ground truth zeroed, IoU = tp / (tp + fp + fn + 1e-15), the mean
    over the classes that are not ignored."""
    lut = np.zeros(1 << 16, np.int64)
    for k, v in cfg["learning_map"].items():
        lut[k] = v
    n = len(cfg["learning_map_inv"])
    ignore = [c for c, ig in cfg["learning_ignore"].items() if ig]
    include = [c for c in range(n) if c not in ignore]
    gt, pred = lut[gt_raw & 0xFFFF], lut[pred_raw & 0xFFFF]
    conf = np.zeros((n, n), np.int64)
    np.add.at(conf, (pred, gt), 1)
    conf[:, ignore] = 0
    tp = np.diag(conf).astype(np.float64)
    fp = conf.sum(axis=1) - tp
    fn = conf.sum(axis=0) - tp
    iou = tp / (tp + fp + fn + 1e-15)
    return iou, iou[include].mean()


def test_score_equals_the_benchmark_protocol(tmp_path, kitti2pgm):
    cfg = yaml.safe_load(open(YAML))
    gt = np.fromfile(SK / "sequences/00/labels/000000.label", dtype=np.uint32)
    rng = np.random.default_rng(5)
    pred = gt.copy()
    flip = rng.random(len(gt)) < 0.3
    ids = np.array(sorted(cfg["learning_map"]), dtype=np.uint32)
    pred[flip] = ids[rng.integers(0, len(ids), flip.sum())]
    out = tmp_path / "pred/sequences/00/predictions"
    out.mkdir(parents=True)
    pred.tofile(out / "000000.label")
    r = kitti2pgm("score", "--gt", str(SK), "--pred", str(tmp_path / "pred"), "--json")
    report = json.loads(r.stdout)
    iou, miou = benchmark_iou(gt, pred, cfg)
    names = report["class_names"]
    assert len(names) == 20 and report["miou_classes"] == names[1:]
    assert abs(report["miou"] - miou) < 1e-12, (report["miou"], miou)
    for c, name in enumerate(names[1:], start=1):
        ours = report["classes"][name]["iou"] or 0.0
        assert abs(ours - iou[c]) < 1e-12, (name, ours, iou[c])
    lut = np.zeros(1 << 16, np.int64)
    for k, v in cfg["learning_map"].items():
        lut[k] = v
    assert report["elements"] == int((lut[gt & 0xFFFF] != 0).sum()), "unlabeled points are not counted"
