#!/usr/bin/env bash
# The codec and level table: `gcm-ortho rectify` of the 1 GiB film scene
# (the defaults otherwise: overviews, internal mask, the error bound) with
# each compression and level, timed as whole processes, the rounds taken
# in turn; prints wall and CPU seconds, peak resident memory and the
# file's size for each run.
#
#   bash benches/codecs.sh [WORKDIR] [SIZE]
#
# WORKDIR (default: a folder under /tmp) needs ~4 GB free; SIZE is the
# scan side in pixels (18918 → 1 GiB of RGB). RUNS (default 3) rounds;
# CODECS (';'-separated, e.g. "deflate 1;jpeg 85") to time only some.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-/tmp/gcm-ortho-bench}
size=${2:-18918}
runs=${RUNS:-3}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
mkdir -p "$work"
scene="$work/scene-$size-k0"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --size "${size}x${size}" --bands 3 --relief hilly --quiet
fi
cat "$scene/scan.tif" > /dev/null
IFS=';' read -r -a codecs <<< "${CODECS:-none;deflate 0;deflate 1;deflate 2;deflate 4;deflate 6;deflate 9;zstd 1;zstd 3;zstd 9;lzw;jpeg 75;jpeg 85;jpeg 95}"
for i in $(seq "$runs"); do
  for codec in "${codecs[@]}"; do
    set -- $codec
    level=()
    [ $# -gt 1 ] && level=(--level "$2")
    [ $# -gt 1 ] && [ "$1" = jpeg ] && level=(--quality "$2")
    rm -f "$work/ortho.tif"
    sync
    t=$( { /usr/bin/time -f "wall_s=%e cpu_s=%U+%S peak_KiB=%M" "$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" \
      --dem "$scene/dem.tif" --quiet --no-sync --compress "$1" "${level[@]}" -o "$work/ortho.tif"; } 2>&1 )
    echo "round=$i $1 ${2:-} $t bytes=$(stat -c %s "$work/ortho.tif")"
  done
done
