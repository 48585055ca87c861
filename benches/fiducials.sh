#!/usr/bin/env bash
# Whole-run benchmark of automatic fiducial marks on the 1 GiB film scan
# (18918 × 18918 RGB, four cross marks, 12.7 µm pixels), in one run on one
# machine:
#   detect   `fiducials` alone: wall time and peak memory (only the
#            margins' windows are read);
#   rectify  `rectify` with the marks measured in the camera file, against
#            the same camera without them (found in the scan at set-up): what
#            automatic marks add to a job of a batch.
#
#   bash benches/fiducials.sh [WORKDIR]
#
# RUNS (default 5) rounds, the runs of each round interleaved. Prints each
# round, then the medians and the median round-by-round ratio found : measured.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${1:-$(mktemp -d /tmp/gcm-fiducials-bench.XXXX)}
RUNS=${RUNS:-5}
cargo build --release --quiet
B=$PWD/target/release/gcm-ortho
mkdir -p "$WORK"
cd "$WORK"
[ -f film/scan.tif ] || "$B" synth --out film --size 18918x18918 --quiet
grep -v '^fiducials_px' film/camera.toml > film/bare.toml
: > rounds.txt
for r in $(seq "$RUNS"); do
  /usr/bin/time -f "%e %M" -o detect.time "$B" fiducials --image film/scan.tif --camera film/bare.toml > /dev/null
  line="$(awk '{printf "%.3f %.0f", $1, $2 / 1024}' detect.time)"
  for cam in camera bare; do
    rm -f out.tif; sync
    "$B" rectify --image film/scan.tif --camera film/$cam.toml --dem film/dem.tif --no-sync -o out.tif --json run.json --quiet
    line="$line $(python3 -c 'import json; r = json.load(open("run.json")); print("%.3f" % r["wall_seconds"])')"
  done
  echo "$line" >> rounds.txt
done
echo "detect s MiB | rectify measured s, found s"
cat rounds.txt
python3 - <<'PY'
import statistics as st
rows = [list(map(float, l.split())) for l in open("rounds.txt")]
print(f"detect: {st.median(r[0] for r in rows):.2f} s, {st.median(r[1] for r in rows):.0f} MiB")
print(f"rectify: measured {st.median(r[2] for r in rows):.2f} s, found {st.median(r[3] for r in rows):.2f} s, ratio {st.median(r[3] / r[2] for r in rows):.3f}")
PY
