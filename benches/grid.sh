#!/usr/bin/env bash
# `grid` benchmark: N random points (synth --points: hills and a town of
# boxes, one a square metre) to a 1 m DEM, gcm-ortho's TIN against GDAL's
# `gdal_grid -a linear` on the same points (a CSV through an OGR VRT), both
# writing Float32 GeoTIFF over the same grid, interleaved rounds on one
# machine; then gcm-ortho alone on the points as LAS (`BIG`, default 10^8)
# at --memory 256M, with its peak resident memory.
#
#   bash benches/grid.sh [WORKDIR] [N]
#
# N defaults to 10^6 (gdal_grid holds every point and its triangulation in
# memory: 1.3 GB at 10^6). Prints each run's wall and CPU time and peak
# memory (/usr/bin/time), the medians over RUNS (default 3) rounds and the
# round-by-round ratios.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-grid-bench}
n=${2:-1000000}
big=${BIG:-100000000}
runs=${RUNS:-3}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
pts="$work/p$n"
[ -f "$pts/points.csv" ] || "$bin" synth --out "$pts" --points "$n" --csv --quiet
side=$(python3 -c "import math; print(math.floor(math.sqrt($n)))")
cat > "$pts/points.vrt" <<VRT
<OGRVRTDataSource><OGRVRTLayer name="points"><SrcDataSource>$pts/points.csv</SrcDataSource><GeometryType>wkbPoint</GeometryType><GeometryField encoding="PointFromColumns" x="x" y="y" z="z"/></OGRVRTLayer></OGRVRTDataSource>
VRT
measure() { # label, command...
  local label=$1; shift
  /usr/bin/time -f "$label wall_s=%e cpu_s=%U peak_MiB=%M" "$@" >/dev/null 2>"$work/time.txt" || { cat "$work/time.txt"; exit 1; }
  tail -1 "$work/time.txt" | awk '{ sub(/peak_MiB=/, "", $NF); printf "%s %s %s peak_MiB=%.0f\n", $1, $2, $3, $NF/1024 }'
}
ours=("$bin" grid "$pts/points.csv" -o "$work/ours.tif" --gsd 1 --crs EPSG:32631 --bounds "500000,4000000,$((500000 + side)),$((4000000 + side))" --memory 256M --quiet)
gdal=(gdal_grid -q -l points -a linear:radius=0:nodata=-9999 -txe 500000 $((500000 + side)) -tye $((4000000 + side)) 4000000 -outsize "$side" "$side" -ot Float32 -co TILED=YES "$pts/points.vrt" "$work/gdal.tif")
for i in $(seq "$runs"); do
  measure "gcm-ortho" "${ours[@]}"
  measure "gcm-ortho-noblunders" "${ours[@]}" --blunders none
  measure "gdal_grid" "${gdal[@]}"
done | tee "$work/runs.txt"
echo "medians over $runs rounds (N = $n):"
for label in gcm-ortho gcm-ortho-noblunders gdal_grid; do
  grep "^$label " "$work/runs.txt" | sed 's/.*wall_s=\([0-9.]*\) cpu_s=\([0-9.]*\) peak_MiB=\([0-9]*\)/\1 \2 \3/' | sort -n | awk -v l="$label" '{w[NR]=$1; c[NR]=$2; m[NR]=$3} END {printf "%-22s wall %7.2f s  cpu %7.2f s  peak %5d MiB\n", l, w[int((NR+1)/2)], c[int((NR+1)/2)], m[int((NR+1)/2)]}'
done
echo "round by round, gdal_grid wall / gcm-ortho wall:"
paste <(grep "^gcm-ortho " "$work/runs.txt") <(grep "^gdal_grid " "$work/runs.txt") | sed 's/wall_s=//g' | awk '{printf "  %.1f\n", $6/$2}'
if [ "$big" -gt 0 ]; then
  bigp="$work/p$big"
  [ -f "$bigp/points.las" ] || "$bin" synth --out "$bigp" --points "$big" --quiet
  measure "gcm-ortho-$big-las" "$bin" grid "$bigp/points.las" -o "$work/big.tif" --gsd 1 --crs EPSG:32631 --memory 256M --quiet
fi
