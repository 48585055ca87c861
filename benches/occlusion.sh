#!/usr/bin/env bash
# Whole-run benchmark of `rectify --occlusion nodata` (a true orthophoto)
# against the same run without it, in one run on one machine, on two scenes:
#   urban  a drone frame (25° off nadir) over a town's DSM posted at 0.5 m,
#          rectified at 0.1 m;
#   film   the 1 GiB film scan over hilly terrain (5 m DEM): no building, so
#          nothing to hide, and the cost must be small there too.
#
#   bash benches/occlusion.sh [WORKDIR]
#
# RUNS (default 5) rounds, the two runs of each scene interleaved. Prints
# each round's wall times and peak memory, then per scene the medians and
# the median of the round-by-round ratio occlusion : plain.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${1:-$(mktemp -d /tmp/gcm-occlusion-bench.XXXX)}
RUNS=${RUNS:-5}
cargo build --release --quiet
B=$PWD/target/release/gcm-ortho
mkdir -p "$WORK"
cd "$WORK"
[ -f urban/scan.tif ] || "$B" synth --out urban --camera drone --relief urban --size 6000x4000 --dem-posting 0.5 --kappa 17 --quiet
[ -f film/scan.tif ] || "$B" synth --out film --size 18918x18918 --quiet
: > rounds.txt
for r in $(seq "$RUNS"); do
  line=""
  for scene in urban film; do
    gsd=(); [ "$scene" = urban ] && gsd=(--gsd 0.1)
    for mode in none nodata; do
      rm -f out.tif; sync
      "$B" rectify --image $scene/scan.tif --camera $scene/camera.toml --dem $scene/dem.tif "${gsd[@]}" --occlusion $mode --no-sync -o out.tif --json run.json --quiet
      line="$line $(python3 -c 'import json; r = json.load(open("run.json")); print("%.3f %.0f" % (r["wall_seconds"], r["peak_rss_mib"]))')"
    done
  done
  echo "$line" >> rounds.txt
done
echo "urban: plain s MiB, occlusion s MiB | film: plain s MiB, occlusion s MiB"
cat rounds.txt
python3 - <<'PY'
import statistics as st
rows = [list(map(float, l.split())) for l in open("rounds.txt")]
for name, k in (("urban", 0), ("film", 4)):
    plain = st.median(r[k] for r in rows); occ = st.median(r[k + 2] for r in rows)
    ratio = st.median(r[k + 2] / r[k] for r in rows)
    print(f"{name}: plain {plain:.2f} s ({st.median(r[k+1] for r in rows):.0f} MiB), --occlusion {occ:.2f} s ({st.median(r[k+3] for r in rows):.0f} MiB), ratio {ratio:.2f}")
PY
