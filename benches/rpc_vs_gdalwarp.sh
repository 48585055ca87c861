#!/usr/bin/env bash
# Satellite benchmark: `gcm-ortho rectify` against `gdalwarp -rpc` on a
# generated 1 GiB RGB RPC scene (25° off-nadir, hilly DEM in EPSG:4326),
# same output grid (the one gcm-ortho chooses), bilinear resampling, both
# writing tiled uncompressed GeoTIFF, in one run on one machine:
#
#   * gcm-ortho at its defaults (k = 16, bilinear corrections), 2 threads;
#   * gdalwarp exact at every pixel: -et 0 -multi -wo NUM_THREADS=2 -wm 256;
#   * gdalwarp with its approximation: -et 0.125 (same flags otherwise).
#
# Then the accuracy of each against the exact model, measured on a 4000²
# scene of the same kind through coordinate images (every output pixel
# holds the scan position it sampled; see tests/rpc.rs): mean and max px.
#
#   bash benches/rpc_vs_gdalwarp.sh [WORKDIR] [SIZE]
#
# WORKDIR needs ~4 GB free; SIZE is the scan side (18919 → 1 GiB of RGB).
# Needs gdalwarp and Debian's python3 with GDAL (python3-gdal) for the
# accuracy part. Prints each run's wall time and peak resident memory
# (/usr/bin/time -v) and the medians of RUNS (default 3) runs.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-rpc-bench}
size=${2:-18919}
runs=${RUNS:-3}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
scene="$work/rpc-$size"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --camera rpc --off-nadir 25 --relief hilly --size "${size}x${size}" --bands 3 --quiet
fi
measure() { # label, command...
  local label=$1; shift
  local t
  t=$( { /usr/bin/time -v "$@" >/dev/null; } 2>&1 >/dev/null | grep -E "Elapsed|Maximum resident" )
  echo "$label $(echo "$t" | awk -F': ' '/Elapsed/ {split($2,a,":"); s=a[1]*60+a[2]; if (length(a)==3) s=a[1]*3600+a[2]*60+a[3]; printf "wall_s=%.2f ", s} /Maximum resident/ {printf "peak_MiB=%.0f", $2/1024}')"
}
ours=("$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif" --compress none
  --memory 128M --threads 2 --quiet --json "$work/ours.tif.json" -o "$work/ours.tif")
grid_of() { # a GeoTIFF → "minx miny maxx maxy res"
  gdalinfo -json "$1" | python3 -c 'import json,sys; d=json.load(sys.stdin); g=d["geoTransform"]; w,h=d["size"]; print(g[0], g[3]+g[5]*h, g[0]+g[1]*w, g[3], g[1])'
}
"${ours[@]}"
read -r -a grid <<< "$(grid_of "$work/ours.tif")"
gdal=(gdalwarp -q -overwrite -rpc -to "RPC_DEM=$scene/dem.tif" -r bilinear -t_srs EPSG:32631
  -te "${grid[0]}" "${grid[1]}" "${grid[2]}" "${grid[3]}" -tr "${grid[4]}" "${grid[4]}"
  -multi -wo NUM_THREADS=2 -wm 256 -co TILED=YES -co BIGTIFF=IF_SAFER "$scene/scan.tif" "$work/gdal.tif")
for i in $(seq "$runs"); do
  measure "gcm-ortho        " "${ours[@]}"
  measure "gdalwarp -et 0   " "${gdal[@]}" -et 0
  measure "gdalwarp -et .125" "${gdal[@]}" -et 0.125
done | tee "$work/runs.txt"
echo "medians over $runs runs:"
for label in "gcm-ortho" "gdalwarp -et 0 " "gdalwarp -et .125"; do
  grep "^$label" "$work/runs.txt" | sed 's/.*wall_s=\([0-9.]*\) peak_MiB=\([0-9]*\)/\1 \2/' | sort -n | awk -v l="$label" '{w[NR]=$1; m[NR]=$2} END {printf "%-18s wall %7.2f s  peak %5d MiB\n", l, w[int((NR+1)/2)], m[int((NR+1)/2)]}'
done
python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); a=r["accuracy_estimate"]; print("gcm-ortho GCM vs exact model on the 1 GiB run (sampled):", a)' "$work/ours.tif.json"

# Accuracy on a 4000² scene, through coordinate images.
acc="$work/rpc-4000"
if [ ! -f "$acc/scan.tif" ]; then
  "$bin" synth --out "$acc" --camera rpc --off-nadir 25 --relief hilly --size 4000x4000 --bands 1 --quiet
fi
/usr/bin/python3 - "$acc" <<'EOF'
import sys, shutil
import numpy as np
from osgeo import gdal
d = sys.argv[1]
n = 4000
c = gdal.GetDriverByName("GTiff").Create(f"{d}/coords.tif", n, n, 2, gdal.GDT_Float32, ["TILED=YES"])
x = np.arange(n, dtype=np.float32) + 0.5
c.GetRasterBand(1).WriteArray(np.tile(x, (n, 1)))
c.GetRasterBand(2).WriteArray(np.tile(x[:, None], (1, n)))
c = None
shutil.copy(f"{d}/scan_RPC.TXT", f"{d}/coords_RPC.TXT")
EOF
"$bin" rectify --image "$acc/coords.tif" --camera "$acc/camera.toml" --dem "$acc/dem.tif" --nodata -1 --compress none --quiet -o "$acc/ours.tif"
read -r -a agrid <<< "$(grid_of "$acc/ours.tif")"
for et in 0 0.125; do
  gdalwarp -q -overwrite -rpc -to "RPC_DEM=$acc/dem.tif" -et "$et" -r bilinear -t_srs EPSG:32631 -dstnodata -1 \
    -te "${agrid[0]}" "${agrid[1]}" "${agrid[2]}" "${agrid[3]}" -tr "${agrid[4]}" "${agrid[4]}" "$acc/coords.tif" "$acc/gdal_$et.tif"
done
/usr/bin/python3 - "$acc" <<'EOF'
import sys
import numpy as np
from osgeo import gdal
d = sys.argv[1]
exact = gdal.Open(f"{d}/gdal_0.tif").ReadAsArray()
def vs_exact(name):
    a = gdal.Open(f"{d}/{name}").ReadAsArray()
    ok = np.all((a > 1.5) & (a < 3998.5) & (exact > 1.5) & (exact < 3998.5), axis=0)
    e = np.hypot(*(a - exact)[:, ok].astype(np.float64))
    print(f"{name:14s} vs gdalwarp -et 0: mean {e.mean():.4f} px, max {e.max():.4f} px over {ok.sum()} px")
vs_exact("ours.tif")
vs_exact("gdal_0.125.tif")
EOF
