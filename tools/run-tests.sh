#!/usr/bin/env bash
# Every test: the README's install command first (tools/install.sh: the CLI and the Python
# side, so that CI installs exactly what a user does), the test dependencies, then the Rust
# suite (unit, integration on fixtures/, doc tests) and the Python packages' tests (native
# module, shard reader, trainer, and the README and docs run as written). pip skips what is
# already installed and keeps its downloads in its cache; cargo reuses its builds.
set -euo pipefail
cd "$(dirname "$0")/.."
t0=$SECONDS
tools/install.sh
export PATH="${CARGO_INSTALL_ROOT:-${CARGO_HOME:-$HOME/.cargo}}/bin:$PATH"
python3 -m pip install --quiet --disable-pip-version-check \
  -e "tools/kitti2pgm_data[test]" -e "tools/trainer[test]"
echo "run-tests.sh: installed in $((SECONDS - t0)) s"
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
