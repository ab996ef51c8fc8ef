"""The README runs as written: every ``sh`` and ``python`` block of README.md,
tools/trainer/README.md and docs/python.md, in that order, in one temporary folder that holds the
repository's ``fixtures`` and ``tools`` (as links), so that the commands' outputs (``out/...``)
never land in the repository.

- ``kitti2pgm`` is the binary under test (target/debug or $KITTI2PGM_BIN) on PATH; the installed
  one is what ``tools/install.sh`` (run by tools/run-tests.sh) puts in ~/.cargo/bin.
- ``KITTI_RAW`` points the full-dataset examples at ``fixtures/raw``; reproduce.sh gets the
  environment of a smoke run (two steps a model, on the CPU).
- A block marked ``sh setup`` is the installation itself, run by tools/run-tests.sh (checked
  here); a block marked ``sh norun`` must say why in an HTML comment just above it.
- A block marked ``sh alone`` needs nothing the blocks before it made: it runs in a folder of its
  own, as a test of its own, so that pytest's workers (tools/run-tests.sh) run it beside the rest.
"""

import json
import os
import pathlib
import re
import subprocess
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
DOCS = ["README.md", "tools/trainer/README.md", "docs/python.md"]
FENCE = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```\s*$", re.S | re.M)


def blocks(doc):
    """(language, marks, code, line) of each fenced block."""
    text = (REPO / doc).read_text()
    out = []
    for m in FENCE.finditer(text):
        line = text[: m.start()].count("\n") + 1
        before = text[: m.start()].rstrip().splitlines()[-1:] or [""]
        out.append((m.group(1), m.group(2).split(), m.group(3), line, before[0]))
    return out


def runnable():
    for doc in DOCS:
        for lang, marks, code, line, before in blocks(doc):
            if lang not in ("sh", "python"):
                continue
            yield doc, lang, marks, code, line, before


def test_every_block_is_run_or_says_why_not():
    seen = list(runnable())
    assert len([b for b in seen if not b[2]]) >= 10, "the docs hold runnable blocks"
    for doc, _lang, marks, code, line, before in seen:
        if "norun" in marks:
            assert before.startswith("<!-- norun:"), f"{doc}:{line}: a norun block says why just above it"
        if "setup" in marks:
            assert "tools/install.sh" in code, f"{doc}:{line}: a setup block installs"
    # The setup blocks are what CI runs before the tests.
    assert "tools/install.sh" in (REPO / "tools/run-tests.sh").read_text()


def _binary():
    env = os.environ.get("KITTI2PGM_BIN")
    if env:
        return os.path.abspath(env)  # a relative path would not hold inside the symlink
    p = REPO / "target" / "debug" / "kitti2pgm"
    if not p.exists():
        subprocess.run(["cargo", "build", "--quiet"], cwd=REPO, check=True)
    return str(p)


def _workspace(tmp_path):
    """A folder holding the repository's fixtures and tools (links), and the environment the
    blocks run in."""
    work = tmp_path / "work"
    work.mkdir()
    for name in ("fixtures", "tools"):
        (work / name).symlink_to(REPO / name)
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "kitti2pgm").symlink_to(_binary())
    env = dict(os.environ,
               PATH=f"{bin_dir}{os.pathsep}{os.path.dirname(sys.executable)}{os.pathsep}{os.environ.get('PATH', '')}",
               KITTI_RAW="fixtures/raw", KITTI2PGM=str(bin_dir / "kitti2pgm"),
               STEPS="2", BATCH="3", WIDTH="0.25", GPUS="1", EXTRA="--device cpu --workers 0",
               CONVERT="--cols 64", EVAL="--device cpu --timing-frames 0", PYTHONUNBUFFERED="1")
    return work, env


def _run(block, work, env):
    doc, lang, _marks, code, line, _ = block
    cmd = ["bash", "-euo", "pipefail", "-c", code] if lang == "sh" else [sys.executable, "-c", code]
    r = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, (f"{doc}:{line} ({lang}) failed with {r.returncode}:\n{code}\n"
                               f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}")


def _alone():
    return [b for b in runnable() if "alone" in b[2]]


@pytest.mark.long(65)
def test_the_docs_run_as_written(tmp_path):
    work, env = _workspace(tmp_path)
    untracked_before = _untracked()
    ran = 0
    for block in runnable():
        if {"setup", "norun", "alone"} & set(block[2]):
            continue
        _run(block, work, env)
        ran += 1
    assert ran >= 10
    # What the commands promise is there.
    out = work / "out"
    assert (out / "raw/ImageSet/val.txt").read_text().split() == ["2011_09_26_0052_0000000000"]
    assert (out / "balance.png").stat().st_size > 0 and (out / "frame.png").stat().st_size > 0
    assert (out / "model.onnx").stat().st_size > 0
    assert sorted(p.name for p in (out / "runs/mid/predictions").iterdir()) == ["2011_09_26_0052_0000000000.npy"]
    # Nothing was written into the repository through the linked folders.
    new = _untracked() - untracked_before
    assert not new, new


@pytest.mark.long(25)
@pytest.mark.parametrize("block", _alone(), ids=lambda b: f"{b[0]}:{b[4]}")
def test_a_block_runs_alone(block, tmp_path):
    """A block marked ``alone``, in a folder of its own: a test of its own, which pytest's
    other worker takes while one runs the chain above."""
    work, env = _workspace(tmp_path)
    untracked_before = _untracked()
    _run(block, work, env)
    if "reproduce.sh" in block[3]:
        _check_reproduced(work / "out")
    new = _untracked() - untracked_before
    assert not new, new


def test_the_reproduction_runs_alone():
    assert any("reproduce.sh" in b[3] for b in _alone()), "the trainer README's reproduce.sh block is marked alone"


def _check_reproduced(out):
    """reproduce.sh, without VAL_DRIVES on the fixtures: six rows, IoUs in range."""
    table = (out / "repro/table.md").read_text().splitlines()
    assert len(table) == 2 + 6 and all(r.startswith("|") for r in table), table
    assert "| squeezeseg | xyzdi+dirgb |" in "\n".join(table)
    rows = json.loads((out / "repro/table.json").read_text())
    assert len(rows) == 6 and all(0.0 <= row["miou"] <= 1.0 for row in rows)


def _untracked():
    """Untracked, unignored files under fixtures/ and tools/."""
    status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=all", "fixtures", "tools"],
                            cwd=REPO, capture_output=True, text=True).stdout
    return {line[3:] for line in status.splitlines() if line.startswith("??")}
