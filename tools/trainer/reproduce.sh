#!/usr/bin/env bash
# Reproduces the paper's table end to end: convert, split, stats, then for SqueezeSeg and
# PointSeg with LiDAR-only, early- and mid-fusion inputs: train, evaluate, kitti2pgm score.
# Writes OUT/table.md (this run's IoUs beside the paper's figures) and OUT/table.json.
#
#   tools/trainer/reproduce.sh RAW_ROOT OUT
#
# Environment (defaults are the paper's setting): STEPS (50000), BATCH (32 a step, split over
# GPUS processes), GPUS (the CUDA devices present, else 1 CPU process), WIDTH (1.0),
# VAL_DRIVES (SqueezeSeg's; a seeded 30% drive split where none of them is in RAW_ROOT), KITTI2PGM (the binary; else target/release, built if needed),
# EXTRA (more trainer options, e.g. "--compile"), CONVERT (more convert options), EVAL (more
# evaluate options).
set -euo pipefail
raw=${1:?usage: reproduce.sh RAW_ROOT OUT}
out=${2:?usage: reproduce.sh RAW_ROOT OUT}
here=$(cd "$(dirname "$0")/../.." && pwd)
steps=${STEPS:-50000}
batch=${BATCH:-32}
width=${WIDTH:-1.0}
gpus=${GPUS:-$(python3 -c 'import torch; print(max(torch.cuda.device_count(), 1))')}
if [ -z "${KITTI2PGM:-}" ]; then
  if command -v kitti2pgm >/dev/null 2>&1; then
    KITTI2PGM=kitti2pgm
  else
    (cd "$here" && cargo build --release --quiet)
    KITTI2PGM=$here/target/release/kitti2pgm
  fi
fi
split=()
if [ -n "${VAL_DRIVES:-}" ]; then
  split=(--val-drives "$VAL_DRIVES")
else
  # SqueezeSeg's val drives, unless none of them is here (a subset of KITTI raw, the fixtures):
  # then a seeded, drive-disjoint 30% split, so that there is something to evaluate on.
  val=$("$KITTI2PGM" --no-progress split "$raw" --out "$(mktemp -d)" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["val"])')
  if [ "$val" = 0 ]; then
    echo "reproduce.sh: none of SqueezeSeg's val drives is in $raw: a seeded 30% drive split instead" >&2
    split=(--random-val 0.3 --seed 0)
  fi
fi
mkdir -p "$out"
"$KITTI2PGM" --no-progress convert "$raw" --out "$out/data" --rgb --format npy,mcap "${split[@]}" ${CONVERT:-}
"$KITTI2PGM" --no-progress split "$raw" --out "$out/data" "${split[@]}"
"$KITTI2PGM" --no-progress stats "$out/data" --imageset "$out/data/ImageSet" --json > "$out/stats.json"
per_gpu=$((batch / gpus))
# One process: the trainer itself (torchrun's launcher would start a second Python and torch,
# and a rendezvous, for nothing); several: torchrun, one process a GPU.
launch=(python3)
[ "$gpus" -gt 1 ] && launch=(torchrun --standalone --nproc_per_node "$gpus")
runs=()
todo=()
for m in squeezeseg pointseg; do
  for i in xyzdi xyzdirgb xyzdi+dirgb; do
    run=$out/runs/$m-$i
    runs+=("$run")
    if [ ! -f "$run/eval.json" ]; then
      resume=()
      [ -f "$run/checkpoint.pt" ] && resume=(--resume) # interrupted, or trained but not evaluated
      "${launch[@]}" -m kitti2pgm_train train --shards "$out/data/shards" \
        --model "$m" --input "$i" --stats "$out/stats.json" --class-weights reference --batch "$per_gpu" \
        --steps "$steps" --width-mult "$width" --out "$run" "${resume[@]}" ${EXTRA:-}
      todo+=(--run "$run")
    fi
  done
done
# The new runs evaluated in one process: one start of Python and torch instead of one a run.
if [ ${#todo[@]} -gt 0 ]; then
  python3 -m kitti2pgm_train evaluate "${todo[@]}" --shards "$out/data/shards" --json ${EVAL:-} > /dev/null
fi
for run in "${runs[@]}"; do
  "$KITTI2PGM" --no-progress score --gt "$out/data" --pred "$run/predictions" \
    --imageset "$out/data/ImageSet/val.txt" --json > "$run/score.json"
done
python3 - "$out" <<'PY'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
paper = {("squeezeseg", "xyzdi"): 33.7, ("squeezeseg", "xyzdirgb"): 36.7, ("squeezeseg", "xyzdi+dirgb"): 37.4,
         ("pointseg", "xyzdi"): 34.8, ("pointseg", "xyzdirgb"): 37.8, ("pointseg", "xyzdi+dirgb"): 37.6}
rows, table = [], ["| model | input | car | pedestrian | cyclist | mIoU | paper mIoU |", "|---|---|---|---|---|---|---|"]
f = lambda v: "-" if v is None else f"{100 * v:.1f}"
for (m, i), ref in paper.items():
    s = json.loads((out / "runs" / f"{m}-{i}" / "score.json").read_text())
    iou = {c: s["classes"][c]["iou"] for c in ("car", "pedestrian", "cyclist")}
    rows.append({"model": m, "input": i, **iou, "miou": s["miou"], "paper_miou": ref})
    table.append(f"| {m} | {i} | {f(iou['car'])} | {f(iou['pedestrian'])} | {f(iou['cyclist'])} | {f(s['miou'])} | {ref} |")
(out / "table.json").write_text(json.dumps(rows, indent=2))
(out / "table.md").write_text("\n".join(table) + "\n")
print("\n".join(table))
PY
