#!/usr/bin/env bash
# What provenance costs: a conversion recording every frame's inputs (content hashes), and a
# re-run that proves every frame unchanged (fingerprints every input again) and keeps it.
#
#   benches/resume.sh [COPIES] [OLD_BINARY]
#
# The 30 real scans of ../shared/kitti/raw are repeated COPIES times (default 10 -> 300
# frames), as in compare_peer.sh. Converts with --all-frames --rgb (scan, tracklets, timestamps,
# calibration and image are each frame's inputs), three runs alternating, best of each:
#   - a fresh conversion (with OLD_BINARY, an earlier build, beside it when given);
#   - a re-run over the finished folder (every frame kept after its inputs are re-hashed).
set -euo pipefail
. "$(dirname "$0")/common.sh"
copies=${1:-10}
old=${2:-}
raw_copies "$copies"
build
frames=$(find -L "$work/raw" -name '*.bin' | wc -l)
echo "frames: $frames, cpu: $(nproc) cores"
t() { local s e; s=$(date +%s.%N); "$@" >/dev/null; e=$(date +%s.%N); echo "$e - $s" | bc; }
min() { echo "if ($1 < $2) $1 else $2" | bc; }
args=(--no-progress convert "$work/raw" --all-frames --rgb)
new_best=999999; old_best=999999; rerun_best=999999
for rep in 1 2 3; do
  rm -rf "$work/new" "$work/old"
  c=$(t "$bin" "${args[@]}" --out "$work/new")
  r=$(t "$bin" "${args[@]}" --out "$work/new")
  new_best=$(min "$c" "$new_best"); rerun_best=$(min "$r" "$rerun_best")
  line="run $rep: convert ${c}s  re-run (all kept) ${r}s"
  if [ -n "$old" ]; then
    o=$(t "$old" "${args[@]}" --out "$work/old")
    old_best=$(min "$o" "$old_best")
    line="$line  earlier build ${o}s"
  fi
  echo "$line"
done
echo "convert:              ${new_best}s"
echo "re-run, all kept:     ${rerun_best}s  = $(echo "scale=3; $rerun_best / $new_best" | bc) of a conversion"
if [ -n "$old" ]; then
  echo "earlier build:        ${old_best}s  -> this build takes $(echo "scale=3; $new_best / $old_best" | bc)x its time"
fi
