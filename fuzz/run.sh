#!/bin/bash
# Runs fuzz targets, each for SECONDS on one core, from the small seeds
# kept in fuzz/seeds/TARGET (the growing corpus stays in fuzz/corpus,
# outside the repository). Needs a nightly toolchain and cargo-fuzz.
#
#   bash fuzz/run.sh SECONDS TARGET [TARGET ...]
#
# A finding stops that target and is left in fuzz/artifacts/TARGET.
set -u
cd "$(dirname "$0")/.." || exit 2
secs=$1
shift
status=0
for t in "$@"; do
  mkdir -p "fuzz/corpus/$t"
  seeds=()
  [ -d "fuzz/seeds/$t" ] && seeds=("fuzz/seeds/$t")
  if cargo +nightly fuzz run -O "$t" "fuzz/corpus/$t" "${seeds[@]}" -- \
      -max_total_time="$secs" -max_len=65536 -rss_limit_mb=2048 -timeout=10 > "fuzz/corpus/$t.log" 2>&1; then
    echo "$t: $(grep -E '^#[0-9]+.*(DONE|pulse)' "fuzz/corpus/$t.log" | tail -1)"
  else
    echo "$t: FINDING (see fuzz/corpus/$t.log)"
    status=1
  fi
done
exit $status
