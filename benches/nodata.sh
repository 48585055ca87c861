#!/usr/bin/env bash
# `rectify --nodata 0` against the same run with the default internal mask,
# on the 1 GiB film scan turned 90 degrees (the lean path: no compression,
# no overviews, no sync), in interleaved rounds on one machine.
#
#   bash benches/nodata.sh [WORKDIR] [OTHER_BINARY]
#
# WORKDIR (default: a new folder under /tmp) needs ~3 GB free. With
# OTHER_BINARY (an earlier build), each round also times its `--nodata 0`
# run, for the ratio against it. RUNS (default 5) rounds. Prints each run's
# wall and CPU seconds and peak resident memory from /usr/bin/time, then the
# medians and the medians of the ratios taken round by round (the machine's
# speed drifts).
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-$(mktemp -d /tmp/gcm-nodata-bench.XXXX)}
other=${2:-}
runs=${RUNS:-5}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
scene="$work/scene"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --size 18918x18918 --relief hilly --camera film --kappa 90 --seed 5 --quiet
fi
args=(rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif"
  --compress none --memory 128M --no-sync --overviews none --quiet)
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
  timed mask "$bin" "${args[@]}" -o "$work/o_mask.tif"
  timed nodata0 "$bin" "${args[@]}" --nodata 0 -o "$work/o_nodata.tif"
  if [ -n "$other" ]; then
    timed before "$other" "${args[@]}" --nodata 0 -o "$work/o_before.tif"
  fi
done
cat "$log"
python3 - "$log" <<'PY'
import sys, statistics as st
runs = {}
for line in open(sys.argv[1]):
    name, wall, user, sys_, rss = line.split()
    runs.setdefault(name, []).append((float(wall), float(user) + float(sys_), int(rss) / 1024))
for name, v in runs.items():
    print(f"{name:8s} wall {st.median(w for w, _, _ in v):.2f} s  cpu {st.median(c for _, c, _ in v):.2f} s  peak {st.median(m for _, _, m in v):.0f} MiB")
def ratio(a, b, k):
    return st.median(x[k] / y[k] for x, y in zip(runs[a], runs[b]))
print(f"nodata0 / mask    cpu {ratio('nodata0', 'mask', 1):.3f}  wall {ratio('nodata0', 'mask', 0):.3f}")
if "before" in runs:
    print(f"nodata0 / before  cpu {ratio('nodata0', 'before', 1):.3f}  wall {ratio('nodata0', 'before', 0):.3f}")
PY
