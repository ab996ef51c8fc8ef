#!/usr/bin/env bash
# Every test: the Rust suite (unit, integration on fixtures/, doc tests) and the Python packages'
# tests (native module, shard reader, trainer). The native module (tools/kitti2pgm_py, PyO3 +
# maturin) is built from source by pip, in release mode (about 3 minutes on 2 cores). Installs the Python dependencies first; pip skips what is
# already there, and keeps its downloads in its cache, so a second run installs nothing. PyPI's
# torch brings its CUDA libraries (about 4 GB) even for the CPU tests.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check \
  -e "tools/kitti2pgm_data[test]" -e "tools/trainer[test]"
python3 -m pip install --quiet --disable-pip-version-check ./tools/kitti2pgm_py
cargo test --locked
cargo build --locked --quiet          # the binary the Python tests drive
python3 -m pytest -q tools
