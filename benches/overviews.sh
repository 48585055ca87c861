#!/usr/bin/env bash
# The overviews' cost: `gcm-ortho rectify` of the 1 GiB film scene without
# overviews, with them (the default) and as a COG, in turn, each round;
# whole processes, the output removed and the disk synced before each run
# (replacing a file makes ext4 write the new one out at the rename, which
# would time the disk, not the run). Prints each run, then the medians and
# the median of the pairs' ratios to the run without overviews.
#
#   bash benches/overviews.sh [WORKDIR] [SIZE]
#
# WORKDIR (default: a folder under /tmp) needs ~2.5 GB free; SIZE is the
# scan side in pixels (18918 → 1 GiB of RGB). RUNS (default 7) rounds.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-bench}
size=${2:-18918}
runs=${RUNS:-7}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
scene="$work/scene-$size-k0"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --size "${size}x${size}" --bands 3 --relief hilly --quiet
fi
cat "$scene/scan.tif" > /dev/null
log="$work/overviews.log"
: > "$log"
for i in $(seq "$runs"); do
  for kind in none default cog; do
    case $kind in
      none) extra=(--overviews none) ;;
      default) extra=() ;;
      cog) extra=(--cog) ;;
    esac
    rm -f "$work/ortho.tif"
    sync
    t=$( { /usr/bin/time -f "%e %U %S %M" "$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" \
      --dem "$scene/dem.tif" --quiet --no-sync "${extra[@]}" -o "$work/ortho.tif"; } 2>&1 )
    echo "$i $kind $t $(stat -c %s "$work/ortho.tif")" | tee -a "$log"
  done
done
rm -f "$work/ortho.tif"
# round kind wall user sys peak_KiB bytes
awk '
  { wall[$2, $1] = $3; cpu[$2, $1] = $4 + $5; peak[$2, $1] = $6; bytes[$2] = $7; n = $1 > n ? $1 : n }
  function median(a, k,   i, m, v, t) {
    m = 0
    for (i = 1; i <= n; i++) v[++m] = a[k, i]
    for (i = 1; i <= m; i++) for (t = i + 1; t <= m; t++) if (v[t] < v[i]) { x = v[i]; v[i] = v[t]; v[t] = x }
    return m % 2 ? v[(m + 1) / 2] : (v[m / 2] + v[m / 2 + 1]) / 2
  }
  END {
    printf "%-8s %7s %7s %9s %6s %10s %12s %10s\n", "output", "wall_s", "cpu_s", "peak_MiB", "MB", "wall/none", "(pairs)", "cpu/none"
    split("none default cog", kinds, " ")
    for (j = 1; j <= 3; j++) {
      k = kinds[j]
      lo = 1e9; hi = 0
      for (i = 1; i <= n; i++) {
        rw[k, i] = wall[k, i] / wall["none", i]; rc[k, i] = cpu[k, i] / cpu["none", i]
        lo = rw[k, i] < lo ? rw[k, i] : lo; hi = rw[k, i] > hi ? rw[k, i] : hi
      }
      printf "%-8s %7.2f %7.2f %9.0f %6.0f %10.3f  %5.2f-%5.2f %10.3f\n", k, median(wall, k), median(cpu, k), median(peak, k) / 1024, bytes[k] / 1e6, median(rw, k), lo, hi, median(rc, k)
    }
  }' "$log"
