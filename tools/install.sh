#!/usr/bin/env bash
# Installs kitti2pgm, all of it, from this checkout:
#   - the CLI: `cargo install --path .` puts `kitti2pgm` in ~/.cargo/bin (Rust 1.89 or later);
#   - the Python side: the native module (`import kitti2pgm`, built from source by maturin), the
#     shard reader (`kitti2pgm_data`) and the trainer (`python -m kitti2pgm_train`, with the
#     ONNX export extra), the last two editable.
#
#   tools/install.sh            # everything (about 6 minutes on 2 cores, most of it compiling)
#   tools/install.sh --cli      # the CLI only
#   tools/install.sh --python   # the Python side only
#
# PyPI's torch brings its CUDA libraries (about 4 GB) even for CPU use.
set -euo pipefail
cd "$(dirname "$0")/.."
cli=1
py=1
case "${1:-}" in
  "") ;;
  --cli) py=0 ;;
  --python) cli=0 ;;
  *) echo "usage: tools/install.sh [--cli | --python]" >&2; exit 2 ;;
esac
if [ "$cli" = 1 ]; then
  if ! command -v cargo >/dev/null 2>&1; then
    if [ -x "$HOME/.cargo/bin/cargo" ]; then
      export PATH="$HOME/.cargo/bin:$PATH"
    else
      echo "install.sh: the CLI needs Rust (cargo, 1.89 or later): see https://rustup.rs" >&2
      exit 1
    fi
  fi
  cargo install --locked --quiet --path .
  bin="${CARGO_INSTALL_ROOT:-${CARGO_HOME:-$HOME/.cargo}}/bin"
  echo "install.sh: kitti2pgm installed in $bin"
  case ":$PATH:" in
    *":$bin:"*) ;;
    *) echo "install.sh: $bin is not on PATH: export PATH=\"$bin:\$PATH\"" >&2 ;;
  esac
fi
if [ "$py" = 1 ]; then
  python3 -m pip install --quiet --disable-pip-version-check \
    ./tools/kitti2pgm_py -e tools/kitti2pgm_data -e "tools/trainer[export]"
  echo "install.sh: Python packages kitti2pgm, kitti2pgm_data, kitti2pgm_train installed"
fi
