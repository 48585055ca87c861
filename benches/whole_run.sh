#!/usr/bin/env bash
# Whole-run benchmark of `gcm-ortho rectify` on a generated 1 GiB RGB film
# scan (hilly DEM, k = 16, bilinear corrections, bilinear resampling,
# uncompressed output), next to a plain `cat` of the same file, in one run
# on one machine.
#
#   bash benches/whole_run.sh [WORKDIR] [SIZE] [KAPPA]
#
# WORKDIR (default: a folder under /tmp) needs ~4 GB free. SIZE is the scan
# side in pixels (18918 → 1 GiB of RGB); KAPPA the swing in degrees (0 or 90
# for the memory check with source columns). RUNS (default 5) rounds.
#
# Each round times, one after the other:
#   cat            cat scan.tif > copy.tif
#   cat+sync       the same, then `sync copy.tif` (the copy on disk)
#   rect2-sync     rectify --threads 2 (default: the output is synced
#                  before it is renamed into place, like cat+sync)
#   rect2-nosync   rectify --threads 2 --no-sync (left to the kernel, like cat)
#   rect1-nosync   rectify --threads 1 --no-sync (every step one after
#                  the other, one processor busy)
#   rect1-onecore  the same pinned to one processor (`taskset -c 0`), as
#                  under a batch scheduler's one-CPU allocation: should
#                  take the time of rect1-nosync
# Before each command the previous outputs are deleted and the disk is
# synced (not timed), so no command pays for another's write-back or for
# deleting an old 1 GiB file. Prints each run's wall time (s) and peak
# resident memory (MiB) from /usr/bin/time -v, then the medians and the
# medians of the ratios taken round by round (the machine's speed drifts).
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-bench}
size=${2:-18918}
kappa=${3:-0}
runs=${RUNS:-5}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
scene="$work/scene-$size-k$kappa"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --size "${size}x${size}" --bands 3 --relief hilly --kappa "$kappa" --quiet
fi
cat "$scene/scan.tif" > /dev/null # the scan in the page cache, as for every run after
measure() { # label, command...
  local label=$1; shift
  rm -f "$work/copy.tif" "$work/ortho.tif"
  sync
  local t
  t=$( { /usr/bin/time -v "$@" >/dev/null; } 2>&1 >/dev/null | grep -E "Elapsed|Maximum resident" )
  echo "$label $(echo "$t" | awk -F': ' '/Elapsed/ {split($2,a,":"); s=a[1]*60+a[2]; if (length(a)==3) s=a[1]*3600+a[2]*60+a[3]; printf "wall_s=%.2f ", s} /Maximum resident/ {printf "peak_MiB=%.0f", $2/1024}')"
}
rect=("$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif"
  --sparsity 16 --corrections bilinear --resample bilinear --compress none --overviews none --memory 128M --quiet -o "$work/ortho.tif")
for i in $(seq "$runs"); do
  measure "round=$i cat         " sh -c "cat '$scene/scan.tif' > '$work/copy.tif'"
  measure "round=$i cat+sync    " sh -c "cat '$scene/scan.tif' > '$work/copy.tif' && sync '$work/copy.tif'"
  measure "round=$i rect2-sync  " "${rect[@]}" --threads 2
  measure "round=$i rect2-nosync" "${rect[@]}" --threads 2 --no-sync
  measure "round=$i rect1-nosync" "${rect[@]}" --threads 1 --no-sync
  measure "round=$i rect1-onecore" taskset -c 0 "${rect[@]}" --threads 1 --no-sync
done | tee "$work/runs.txt"
rm -f "$work/copy.tif" "$work/ortho.tif"
wall() { awk -v l="$1" '$2 == l' "$work/runs.txt" | sed 's/.*wall_s=\([0-9.]*\).*/\1/'; }
peak() { awk -v l="$1" '$2 == l' "$work/runs.txt" | sed 's/.*peak_MiB=\([0-9]*\).*/\1/'; }
median() { sort -g | awk '{v[NR]=$1} END {if (NR%2) print v[(NR+1)/2]; else printf "%.3f\n", (v[NR/2]+v[NR/2+1])/2}'; }
echo "medians over $runs rounds:"
for label in cat cat+sync rect2-sync rect2-nosync rect1-nosync rect1-onecore; do
  printf "%-14s wall %6.2f s  peak %4.0f MiB\n" "$label" "$(wall "$label" | median)" "$(peak "$label" | median)"
done
ratio() { paste <(wall "$1") <(wall "$2") | awk '{printf "%.3f\n", $1/$2}' | median; }
echo "ratios, round by round (median):"
echo "  rect2-sync   / cat+sync       $(ratio rect2-sync cat+sync)"
echo "  rect2-nosync / cat            $(ratio rect2-nosync cat)"
echo "  rect1-nosync / rect2-nosync   $(ratio rect1-nosync rect2-nosync)"
echo "  rect1-onecore / rect2-nosync  $(ratio rect1-onecore rect2-nosync)"
