#!/usr/bin/env bash
# Installs kitti2pgm, all of it, from this checkout:
#   - the CLI: `cargo install --path .` puts `kitti2pgm` in ~/.cargo/bin (Rust 1.92 or later);
#   - the Python side: the native module (`import kitti2pgm`, built from source by maturin), the
#     shard reader (`kitti2pgm_data`) and the trainer (`python -m kitti2pgm_train`, with the
#     ONNX export extra), the last two editable.
#
#   tools/install.sh              # everything (about 4 minutes on 2 cores, most of it compiling)
#   tools/install.sh --cli        # the CLI only
#   tools/install.sh --python     # the Python side only
#   tools/install.sh --with-tests # everything, the packages with their `test` extras (what
#                                 # tools/run-tests.sh runs: one pip run for both)
#
# The CLI, the module and the tests share one build (the workspace's target/, one feature set:
# Cargo.toml, one PyO3 configuration: tools/pyo3-config.sh), so the module compiles only its own
# crates after the CLI, and nothing after tools/run-tests.sh's build. What was installed from
# these very sources is not installed again: each step records a digest of its inputs in
# target/install-stamps/ (tools/stamps.sh) and says when it skips (a second run takes seconds).
# Every step prints its time. PyPI's torch brings its CUDA libraries (about 4 GB) even for CPU use.
set -euo pipefail
cd "$(dirname "$0")/.."
cli=1
py=1
tests=0
case "${1:-}" in
  "") ;;
  --cli) py=0 ;;
  --python) cli=0 ;;
  --with-tests) tests=1 ;;
  *) echo "usage: tools/install.sh [--cli | --python | --with-tests]" >&2; exit 2 ;;
esac
if ! command -v cargo >/dev/null 2>&1; then
  if [ -x "$HOME/.cargo/bin/cargo" ]; then
    export PATH="$HOME/.cargo/bin:$PATH"
  else
    echo "install.sh: kitti2pgm needs Rust (cargo, 1.92 or later): see https://rustup.rs" >&2
    exit 1
  fi
fi
who=install.sh
# shellcheck source=tools/stamps.sh
. tools/stamps.sh

rust_sources=(src build.rs proto Cargo.toml Cargo.lock)
if [ "$cli" = 1 ]; then
  bin="${CARGO_INSTALL_ROOT:-${CARGO_HOME:-$HOME/.cargo}}/bin"
  # The stamp holds only while the installed binary is the one this script installed.
  # (Nothing, and no failure, where none is installed yet: a fresh machine.)
  installed() { { sha256sum "$bin/kitti2pgm" 2>/dev/null || true; } | cut -c1-16; }
  have=$(installed)
  [ -n "$have" ] && [ "$(cat "$stamps/cli-binary" 2>/dev/null)" = "$have" ] || fresh cli
  step cli "the CLI (cargo install)" "$(digest "${rust_sources[@]}")" \
    cargo install --locked --quiet --path .
  installed >"$stamps/cli-binary"
  echo "install.sh: kitti2pgm installed in $bin"
  case ":$PATH:" in
    *":$bin:"*) ;;
    *) echo "install.sh: $bin is not on PATH: export PATH=\"$bin:\$PATH\"" >&2 ;;
  esac
fi
if [ "$py" = 1 ]; then
  pip=(python3 -m pip install --quiet --disable-pip-version-check)
  # The module: the library's sources and its own; the stamp holds only while the installed
  # module is the one this script installed (another checkout may have replaced it).
  module() {
    python3 -c 'import glob, hashlib, kitti2pgm, os
so = glob.glob(os.path.join(os.path.dirname(kitti2pgm.__file__), "*.so"))
print(hashlib.sha256(open(so[0], "rb").read()).hexdigest()[:16] if so else "")' 2>/dev/null ||
      true # none installed yet
  }
  have=$(module)
  [ -n "$have" ] && [ "$(cat "$stamps/module-file" 2>/dev/null)" = "$have" ] || fresh module
  # shellcheck source=tools/pyo3-config.sh
  . tools/pyo3-config.sh
  step module "the Python module (maturin)" \
    "$(digest "${rust_sources[@]}" tools/kitti2pgm_py/src tools/kitti2pgm_py/Cargo.toml \
      tools/kitti2pgm_py/pyproject.toml tools/kitti2pgm_py/pyo3-build.txt) pyo3:${PYO3_CONFIG_FILE:-maturin}" \
    "${pip[@]}" ./tools/kitti2pgm_py
  module >"$stamps/module-file"
  # The stamp holds only while the packages import from this checkout (another checkout's
  # editable install replaces them).
  python3 -c 'import os, kitti2pgm_data as d, kitti2pgm_train as t
here = lambda m, p: os.path.realpath(m.__file__).startswith(os.path.realpath(p) + os.sep)
raise SystemExit(not (here(d, "tools/kitti2pgm_data") and here(t, "tools/trainer")))' \
    2>/dev/null || fresh packages
  # With the tests' extras, in the same pip run: a second run of pip for them built both
  # editable packages again (8.6 s against 1.5 s for the rest of the tests' dependencies).
  # A plain install after one with the extras has nothing to do (the extras stay); read after
  # the check above, so that a stamp it forgot is not taken for one.
  data=tools/kitti2pgm_data trainer="tools/trainer[export]"
  want=$(digest tools/kitti2pgm_data/pyproject.toml tools/trainer/pyproject.toml)
  if [ "$tests" = 1 ]; then
    data="$data[test]" trainer="tools/trainer[export,test]" want="$want with-tests"
  elif [ "$(cat "$stamps/packages" 2>/dev/null)" = "$want with-tests" ]; then
    want="$want with-tests"
  fi
  # setuptools builds the two editable packages: the installed one where it can (pip's isolated
  # build installed it twice again, 7.4 s instead of 3.6 s), else pip's isolation installs it.
  iso=()
  python3 -c 'import setuptools as s; raise SystemExit(tuple(map(int, s.__version__.split(".")[:2])) < (70, 1))' \
    2>/dev/null && iso=(--no-build-isolation)
  step packages "kitti2pgm_data and kitti2pgm_train (editable)" "$want" \
    "${pip[@]}" "${iso[@]}" -e "$data" -e "$trainer"
  echo "install.sh: Python packages kitti2pgm, kitti2pgm_data, kitti2pgm_train installed"
fi
