#!/usr/bin/env bash
# Times `kitti2pgm check` against `convert` on the same frames: ten copies (hard links) of
# ../shared's drive 0052 (20 consecutive scans with images, tracklets, the day's calibration),
# 200 frames; best of three alternating runs. Then the tracklet-only checks on the 36 shared
# tracklet files.
#   benches/check.sh [THREADS]
set -euo pipefail
. "$(dirname "$0")/common.sh"
threads=${1:-$(nproc)}
build
day=$work/raw/2011_09_26
mkdir -p "$day"
cp "$shared"/kitti/raw/2011_09_26/calib_*.txt "$day/"
for i in $(seq 0 9); do
  cp -al "$shared/kitti/raw/2011_09_26/2011_09_26_drive_0052_sync" "$day/2011_09_26_drive_910${i}_sync"
done
best() { sort -n | head -1; }
t() { local s e; s=$(date +%s.%N); "$@" >/dev/null; e=$(date +%s.%N); echo "$e - $s" | bc; }
conv=(); chk=(); ann=()
for r in 1 2 3; do
  conv+=("$(t "$bin" --threads "$threads" --no-progress convert "$work/raw" --out "$work/out" --overwrite)")
  chk+=("$(t "$bin" --threads "$threads" --no-progress check "$work/raw")")
  ann+=("$(t "$bin" --threads "$threads" --no-progress check "$work/raw" --no-scans)")
done
c=$(printf '%s\n' "${conv[@]}" | best); k=$(printf '%s\n' "${chk[@]}" | best); a=$(printf '%s\n' "${ann[@]}" | best)
echo "200 frames, $threads threads: convert $c s, check $k s (ratio $(echo "scale=2; $k / $c" | bc)), check --no-scans $a s"
tr=()
for r in 1 2 3; do tr+=("$(t "$bin" --threads "$threads" --no-progress check "$shared/kitti/tracklets")"); done
echo "36 tracklet files: $(printf '%s\n' "${tr[@]}" | best) s"
