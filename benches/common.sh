# Sourced by the benchmark scripts: the repository (`here`), ../shared (`shared`, or $SHARED), a
# scratch folder (`work`, removed on exit unless KEEP is set), `raw_copies` and `build`, which builds the
# release binary and sets `bin`.
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
shared=${SHARED:-$here/../shared}
work=$(mktemp -d)
if [ -n "${KEEP:-}" ]; then echo "kept: $work"; else trap 'rm -rf "$work"' EXIT; fi
# `raw_copies COPIES`: the 30 real scans of ../shared/kitti/raw (drives 0001 and 0052, with
# image_02 and the tracklets) COPIES times, as drive folders of symbolic links under
# `$work/raw`, beside the day's calibration.
raw_copies() {
  local day=2011_09_26 n=0 i d dst part
  local src=$shared/kitti/raw/$day
  mkdir -p "$work/raw/$day"
  cp "$src"/calib_*.txt "$work/raw/$day/"
  for i in $(seq 1 "$1"); do
    for d in 0001 0052; do
      n=$((n + 1))
      dst=$work/raw/$day/${day}_drive_$(printf %04d $((1000 + n)))_sync
      mkdir -p "$dst"
      for part in velodyne_points image_02 tracklet_labels.xml; do
        ln -s "$src/${day}_drive_${d}_sync/$part" "$dst/$part"
      done
    done
  done
}
build() {
  (cd "$here" && cargo build --release --quiet)
  bin=$here/target/release/kitti2pgm
}
