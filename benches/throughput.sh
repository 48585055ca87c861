#!/usr/bin/env bash
# Throughput of `rectify` on the 1 GiB film scan turned 90 degrees, in
# interleaved rounds on one machine: the lean path against `cat`, `--nodata
# 0` against the default mask, the defaults against the lean path, and
# (given an earlier build) the lean path against that build's.
#
#   bash benches/throughput.sh [WORKDIR] [EARLIER_BINARY]
#
# WORKDIR (default: a new folder under /tmp) needs ~4 GB free. RUNS
# (default 5) rounds. Each round times, one after the other:
#   cat       cat scan.tif > copy.tif
#   lean      rectify --compress none --overviews none --no-sync (mask)
#   nodata0   the same with --nodata 0
#   defaults  rectify at its defaults (deflate with the predictor,
#             overviews, mask, statistics, synced rename)
#   earlier   EARLIER_BINARY's lean run, where one is given (a build that
#             knows no --overviews runs without it)
# Before each command the previous outputs are deleted and the disk synced
# (not timed). Prints each run's wall and CPU seconds and peak resident
# memory (/usr/bin/time), then medians and the medians of the ratios taken
# round by round (the machine's speed drifts).
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-$(mktemp -d /tmp/gcm-throughput.XXXX)}
earlier=${2:-}
runs=${RUNS:-5}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
scene="$work/scene"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --size 18918x18918 --relief hilly --camera film --kappa 90 --seed 5 --quiet
fi
cat "$scene/scan.tif" >/dev/null # in the page cache, as for every run after
args=(rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif" --memory 128M --quiet)
lean=(--compress none --overviews none --no-sync)
earlier_lean=(--compress none --no-sync)
if [ -n "$earlier" ] && "$earlier" rectify --help | grep -q -- --overviews; then
  earlier_lean=("${lean[@]}")
fi
log="$work/times.txt"
: >"$log"
timed() { # name, command...
  local name=$1
  shift
  rm -f "$work"/o_*.tif "$work/copy.tif"
  sync
  /usr/bin/time -f "$name %e %U %S %M" -a -o "$log" "$@"
}
for r in $(seq "$runs"); do
  timed cat sh -c "cat '$scene/scan.tif' > '$work/copy.tif'"
  timed lean "$bin" "${args[@]}" "${lean[@]}" -o "$work/o_lean.tif"
  timed nodata0 "$bin" "${args[@]}" "${lean[@]}" --nodata 0 -o "$work/o_nodata.tif"
  timed defaults "$bin" "${args[@]}" -o "$work/o_defaults.tif"
  if [ -n "$earlier" ]; then
    timed earlier "$earlier" "${args[@]}" "${earlier_lean[@]}" -o "$work/o_earlier.tif"
  fi
done
rm -f "$work"/o_*.tif "$work/copy.tif"
cat "$log"
python3 - "$log" <<'PY'
import sys, statistics as st
runs = {}
for line in open(sys.argv[1]):
    name, wall, user, sys_, rss = line.split()
    runs.setdefault(name, []).append((float(wall), float(user) + float(sys_), int(rss) / 1024))
for name, v in runs.items():
    print(f"{name:9s} wall {st.median(w for w, _, _ in v):.2f} s  cpu {st.median(c for _, c, _ in v):.2f} s  peak {st.median(m for _, _, m in v):.0f} MiB")
def ratio(a, b, k):
    return st.median(x[k] / y[k] for x, y in zip(runs[a], runs[b]))
for a, b in [("lean", "cat"), ("nodata0", "lean"), ("defaults", "lean"), ("lean", "earlier")]:
    if a in runs and b in runs:
        cpu = "" if b == "cat" else f"cpu {ratio(a, b, 1):.3f}  "
        print(f"{a:8s} / {b:8s} {cpu}wall {ratio(a, b, 0):.3f}")
PY
