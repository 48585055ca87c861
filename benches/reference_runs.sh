#!/bin/bash
# The reference runs of a restructuring: the same commands with two builds,
# every output compared byte for byte (and what each said on stderr).
#
#   bash benches/reference_runs.sh NEW_BINARY OLD_BINARY WORKDIR
#
# Scenes are made once in WORKDIR by the new build's `synth` (deterministic
# from their seeds): a film scan, a digital frame, a 3-band RPC scene, a
# film scan turned 90 degrees (bands of tile columns), 2x2 and 8x8 blocks,
# random points, an RPC stereo pair. Prints "NAME identical" or
# "NAME DIFFERENT" a run; exits 1 if any differs.
set -u
NEW=$1 OLD=$2 W=$3
mkdir -p "$W" && cd "$W" || exit 2
synth() { [ -d "$1" ] || "$NEW" synth --out "$@" --quiet; }
synth film --size 3000x3000 --relief hilly --camera film --seed 5
synth digital --size 2500x2000 --relief hilly --camera digital --seed 7
synth rpc --size 2500x2500 --relief hilly --camera rpc --off-nadir 25 --bands 3 --seed 3
synth turned --size 6000x6000 --relief hilly --camera film --kappa 90 --seed 5
synth block2 --block 2x2 --camera drone --seed 11
synth block8 --camera digital --relief urban --size 1000x1000 --dem-posting 1 --scale 8000 --block 8x8 --seed 12
synth pts --points 300000 --seed 4
synth st --stereo 0.6 --camera rpc --size 1500x1500 --seed 9
differ=0
run() { # NAME, then the command's arguments (the output is given here)
  local n=$1
  shift
  for side in new old; do
    local bin=$NEW
    [ $side = old ] && bin=$OLD
    rm -f "$n.$side.tif"
    "$bin" "$@" -o "$n.$side.tif" --quiet > /dev/null 2> "$n.$side.err" || echo "$n: $side build failed: $(head -c 300 "$n.$side.err")"
    sed -i "s/$n\.$side\.tif/OUT/g" "$n.$side.err"
  done
  if cmp -s "$n.new.tif" "$n.old.tif"; then echo "$n identical"; else echo "$n DIFFERENT"; differ=1; fi
  cmp -s "$n.new.err" "$n.old.err" || { echo "  stderr differs:"; diff "$n.old.err" "$n.new.err" | head -6; }
}
run film rectify --image film/scan.tif --camera film/camera.toml --dem film/dem.tif
run film_cog rectify --image film/scan.tif --camera film/camera.toml --dem film/dem.tif --cog
run film_nodata rectify --image film/scan.tif --camera film/camera.toml --dem film/dem.tif --nodata 0 --compress none
run digital rectify --image digital/scan.tif --camera digital/camera.toml --dem digital/dem.tif
run rpc rectify --image rpc/scan.tif --rpc rpc/scan_RPC.TXT --dem rpc/dem.tif
run rpc_window rectify --image rpc/scan.tif --rpc rpc/scan_RPC.TXT --dem rpc/dem.tif --window 1,1,2,2
run turned rectify --image turned/scan.tif --camera turned/camera.toml --dem turned/dem.tif --compress none --memory 128M
run turned_average rectify --image turned/scan.tif --camera turned/camera.toml --dem turned/dem.tif --resample average --alpha --memory 64M
run turned_one_thread rectify --image turned/scan.tif --camera turned/camera.toml --dem turned/dem.tif --nodata 0 --gsd 3 --threads 1
run block2 mosaic block2/manifest.toml
run block8 mosaic block8/manifest.toml --cog
run grid grid pts/points.las --crs EPSG:32631 --gsd 1
run grid_idw_shard grid pts/points.las --crs EPSG:32631 --gsd 1 --method idw --shard 2/3
run dem dem --left st/left.tif --right st/right.tif --left-rpc st/left_RPC.TXT --right-rpc st/right_RPC.TXT --gsd 2 --heights -50,400
exit $differ
