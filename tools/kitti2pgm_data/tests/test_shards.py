"""The Python view of a shard equals the .npy output of the same frames, bit for bit."""

import glob
import os
import shutil

import numpy as np
import pytest
from kitti2pgm_data import ShardDataset, ShardError, ShardReader, class_map, iter_frames, read_metadata

IDS = ["2011_09_26_0001_0000000000", "2011_09_26_0001_0000000045", "2011_09_26_0052_0000000000"]


def shards(d):
    return sorted(glob.glob(os.path.join(d, "shards", "*.mcap")))


def assert_same_as_npy(frame, d):
    npy = np.load(os.path.join(d, "lidar_2d", f"{frame['id']}.npy"))
    names = ["x", "y", "z", "intensity", "range", "label", "r", "g", "b"][: npy.shape[2]]
    inputs = [i for i, n in enumerate(names) if n != "label"]
    assert frame["channels"] == [names[i] for i in inputs]
    assert frame["tensor"].dtype == np.float32
    assert frame["tensor"].shape == (64, 512, len(inputs))
    # Bit for bit: compare the float32 bit patterns.
    assert np.array_equal(frame["tensor"].view(np.uint32), np.ascontiguousarray(npy[..., inputs]).view(np.uint32))
    assert np.array_equal(frame["label"], npy[..., 5].astype(np.uint8))
    assert np.array_equal(frame["mask"], (npy[..., 4] > 0).astype(np.uint8))
    assert frame["instance"].dtype == np.uint16 and frame["instance"].shape == (64, 512)
    assert np.all(frame["instance"][frame["label"] == 0] == 0)


@pytest.mark.parametrize("name", ["rgb_lz4", "lidar_none", "lidar_zstd"])
def test_iter_frames_equals_npy(name, request):
    d = request.getfixturevalue(name)
    frames = list(iter_frames(shards(d)))
    assert sorted(f["id"] for f in frames) == IDS
    for f in frames:
        assert_same_as_npy(f, d)
        assert (f["rgb_valid"] is not None) == (name == "rgb_lz4")


def test_frames_in_frame_id_order_and_splits(rgb_lz4):
    train, val = shards(rgb_lz4)
    assert os.path.basename(train) == "train-00000.mcap" and os.path.basename(val) == "val-00000.mcap"
    assert [f["id"] for f in iter_frames(train)] == IDS[:2]
    assert [f["split"] for f in iter_frames(val)] == ["val"]
    f = next(iter_frames(train))
    assert f["drive"] == "2011_09_26_drive_0001_sync" and f["frame_index"] == 0
    assert f["timestamp_ns"] > 1_300_000_000 * 10**9


def test_random_access_and_shuffling(rgb_lz4, lidar_none):
    for d in (rgb_lz4, lidar_none):
        ds = ShardDataset(shards(d))
        assert len(ds) == 3
        assert [ds[i]["id"] for i in range(3)] == IDS
        assert ds[-1]["id"] == IDS[-1]
        for i in (2, 0, 1):
            assert_same_as_npy(ds[i], d)
        with pytest.raises(IndexError):
            ds[3]
        p = ds.shuffled_indices(seed=1)
        assert sorted(p.tolist()) == [0, 1, 2]
        assert np.array_equal(p, ds.shuffled_indices(seed=1))
    ds = ShardDataset(shards(lidar_none), transform=lambda f: f["tensor"].shape)
    assert ds[0] == (64, 512, 5)


def test_uncompressed_frames_are_zero_copy_views(lidar_none):
    r = ShardReader(shards(lidar_none)[0])
    f = r[0]
    assert not f["tensor"].flags.writeable  # a view of the mapped file
    assert not f["tensor"].flags.owndata


def test_metadata(rgb_lz4):
    md = read_metadata(shards(rgb_lz4)[0])
    assert md["split"] == "train"
    assert md["frames"] == IDS[:2]
    assert "2011_09_26_drive_0052_sync" in md["drives"]
    assert md["params"]["map"]["spec"]["rows"] == 64
    assert md["frame_topic"] == "/kitti2pgm/frame"
    cm = class_map(shards(rgb_lz4)[0])
    assert [c["name"] for c in cm["classes"]] == ["background", "car", "pedestrian", "cyclist"]
    with ShardReader(shards(rgb_lz4)[0]) as r:
        assert r.metadata()["version"] == md["version"]


def test_truncated_shard_names_shard_and_frame(rgb_lz4, scratch):
    src = shards(rgb_lz4)[0]
    data = open(src, "rb").read()
    cut = scratch / "cut.mcap"
    # Keep the first chunk whole and cut into the second.
    with ShardReader(src) as r:
        offsets = sorted(c.chunk_start_offset for c in r._chunks)
    cut.write_bytes(data[: offsets[1] + 1000])
    with pytest.raises(ShardError, match="cut.mcap.*(summary|finished)"):
        ShardReader(cut)
    got = []
    with pytest.raises(ShardError, match=r"cut\.mcap: frame #1 after frame 2011_09_26_0001_0000000000"):
        for f in iter_frames(cut):
            got.append(f["id"])
    assert got == IDS[:1], "the frames before the cut stay readable"


def test_corrupted_chunk_is_reported(lidar_none, scratch):
    src = shards(lidar_none)[0]
    bad = scratch / "bad.mcap"
    shutil.copy(src, bad)
    with ShardReader(bad) as r:
        c = r._chunks[0]
    data = bytearray(bad.read_bytes())
    mid = c.chunk_start_offset + c.chunk_length // 2
    data[mid:mid + 64] = bytes(b ^ 0x5A for b in data[mid:mid + 64])
    bad.write_bytes(bytes(data))
    with ShardReader(bad, validate_crc=True) as r:
        with pytest.raises(ShardError, match="bad.mcap: frame #0: chunk CRC mismatch"):
            r[0]


def test_prediction_shards_decode_and_score(rgb_lz4, scratch, kitti2pgm_path):
    """A prediction shard decodes with the same reader and kitti2pgm score reads it."""
    import json
    import subprocess

    from kitti2pgm_data import FrameSchema, decode_frame, write_predictions
    from kitti2pgm_data.writer import frame_schema

    frames = list(iter_frames(shards(rgb_lz4)))
    preds = [{"id": f["id"], "label": f["label"], "drive": f["drive"], "frame_index": f["frame_index"]} for f in frames]
    out = scratch / "pred.mcap"
    assert write_predictions(out, preds, schema_from=shards(rgb_lz4)[0], metadata={"run": "test"}) == 3
    from mcap.reader import make_reader
    with open(out, "rb") as f:
        msgs = [m for _, _, m in make_reader(f).iter_messages(topics=["/kitti2pgm/prediction"])]
    d = decode_frame(msgs[0].data, FrameSchema(frame_schema(out)))
    assert d["id"] == IDS[0] and np.array_equal(d["label"], frames[0]["label"])
    r = subprocess.run([kitti2pgm_path, "score", "--gt", str(rgb_lz4), "--pred", str(out), "--json"],
                       capture_output=True, text=True, check=True)
    assert json.loads(r.stdout)["classes"]["car"]["iou"] == 1.0


def test_schema_comes_from_the_shard(rgb_lz4):
    """The field table is the shard's stored schema: every field of the message, with its type."""
    from kitti2pgm_data import FrameSchema
    from kitti2pgm_data.writer import frame_schema

    schema = FrameSchema(frame_schema(shards(rgb_lz4)[0]))
    assert schema.by_name["tensor"] == (8, "bytes", False)
    assert schema.by_name["channels"] == (7, "string", True)
    assert schema.by_name["timestamp_ns"] == (4, "uint64", False)
    assert len(schema.by_name) == 13
    with pytest.raises(ValueError, match="does not define"):
        FrameSchema(frame_schema(shards(rgb_lz4)[0]), message="kitti2pgm.Other")


def test_bad_metadata_is_named(rgb_lz4, scratch):
    """A shard whose metadata record is malformed is refused, naming the shard."""
    from mcap.writer import Writer

    path = scratch / "bad.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="kitti2pgm", library="test")
        w.add_metadata("kitti2pgm", {"version": "0", "params": "{not json"})
        w.finish()
    with pytest.raises(ShardError, match="bad.mcap: malformed"):
        read_metadata(path)


def test_metadata_of_the_old_spelling_reads_in_todays(rgb_lz4, scratch):
    """(Issue 29) Enum values are spelled as the CLI spells them (rings, nearest, lz4); shards of
    earlier versions spelled them as Rust's identifiers (Rings, Nearest, Lz4): read_metadata gives
    both in today's spelling, so no caller lowers or compares spellings itself."""
    import json

    from mcap.writer import Writer

    md = read_metadata(shards(rgb_lz4)[0])
    spec, rgb = md["params"]["map"]["spec"], md["params"]["map"]["rgb"]
    assert (spec["row_mode"], rgb["sampling"], md["params"]["shards"]["compression"]) == ("rings", "nearest", "lz4")
    assert md["params"]["map"]["class_map"]["absent_in_miou"] == "left_out"
    old = json.dumps(md["params"]).replace('"rings"', '"Rings"').replace('"nearest"', '"Nearest"') \
        .replace('"lz4"', '"Lz4"').replace('"left_out"', '"LeftOut"')
    path = scratch / "old.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="kitti2pgm", library="test")
        w.add_metadata("kitti2pgm", {k: (old if k == "params" else "\n".join(v) if isinstance(v, list) else v)
                                     for k, v in md.items()})
        w.finish()
    assert read_metadata(path)["params"] == md["params"]
