#!/usr/bin/env bash
# `kitti2pgm infer` against the engine alone (the floor: ONNX Runtime on the converted maps, in
# memory) and against the Python pipeline users write (benches/infer_python_peer.py: numpy,
# kitti2pgm's Python project and unproject, onnxruntime), same model, same threads, same run.
#
#   benches/compare_infer.sh [COPIES] [THREADS]
#
# The model: SqueezeSeg at the paper's size (xyzdi, about 0.9 M parameters) trained one step on
# the 30 real scans of ../shared/kitti/raw and exported (the weights do not change the time).
# The scans: those 30, COPIES times (default 4: 120 scans). RUNS (5) runs each, alternating; the
# best counts, and each run's ratios (their median). The per-point outputs of infer and the peer are compared at the end.
set -euo pipefail
. "$(dirname "$0")/common.sh"
copies=${1:-4}
threads=${2:-$(nproc)}
raw_copies "$copies"
build
"$bin" --no-progress convert "$shared/kitti/raw" --out "$work/conv" --format npy,mcap >/dev/null
python3 -m kitti2pgm_train train --shards "$work/conv/shards" --model squeezeseg --input xyzdi \
  --out "$work/run" --steps 1 --batch 2 --workers 0 --device cpu >/dev/null 2>&1
python3 -m kitti2pgm_train export --run "$work/run" --out "$work/model.onnx" >/dev/null 2>&1
scans=$(find -L "$work/raw" -name '*.bin' | wc -l)
mkdir -p "$work/maps"
for i in $(seq 1 "$copies"); do
  for f in "$work"/conv/lidar_2d/*.npy; do ln -sf "$f" "$work/maps/$i-$(basename "$f")"; done
done
echo "scans: $scans, threads: $threads, cpu: $(nproc) cores"
t() { local TIMEFORMAT='%R' r; r=$( { time "$@" >/dev/null 2>&1; } 2>&1 ); echo "$r"; }
min() { echo "if ($1 < $2) $1 else $2" | bc; }
eng() { python3 "$here/benches/infer_python_peer.py" "$work/model.onnx" - - --threads "$threads" \
  --engine-only "$work/maps" | python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'; }
eb=999999; pb=999999; ob=999999
ratios=()
for rep in $(seq 1 "${RUNS:-5}"); do
  rm -rf "$work/peer" "$work/ours"
  e=$(eng)
  p=$(t python3 "$here/benches/infer_python_peer.py" "$work/model.onnx" "$work/raw" "$work/peer" --threads "$threads")
  o=$(t "$bin" --threads "$threads" --no-progress infer --model "$work/model.onnx" "$work/raw" --out "$work/ours" \
    --model-threads "$threads")
  eb=$(min "$e" "$eb"); pb=$(min "$p" "$pb"); ob=$(min "$o" "$ob")
  echo "run $rep: engine alone ${e}s  python peer ${p}s  kitti2pgm infer ${o}s"
  ratios+=("$(echo "scale=3; $o / $e" | bc) $(echo "scale=3; $p / $o" | bc)")
done
# The machine is shared: each run's own ratios (the three timed back to back), their median.
printf '%s\n' "${ratios[@]}" | python3 -c 'import statistics,sys; r=[tuple(map(float,l.split())) for l in sys.stdin]; print("per run, median: %.2fx the engine'"'"'s time, %.2fx the peer'"'"'s speed (runs: %s)" % (statistics.median(a for a,_ in r), statistics.median(b for _,b in r), ", ".join("%.2f/%.2f" % x for x in r)))'

sps() { echo "scale=1; $scans / $1" | bc; }
echo "engine alone (onnxruntime, maps in memory): $(sps "$eb") scans/s"
echo "python peer (numpy + kitti2pgm + onnxruntime): $(sps "$pb") scans/s (wall, process start included)"
echo "kitti2pgm infer: $(sps "$ob") scans/s  at $(echo "scale=2; $ob / $eb" | bc)x the engine's time, $(echo "scale=2; $pb / $ob" | bc)x the peer's speed"
"$bin" --threads "$threads" --no-progress infer --model "$work/model.onnx" "$work/raw" --out "$work/ours" \
  --model-threads "$threads" --json | python3 -c 'import json,sys; s=json.load(sys.stdin); print("stages (s, summed over frames):", s["seconds"], "wall", round(s["wall_seconds"], 3))'
python3 - "$work/ours/labels" "$work/peer/labels" <<'PY'
import glob, os, sys
import numpy as np
ours, peer = sys.argv[1], sys.argv[2]
diff = total = 0
for f in sorted(glob.glob(os.path.join(peer, "*", "*.label"))):
    a = np.fromfile(f, "<u4"); b = np.fromfile(os.path.join(ours, os.path.relpath(f, peer)), "<u4")
    diff += int((a != b).sum()); total += len(a)
print(f"per-point classes that differ from the peer's: {diff} of {total}")
PY
