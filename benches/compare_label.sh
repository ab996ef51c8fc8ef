#!/usr/bin/env bash
# `kitti2pgm label` against the numpy peer users write today (benches/label_numpy_peer.py: points
# in rotated boxes, vectorised) and against its own floor, same scans, same machine, same run.
#
#   benches/compare_label.sh [COPIES] [BOXES] [WORKERS]
#
# The real VLP-16 scan (fixtures/lidars, 14,831 points) COPIES times (default 300) as
# sequences/00/velodyne/<frame6>.pcd links, and a SUSTechPOINTS scene of as many frames with
# BOXES boxes each (default 30; seeded). The floor: `kitti2pgm label` with the same scans and an
# empty box list a frame (reading the scans and writing the label files alone). Each run labels
# from scratch (the labels and the record removed first). Three runs each, alternating; the best
# counts. The two outputs are compared entry by entry at the end.
set -euo pipefail
. "$(dirname "$0")/common.sh"
copies=${1:-300}
boxes=${2:-30}
workers=${3:-$(nproc)}
scan=$here/fixtures/lidars/velodyne/vlp16_1673400472138016708.pcd
seq=$work/root/sequences/00
mkdir -p "$seq/velodyne" "$work/empty/label" "$work/empty/lidar"
for i in $(seq 0 $((copies - 1))); do
  ln -s "$scan" "$seq/velodyne/$(printf %06d "$i").pcd"
  echo '[]' >"$work/empty/label/$(printf %06d "$i").json"
done
python3 "$here/benches/label_numpy_peer.py" scene "$work/scene" --frames "$copies" --boxes "$boxes"
build
echo "scans: $copies, boxes a scan: $boxes, workers/threads: $workers, cpu: $(nproc) cores"
t() { local TIMEFORMAT='%R' r; r=$( { time "$@" >/dev/null 2>&1; } 2>&1 ); echo "$r"; }
min() { echo "if ($1 < $2) $1 else $2" | bc; }
fresh() { rm -rf "$seq/labels" "$seq/box_labels.json"; }
ours() { fresh; "$bin" --threads "$workers" --no-progress label "$work/root" --boxes "$1"; }
pb=999999; ob=999999; fb=999999
for rep in 1 2 3; do
  rm -rf "$work/peer"
  p=$(t python3 "$here/benches/label_numpy_peer.py" label "$work/root" "$work/scene" "$work/peer" --workers "$workers")
  f=$(t ours "$work/empty")
  o=$(t ours "$work/scene")
  pb=$(min "$p" "$pb"); ob=$(min "$o" "$ob"); fb=$(min "$f" "$fb")
  echo "run $rep: peer ${p}s  kitti2pgm ${o}s  floor (read + write, no box) ${f}s"
done
sps() { echo "scale=1; $copies / $1" | bc; }
echo "peer (numpy, $workers workers):   $(sps "$pb") scans/s (wall, process start included)"
echo "kitti2pgm label:              $(sps "$ob") scans/s  ratio $(echo "scale=2; $pb / $ob" | bc)x the peer"
echo "floor (kitti2pgm, no boxes):  $(sps "$fb") scans/s  kitti2pgm at $(echo "scale=2; $ob / $fb" | bc)x the floor's time"
python3 - "$seq/labels" "$work/peer" <<'PY'
import glob, os, sys
import numpy as np
ours, peer = sys.argv[1], sys.argv[2]
diff = total = 0
for f in sorted(glob.glob(os.path.join(peer, "*.label"))):
    a = np.fromfile(f, "<u4"); b = np.fromfile(os.path.join(ours, os.path.basename(f)), "<u4")
    diff += int((a != b).sum()); total += len(a)
print(f"entries that differ from the peer's: {diff} of {total}")
PY
