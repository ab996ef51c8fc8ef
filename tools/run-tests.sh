#!/usr/bin/env bash
# Every test: the README's install command (tools/install.sh: the CLI and the Python side, so
# that CI installs exactly what a user does, with the packages' test extras), the other test
# dependencies, the code's own checks (cargo fmt --check, clippy -D warnings in the build, ruff,
# mypy: ruff.toml and mypy.ini), then the Rust suite (unit, integration on fixtures/, doc tests)
# and the Python packages' tests (native module, shard reader, trainer, and the README and docs
# run as written).
# Each step prints its time and the time so far (docs/performance.md, "A fresh clone, installed
# and tested").
#
# One build serves all: the first step (release profile) compiles every dependency once, with
# the one feature set of Cargo.toml, and the CLI, the tests, the benchmarks and the native module
# with them, the workspace's own crates through clippy's driver, so that the lints come from this
# very compile; `cargo install` and maturin (tools/install.sh) and `cargo test` then find them
# built. The test dependencies installed by pip are installed again only when their list changes
# (a stamp in target/install-stamps/).
set -euo pipefail
cd "$(dirname "$0")/.."
t0=$SECONDS
t=$SECONDS
lap() {
  echo "run-tests.sh: $1: $((SECONDS - t)) s (at $((SECONDS - t0)) s)"
  t=$SECONDS
}
# Everything Rust in one build graph first: the CLI, the tests and the native module (with the
# PyO3 configuration maturin then uses: tools/pyo3-config.sh). The crate's library compiles
# mostly on one core (its front end) while its unit tests' build (the library again, cfg(test))
# and PyO3's chain take the other; built one after the other (the install's CLI, the module, the
# tests) they took 15-35 s longer (docs/performance.md). The install then finds them built.
export PATH="${CARGO_INSTALL_ROOT:-${CARGO_HOME:-$HOME/.cargo}}/bin:$PATH"
if command -v cargo >/dev/null 2>&1; then # else tools/install.sh says what is missing
  # clippy's lints (warnings are errors) in the build itself: its driver compiles the workspace's
  # crates in place of rustc, as `cargo clippy -- -D warnings` has it do (these two variables are
  # what that command sets), but to the end instead of stopping at the analysis. A separate
  # `cargo clippy` analysed every crate of the workspace a second time and checked every
  # dependency again in check mode (45-65 s; docs/performance.md). The dependencies are
  # compiled by rustc, as always; the workspace's crates are compiled by the driver in every step
  # below (install, maturin, cargo test inherit these), and cargo keeps them apart from a plain
  # build's (the wrapper is part of their file names).
  driver=$(command -v clippy-driver || true)
  if [ -z "$driver" ]; then
    echo "run-tests.sh: clippy is missing: rustup component add clippy" >&2
    exit 1
  fi
  export RUSTC_WORKSPACE_WRAPPER="$driver"
  export CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
  # The driver must compile, and lint and deny: a canary that only a lint of clippy's own (not
  # rustc's) rejects must fail, and the same without it pass.
  canary=$(mktemp -d)
  lint() {
    echo "pub fn one() -> u8 { $1 }" >"$canary/canary.rs"
    "$driver" rustc --edition 2021 --crate-type lib --emit metadata --out-dir "$canary" \
      "$canary/canary.rs" >/dev/null 2>&1
  }
  clean=0 denied=0
  lint "1" && clean=1
  lint "return 1;" || denied=1
  rm -rf "$canary"
  if [ "$clean" = 0 ]; then
    echo "run-tests.sh: clippy's driver ($driver) compiles no canary: is the toolchain whole?" >&2
    exit 1
  elif [ "$denied" = 0 ]; then
    echo "run-tests.sh: clippy's driver passed a needless return: its lints would not run" >&2
    exit 1
  fi
  # shellcheck source=tools/pyo3-config.sh
  . tools/pyo3-config.sh
  module=()
  [ -n "${PYO3_CONFIG_FILE:-}" ] && module=(-p kitti2pgm-py)
  # What `cargo test` builds, the benchmarks' package (linted, as every crate of the workspace)
  # and the module's library (not --all-targets: it built the module's library as a test harness
  # too, 8 s, which it has none of: test = false).
  cargo build --release --locked --lib --bins --tests --examples --bench stages --quiet \
    -p kitti2pgm -p kitti2pgm-bench "${module[@]}"
fi
lap "the Rust build, linted (the CLI, the tests, the benchmarks, the module)"
tools/install.sh --with-tests
lap "install"
who=run-tests.sh
# shellcheck source=tools/stamps.sh
. tools/stamps.sh
# The test dependencies: the packages' `test` extras came with the install (--with-tests); the
# tools here once for a given list (and interpreter), then skipped.
python3 -c 'import pytest, ruff, mypy, xdist' 2>/dev/null || fresh test-deps
step test-deps "Python test dependencies" "$(digest tools/run-tests.sh)" \
  python3 -m pip install --quiet --disable-pip-version-check "ruff==0.17.6" "mypy==2.4.1" \
  "pytest-xdist==3.8.0"
# ouster-sdk, the Ouster tests' reference decoder, in an environment of its own (it pins
# rosbags, flask and click to versions the test environment does not share), made once per
# version and Python and kept in the user's cache, so that every checkout reuses it.
pyver=$(python3 -c 'import sys; print("%d.%d" % sys.version_info[:2])')
venv="${XDG_CACHE_HOME:-$HOME/.cache}/kitti2pgm/ouster-sdk-1.0.1-py$pyver"
if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c 'import ouster.sdk' 2>/dev/null &&
  [ "$(cat "$venv/kitti2pgm-stamp" 2>/dev/null)" = "ouster-sdk==1.0.1" ]; then
  echo "run-tests.sh: ouster-sdk: skipped (its environment in $venv holds 1.0.1)"
else
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "ouster-sdk==1.0.1"
  echo "ouster-sdk==1.0.1" >"$venv/kitti2pgm-stamp"
fi
export OUSTER_PYTHON="$venv/bin/python"
lap "test dependencies"
# The code's own checks, Rust and Python: formatting, lints (warnings are errors), types. The
# Rust lints ran in the build above.
cargo fmt --all --check
python3 -m ruff check tools
# mypy's cache in the user's cache, shared by every checkout: what it holds of torch and numpy
# (22 s of a cold run, 1 s warm) is checked again only when they change; mypy takes a module's
# cached analysis only while its source's digest matches.
python3 -m mypy --cache-dir "${XDG_CACHE_HOME:-$HOME/.cache}/kitti2pgm/mypy"
lap "formatting, lints and types clean"
# Built above (release profile, the dependencies optimised): this runs them. The tests that need
# ../shared are #[ignore = "needs ../shared"]: run them where it is.
if [ -d ../shared/kitti ]; then
  cargo test --release --locked -- --include-ignored
else
  echo "run-tests.sh: ../shared is absent: the tests that need it are ignored (cargo lists them)"
  cargo test --release --locked
fi
lap "Rust tests"
# The binary the Python tests drive: the one the Rust tests ran. Two workers (pytest-xdist; one
# on a single core), each test to the first free one and the rest taken over by an idle one
# (`worksteal`): the docs' chain of blocks (about 70 s) on one, the other tests beside it;
# tools/conftest.py gives each worker's torch its share of the cores (threads of both workers
# that outnumber the cores spin-wait on each other).
workers=$(($(nproc) < 2 ? 1 : 2))
KITTI2PGM_BIN="$PWD/target/release/kitti2pgm" python3 -m pytest -q -n "$workers" --dist worksteal tools
lap "Python tests"
echo "run-tests.sh: done in $((SECONDS - t0)) s"
