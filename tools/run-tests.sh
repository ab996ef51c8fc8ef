#!/usr/bin/env bash
# Every test: the README's install command first (tools/install.sh: the CLI and the Python
# side, so that CI installs exactly what a user does), the test dependencies, the code's own
# checks (cargo fmt --check, clippy -D warnings, ruff, mypy: ruff.toml and mypy.ini), then the
# Rust suite (unit, integration on fixtures/, doc tests) and the Python packages' tests (native
# module, shard reader, trainer, and the README and docs run as written). pip skips what is
# already installed and keeps its downloads in its cache; cargo reuses its builds.
set -euo pipefail
cd "$(dirname "$0")/.."
t0=$SECONDS
tools/install.sh
export PATH="${CARGO_INSTALL_ROOT:-${CARGO_HOME:-$HOME/.cargo}}/bin:$PATH"
python3 -m pip install --quiet --disable-pip-version-check \
  -e "tools/kitti2pgm_data[test]" -e "tools/trainer[test]" "ruff==0.17.6" "mypy==2.4.1"
# ouster-sdk, the Ouster tests' reference decoder, in an environment of its own: it pins
# rosbags, flask and click to versions the test environment does not share.
[ -x target/ouster-sdk-venv/bin/python ] || python3 -m venv target/ouster-sdk-venv
target/ouster-sdk-venv/bin/python -m pip install --quiet --disable-pip-version-check "ouster-sdk==1.0.1"
export OUSTER_PYTHON="$PWD/target/ouster-sdk-venv/bin/python"
echo "run-tests.sh: installed in $((SECONDS - t0)) s"
# The code's own checks, Rust and Python: formatting, lints (warnings are errors), types.
cargo fmt --all --check
cargo clippy --workspace --all-targets --locked --quiet -- -D warnings
python3 -m ruff check tools
python3 -m mypy
echo "run-tests.sh: formatting, lints and types clean at $((SECONDS - t0)) s"
# In the release profile: `cargo install` (tools/install.sh) has just built every dependency
# there, so the tests compile only the crate's own test targets, and run optimised.
# The tests that need ../shared are #[ignore = "needs ../shared"]: run them where it is.
if [ -d ../shared/kitti ]; then
  cargo test --release --locked -- --include-ignored
else
  echo "run-tests.sh: ../shared is absent: the tests that need it are ignored (cargo lists them)"
  cargo test --release --locked
fi
# The binary the Python tests drive: the one the Rust tests ran.
KITTI2PGM_BIN="$PWD/target/release/kitti2pgm" python3 -m pytest -q tools
echo "run-tests.sh: done in $((SECONDS - t0)) s"
