#!/usr/bin/env bash
# A panoramic scan against a frame scan of the same size (about 1 GiB each,
# one band), each rectified at the defaults on its own DEM, in interleaved
# rounds on one machine: the panoramic camera's cost over the frame's.
#
#   bash benches/panoramic.sh [WORKDIR] [PIXELS_ALONG_THE_SCAN]
#
# The panoramic scan is a KH-4B-like strip (`synth --camera panoramic`,
# 70° over the columns: 100,000 columns make KH-4B's own 7.4 µm pixel, 2.2
# m on the ground) of PIXELS x PIXELS/10 on hills; the frame scan a film
# scan of as many pixels (square) at 1:300,000 (2.3 m pixels) on the same
# kind of hills. Each on a DEM posted at 30 m in the orthophoto's CRS (the
# strip's EPSG:4326 relief warped to UTM by gdalwarp: a DEM in another CRS
# costs any camera more, measured as `pan4326`, its own DEM). WORKDIR (default: a new folder under /tmp) needs ~3 GB
# free. Both without overviews: the strip's orthophoto is some 450 tiles
# wide, whose overviews alone want more than 128M (the run says so). RUNS
# (default 3) rounds. Prints each run's wall and CPU seconds and
# peak resident memory from /usr/bin/time, the medians, and the medians of
# the ratios taken round by round (the machine's speed drifts).
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-$(mktemp -d /tmp/gcm-panoramic-bench.XXXX)}
cols=${2:-100000}
rows=$((cols / 10))
side=$(python3 -c "import math; print(round(math.sqrt($cols * $rows)))")
runs=${RUNS:-3}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
if [ ! -f "$work/pan/scan.tif" ]; then
  "$bin" synth --out "$work/pan" --camera panoramic --size "${cols}x${rows}" --bands 1 --relief hilly --dem-posting 30 --quiet
fi
if [ ! -f "$work/frame/scan.tif" ]; then
  "$bin" synth --out "$work/frame" --camera film --size "${side}x${side}" --bands 1 --relief hilly --dem-posting 30 --scale 300000 --quiet
fi
if [ ! -f "$work/pan/dem_utm.tif" ]; then
  gdalwarp -q -t_srs EPSG:32631 -tr 30 30 -r bilinear -dstnodata -9999 "$work/pan/dem.tif" "$work/pan/dem_utm.tif"
fi
log="$work/times.txt"
: >"$log"
timed() { # name, command...
  local name=$1
  shift
  rm -f "$work"/o_*.tif
  sync
  /usr/bin/time -f "$name %e %U %S %M" -a -o "$log" "$@"
}
for r in $(seq "$runs"); do
  # (--dem-hole nodata: the warped DEM's collar of nodata is read as holes
  # where the DEM is read a chunk at a time.)
  for s in pan frame pan4326; do
    dem=$work/${s%4326}/dem.tif
    [ "$s" = pan ] && dem=$work/pan/dem_utm.tif
    timed "$s" "$bin" rectify --image "$work/${s%4326}/scan.tif" --camera "$work/${s%4326}/camera.toml" --dem "$dem" \
      --dem-hole nodata --memory 128M --overviews none --quiet --json "$work/$s.json" -o "$work/o_$s.tif"
  done
done
cat "$log"
python3 - "$log" "$work" <<'PY'
import sys, json, statistics as st
runs = {}
for line in open(sys.argv[1]):
    name, wall, user, sys_, rss = line.split()
    runs.setdefault(name, []).append((float(wall), float(user) + float(sys_), int(rss) / 1024))
for name, v in runs.items():
    g = json.load(open(f"{sys.argv[2]}/{name}.json"))["gcm"]
    r = json.load(open(f"{sys.argv[2]}/{name}.json"))
    out = r["grid"]["width"] * r["grid"]["height"] / 1e6
    print(f"{name:6s} wall {st.median(w for w, _, _ in v):.2f} s  cpu {st.median(c for _, c, _ in v):.2f} s  peak {st.median(m for _, _, m in v):.0f} MiB  output {out:.0f} Mpx  gcm {g}")
def ratio(a, b, k):
    return st.median(x[k] / y[k] for x, y in zip(runs[a], runs[b]))
for a in ("pan", "pan4326"):
    print(f"{a} / frame  wall {ratio(a, 'frame', 0):.2f}  cpu {ratio(a, 'frame', 1):.2f}")
PY
