#!/usr/bin/env bash
# `dem` benchmark: a synthetic in-track RPC pair (synth --camera rpc
# --stereo 0.5: two pushbroom views of rolling relief, 0.5 m pixels) of
# SIZE × SIZE pixels to a 2 m DSM, against OpenCV's StereoSGBM on the same
# two scans (their rows run along the track, so the parallax is along the
# columns: OpenCV gets them transposed; 5 paths, 5 × 5 blocks, disparities
# -128..127, 2 threads) — its disparity map only, no heights, no DSM.
# Interleaved rounds; each run's wall and CPU time and peak memory
# (/usr/bin/time), medians over RUNS (default 3), round-by-round ratios,
# and each tool's share of the left image matched.
#
#   bash benches/stereo.sh [WORKDIR] [SIZE]
#
# SIZE defaults to 3000 (9 Mpx a view).
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-stereo-bench}
size=${2:-3000}
runs=${RUNS:-3}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
pair="$work/pair$size"
[ -f "$pair/right.tif" ] || "$bin" synth --out "$pair" --camera rpc --stereo 0.5 --size "${size}x${size}" --bands 1 --off-nadir 5 --quiet
measure() { # label, command...
  local label=$1; shift
  /usr/bin/time -f "$label wall_s=%e cpu_s=%U peak_MiB=%M" "$@" >"$work/out.txt" 2>"$work/time.txt" || { cat "$work/time.txt"; exit 1; }
  tail -1 "$work/time.txt" | awk '{ sub(/peak_MiB=/, "", $NF); printf "%s %s %s peak_MiB=%.0f\n", $1, $2, $3, $NF/1024 }'
}
ours=("$bin" dem --left "$pair/left.tif" --right "$pair/right.tif" --left-rpc "$pair/left_RPC.TXT" --right-rpc "$pair/right_RPC.TXT"
  -o "$work/dsm.tif" --gsd 2 --memory 256M --json "$work/dem.json" --quiet)
cat > "$work/sgbm.py" <<'PY'
import sys, time, cv2, numpy as np
from osgeo import gdal
cv2.setNumThreads(2)
l = gdal.Open(sys.argv[1]).ReadAsArray().T.copy()
r = gdal.Open(sys.argv[2]).ReadAsArray().T.copy()
sgbm = cv2.StereoSGBM_create(minDisparity=-128, numDisparities=256, blockSize=5, P1=8 * 25, P2=32 * 25,
                             disp12MaxDiff=1, uniquenessRatio=5, mode=cv2.STEREO_SGBM_MODE_SGBM)
t = time.time()
d = sgbm.compute(l, r)
valid = d > (-129 * 16)
print("matched %.4f compute_s %.2f" % (valid.mean(), time.time() - t))
PY
opencv=(/usr/bin/python3 "$work/sgbm.py" "$pair/left.tif" "$pair/right.tif")
for i in $(seq "$runs"); do
  measure "gcm-ortho" "${ours[@]}"
  measure "opencv-sgbm" "${opencv[@]}"
  echo "opencv-matched $(cat "$work/out.txt")"
done | tee "$work/runs.txt"
echo "medians over $runs rounds (two views of $size x $size):"
for label in gcm-ortho opencv-sgbm; do
  grep "^$label " "$work/runs.txt" | sed 's/.*wall_s=\([0-9.]*\) cpu_s=\([0-9.]*\) peak_MiB=\([0-9]*\)/\1 \2 \3/' | sort -n | awk -v l="$label" -v px="$size" '{w[NR]=$1; c[NR]=$2; m[NR]=$3} END {ww=w[int((NR+1)/2)]; printf "%-12s wall %7.2f s (%.2f Mpx/s of the left view)  cpu %7.2f s  peak %5d MiB\n", l, ww, px*px/ww/1e6, c[int((NR+1)/2)], m[int((NR+1)/2)]}'
done
echo "round by round, gcm-ortho wall / OpenCV wall:"
paste <(grep "^gcm-ortho " "$work/runs.txt") <(grep "^opencv-sgbm " "$work/runs.txt") | sed 's/wall_s=//g' | awk '{printf "  %.2f\n", $2/$6}'
python3 -c "import json; r = json.load(open('$work/dem.json')); print('gcm-ortho matched %.4f of the overlap, DSM made in %.2f s of the run' % (r['matched_share'], r['dsm']['seconds']))"
grep "^opencv-matched" "$work/runs.txt" | tail -1
