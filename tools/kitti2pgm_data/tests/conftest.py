"""Fixtures: shards converted from the repository's real KITTI fixtures by the kitti2pgm binary."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def kitti2pgm_bin() -> str:
    """The binary: $KITTI2PGM_BIN, else target/{debug,release}/kitti2pgm (built if missing)."""
    env = os.environ.get("KITTI2PGM_BIN")
    if env:
        return env
    for profile in ("debug", "release"):
        p = REPO / "target" / profile / "kitti2pgm"
        if p.exists():
            return str(p)
    subprocess.run(["cargo", "build", "--quiet"], cwd=REPO, check=True)
    return str(REPO / "target" / "debug" / "kitti2pgm")


def convert(out: pathlib.Path, *extra: str) -> pathlib.Path:
    subprocess.run(
        [kitti2pgm_bin(), "--no-progress", "convert", str(REPO / "fixtures" / "raw"), "--out", str(out),
         "--format", "npy,mcap", *extra],
        check=True, stdout=subprocess.DEVNULL,
    )
    return out


@pytest.fixture(scope="session")
def rgb_lz4(tmp_path_factory):
    """Colour, lz4, drive 0052 in val."""
    return convert(tmp_path_factory.mktemp("rgb_lz4"), "--rgb", "--val-drives", "52")


@pytest.fixture(scope="session")
def lidar_none(tmp_path_factory):
    """LiDAR only, uncompressed, one frame per shard."""
    return convert(tmp_path_factory.mktemp("lidar_none"), "--compression", "none", "--shard-frames", "1")


@pytest.fixture(scope="session")
def lidar_zstd(tmp_path_factory):
    return convert(tmp_path_factory.mktemp("lidar_zstd"), "--compression", "zstd")


@pytest.fixture()
def scratch(tmp_path):
    return tmp_path


@pytest.fixture(scope="session")
def kitti2pgm_path():
    """The kitti2pgm binary's path."""
    return kitti2pgm_bin()
