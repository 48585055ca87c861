#!/usr/bin/env bash
# Peak memory of `gcm-ortho mosaic` against the number of frames: blocks of
# 2000² digital frames over a town (60 % forward / 30 % side overlap, urban
# DSM), each made into one mosaic at --memory MEMORY, the blocks taken in
# turn round by round, in one run on one machine.
#
#   bash benches/mosaic_frames.sh [WORKDIR] [BLOCKS...]
#
# BLOCKS are COLSxROWS (default 2x2 8x8: 4 and 64 frames). RUNS (default 5)
# rounds, MEMORY (default 256M). Prints each round's peak RSS and render
# time from the mosaic's report, then per block the medians and the median
# of its peak : the first block's, taken round by round.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${1:-$(mktemp -d /tmp/gcm-mosaic-frames.XXXX)}
shift || true
BLOCKS=("$@")
[ ${#BLOCKS[@]} -gt 0 ] || BLOCKS=(2x2 8x8)
RUNS=${RUNS:-5}
MEMORY=${MEMORY:-256M}
cargo build --release --quiet
B=$PWD/target/release/gcm-ortho
for b in "${BLOCKS[@]}"; do
  [ -f "$WORK/$b/manifest.toml" ] || "$B" synth --out "$WORK/$b" --camera digital --relief urban --size 2000x2000 --dem-posting 1 --scale 8000 --block "$b" --quiet
done
cd "$WORK"
rm -f rounds.txt
for r in $(seq "$RUNS"); do
  for b in "${BLOCKS[@]}"; do
    rm -f m.tif
    "$B" mosaic "$b/manifest.toml" -o m.tif --memory "$MEMORY" --json m.json --quiet
    python3 - "$r" "$b" <<'PY' >> rounds.txt
import json, sys
m = json.load(open("m.json"))
print(sys.argv[1], sys.argv[2], len(m["images"]), f'{m["peak_rss_mib"]:.1f}', f'{m["seconds"]["render"]:.2f}', m["strips"])
PY
  done
done
rm -f m.tif
echo "round block frames peakMiB render_s strips"
cat rounds.txt
python3 - "${BLOCKS[0]}" <<'PY'
import sys, statistics as st
rows = [l.split() for l in open("rounds.txt")]
first = sys.argv[1]
peak = {(r[0], r[1]): float(r[3]) for r in rows}
blocks = list(dict.fromkeys(r[1] for r in rows))
for b in blocks:
    mine = [r for r in rows if r[1] == b]
    ratio = st.median(peak[(r[0], b)] / peak[(r[0], first)] for r in mine)
    print(f"{b}: {mine[0][2]} frames, peak median {st.median(float(r[3]) for r in mine):.1f} MiB "
          f"({min(float(r[3]) for r in mine):.1f}-{max(float(r[3]) for r in mine):.1f}), "
          f"render {st.median(float(r[4]) for r in mine):.2f} s, peak : {first}'s {ratio:.3f}")
PY
