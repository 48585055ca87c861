#!/usr/bin/env bash
# The Python call against the command on the 1 GiB film scan turned 90
# degrees, at the defaults, in interleaved rounds on one machine.
#
#   bash benches/python_vs_cli.sh [WORKDIR]
#
# WORKDIR (default: a new folder under /tmp) needs ~3 GB free and gets a
# virtual environment with the package's wheel (maturin, from PyPI).
# RUNS (default 5) rounds. Each round times, one after the other:
#   cli      gcm-ortho rectify ... --quiet
#   python   python -c 'gcm_ortho.rectify(...)' (the interpreter's start
#            and the import included)
# Before each command the previous output is deleted and the disk synced
# (not timed). Prints each run's wall and CPU seconds and peak resident
# memory (/usr/bin/time), their medians and the medians of the python/cli
# ratios taken round by round.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:-$(mktemp -d /tmp/gcm-python.XXXX)}
runs=${RUNS:-5}
bin=$PWD/target/release/gcm-ortho
cargo build --release -q
if [ ! -x "$work/env/bin/python" ]; then
  python3 -m venv "$work/env"
  "$work/env/bin/pip" install -q "maturin>=1.5,<2"
fi
rm -rf "$work/wheels"
"$work/env/bin/maturin" build --release --quiet -m python/Cargo.toml --out "$work/wheels"
"$work/env/bin/pip" install -q --force-reinstall --no-deps "$work"/wheels/*.whl
scene="$work/scene"
if [ ! -f "$scene/scan.tif" ]; then
  "$bin" synth --out "$scene" --size 18918x18918 --relief hilly --camera film --kappa 90 --seed 5 --quiet
fi
cat "$scene/scan.tif" >/dev/null # in the page cache, as for every run after
log="$work/times.txt"
: >"$log"
timed() { # name, command...
  local name=$1
  shift
  rm -f "$work"/o_*.tif
  sync
  /usr/bin/time -f "$name %e %U %S %M" -a -o "$log" "$@"
}
py="import gcm_ortho; gcm_ortho.rectify('$scene/scan.tif', '$scene/camera.toml', '$scene/dem.tif', '$work/o_python.tif')"
for r in $(seq "$runs"); do
  timed cli "$bin" rectify --image "$scene/scan.tif" --camera "$scene/camera.toml" --dem "$scene/dem.tif" -o "$work/o_cli.tif" --quiet
  timed python "$work/env/bin/python" -c "$py"
done
rm -f "$work"/o_*.tif
cat "$log"
python3 - "$log" <<'PY'
import sys, statistics as st
runs = {}
for line in open(sys.argv[1]):
    name, wall, user, sys_, rss = line.split()
    runs.setdefault(name, []).append((float(wall), float(user) + float(sys_), int(rss) / 1024))
for name, v in runs.items():
    print(f"{name:7s} wall {st.median(w for w, _, _ in v):.2f} s  cpu {st.median(c for _, c, _ in v):.2f} s  peak {st.median(m for _, _, m in v):.0f} MiB")
for k, what in [(0, "wall"), (1, "cpu"), (2, "peak")]:
    print(f"python / cli {what} {st.median(p[k] / c[k] for p, c in zip(runs['python'], runs['cli'])):.3f}")
PY
