#!/usr/bin/env bash
# Peer comparison: kinpost compensate against bench/peer_numpy.py (seed 000's
# method vectorised in NumPy/SciPy) on the same pose program, file in and
# file out, wall clock, best of RUNS (default 7). The runs of the three
# commands are interleaved, so that a slower spell of a shared machine
# falls on all of them alike. Not part of CI.
#
#   bash bench/run.sh [POSES]        (default 200000)
#
# Prints both times, the ratio, and each side's remaining tool-tip error.
set -euo pipefail
cd "$(dirname "$0")/.."
POSES="${1:-200000}"
RUNS="${RUNS:-7}"
ERRORS=fixtures/errors/zhao2022-xzbc.csv
WORK="${BENCH_DIR:-${TMPDIR:-/tmp}/kinpost-bench}"
mkdir -p "$WORK"

python3 -c 'import numpy, scipy' 2>/dev/null || python3 -m pip install --quiet numpy scipy

cargo build --release --quiet --bin kinpost --example bench_program
KINPOST=target/release/kinpost
PROGRAM="$WORK/poses-$POSES.nc"
[ -s "$PROGRAM" ] || target/release/examples/bench_program "$POSES" > "$PROGRAM"
echo "== $POSES poses ($(du -h "$PROGRAM" | cut -f1)), zhao2022-xzbc, error tables $ERRORS, $(nproc) cores"

now() { date +%s.%N; }
# Wall time of "$@" in seconds.
timed() {
  local t0 t1
  t0=$(now); "$@"; t1=$(now)
  awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }'
}
min() { awk -v a="$1" -v b="$2" 'BEGIN { print (b == "" || a < b) ? a : b }'; }

kin() { "$KINPOST" compensate --errors "$ERRORS" "$PROGRAM" -o "$WORK/kinpost.nc" 2> "$WORK/kinpost.log"; }
kin1() { RAYON_NUM_THREADS=1 kin; }
peer() { python3 bench/peer_numpy.py --errors "$ERRORS" "$PROGRAM" -o "$WORK/peer.nc" 2> "$WORK/peer.log"; }

t_kin=""; t_kin1=""; t_peer=""
for _ in $(seq "$RUNS"); do
  t_kin=$(min "$(timed kin)" "$t_kin")
  t_kin1=$(min "$(timed kin1)" "$t_kin1")
  t_peer=$(min "$(timed peer)" "$t_peer")
done
kin_tip=$(sed -n 's/.*tool-tip error:.*after max \([^ ]*\) mm.*/\1/p' "$WORK/kinpost.log")
kin_it=$(sed -n 's/.*Newton iterations: \(.*\)/\1/p' "$WORK/kinpost.log")
peer_line=$(cat "$WORK/peer.log")

printf '%-34s %8s s   tool-tip residual max %s mm (%s)\n' "kinpost compensate (all cores)" "$t_kin" "$kin_tip" "$kin_it"
printf '%-34s %8s s\n' "kinpost compensate (1 thread)" "$t_kin1"
printf '%-34s %8s s   %s\n' "peer_numpy.py" "$t_peer" "$peer_line"
awk -v p="$t_peer" -v k="$t_kin" -v k1="$t_kin1" 'BEGIN {
  printf "ratio peer / kinpost: %.1fx (1 thread: %.1fx)\n", p / k, p / k1 }'
