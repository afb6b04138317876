#!/bin/bash
# Byte-identity of APT CL conversion between two kinpost binaries: program
# output, stderr, exit code and the --report JSON of `post`,
# `post --feed inverse-time` and `compensate`, over every CL program under
# fixtures/, tests/it/cl_dialects/ and ../shared/real/ plus generated ones
# (arcs, holes, G80, refusals across chunk boundaries), on every machine of
# fixtures/machines/, with all threads and with RAYON_NUM_THREADS=1; and the
# bench's lens-cl workload when $BENCH_DIR holds it.
#
#   bash bench/cl_identity.sh OLD_BINARY [NEW_BINARY]   # new: target/release/kinpost
#
# Exit 0 when every file is equal. Not run in CI.
set -u
cd "$(dirname "$0")/.."
R=$(pwd)
OLD=$1; NEW=${2:-$R/target/release/kinpost}
BENCH_DIR=${BENCH_DIR:-${TMPDIR:-/tmp}/kinpost-bench}
WORK=$(mktemp -d); trap 'rm -rf "$WORK"' EXIT
mkdir -p "$WORK/in"
# An X Y Z error table (the first three blocks of the wang2023 table) for
# machines without a table of their own.
awk '/^A,/{exit} {print}' fixtures/errors/wang2023-xyzab.csv > "$WORK/xyz.csv"
python3 - "$WORK/in" <<'PY'
import math, sys
d = sys.argv[1]
def prog(n, seed, tilt=0.3, inch=False):
    s = 1 / 25.4 if inch else 1.0
    out = ["PARTNO/SYNTH %d" % seed, "UNITS/INCHES" if inch else "UNITS/MM", "LOADTL/3",
           "SPINDL/RPM,8000,CLW", "COOLNT/ON", "FEDRAT/MMPM,500"]
    k = 0
    while len(out) < n:
        k += 1
        r = (k * 7 + seed) % 23
        if r == 0:
            out += ["RAPID", "GOTO/0,%.4f,%.4f,0,0,1" % (10 * s, 20 * s),
                    "CYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10", "GOTO/0,%.4f,0" % (10 * s),
                    "GOTO/%.4f,%.4f,0" % (5 * s, 10 * s), "CYCLE/OFF", "GOTO/%.4f,%.4f,%.4f" % (5 * s, 10 * s, 20 * s)]
        elif r == 5:
            out += ["GOTO/%.4f,0,%.4f,0,0,1" % (10 * s, 5 * s), "CIRCLE/0,0,%.4f,0,0,1,%.4f" % (5 * s, 10 * s),
                    "GOTO/0,%.4f,%.4f" % (10 * s, 5 * s)]
        elif r == 9:
            out += ["RAPID", "GOTO/%.4f,0,%.4f,0,0,1" % (10 * s, 5 * s), "RAPID",
                    "CIRCLE/0,0,%.4f,0,0,1,%.4f" % (5 * s, 10 * s), "GOTO/%.4f,0,%.4f" % (-10 * s, 5 * s)]
        elif r == 11:
            out.append("FEDRAT/MMPM,%d" % (300 + (k % 5) * 100))
        elif r == 13:
            out.append("$$ comment %d (paren)" % k)
        elif r == 17:
            out.append("FEDRAT/%d,IPM" % (10 + k % 3))
        elif r == 19:
            out += ["CYCLE/DEEP,FEDTO,3,STEP,1,RAPTO,2,RTRCTO,10,MMPM,200",
                    "GOTO/%.4f,%.4f,0,0,0,1" % (3 * s, -4 * s), "CYCLE/OFF",
                    "GOTO/%.4f,%.4f,%.4f,0,0,1" % (3 * s, -4 * s, 20 * s)]
        else:
            t = k * 0.05
            a, b = tilt * math.sin(t), tilt * math.cos(t * 0.7)
            v = (math.sin(a) * math.cos(b), math.sin(b), math.cos(a) * math.cos(b))
            n2 = math.sqrt(sum(c * c for c in v))
            out.append("GOTO/%.4f,%.4f,%.4f,%.9f,%.9f,%.9f" % (
                20 * math.cos(t) * s, 20 * math.sin(t) * s, (3 + math.sin(3 * t)) * s,
                v[0] / n2, v[1] / n2, v[2] / n2))
    return out + ["COOLNT/OFF", "SPINDL/OFF", "FINI"]
def put(name, lines):
    open("%s/%s" % (d, name), "w").write("\n".join(lines) + "\n")
put("synth-a.cls", prog(1800, 0))
b = prog(1300, 3, tilt=0.0)
put("synth-b.cls", b)
put("synth-5ax.cls", prog(2500, 5, tilt=0.6))
put("synth-inch.cls", prog(700, 2, inch=True))
put("synth-lowerr.cls", b[:900] + ["CYCLE/ON,FEDTO,-5"] + b[900:])
put("synth-tap.cls", b[:700] + ["GOTO/0,0,30,0,0,1", "CYCLE/TAP,FEDTO,10,MMPR,1.5,RAPTO,3", "GOTO/0,0,0", "CYCLE/OFF"] + b[700:])
put("synth-reach.cls", b[:1000] + ["GOTO/5000,0,0,0,0,1"] + b[1000:])
put("synth-axis.cls", b[:1100] + ["GOTO/1,2,3,0,0,2"] + b[1100:])
put("s-tap.cls", ["UNITS/MM", "GOTO/0,0,30,0,-0.5,0.8660254", "CYCLE/TAP,FEDTO,10,MMPR,1.5,RAPTO,3", "GOTO/0,0,0", "CYCLE/OFF"])
put("s-circ.cls", ["UNITS/MM", "FEDRAT/MMPM,500", "GOTO/10,0,0", "CIRCLE/0,0,0,0,0,1", "GOTO/10,0,0",
                   "CIRCLE/0,0,0,0,0,-1", "GOTO/0,-10,-2", "GOTO/5,5,0"])
put("s-inch.cls", ["UNITS/INCHES", "GOTO/1,0,2", "CYCLE/DEEP,FEDTO,0.5,STEP,0.1,RAPTO,0.1,RTRCTO,1,IPM,10",
                   "GOTO/1,0,0", "CYCLE/OFF", "GOTO/0,1,0", "CIRCLE/0,0,0,0,0,1", "GOTO/-1,0,0"])
put("s-mix.cls", ["UNITS/MM", "FEDRAT/MMPM,300", "GOTO/10,0,5", "CIRCLE/0,0,5,0,0,1", "GOTO/0,10,5",
                  "CYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10", "GOTO/0,10,0", "CYCLE/OFF", "GOTO/0,10,20"])
put("s-g80.cls", ["UNITS/MM", "FEDRAT/MMPM,300", "GOTO/0,0,10", "CYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10", "RAPID",
                  "GOTO/0,0,0", "CYCLE/OFF", "GOTO/5,0,10", "GOTO/6,0,10",
                  "CYCLE/DRILL,FEDTO,4,RAPTO,2,RTRCTO,10", "CYCLE/OFF", "GOTO/7,0,10"])
put("s-itime.cls", ["UNITS/MM", "FEDRAT/MMPR,0.05", "GOTO/0,0,10,0,0.3,0.9539392", "GOTO/5,0,10,0.3,0,0.9539392",
                    "FEDRAT/MMPM,200", "GOTO/5,5,10,0,0,1", "GOTO/5,6,10,0.2,0.1,0.97467943", "CIRCLE/0,0,10,0,0,1", "GOTO/0,0,10", "END"])
PY
INPUTS="$(find fixtures tests/it/cl_dialects -type f \( -name '*.cls' -o -name '*.cl' -o -name '*.ncl' -o -name '*.aptsource' \)) $(find ../shared/real -type f -name '*.apt' 2>/dev/null) $(ls "$WORK"/in/*)"
run() { # binary outdir
  local bin=$1 out=$2 n=0
  mkdir -p "$out"
  for f in $INPUTS; do
    b=$(basename "$f")
    for mf in fixtures/machines/*.json; do
      m=$(basename "$mf" .json)
      E="--errors $WORK/xyz.csv"
      [ -f "fixtures/errors/$m.csv" ] && E="--errors fixtures/errors/$m.csv"
      case $m in xyzb*) E="--errors fixtures/errors/zhao2022-xzbc.csv" ;; esac
      for th in all 1; do
        if [ $th = 1 ]; then export RAYON_NUM_THREADS=1; else unset RAYON_NUM_THREADS; fi
        k="$out/$b.$m.$th"
        "$bin" post -m "$mf" "$f" -o "$k.post.nc" 2> "$k.post.err"; echo $? > "$k.post.rc"
        "$bin" post --feed inverse-time -m "$mf" "$f" -o "$k.itime.nc" 2> "$k.itime.err"; echo $? > "$k.itime.rc"
        # shellcheck disable=SC2086
        "$bin" compensate -m "$mf" $E "$f" -o "$k.comp.nc" --report "$k.comp.json" 2> "$k.comp.err"; echo $? > "$k.comp.rc"
        n=$((n + 3))
      done
    done
  done
  if [ -s "$BENCH_DIR/lens-200000.cls" ] && [ -s "$BENCH_DIR/dense.csv" ]; then
    for th in all 1; do
      if [ $th = 1 ]; then export RAYON_NUM_THREADS=1; else unset RAYON_NUM_THREADS; fi
      k="$out/bench.$th"
      "$bin" post -m zhao2022-xzbc "$BENCH_DIR/lens-200000.cls" -o "$k.post.nc" 2> "$k.post.err"; echo $? > "$k.post.rc"
      "$bin" compensate -m zhao2022-xzbc --errors "$BENCH_DIR/dense.csv" "$BENCH_DIR/lens-200000.cls" \
        -o "$k.comp.nc" --report "$k.comp.json" 2> "$k.comp.err"; echo $? > "$k.comp.rc"
      n=$((n + 2))
    done
  fi
  unset RAYON_NUM_THREADS
  echo "$n"
}
n_old=$(run "$OLD" "$WORK/old"); n_new=$(run "$NEW" "$WORK/new")
# The error messages name the binary.
sed -i "s|$(basename "$OLD")|kinpost|g" "$WORK"/old/*.err
sed -i "s|$(basename "$NEW")|kinpost|g" "$WORK"/new/*.err
files=$(ls "$WORK/old" | wc -l)
if diff -r "$WORK/old" "$WORK/new" > "$WORK/diff"; then
  echo "cl_identity: $n_old runs each, $files files, all equal ($(cat "$WORK"/old/*.rc | sort | uniq -c | tr -s ' ' | tr '\n' ';') exit codes)"
else
  echo "cl_identity: $n_old/$n_new runs, differences:"; diff -rq "$WORK/old" "$WORK/new" | head -40; exit 1
fi
