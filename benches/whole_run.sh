#!/usr/bin/env bash
# Whole-run benchmark of `gcm-ortho rectify` on a generated 1 GiB RGB film
# scan (hilly DEM, k = 16, bilinear corrections, bilinear resampling), next
# to a plain `cat` of the same file, in one run on one machine.
#
#   bash benches/whole_run.sh [WORKDIR] [SIZE] [KAPPA]
#
# WORKDIR (default: a folder under /tmp) needs ~3 GB free. SIZE is the scan
# side in pixels (18918 → 1 GiB of RGB); KAPPA the swing in degrees (0 or 90
# for the memory check with source columns). Prints one line per run with
# the wall time (s) and peak resident memory (MiB) that /usr/bin/time -v
# reports, and the medians of 3 runs.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-bench}
size=${2:-18918}
kappa=${3:-0}
runs=${RUNS:-3}
bin=target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
scene="$work/scene-$size-k$kappa"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --size "${size}x${size}" --bands 3 --relief hilly --kappa "$kappa" --quiet
fi
measure() { # label, command...
  local label=$1; shift
  local t
  t=$( { /usr/bin/time -v "$@" >/dev/null; } 2>&1 >/dev/null | grep -E "Elapsed|Maximum resident" )
  echo "$label $(echo "$t" | awk -F': ' '/Elapsed/ {split($2,a,":"); s=a[1]*60+a[2]; if (length(a)==3) s=a[1]*3600+a[2]*60+a[3]; printf "wall_s=%.2f ", s} /Maximum resident/ {printf "peak_MiB=%.0f", $2/1024}')"
}
for i in $(seq "$runs"); do
  measure "cat          " sh -c "cat '$scene/scan.tif' > '$work/copy.tif'"
  measure "rectify 2 thr" "$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif" \
    --sparsity 16 --corrections bilinear --resample bilinear --compress none --memory 128M --threads 2 --quiet -o "$work/ortho.tif"
  measure "rectify 1 thr" "$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif" \
    --sparsity 16 --corrections bilinear --resample bilinear --compress none --memory 128M --threads 1 --quiet -o "$work/ortho.tif"
done | tee "$work/runs.txt"
echo "medians over $runs runs:"
for label in "cat" "rectify 2 thr" "rectify 1 thr"; do
  grep "^$label" "$work/runs.txt" | sed 's/.*wall_s=\([0-9.]*\) peak_MiB=\([0-9]*\)/\1 \2/' | sort -n | awk -v l="$label" '{w[NR]=$1; m[NR]=$2} END {printf "%-14s wall %.2f s  peak %d MiB\n", l, w[int((NR+1)/2)], m[int((NR+1)/2)]}'
done
rm -f "$work/copy.tif"
