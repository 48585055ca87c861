#!/usr/bin/env bash
# A JPEG 2000 scene larger than the memory budget: a 20000² 12-bit
# satellite scan (lossy, 1024² codestream tiles, 6 resolutions, made by
# GDAL's OpenJPEG driver) rectified within --memory 128M, against the same
# pixels as an uncompressed tiled TIFF; the difference is the decoding's
# share. Prints wall and CPU seconds and peak resident memory of each run.
#
#   bash benches/jpeg2000.sh [WORKDIR]      # RUNS (default 3) rounds
#
# Needs gdal_translate and ~2 GB free in WORKDIR.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-jp2}
runs=${RUNS:-3}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
cd "$work"
if [ ! -f scan12.jp2 ]; then
  "$bin" synth --out s --size 20000x20000 --bands 1 --bits 16 --camera rpc --quiet
  gdal_translate -q -scale 0 65535 0 4095 -ot UInt16 -of JP2OpenJPEG -co NBITS=12 -co QUALITY=25 \
    -co BLOCKXSIZE=1024 -co BLOCKYSIZE=1024 -co RESOLUTIONS=6 s/scan.tif scan12.jp2
  gdal_translate -q -co NBITS=16 -co TILED=YES -co BLOCKXSIZE=1024 -co BLOCKYSIZE=1024 scan12.jp2 ref.tif
  rm s/scan.tif
fi
cat ref.tif scan12.jp2 > /dev/null
for i in $(seq "$runs"); do
  for f in ref.tif scan12.jp2; do
    rm -f o.tif
    sync
    t=$( { /usr/bin/time -f "wall_s=%e cpu_s=%U+%S peak_KiB=%M" "$bin" rectify --image "$f" --camera s/camera.toml \
      --dem s/dem.tif --memory 128M --quiet --no-sync -o o.tif; } 2>&1 )
    echo "round=$i $f $t"
  done
done
