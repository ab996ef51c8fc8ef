"""Training on point shards: projection on the fly through the native module, 3D augmentation."""

import numpy as np
import pytest
import torch
from kitti2pgm_train.cli import main
from kitti2pgm_train.data import FrameSet, Normaliser, StepBatches, TorchFrames, collate
from kitti2pgm_train.onthefly import Augmentation, PointFrameSet, open_frames

NORM = Normaliser.from_stats(None)


def sets(root, inputs="xyzdi+dirgb", augment=None, seed=0):
    maps = FrameSet(sorted((root / "shards").glob("*.mcap")), inputs, NORM)
    points = open_frames(sorted((root / "points").glob("*.mcap")), inputs, NORM, augment or Augmentation(), seed)
    assert isinstance(points, PointFrameSet)
    return maps, points


def same(a, b):
    assert a["id"] == b["id"]
    for x, y in zip(a["inputs"], b["inputs"]):
        assert torch.equal(x, y)
    for k in ("xyz", "mask", "label"):
        assert torch.equal(a[k], b[k]), k


def test_unaugmented_samples_are_the_converted_maps(with_points):
    maps, points = sets(with_points)
    assert (points.height, points.width) == (64, 256) and points.channels == maps.channels
    for i in range(len(maps)):
        same(maps.item(i), points.item(i))
        # No augmentation asked for: a training key changes nothing.
        same(maps.item(i), points.item(i, key=(5, 1)))


def test_zero_rotation_unit_scale_is_the_unaugmented_sample(with_points):
    maps, points = sets(with_points, augment=Augmentation(rotate_deg=0.0, scale=(1.0, 1.0)))
    for i in range(len(maps)):
        same(maps.item(i), points.item(i, key=(3, i)))


def test_augmentation_is_seeded_and_keeps_rings(with_points):
    aug = Augmentation.parse("rotate,scale,jitter,drop,flip")
    _, points = sets(with_points, augment=aug, seed=4)
    a, b = points.sample(0, True, (7, 2)), points.sample(0, True, (7, 2))
    assert a["map"].tobytes() == b["map"].tobytes()
    c = points.sample(0, True, (8, 2))
    assert c["map"].tobytes() != a["map"].tobytes()
    # Every point in view sits in the row of its ring (64 rows: the row is the ring).
    ring = points.ds[0]["ring"]
    import kitti2pgm

    def with_cells(key):
        f = points.ds[0]
        kw = dict(points.map_args, **points.augment.draw(4, key, True))
        kw.update(rgb=f["rgb"], rgb_valid=f["rgb_valid"].astype(bool))
        return kitti2pgm.project(f["points"], rings=f["ring"], labels=f["label"], instance=f["instance"], **kw)
    assert a["row"] is None
    for m in (with_cells((7, 2)), with_cells((8, 2)), with_cells(None)):
        assert m["map"].tobytes() in (a["map"].tobytes(), c["map"].tobytes(), points.sample(0)["map"].tobytes())
        seen = m["row"] >= 0
        assert seen.sum() > 10_000 and np.array_equal(m["row"][seen], ring[seen].astype(np.int32))
    with pytest.raises(ValueError, match="unknown"):
        Augmentation.parse("rotate,shear")
    with pytest.raises(ValueError, match="needs point shards"):
        open_frames(sorted((with_points / "shards").glob("*.mcap")), "xyzdi", NORM, aug)


def test_workers_give_the_single_process_batches(with_points):
    aug = Augmentation.parse("rotate,scale,jitter,drop,flip")
    _, points = sets(with_points, "xyzdi", aug, seed=1)
    sampler = StepBatches(len(points), 2, 0, 3, 1, True)
    loader = torch.utils.data.DataLoader(TorchFrames(points), batch_sampler=sampler, collate_fn=collate, num_workers=2)
    for got, keys in zip(loader, StepBatches(len(points), 2, 0, 3, 1, True)):
        same(got, collate([points.item(i, flip=f, key=k) for i, f, k in keys]))


def test_train_and_resume_on_point_shards(with_points, tmp_path):
    base = ["train", "--shards", str(with_points / "points"), "--model", "squeezeseg", "--input", "xyzdi",
            "--width-mult", "0.25", "--batch", "2", "--steps", "4", "--lr", "0.05", "--dropout", "0",
            "--device", "cpu", "--log-every", "2", "--workers", "2", "--checkpoint-every", "2",
            "--augment", "rotate,scale,jitter,drop,flip", "--seed", "3"]
    straight, resumed = tmp_path / "straight", tmp_path / "resumed"
    assert main(base + ["--out", str(straight)]) == 0
    assert main(base + ["--out", str(resumed), "--stop-after", "2"]) == 0
    assert main(base + ["--out", str(resumed), "--resume"]) == 0
    a = torch.load(straight / "checkpoint.pt", weights_only=False)["model"]
    b = torch.load(resumed / "checkpoint.pt", weights_only=False)["model"]
    for k in a:
        assert torch.equal(a[k], b[k]), k
    import json
    cfg = json.loads((straight / "config.json").read_text())
    assert cfg["on_the_fly"] and cfg["augmentation"]["rotate_deg"] == 180.0


def test_another_sensor_s_point_shards_project_to_its_maps(tmp_path, kitti2pgm):
    """Point shards of a VLP-16 sequence carry each point's beam row; projected on the fly with
    the shards' sensor they are the maps convert wrote (16 rows)."""
    repo = __import__("pathlib").Path(__file__).resolve().parents[3]
    out = tmp_path / "own"
    kitti2pgm("convert", str(repo / "fixtures" / "own_lidar"), "--out", str(out), "--sensor", "vlp16",
              "--all-frames", "--cols", "512", "--format", "mcap,points", "--class-map", "semantic-kitti")
    maps = FrameSet(sorted((out / "shards").glob("*.mcap")), "xyzdi", NORM)
    points = open_frames(sorted((out / "points").glob("*.mcap")), "xyzdi", NORM)
    assert (points.height, points.width) == (16, 512)
    assert points.map_args["beams"] == 16
    same(maps.item(0), points.item(0))
