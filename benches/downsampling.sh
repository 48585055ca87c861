#!/usr/bin/env bash
# Whole-run benchmark of downsampling with the area kernel on the 1 GiB
# film scan (18918 × 18918 RGB): `--resample average` at 4× and 10× the
# scan's GSD against `bilinear` at the scan's GSD (the default run), each
# as input MB/s (scan bytes over wall time) and peak memory under the
# default 128 MiB budget; also bilinear at 10× (what average replaces).
#
#   bash benches/downsampling.sh [WORKDIR]
#
# RUNS (default 3) rounds, the runs of each round interleaved. Prints each
# round, then the medians and the median round-by-round ratios to the
# full-resolution bilinear run.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${1:-$(mktemp -d /tmp/gcm-downsampling-bench.XXXX)}
RUNS=${RUNS:-3}
cargo build --release --quiet
B=$PWD/target/release/gcm-ortho
mkdir -p "$WORK"
cd "$WORK"
[ -f film/scan.tif ] || "$B" synth --out film --size 18918x18918 --quiet
rm -f out.tif
"$B" rectify --image film/scan.tif --camera film/camera.toml --dem film/dem.tif --no-sync -o out.tif --json run.json --quiet --overviews none
GSD=$(python3 -c 'import json; print(json.load(open("run.json"))["grid"]["gsd"])')
MB=$(python3 -c "import os; print(os.path.getsize('film/scan.tif') / 1e6)")
runs=("bilinear 1" "average 4" "average 10" "bilinear 10")
: > rounds.txt
for r in $(seq "$RUNS"); do
  line=""
  for run in "${runs[@]}"; do
    set -- $run
    g=$(python3 -c "print($GSD * $2)")
    rm -f out.tif; sync
    /usr/bin/time -f "%e %M" -o run.time "$B" rectify --image film/scan.tif --camera film/camera.toml --dem film/dem.tif \
      --gsd "$g" --resample "$1" --overviews none --no-sync -o out.tif --quiet 2> /dev/null
    line="$line $(awk '{printf "%.3f %.0f", $1, $2 / 1024}' run.time)"
  done
  echo "$line" >> rounds.txt
done
echo "wall s, peak MiB for: ${runs[*]}"
cat rounds.txt
MB=$MB python3 - <<'PY'
import os, statistics as st
names = ["bilinear at the scan's GSD", "average at 4x", "average at 10x", "bilinear at 10x"]
rows = [list(map(float, l.split())) for l in open("rounds.txt")]
mb = float(os.environ["MB"])
for k, name in enumerate(names):
    t = [r[2 * k] for r in rows]
    ratio = st.median(r[2 * k] / r[0] for r in rows)
    print(f"{name}: {st.median(t):.2f} s, {mb / st.median(t):.0f} MB/s in, peak {st.median(r[2 * k + 1] for r in rows):.0f} MiB, time {ratio:.2f}x the first")
PY
