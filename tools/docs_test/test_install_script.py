"""tools/install.sh on a machine where nothing is installed yet: the README's first command.

The CLI's step into an empty install root (``CARGO_INSTALL_ROOT``): it installs, a second run
skips it and says so, and a binary that went missing is installed again. A fresh machine once
made the script stop at its first check, silently, before installing anything (the check read a
binary that was not there, under ``set -o pipefail``). ``cargo install`` finds the release build
of tools/run-tests.sh; run alone, this test compiles it first.
"""

import os
import pathlib
import subprocess

REPO = pathlib.Path(__file__).resolve().parents[2]


def _install_cli(root: pathlib.Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "CARGO_INSTALL_ROOT": str(root)}
    return subprocess.run(
        ["bash", str(REPO / "tools" / "install.sh"), "--cli"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )


def test_install_cli_into_an_empty_root_then_skips_then_reinstalls_what_went_missing(tmp_path):
    root = tmp_path / "root"
    binary = root / "bin" / "kitti2pgm"

    first = _install_cli(root)
    assert first.returncode == 0, first.stderr
    assert "install.sh: the CLI (cargo install): " in first.stdout
    assert "skipped" not in first.stdout
    assert binary.is_file()
    version = subprocess.run([str(binary), "--version"], capture_output=True, text=True, check=True)
    assert version.stdout.startswith("kitti2pgm ")
    # Not on PATH: the script says how to put it there.
    assert f'export PATH="{root / "bin"}:$PATH"' in first.stderr

    second = _install_cli(root)
    assert second.returncode == 0, second.stderr
    assert "the CLI (cargo install): skipped (installed from these inputs already)" in second.stdout

    binary.unlink()
    third = _install_cli(root)
    assert third.returncode == 0, third.stderr
    assert "skipped" not in third.stdout
    assert binary.is_file()
