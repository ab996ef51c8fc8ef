"""Ouster captures decoded by the vendor's own SDK (``ouster-sdk``, PyPI, a test dependency only)
into points, written as PCD (with and without a ring field) and as a ROS 2 bag (by ``rosbags``):
the rows come from the metadata alone (every point on its own beam), and with Ouster's columns
the map is the SDK's destaggered image, pixel for pixel.

The SDK runs in an environment of its own (``$OUSTER_PYTHON``, made by tools/run-tests.sh):
it pins rosbags, flask and click to versions this one does not share. ``ouster_decode.py`` holds
its few lines.

Captures: the two in ``fixtures/lidars/ouster`` (OS-1-32, OS-1-128) and, where ``../shared`` is
beside the repository, all five of ``../shared/lidars/ouster``.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import tempfile

import kitti2pgm as k2
import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
BIN = os.environ.get("KITTI2PGM_BIN", "kitti2pgm")
FOLDERS = [REPO / "fixtures" / "lidars" / "ouster", REPO.parent / "shared" / "lidars" / "ouster"]
CAPTURES = {p.stem: p for folder in FOLDERS if folder.is_dir() for p in sorted(folder.glob("*.json"))}


SDK_PYTHON = os.environ.get("OUSTER_PYTHON", sys.executable)
DECODE = pathlib.Path(__file__).with_name("ouster_decode.py")


class Capture:
    """One frame of a capture as the SDK decodes it: staggered range (mm) and points (float32,
    the sensor frame, metres), the same destaggered (the image Ouster's tools show), and each
    row's pixel shift."""

    def __init__(self, meta: pathlib.Path):
        with tempfile.TemporaryDirectory() as tmp:
            out = pathlib.Path(tmp) / "frame.npz"
            r = subprocess.run([SDK_PYTHON, str(DECODE), str(meta), str(out)], capture_output=True, text=True)
            assert r.returncode == 0, f"ouster-sdk ({SDK_PYTHON}; tools/run-tests.sh makes it): {r.stderr}"
            with np.load(out) as d:
                self.range, self.xyz = d["range"], d["xyz"]
                self.reflectivity = d["reflectivity"].astype(np.float32)
                self.d_range, self.d_xyz = d["d_range"], d["d_xyz"]
                self.shift = d["shift"]
        self.meta = meta
        self.valid = self.range > 0

    def points(self, ring: bool) -> np.ndarray:
        """The valid pixels as points, row by row (as ouster-ros writes them): x, y, z,
        intensity (reflectivity) and, with `ring`, the beam (Ouster's channel: 0 the highest)."""
        fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")]
        u = np.nonzero(self.valid)[0]
        pts = np.zeros(len(u), dtype=fields + ([("ring", "<u2")] if ring else []))
        for i, axis in enumerate("xyz"):
            pts[axis] = self.xyz[..., i][self.valid]
        pts["intensity"] = self.reflectivity[self.valid]
        if ring:
            pts["ring"] = u
        return pts


@pytest.fixture(scope="module", params=sorted(CAPTURES))
def capture(request) -> Capture:
    return Capture(CAPTURES[request.param])


def write_pcd(path: pathlib.Path, pts: np.ndarray) -> None:
    """A binary PCD of a structured array (fixtures/ouster_to_pcd.py's writer, numpy only)."""
    sys.path.insert(0, str(REPO / "fixtures"))
    import ouster_to_pcd

    path.parent.mkdir(parents=True, exist_ok=True)
    ouster_to_pcd.write_pcd(path, pts)


def run(*args: object) -> subprocess.CompletedProcess:
    r = subprocess.run([BIN, "--no-progress", *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r


def convert(root: pathlib.Path, out: pathlib.Path, meta: pathlib.Path, *extra: object):
    """`kitti2pgm convert` of a one-frame root: the map and the summary."""
    run("convert", root, "--out", out, "--sensor-calibration", meta, "--all-frames", *extra)
    (npy,) = (out / "lidar_2d").glob("*.npy")
    return np.load(npy), json.loads((out / "convert_summary.json").read_text())


def assert_the_sdk_image(m: np.ndarray, c: Capture) -> None:
    """Every valid pixel of the SDK's destaggered image holds its own point at the same row and
    column of the map (x, y, z equal, the range channel the point's), and nothing else is filled."""
    h, w = c.range.shape
    assert m.shape[:2] == (h, w)
    valid = c.d_range > 0
    same = np.all(m[..., :3] == c.d_xyz, axis=-1) & valid
    assert same.sum() / valid.sum() >= 0.999, f"{c.meta.stem}: {same.sum()} of {valid.sum()} pixels"
    assert same.sum() == valid.sum()  # measured: all of them, on the five captures
    assert np.array_equal(m[..., 4] > 0, valid)
    np.testing.assert_allclose(m[..., 4][valid], np.linalg.norm(c.d_xyz[valid], axis=-1), rtol=1e-6)


@pytest.mark.parametrize("ring", [True, False], ids=["ring-field", "metadata-alone"])
def test_ouster_columns_give_the_sdk_s_destaggered_image(capture, ring, tmp_path):
    root = tmp_path / "root"
    write_pcd(root / "sequences" / "00" / "velodyne" / "000000.pcd", capture.points(ring))
    m, summary = convert(root, tmp_path / "out", capture.meta, "--ouster-columns", "--ring-order", "top-down")
    assert_the_sdk_image(m, capture)
    assert summary["params"]["map"]["sensor"]["ouster_columns"] is True
    assert (summary["ring_field_frames"], summary["beam_table_frames"]) == ((1, 0) if ring else (0, 1))
    assert summary["off_model"] == 0 and summary["collisions"] == 0


def test_rows_are_the_beams_from_the_metadata_alone(capture):
    """Without a ring field, every point's row is its own beam (the SDK's row), with the beam
    origin offset and the lidar-to-sensor transform undone; no point is off the model."""
    pts = capture.points(ring=False)
    xyzi = np.stack([pts["x"], pts["y"], pts["z"], pts["intensity"]], axis=-1)
    m = k2.project(xyzi, sensor=str(capture.meta), cols=1024, fov_deg=360.0)
    beams = np.nonzero(capture.valid)[0]
    assert m["map"].shape[0] == capture.range.shape[0]
    np.testing.assert_array_equal(m["row"], beams)
    assert m["stats"]["off_model"] == 0


def test_python_project_and_dataset_give_the_same_image(capture, tmp_path):
    """`project(sensor=meta, ouster_columns=True)` and `Dataset(..., ouster_columns=True)`, the
    training loader's way, give convert's map: the SDK's image."""
    pts = capture.points(ring=False)
    xyzi = np.stack([pts["x"], pts["y"], pts["z"], pts["intensity"]], axis=-1)
    m = k2.project(xyzi, sensor=str(capture.meta), ouster_columns=True)
    assert_the_sdk_image(m["map"], capture)
    assert m["stats"]["off_model"] == 0
    root = tmp_path / "root"
    write_pcd(root / "sequences" / "00" / "velodyne" / "000000.pcd", pts)
    converted, _ = convert(root, tmp_path / "out", capture.meta, "--ouster-columns")
    ds = k2.Dataset(root, sensor=str(capture.meta), ouster_columns=True, all_frames=True)
    np.testing.assert_array_equal(ds.project(0)["map"], converted)
    # Each point's column: its pixel's column in the SDK's destaggered image.
    w = capture.range.shape[1]
    u, m = np.nonzero(capture.valid)
    np.testing.assert_array_equal(ds[0]["column"], (m + capture.shift[u]) % w)
    assert k2.Dataset(root, sensor=str(capture.meta), all_frames=True)[0]["column"] is None


def test_a_ros2_bag_of_the_sdk_s_points_converts_to_the_same_image(capture, tmp_path):
    """The points as a PointCloud2 in a ROS 2 bag written by rosbags: unpack, then convert."""
    from rosbags.typesys import Stores, get_typestore

    sys.path.insert(0, str(REPO / "fixtures"))
    import make_bag

    ts = get_typestore(Stores.ROS2_HUMBLE)
    pc2 = "sensor_msgs/msg/PointCloud2"
    msg = make_bag.pointcloud2(ts, capture.points(ring=False), 1_700_000_000_000_000_000, "os_sensor")
    make_bag.write_bag(tmp_path / "bag", [("/ouster/points", pc2, msg, 1_700_000_000_000_000_000, True)], ts)
    run("unpack", tmp_path / "bag", "--topic", "/ouster/points", "--out", tmp_path / "root")
    m, _ = convert(tmp_path / "root", tmp_path / "out", capture.meta, "--ouster-columns")
    assert_the_sdk_image(m, capture)


def test_ouster_columns_refuse_what_cannot_hold_them(tmp_path):
    meta = CAPTURES["OS-1-32-G_v2.1.1_1024x10"]
    root = tmp_path / "root"
    write_pcd(root / "sequences" / "00" / "velodyne" / "000000.pcd", Capture(meta).points(ring=False))

    def fails(*args: object) -> str:
        r = subprocess.run([BIN, "--no-progress", "convert", str(root), "--out", str(tmp_path / "o"),
                            "--all-frames", *map(str, args)], capture_output=True, text=True)
        assert r.returncode != 0
        return r.stderr

    assert "1024 columns over 360 degrees" in fails("--sensor-calibration", meta, "--ouster-columns", "--cols", "512")
    assert "1024 columns over 360 degrees" in fails("--sensor-calibration", meta, "--ouster-columns", "--fov-deg", "90")
    vlp = REPO / "fixtures" / "lidars" / "velodyne" / "VLP16.yaml"
    assert "Ouster metadata file" in fails("--sensor-calibration", vlp, "--ouster-columns")
    assert "Ouster metadata file" in fails("--sensor", "vlp16", "--ouster-columns")
    assert "--sensor-calibration" in fails("--ouster-columns")
    assert "point shards" in fails("--sensor-calibration", meta, "--ouster-columns", "--format", "points")
    # The Python side refuses the same, and augmentations that move points off the columns.
    pts = Capture(meta).points(ring=False)
    xyzi = np.stack([pts["x"], pts["y"], pts["z"], pts["intensity"]], axis=-1)
    with pytest.raises(ValueError, match="1024 columns over 360 degrees"):
        k2.project(xyzi, sensor=str(meta), ouster_columns=True, cols=2048)
    with pytest.raises(ValueError, match="Ouster metadata file"):
        k2.project(xyzi, sensor="vlp16", ouster_columns=True)
    with pytest.raises(ValueError, match="needs the sensor"):
        k2.project(xyzi, ouster_columns=True)
    with pytest.raises(ValueError, match="rotation or flip"):
        k2.project(xyzi, sensor=str(meta), ouster_columns=True, rotate_deg=10.0)
    with pytest.raises(ValueError, match="rotation or flip"):
        k2.project(xyzi, sensor=str(meta), ouster_columns=True, flip=True)
    # Scale, jitter and drop keep each point's column.
    kept = k2.project(xyzi, sensor=str(meta), ouster_columns=True, drop=0.5, seed=3)
    whole = k2.project(xyzi, sensor=str(meta), ouster_columns=True)
    hit = kept["col"] >= 0
    np.testing.assert_array_equal(kept["col"][hit], whole["col"][hit])
    with pytest.raises(ValueError, match="needs the sensor"):
        k2.Dataset(root, ouster_columns=True, all_frames=True)
    with pytest.raises(ValueError, match="Ouster metadata file"):
        k2.Dataset(root, sensor="vlp16", ouster_columns=True, all_frames=True)
