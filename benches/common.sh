# Sourced by the benchmark scripts: the repository (`here`), ../shared (`shared`, or $SHARED), a
# scratch folder (`work`, removed on exit unless KEEP is set) and `build`, which builds the
# release binary and sets `bin`.
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
shared=${SHARED:-$here/../shared}
work=$(mktemp -d)
if [ -n "${KEEP:-}" ]; then echo "kept: $work"; else trap 'rm -rf "$work"' EXIT; fi
build() {
  (cd "$here" && cargo build --release --quiet)
  bin=$here/target/release/kitti2pgm
}
