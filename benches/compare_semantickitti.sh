#!/usr/bin/env bash
# SemanticKITTI conversion against its numpy peer (../shared/bench/semantickitti_numpy_baseline.py),
# same scans, same machine, same run, same number of cores.
#
#   benches/compare_semantickitti.sh [COPIES] [WORKERS]
#
# The three real scans of ../shared/semantickitti (sequence 00) with their labels are repeated
# under COPIES x 3 frame numbers (default 100 -> 300 scans) as symbolic links. The peer writes a
# 64 x 2048 x 6 .npy per scan (elevation bins, learning-mapped labels); kitti2pgm writes the same
# layout with rings (--fov-deg 360 --cols 2048 --no-point-labels), then again with the per-point
# .label files the peer does not write. The floor (benches/io_floor.py, as many processes) reads
# every .bin and .label and writes a .npy of the same size per scan, computing nothing (timed
# inside, without Python's start). Each runs three times, alternating, each after `sync` (no run
# pays for the last one's writeback); the best run counts.
set -euo pipefail
. "$(dirname "$0")/common.sh"
copies=${1:-100}
workers=${2:-$(nproc)}
src=$shared/semantickitti/sequences/00
seq=$work/sk/sequences/00
mkdir -p "$seq/velodyne" "$seq/labels"
cp "$src/calib.txt" "$seq/"
n=0
for i in $(seq 1 "$copies"); do
  for f in 000000 000001 000002; do
    name=$(printf %06d $n); n=$((n + 1))
    ln -s "$src/velodyne/$f.bin" "$seq/velodyne/$name.bin"
    ln -s "$src/labels/$f.label" "$seq/labels/$name.label"
  done
done
build
echo "scans: $n, workers/threads: $workers, cpu: $(nproc) cores"
t() { local s e; sync; s=$(date +%s.%N); "$@" >/dev/null; e=$(date +%s.%N); echo "$e - $s" | bc; }
min() { echo "if ($1 < $2) $1 else $2" | bc; }
pb=999999; ob=999999; lb=999999; fb=999999
for rep in 1 2 3; do
  rm -rf "$work/peer" "$work/ours" "$work/ours_lab" "$work/floor"
  p=$(t python3 "$shared/bench/semantickitti_numpy_baseline.py" "$work/sk" "$work/peer" --workers "$workers" --yaml "$shared/semantickitti/semantic-kitti.yaml")
  o=$(t "$bin" --threads "$workers" --no-progress convert "$work/sk" --out "$work/ours" --fov-deg 360 --cols 2048 --no-point-labels)
  l=$(t "$bin" --threads "$workers" --no-progress convert "$work/sk" --out "$work/ours_lab" --fov-deg 360 --cols 2048)
  f=$(sync; python3 "$here/benches/io_floor.py" semantickitti "$work/sk" "$work/floor" --workers "$workers")
  pb=$(min "$p" "$pb"); ob=$(min "$o" "$ob"); lb=$(min "$l" "$lb"); fb=$(min "$f" "$fb")
  echo "run $rep: peer ${p}s  kitti2pgm ${o}s  kitti2pgm+labels ${l}s  floor ${f}s"
done
sps() { echo "scale=1; $n / $1" | bc; }
echo "peer (numpy, $workers workers):          $(sps "$pb") scans/s (wall, process start included)"
echo "kitti2pgm (same output):               $(sps "$ob") scans/s  ratio $(echo "scale=2; $pb / $ob" | bc)x"
echo "kitti2pgm (+ per-point .label files):  $(sps "$lb") scans/s  ratio $(echo "scale=2; $pb / $lb" | bc)x"
echo "floor (read, write the same bytes):    $(sps "$fb") scans/s  ratio $(echo "scale=2; $pb / $fb" | bc)x (the most any tool can reach); kitti2pgm takes $(echo "scale=2; $ob / $fb" | bc)x its time"
