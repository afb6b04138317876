#!/usr/bin/env bash
# Peer comparison: kinpost compensate against bench/peer_numpy.py (seed 000's
# method vectorised in NumPy/SciPy) on the same poses, file in and file out,
# wall clock, best of RUNS (default 7). The runs of the commands are
# interleaved, so that a slower spell of a shared machine falls on all of
# them alike. Not part of CI.
#
#   bash bench/run.sh [POSES] [WORKLOAD]     (defaults: 200000, spiral and lens-cl)
#
# Workloads:
#   spiral  — the lens spiral as G-code, the 376-row error table of the
#             fixtures (fixtures/errors/zhao2022-xzbc.csv);
#   lens-cl — seed 000's lens ring run back and forth, as APT CL for
#             kinpost (the peer reads the same poses as G-code), with a
#             dense 6,003-row table (X, Z every 0.1 mm, B every 0.09°, six
#             error motions each: examples/dense_table.rs);
#   tables  — lens-cl compensated with that table and with ones 4 and 16
#             times finer (24,003 and 96,003 rows): loading and fitting
#             grow with the rows, the conversion does not (no peer run;
#             the fit cache off, so that every run fits).
#
# Fitted error models are cached by the table's content (docs/error-tables.md,
# "Fitted-model cache"), here in $WORK/fit-cache: the first compensate run of
# a workload fits its table, the later ones read the fit back, which is what
# a user's second run with the same table does. "compensate (no fit cache)"
# fits the table in every run (KINPOST_CACHE_DIR=off).
#
# Prints per workload the times of compensate (both cores, one thread),
# post and the peer (wall clock, and in brackets the user CPU time, which a
# loaded machine disturbs less), the ratios peer / compensate and
# compensate / post (wall clock), post's throughput in MB/s, and each
# side's remaining tool-tip error.
set -euo pipefail
cd "$(dirname "$0")/.."
POSES="${1:-200000}"
WORKLOADS="${2:-spiral lens-cl}"
RUNS="${RUNS:-7}"
WORK="${BENCH_DIR:-${TMPDIR:-/tmp}/kinpost-bench}"
mkdir -p "$WORK"
export KINPOST_CACHE_DIR="$WORK/fit-cache"

python3 -c 'import numpy, scipy' 2>/dev/null || python3 -m pip install --quiet numpy scipy

cargo build --release --quiet --bin kinpost --example bench_program --example bench_lens_cl --example dense_table
KINPOST=target/release/kinpost

# Wall time of "$@" (a command or a function of this script) in seconds;
# its user CPU time goes to $WORK/user.
timed() {
  local TIMEFORMAT="%3R %3U"
  { time "$@" ; } 2> "$WORK/time"
  cut -d' ' -f1 "$WORK/time"
}
user() { cut -d' ' -f2 "$WORK/time"; }
min() { awk -v a="$1" -v b="$2" 'BEGIN { print (b == "" || a < b) ? a : b }'; }

# run_workload NAME KINPOST_PROGRAM PEER_PROGRAM ERRORS
run_workload() {
  local name="$1" program="$2" peer_program="$3" errors="$4"
  local bytes; bytes=$(stat -c %s "$program")
  echo "== $name: $POSES poses ($(du -h "$program" | cut -f1)), zhao2022-xzbc, errors $(basename "$errors") ($(grep -c '^[-0-9]' "$errors") rows), $(nproc) cores"
  kin() { "$KINPOST" compensate --machine zhao2022-xzbc --errors "$errors" "$program" -o "$WORK/kinpost.nc" 2> "$WORK/kinpost.log"; }
  kin1() { RAYON_NUM_THREADS=1 kin; }
  kin_fit() { KINPOST_CACHE_DIR=off kin; }
  post() { "$KINPOST" post --machine zhao2022-xzbc "$program" -o "$WORK/post.nc" 2> "$WORK/post.log"; }
  peer() { python3 bench/peer_numpy.py --errors "$errors" "$peer_program" -o "$WORK/peer.nc" 2> "$WORK/peer.log"; }
  local t_kin="" t_kin1="" t_fit="" t_post="" t_peer="" u_kin="" u_kin1="" u_fit="" u_post="" u_peer=""
  for _ in $(seq "$RUNS"); do
    t_kin=$(min "$(timed kin)" "$t_kin"); u_kin=$(min "$(user)" "$u_kin")
    t_fit=$(min "$(timed kin_fit)" "$t_fit"); u_fit=$(min "$(user)" "$u_fit")
    t_kin1=$(min "$(timed kin1)" "$t_kin1"); u_kin1=$(min "$(user)" "$u_kin1")
    t_post=$(min "$(timed post)" "$t_post"); u_post=$(min "$(user)" "$u_post")
    t_peer=$(min "$(timed peer)" "$t_peer"); u_peer=$(min "$(user)" "$u_peer")
  done
  local kin_tip kin_it
  kin_tip=$(sed -n 's/.*tool-tip error:.*(solution \([^ ]*\) mm).*/\1/p' "$WORK/kinpost.log")
  kin_it=$(sed -n 's/.*Newton iterations: \(.*\)/\1/p' "$WORK/kinpost.log")
  printf '%-34s %8s s (user %s s)   tool-tip residual max %s mm (%s)\n' "kinpost compensate (all cores)" "$t_kin" "$u_kin" "$kin_tip" "$kin_it"
  printf '%-34s %8s s (user %s s)\n' "kinpost compensate (1 thread)" "$t_kin1" "$u_kin1"
  printf '%-34s %8s s (user %s s)\n' "kinpost compensate (no fit cache)" "$t_fit" "$u_fit"
  printf '%-34s %8s s (user %s s)\n' "kinpost post" "$t_post" "$u_post"
  printf '%-34s %8s s (user %s s)   %s\n' "peer_numpy.py" "$t_peer" "$u_peer" "$(cat "$WORK/peer.log")"
  awk -v p="$t_peer" -v k="$t_kin" -v k1="$t_kin1" -v kf="$t_fit" -v po="$t_post" -v b="$bytes" 'BEGIN {
    printf "ratio peer / compensate: %.1fx (1 thread: %.1fx; no fit cache: %.1fx); compensate / post: %.2f; post: %.0f MB/s\n",
      p / k, p / k1, p / kf, k / po, b / po / 1e6 }'
}

for w in $WORKLOADS; do
  case "$w" in
    spiral)
      program="$WORK/poses-$POSES.nc"
      [ -s "$program" ] || target/release/examples/bench_program "$POSES" > "$program"
      run_workload spiral "$program" "$program" fixtures/errors/zhao2022-xzbc.csv
      ;;
    lens-cl)
      cl="$WORK/lens-$POSES.cls"; nc="$WORK/lens-$POSES.nc"; dense="$WORK/dense.csv"
      [ -s "$cl" ] || target/release/examples/bench_lens_cl "$POSES" cl > "$cl"
      [ -s "$nc" ] || target/release/examples/bench_lens_cl "$POSES" gcode > "$nc"
      [ -s "$dense" ] || target/release/examples/dense_table > "$dense"
      run_workload lens-cl "$cl" "$nc" "$dense"
      ;;
    tables)
      # The speed as the error tables grow: lens-cl compensated with the
      # dense table, 4 and 16 times finer (6,003 / 24,003 / 96,003 rows).
      cl="$WORK/lens-$POSES.cls"
      [ -s "$cl" ] || target/release/examples/bench_lens_cl "$POSES" cl > "$cl"
      echo "== tables: lens-cl, $POSES poses, compensate with finer tables, $(nproc) cores"
      for f in 1 4 16; do
        t="$WORK/dense-x$f.csv"
        [ -s "$t" ] || target/release/examples/dense_table "$f" > "$t"
        load() { KINPOST_CACHE_DIR=off "$KINPOST" compensate -q --machine zhao2022-xzbc --errors "$t" "$WORK/empty.nc" -o "$WORK/empty-out.nc" 2> /dev/null; }
        comp() { KINPOST_CACHE_DIR=off "$KINPOST" compensate -q --machine zhao2022-xzbc --errors "$t" "$cl" -o "$WORK/kinpost.nc" 2> /dev/null; }
        : > "$WORK/empty.nc"
        t_load=""; t_comp=""
        for _ in $(seq "$RUNS"); do
          t_load=$(min "$(timed load)" "$t_load"); t_comp=$(min "$(timed comp)" "$t_comp")
        done
        printf '%6s rows: load and fit %s s, compensate %s s, compensate less loading %s s\n' \
          "$(grep -c '^[-0-9]' "$t")" "$t_load" "$t_comp" "$(awk -v a="$t_comp" -v b="$t_load" 'BEGIN { printf "%.3f", a - b }')"
      done
      ;;
    *) echo "unknown workload $w (spiral, lens-cl, tables)" >&2; exit 2 ;;
  esac
done
