#!/usr/bin/env bash
# Another sensor's PCD folder against the numpy peer users write today (benches/pcd_numpy_peer.py:
# elevation bins from fov_up / fov_down), same scans, same machine, same run, same cores.
#
#   benches/compare_pcd.sh [SENSOR] [COPIES] [WORKERS]
#
# SENSOR: vlp16 (the real VLP-16 scan, 14,831 points, 16 rows, +15 / -15 degrees) or pandar40p
# (the real Pandar40P scan, 56,762 points, 40 rows, +15 / -25 degrees), from fixtures/lidars,
# repeated COPIES times (default 300) as sequences/00/velodyne/<frame6>.pcd symbolic links. Both
# write an H x 1024 x 6 float32 .npy per scan; kitti2pgm with the sensor's beams as rows
# (--sensor, --no-point-labels). The floor reads every .pcd once (cat, page cache warm). Three
# runs each, alternating; the best run counts.
set -euo pipefail
. "$(dirname "$0")/common.sh"
sensor=${1:-vlp16}
copies=${2:-300}
workers=${3:-$(nproc)}
case "$sensor" in
  vlp16) scan=$here/fixtures/lidars/velodyne/vlp16_1673400472138016708.pcd; rows=16; up=15; down=-15 ;;
  pandar40p) scan=$here/fixtures/lidars/hesai/Pandar40P_1673400149711850138.pcd; rows=40; up=15; down=-25 ;;
  *) echo "SENSOR: vlp16 or pandar40p" >&2; exit 2 ;;
esac
seq=$work/pcd/sequences/00/velodyne
mkdir -p "$seq"
for i in $(seq 0 $((copies - 1))); do ln -s "$scan" "$seq/$(printf %06d "$i").pcd"; done
build
echo "sensor: $sensor, scans: $copies, workers/threads: $workers, cpu: $(nproc) cores"
# Wall and CPU (user + system, children included) seconds of one command: "WALL CPU".
t() { local TIMEFORMAT='%R %U %S' r; r=$( { time "$@" >/dev/null 2>&1; } 2>&1 ); echo "$r" | awk '{print $1, $2 + $3}'; }
min() { echo "if ($1 < $2) $1 else $2" | bc; }
floor() { cat "$seq"/*.pcd > /dev/null; }
pb=999999; ob=999999; fb=999999; pc=999999; oc=999999
for rep in 1 2 3; do
  rm -rf "$work/peer" "$work/ours"
  read -r p pcpu < <(t python3 "$here/benches/pcd_numpy_peer.py" "$work/pcd" "$work/peer" --rows "$rows" --fov-up "$up" --fov-down "$down" --workers "$workers")
  read -r o ocpu < <(t "$bin" --threads "$workers" --no-progress convert "$work/pcd" --out "$work/ours" --sensor "$sensor" --all-frames --cols 1024 --no-point-labels)
  read -r f _ < <(t floor)
  pb=$(min "$p" "$pb"); ob=$(min "$o" "$ob"); fb=$(min "$f" "$fb"); pc=$(min "$pcpu" "$pc"); oc=$(min "$ocpu" "$oc")
  echo "run $rep: peer ${p}s (cpu ${pcpu}s)  kitti2pgm ${o}s (cpu ${ocpu}s)  floor ${f}s"
done
sps() { echo "scale=1; $copies / $1" | bc; }
echo "peer (numpy, elevation bins, $workers workers): $(sps "$pb") scans/s (wall, process start included)"
echo "kitti2pgm (beam rows, same layout):          $(sps "$ob") scans/s  ratio $(echo "scale=2; $pb / $ob" | bc)x"
echo "CPU seconds (best): peer $pc, kitti2pgm $oc  ratio $(echo "scale=2; $pc / $oc" | bc)x"
echo "floor (read the .pcd files, 1 process):      $(sps "$fb") scans/s"
