"""Fixtures: the repository's real KITTI fixtures converted to shards by the kitti2pgm binary."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def kitti2pgm_bin() -> str:
    env = os.environ.get("KITTI2PGM_BIN")
    if env:
        return env
    for profile in ("debug", "release"):
        p = REPO / "target" / profile / "kitti2pgm"
        if p.exists():
            return str(p)
    subprocess.run(["cargo", "build", "--quiet"], cwd=REPO, check=True)
    return str(REPO / "target" / "debug" / "kitti2pgm")


def run_bin(*args, **kw):
    return subprocess.run([kitti2pgm_bin(), "--no-progress", *args], check=True, capture_output=True, text=True, **kw)


@pytest.fixture(scope="session")
def converted(tmp_path_factory):
    """The three fixture frames, with colour, as .npy and shards, on a 64 x 256 map (half the
    columns of the default map over the same 90 degrees: the same real data, four times cheaper
    to train on a CPU)."""
    out = tmp_path_factory.mktemp("conv")
    run_bin("convert", str(REPO / "fixtures" / "raw"), "--out", str(out), "--format", "npy,mcap", "--rgb", "--cols", "256")
    return out


@pytest.fixture(scope="session")
def lidar_only(tmp_path_factory):
    out = tmp_path_factory.mktemp("lidar")
    run_bin("convert", str(REPO / "fixtures" / "raw"), "--out", str(out), "--format", "mcap", "--cols", "256")
    return out


@pytest.fixture(scope="session")
def kitti2pgm():
    """Runs the kitti2pgm binary (checked, output captured as text)."""
    return run_bin
