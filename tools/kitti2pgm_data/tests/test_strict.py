"""The Python reader is as strict as the Rust one (issue 18): every flipped bit of a frame's
chunk is caught, whatever the compression and for point shards too; unfinished conversions,
shards of two conversions and mixed map sizes are refused; nothing half-written is left."""

import json
import os
import pathlib

import numpy as np
import pytest
from kitti2pgm_data import ShardDataset, ShardError, ShardReader, iter_frames, write_predictions

REPO = pathlib.Path(__file__).resolve().parents[3]
TOOLS = REPO / "tools"


def _convert(out, *extra):
    import importlib.util

    spec = importlib.util.spec_from_file_location("k2p_conftest", TOOLS / "conftest.py")
    conf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(conf)
    return conf.convert(out, *extra)


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    """Map shards uncompressed, zstd and lz4, and point shards: one frame per shard."""
    out = {}
    for name, extra in {"none": ["--format", "mcap", "--compression", "none"],
                        "zstd": ["--format", "mcap", "--compression", "zstd"],
                        "lz4": ["--format", "mcap"],
                        "points": ["--format", "points"]}.items():
        d = _convert(tmp_path_factory.mktemp(name), *extra, "--shard-frames", "1", "--cols", "128")
        out[name] = sorted((d / ("points" if name == "points" else "shards")).glob("*.mcap"))
    return out


def _flipped_copies(src, scratch, n, seed):
    """`n` copies of the shard, each with one bit flipped inside its frame's chunk records."""
    with ShardReader(src) as r:
        c = r._chunks[0]
    good = src.read_bytes()
    # The chunk's records: after its header (op, length, times, sizes, CRC, compression name).
    clen = int.from_bytes(good[c.chunk_start_offset + 37:c.chunk_start_offset + 41], "little")
    start = c.chunk_start_offset + 41 + clen + 8
    end = c.chunk_start_offset + c.chunk_length
    rng = np.random.default_rng(seed)
    for k in range(n):
        data = bytearray(good)
        at = int(rng.integers(start, end))
        data[at] ^= 1 << int(rng.integers(0, 8))
        path = scratch / f"flip{k}.mcap"
        path.write_bytes(bytes(data))
        yield path, at


@pytest.mark.parametrize("kind", ["none", "zstd", "lz4", "points"])
def test_every_flipped_bit_is_caught(kinds, kind, tmp_path):
    src = kinds[kind][0]
    for path, _at in _flipped_copies(src, tmp_path, 15, seed=len(kind)):
        with pytest.raises(ShardError, match=path.name):
            with ShardReader(path) as r:
                r[0]
        with pytest.raises(ShardError, match=path.name):
            list(iter_frames(path))
    # The good shard reads, as a single path (str or Path) too.
    assert len(ShardDataset(str(src))) == 1
    assert len(list(iter_frames(pathlib.Path(src)))) == 1


def test_unfinished_conversions_are_refused_unless_partial(tmp_path):
    out = _convert(tmp_path / "out", "--format", "mcap", "--cols", "128")
    summary = out / "convert_summary.json"
    s = json.loads(summary.read_text())
    s["complete"] = False
    summary.write_text(json.dumps(s))
    paths = sorted((out / "shards").glob("*.mcap"))
    with pytest.raises(ShardError, match="did not finish"):
        ShardDataset(paths)
    with pytest.raises(ShardError, match="did not finish"):
        list(iter_frames(paths))
    with pytest.warns(UserWarning, match="PARTIAL"):
        ds = ShardDataset(paths, partial=True)
    assert ds.partial and len(ds) == 3


def test_shards_of_two_conversions_are_refused(tmp_path):
    a = _convert(tmp_path / "a", "--format", "mcap", "--cols", "128", "--shard-frames", "1")
    b = _convert(tmp_path / "b", "--format", "mcap", "--cols", "256", "--shard-frames", "1")
    c = _convert(tmp_path / "c", "--format", "mcap", "--cols", "128", "--shard-frames", "3")
    sa, sb, sc = (sorted((d / "shards").glob("*.mcap")) for d in (a, b, c))
    with pytest.raises(ShardError, match="other map parameters"):
        ShardDataset([sa[0], sb[1]])
    with pytest.raises(ShardError, match="is also in"):
        ShardDataset(sa + sc)
    assert len(ShardDataset(sa)) == 3


def test_a_failed_prediction_write_leaves_nothing(tmp_path):
    out = _convert(tmp_path / "out", "--format", "mcap", "--cols", "128")
    shard = sorted((out / "shards").glob("*.mcap"))[0]
    frames = list(iter_frames(shard))
    bad = [{"id": f["id"], "label": np.full_like(f["label"], 200)} for f in frames]
    dest = tmp_path / "preds"
    dest.mkdir()
    with pytest.raises(ValueError, match="class id 200"):
        write_predictions(dest / "p.mcap", bad, schema_from=shard)
    assert os.listdir(dest) == []
