#!/usr/bin/env bash
# Whole-conversion benchmark against the numpy peer (../shared/bench/numpy_baseline.py), same
# frames, same machine, same run, same number of cores.
#
#   benches/compare_peer.sh [COPIES] [WORKERS]
#
# The 30 real scans of ../shared/kitti/raw (drives 0001 and 0052, with image_02) are repeated
# COPIES times (default 10 -> 300 frames) as extra drive folders made of symbolic links, so that
# both tools see a batch large enough for their start-up to vanish. Both convert every scan to a
# 64x512x9 .npy with colour from camera 2 (kitti2pgm: --all-frames --rgb --no-point-labels; a
# second kitti2pgm run adds the per-point .label files the peer does not write). The floor
# (benches/io_floor.py raw, as many processes) reads each scan and its PNG file (not decoded) and
# writes a .npy of the same size, computing nothing (timed inside, without Python's start). Each
# runs three times, alternating, each after `sync` (no run pays for the last one's writeback),
# and the best run counts. Prints frames/s and the ratios.
set -euo pipefail
. "$(dirname "$0")/common.sh"
copies=${1:-10}
workers=${2:-$(nproc)}
raw_copies "$copies"
build
frames=$(find -L "$work/raw" -name '*.bin' | wc -l)
echo "frames: $frames, workers/threads: $workers, cpu: $(nproc) cores"
peer_best=999999; ours_best=999999; ours_lab_best=999999; floor_best=999999
t() { local s e; sync; s=$(date +%s.%N); "$@" >/dev/null; e=$(date +%s.%N); echo "$e - $s" | bc; }
min() { echo "if ($1 < $2) $1 else $2" | bc; }
for rep in 1 2 3; do
  rm -rf "$work/peer" "$work/ours" "$work/ours_lab" "$work/floor"
  p=$(t python3 "$shared/bench/numpy_baseline.py" "$work/raw" "$work/peer" --workers "$workers")
  o=$(t "$bin" --threads "$workers" --no-progress convert "$work/raw" --out "$work/ours" --all-frames --rgb --no-point-labels)
  l=$(t "$bin" --threads "$workers" --no-progress convert "$work/raw" --out "$work/ours_lab" --all-frames --rgb)
  f=$(sync; python3 "$here/benches/io_floor.py" raw "$work/raw" "$work/floor" --workers "$workers")
  peer_best=$(min "$p" "$peer_best"); ours_best=$(min "$o" "$ours_best"); ours_lab_best=$(min "$l" "$ours_lab_best"); floor_best=$(min "$f" "$floor_best")
  echo "run $rep: peer ${p}s  kitti2pgm ${o}s  kitti2pgm+labels ${l}s  floor ${f}s"
done
fps() { echo "scale=1; $frames / $1" | bc; }
echo "peer (numpy, $workers workers):          $(fps "$peer_best") frames/s (wall, process start included)"
echo "kitti2pgm (same output):               $(fps "$ours_best") frames/s  ratio $(echo "scale=2; $peer_best / $ours_best" | bc)x"
echo "kitti2pgm (+ per-point .label files):  $(fps "$ours_lab_best") frames/s  ratio $(echo "scale=2; $peer_best / $ours_lab_best" | bc)x"
echo "I/O floor (no PNG decoding):           $(fps "$floor_best") frames/s  ratio $(echo "scale=2; $peer_best / $floor_best" | bc)x (the most any tool can reach); kitti2pgm takes $(echo "scale=2; $ours_best / $floor_best" | bc)x its time"
