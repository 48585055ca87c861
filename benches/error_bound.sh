#!/usr/bin/env bash
# The error bound's cost: `gcm-ortho rectify`
# at the defaults against the exact model at every pixel (`--sparsity 1`)
# on the drone frame over buildings, and against no bound (`--max-error
# none`) on the 1 GiB film scene; whole processes, each pair in turn, the
# output removed and the disk synced before each run (replacing a file
# makes ext4 write the new one out at the rename). Prints each run, then
# the medians and the median of the pairs' ratios: the drone frame's
# `--sparsity 1` over the default (the default's speed-up), the film
# scene's default over no bound (the bound's cost).
#
#   bash benches/error_bound.sh [WORKDIR]
#
# WORKDIR (default: a folder under /tmp) needs ~2 GB free. RUNS (default
# 7) rounds; SCENES ("drone film" by default) to time only one.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-bench}
runs=${RUNS:-7}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
drone="$work/drone-urban-4000"
[ -f "$drone/scan.tif" ] || "$bin" synth --out "$drone" --camera drone --relief urban --size 4000x3000 --dem-posting 0.8 --scale 19000 --off-nadir 25 --kappa 17 --quiet
film="$work/scene-18918-k0"
[ -f "$film/scan.tif" ] || "$bin" synth --out "$film" --size 18918x18918 --bands 3 --relief hilly --quiet
log="$work/error_bound.log"
: > "$log"
run() { # scene label args...
  local scene=$1 label=$2
  shift 2
  rm -f "$work/ortho.tif"
  sync
  t=$( { /usr/bin/time -f "%e %U %S %M" "$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif" \
    --quiet --no-sync "$@" -o "$work/ortho.tif"; } 2>&1 )
  echo "$i $label $t" | tee -a "$log"
}
for scene in ${SCENES:-drone film}; do
  case $scene in
    drone) cat "$drone/scan.tif" > /dev/null ;;
    film) cat "$film/scan.tif" > /dev/null ;;
  esac
  for i in $(seq "$runs"); do
    case $scene in
      drone)
        run "$drone" drone-default --compress none --overviews none
        run "$drone" drone-sparsity-1 --compress none --overviews none --sparsity 1 --memory 2G ;;
      film)
        run "$film" film-no-bound --max-error none
        run "$film" film-default ;;
    esac
  done
done
rm -f "$work/ortho.tif"
# round label wall user sys peak_KiB; each pair's ratio: its second run over its first
awk '
  { wall[$2, $1] = $3; peak[$2, $1] = $6; if (!($2 in seen)) { seen[$2] = 1; order[++k] = $2 } n = $1 > n ? $1 : n }
  function median(a, key,   i, m, v, t, x) {
    m = 0
    for (i = 1; i <= n; i++) if ((key, i) in a) v[++m] = a[key, i]
    for (i = 1; i <= m; i++) for (t = i + 1; t <= m; t++) if (v[t] < v[i]) { x = v[i]; v[i] = v[t]; v[t] = x }
    return m % 2 ? v[(m + 1) / 2] : (v[m / 2] + v[m / 2 + 1]) / 2
  }
  END {
    for (j = 1; j <= k; j++) printf "%-18s wall %6.2f s  peak %5.0f MiB\n", order[j], median(wall, order[j]), median(peak, order[j]) / 1024
    for (j = 1; j < k; j += 2) {
      a = order[j]; b = order[j + 1]
      for (i = 1; i <= n; i++) r[i] = wall[b, i] / wall[a, i]
      m = 0; for (i = 1; i <= n; i++) { rr["x", i] = r[i] }
      printf "%s / %s: %.2fx (median of %d pairs)\n", b, a, median(rr, "x"), n
    }
  }' "$log"
