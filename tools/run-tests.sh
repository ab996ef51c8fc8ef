#!/usr/bin/env bash
# Every test: the Rust suite (unit, integration on fixtures/, doc tests) and the Python packages'
# tests. Installs the Python test dependencies first (idempotent: pip skips what is there).
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check -e "tools/kitti2pgm_data[test]"
cargo test --locked
cargo build --locked --quiet          # the binary the Python tests drive
python3 -m pytest -q tools
