#!/usr/bin/env bash
# Times `kitti2pgm score` on a set the size of SqueezeSeg's val set (2,791 frames): the 30 real
# converted frames of ../shared/kitti/raw copied under 2,791 frame ids, as ground truth and as
# predictions (HxW int64 label maps with 10% of the cells changed, written by numpy).
#   benches/score_val.sh [THREADS]
set -euo pipefail
. "$(dirname "$0")/common.sh"
threads=${1:-$(nproc)}
build
"$bin" --no-progress convert "$shared/kitti/raw" --out "$work/src" >/dev/null
python3 - "$work" <<'PY'
import sys, os, glob, numpy as np
w = sys.argv[1]
src = sorted(glob.glob(f"{w}/src/lidar_2d/*.npy"))
os.makedirs(f"{w}/gt/lidar_2d"); os.makedirs(f"{w}/pred")
rng = np.random.default_rng(0)
preds = []
for f in src:
    l = np.load(f)[..., 5].astype(np.int64)
    m = rng.random(l.shape) < 0.1
    l[m] = rng.integers(0, 4, m.sum())
    preds.append(l)
for i in range(2791):
    fid = f"2011_09_26_{9000 + i // 1000:04d}_{i % 1000:010d}"
    os.link(src[i % len(src)], f"{w}/gt/lidar_2d/{fid}.npy")
    np.save(f"{w}/pred/{fid}.npy", preds[i % len(src)])
PY
s=$(date +%s.%N)
"$bin" --threads "$threads" --no-progress score --gt "$work/gt" --pred "$work/pred" | tail -n +1 | grep -E "frames|mIoU"
e=$(date +%s.%N)
echo "score: 2791 frames in $(echo "$e - $s" | bc) s with $threads threads"
