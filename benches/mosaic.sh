#!/usr/bin/env bash
# Whole-run benchmark of `gcm-ortho mosaic` on a generated block over a town
# (digital frames, 60 % forward / 30 % side overlap, urban DSM), against
# `rectify` of one of its frames, in one run on one machine.
#
#   bash benches/mosaic.sh [WORKDIR] [SIZE] [BLOCK]
#
# SIZE is each frame's WxH (default 3000x2000), BLOCK the frames COLSxROWS
# (default 4x4). RUNS (default 3) rounds. Prints, per round, the mosaic's
# wall time, its phases (plan, balance, seams, render, from its report),
# its peak memory, and the frame's; then the medians of the output
# throughput (Mpx/s) and of its ratio mosaic : rectify taken round by round,
# of the whole run and of the render alone (the issue's target).
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${1:-$(mktemp -d /tmp/gcm-mosaic-bench.XXXX)}
SIZE=${2:-3000x2000}
BLOCK=${3:-4x4}
RUNS=${RUNS:-3}
cargo build --release --quiet
B=$PWD/target/release/gcm-ortho
[ -f "$WORK/manifest.toml" ] || "$B" synth --out "$WORK" --camera digital --relief urban --size "$SIZE" --dem-posting 1 --scale 8000 --block "$BLOCK" --quiet
cd "$WORK"
for r in $(seq "$RUNS"); do
  rm -f mosaic.tif one.tif; sync
  "$B" mosaic manifest.toml -o mosaic.tif --json mosaic.json --quiet
  rm -f mosaic.tif; sync
  "$B" rectify --image scans/001.tif --camera scans/001.toml --dem dem.tif -o one.tif --json one.json --quiet
  python3 - <<'PY' >> rounds.txt
import json
m = json.load(open("mosaic.json")); o = json.load(open("one.json"))
mt = m["width"] * m["height"] / 1e6 / m["wall_seconds"]
ot = o["output_mpx_per_s"]
s = m["seconds"]
rt = m["width"] * m["height"] / 1e6 / s["render"]
print(f'{m["wall_seconds"]:.2f} {s["plan"]:.2f} {s["balance"]:.2f} {s["seams"]:.2f} {s["render"]:.2f} {m["peak_rss_mib"]:.0f} {mt:.1f} {o["wall_seconds"]:.2f} {o["peak_rss_mib"]:.0f} {ot:.1f} {mt/ot:.3f} {rt:.1f} {rt/ot:.3f}')
PY
done
echo "wall plan balance seams render peakMiB mosaicMpx/s | one_wall one_peakMiB oneMpx/s ratio | renderMpx/s render_ratio"
tail -n "$RUNS" rounds.txt
tail -n "$RUNS" rounds.txt | python3 -c '
import sys, statistics as st
rows = [list(map(float, l.split())) for l in sys.stdin]
med = lambda k: st.median(r[k] for r in rows)
print(f"median: mosaic {med(0):.2f} s (plan {med(1):.2f}, balance {med(2):.2f}, seams {med(3):.2f}, render {med(4):.2f}), peak {med(5):.0f} MiB, {med(6):.1f} Mpx/s; rectify one frame {med(9):.1f} Mpx/s; ratio {med(10):.3f}; render {med(11):.1f} Mpx/s, ratio {med(12):.3f}; planning share {st.median((r[1] + r[2] + r[3]) / r[0] for r in rows):.3f}")'
