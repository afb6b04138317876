#!/usr/bin/env bash
# Peak memory (RSS) of the streaming commands (post, compensate,
# analyze --nonlinear with --json or --svg, linkage, simulate) on a long program, default
# 2,000,000 blocks (about 160 MB of G-code), and as many APT CL statements.
# Not part of CI.
#
#   bash bench/memory.sh [POSES]
set -euo pipefail
cd "$(dirname "$0")/.."
POSES="${1:-2000000}"
WORK="${BENCH_DIR:-${TMPDIR:-/tmp}/kinpost-bench}"
mkdir -p "$WORK"
command -v /usr/bin/time >/dev/null || { apt-get update -qq && apt-get install -y -qq time; }
cargo build --release --quiet --bin kinpost --example bench_program --example bench_lens_cl
PROGRAM="$WORK/poses-$POSES.nc"
[ -s "$PROGRAM" ] || target/release/examples/bench_program "$POSES" > "$PROGRAM"
echo "== $POSES blocks ($(du -h "$PROGRAM" | cut -f1))"
run() {
  local name=$1; shift
  /usr/bin/time -v "$@" 2> "$WORK/time.log" >/dev/null
  printf '%-40s peak RSS %6d KB   wall %s\n' "$name" \
    "$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$WORK/time.log")" \
    "$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$WORK/time.log")"
}
run "post -o FILE" target/release/kinpost post -q "$PROGRAM" -o "$WORK/post.nc"
run "post (stdout)" target/release/kinpost post -q "$PROGRAM"
run "compensate -o FILE" target/release/kinpost compensate -q --errors fixtures/errors/zhao2022-xzbc.csv "$PROGRAM" -o "$WORK/comp.nc"
run "compensate --report FILE -o FILE" target/release/kinpost compensate -q --errors fixtures/errors/zhao2022-xzbc.csv --report "$WORK/report.json" "$PROGRAM" -o "$WORK/comp.nc"
run "analyze --nonlinear (text)" target/release/kinpost analyze --errors fixtures/errors/zhao2022-xzbc.csv --nonlinear "$PROGRAM"
run "analyze --nonlinear --json" target/release/kinpost analyze --errors fixtures/errors/zhao2022-xzbc.csv --nonlinear --json "$PROGRAM"
run "analyze --nonlinear --svg FILE" target/release/kinpost analyze --errors fixtures/errors/zhao2022-xzbc.csv --nonlinear --svg "$WORK/analyze.svg" "$PROGRAM"
run "linkage -o FILE" target/release/kinpost linkage -q "$PROGRAM" -o "$WORK/link.nc"
run "simulate -o FILE" target/release/kinpost simulate -p "$PROGRAM" --errors fixtures/errors/zhao2022-xzbc.csv --inject backlash:X=0.003 -o "$WORK/sim.csv"
run "simulate --time-offset --feedback -o FILE" target/release/kinpost simulate -p "$PROGRAM" --time-offset 0.2 --feedback --inject servo_lag:X=0.02 -o "$WORK/sim.csv"
rm -f "$WORK/link.nc" "$WORK/sim.csv" "$WORK/analyze.svg"
# The same length as APT CL (the lens ring back and forth).
CL="$WORK/lens-$POSES.cls"
[ -s "$CL" ] || target/release/examples/bench_lens_cl "$POSES" cl > "$CL"
echo "== $POSES APT CL statements ($(du -h "$CL" | cut -f1))"
run "post APT CL -o FILE" target/release/kinpost post -q "$CL" -o "$WORK/post.nc"
run "compensate APT CL --report FILE -o FILE" target/release/kinpost compensate -q --errors fixtures/errors/zhao2022-xzbc.csv --report "$WORK/report.json" "$CL" -o "$WORK/comp.nc"
rm -f "$WORK/post.nc" "$WORK/comp.nc" "$WORK/report.json"
