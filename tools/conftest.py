"""Fixtures of both Python packages' tests: the repository's real KITTI fixtures converted by the
kitti2pgm binary (to .npy maps and shards)."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
RAW = REPO / "fixtures" / "raw"


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


def run_bin(*args, **kw):
    """Runs the binary (checked, output captured as text)."""
    return subprocess.run([kitti2pgm_bin(), "--no-progress", *args], check=True, capture_output=True, text=True, **kw)


def convert(out: pathlib.Path, *extra: str) -> pathlib.Path:
    run_bin("convert", str(RAW), "--out", str(out), *extra)
    return out


def pytest_configure(config):
    """Torch's threads in the tests and OpenMP's in the processes they start (torch reads
    OMP_NUM_THREADS when imported, after this hook): at most two, the cores shared among
    pytest-xdist's workers (tools/run-tests.sh starts two). Threads that outnumber the cores
    spin-wait on each other: two workers of two threads each on 2 cores made the overfitting test
    take 104 s instead of 27 s. A value the user set is kept; xdist's controller runs no test and
    sets none (its workers would inherit it)."""
    if "OMP_NUM_THREADS" in os.environ:
        return
    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT")
    if workers is None and config.getoption("numprocesses", default=None) not in (None, 0):
        return
    share = (os.cpu_count() or 1) // int(workers or 1)
    os.environ["OMP_NUM_THREADS"] = str(max(1, min(2, share)))


def pytest_collection_modifyitems(config, items):
    """Under pytest-xdist, the long tests (``@pytest.mark.long(seconds)``) each at the head of a
    worker's share, the longest first to the least loaded: xdist's `worksteal` gives each worker
    a contiguous share of the collection and an idle one takes over the tail of another's, never
    its head, so two long tests in one share run one after the other however idle the other
    worker is (the docs' chain and the reproduction did: 127 s where their sum over two workers
    is about 95 s). The order is the same on every worker, as xdist requires."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT") or 1)
    if workers < 2:
        return
    sizes, left = [], len(items)
    for k in range(workers):  # xdist's first split: each idle worker its share of what is left
        sizes.append(left // (workers - k))
        left -= sizes[-1]
    cost = {id(i): float(i.get_closest_marker("long").args[0]) for i in items if i.get_closest_marker("long")}
    heads: list[list] = [[] for _ in range(workers)]
    load = [0.0] * workers
    for item in sorted((i for i in items if id(i) in cost), key=lambda i: -cost[id(i)]):
        k = min((k for k in range(workers) if len(heads[k]) < sizes[k]), key=lambda k: load[k])
        heads[k].append(item)
        load[k] += cost[id(item)]
    rest = iter([i for i in items if id(i) not in cost])
    items[:] = [item for k in range(workers)
                for item in heads[k] + [next(rest) for _ in range(sizes[k] - len(heads[k]))]]


@pytest.fixture(scope="session")
def rgb_lz4(tmp_path_factory):
    """Colour, lz4, drive 0052 in val; .npy and shards."""
    return convert(tmp_path_factory.mktemp("rgb_lz4"), "--format", "npy,mcap", "--rgb", "--val-drives", "52")


@pytest.fixture(scope="session")
def lidar_none(tmp_path_factory):
    """LiDAR only, uncompressed, one frame per shard."""
    return convert(tmp_path_factory.mktemp("lidar_none"), "--format", "npy,mcap", "--compression", "none",
                   "--shard-frames", "1")


@pytest.fixture(scope="session")
def lidar_zstd(tmp_path_factory):
    return convert(tmp_path_factory.mktemp("lidar_zstd"), "--format", "npy,mcap", "--compression", "zstd")


@pytest.fixture(scope="session")
def converted(tmp_path_factory):
    """The three fixture frames, with colour, as .npy and shards, on a 64 x 256 map (half the
    columns of the default map over the same 90 degrees: the same real data, four times cheaper
    to train on a CPU)."""
    return convert(tmp_path_factory.mktemp("conv"), "--format", "npy,mcap", "--rgb", "--cols", "256")


@pytest.fixture(scope="session")
def lidar_only(tmp_path_factory):
    return convert(tmp_path_factory.mktemp("lidar"), "--format", "mcap", "--cols", "256")


@pytest.fixture()
def scratch(tmp_path):
    return tmp_path


@pytest.fixture(scope="session")
def kitti2pgm_path():
    """The kitti2pgm binary's path."""
    return kitti2pgm_bin()


@pytest.fixture(scope="session")
def kitti2pgm():
    """Runs the kitti2pgm binary (checked, output captured as text)."""
    return run_bin


@pytest.fixture(scope="session")
def with_points(tmp_path_factory):
    """The `converted` maps again, with point shards beside them (OUT/shards and OUT/points)."""
    return convert(tmp_path_factory.mktemp("points"), "--format", "mcap,points", "--rgb", "--cols", "256")
