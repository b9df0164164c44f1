#!/usr/bin/env bash
# Every program's command line follows tools/common/cli.hpp, run as a user runs it: --version
# prints "NAME VERSION (COMMIT)" and exits 0; --help prints the usage on stdout and exits 0, on
# the program and on each subcommand; an unknown option exits 2 naming it on stderr, and so does a
# bad value; --opt=value is taken as --opt value is (shown by the value reaching the program: the
# file it names in its error, or what it writes).
#   cli_conventions.sh "VERSION (COMMIT)" SOURCE_DIR BUILD_DIR WORK_DIR NAME=PATH...
set -u
VERSION="$1" SRC="$2" BUILD="$3" WORK="$4"
shift 4
rm -rf "$WORK" && mkdir -p "$WORK"
fail=0
declare -A bin
for pair in "$@"; do bin[${pair%%=*}]="${pair#*=}"; done

# expect CODE STREAM FRAGMENT -- COMMAND...: COMMAND exits CODE and STREAM (stdout or stderr)
# holds FRAGMENT (empty: anything).
expect() {
  local code="$1" stream="$2" frag="$3"
  shift 4
  "$@" > "$WORK/out" 2> "$WORK/err" < /dev/null
  local rc=$?
  local text
  text=$(cat "$WORK/$( [[ $stream == stdout ]] && echo out || echo err)")
  if [[ $rc -ne $code || "$text" != *"$frag"* ]]; then
    echo "FAIL: ${*#"$BUILD/"} -> exit $rc, wanted $code with '$frag' on $stream; stdout:"
    head -5 "$WORK/out"; echo "stderr:"; head -5 "$WORK/err"
    fail=1
  else
    echo "ok: $(basename "$1") ${*:2} -> $code"
  fi
}

# --version, --help and an unknown option: the same on every program (ARGS: a command word
# where the program needs one before an option is looked at).
for name in "${!bin[@]}"; do
  b="${bin[$name]}"
  out=$("$b" --version 2>&1); rc=$?
  if [[ $rc -ne 0 || "$out" != "$name $VERSION" ]]; then
    echo "FAIL: $name --version -> exit $rc: '$out', wanted '$name $VERSION'"
    fail=1
  fi
  expect 0 stdout "--version" -- "$b" --help
  [[ -s "$WORK/err" ]] && { echo "FAIL: $name --help wrote to stderr: $(cat "$WORK/err")"; fail=1; }
  grep -q "Usage: $name" "$WORK/out" || { echo "FAIL: $name --help has no 'Usage: $name'"; fail=1; }
  expect 2 stderr "$name: unknown option '--frobnicate'" -- "$b" --frobnicate
  expect 2 stderr "unknown option '--frobnicate'" -- "$b" --frobnicate=3
done

T="$WORK/t"
mkdir -p "$T"
cam="$SRC/config/camera-sim.yaml"
if [[ -n "${bin[mfc-teach]:-}" ]]; then
  b="${bin[mfc-teach]}"
  expect 2 stderr "--views 'x' is not an integer" -- "$b" "$T/none.stl" --camera="$cam" --out="$T/x.tdb" --views=x
  expect 1 stderr "none.stl" -- "$b" "$T/none.stl" --camera="$cam" --out="$T/x.tdb" --views=12 --quiet
  expect 2 stderr "--camera is required" -- "$b" "$T/none.stl" --out "$T/x.tdb"
  expect 2 stderr "more than one MODEL given" -- "$b" a.stl b.stl --camera "$cam" --out "$T/x.tdb"
fi
if [[ -n "${bin[mfc-calibrate]:-}" ]]; then
  b="${bin[mfc-calibrate]}"
  for sub in intrinsics hand-eye rollback import; do
    expect 0 stdout "Usage: mfc-calibrate $sub" -- "$b" "$sub" --help
  done
  expect 2 stderr "unknown option '--frobnicate'" -- "$b" intrinsics --frobnicate --out x.yaml
  expect 2 stderr "run 'mfc-calibrate intrinsics --help'" -- "$b" intrinsics --frobnicate
  expect 2 stderr "a command is required (intrinsics, hand-eye, rollback, import)" -- "$b"
  expect 2 stderr "unknown command 'calibrate'" -- "$b" calibrate
  expect 0 stdout "wrote" -- "$b" import "$SRC/tests/vision/calib/foreign/ros_plumb_bob.yaml" --out="$T/cam.yaml" \
    --working-distance=420
  grep -q "working_distance_mm: 420." "$T/cam.yaml" || { echo "FAIL: --working-distance=420 not written"; fail=1; }
fi
if [[ -n "${bin[mfc-detect]:-}" ]]; then
  b="${bin[mfc-detect]}"
  expect 1 stderr "$T/nope" -- "$b" --dataset="$T/nope" --templates="$T/a.tdb" --out="$T/x.csv"
  expect 2 stderr "--search-rounds must be 1.." -- "$b" --dataset="$T/nope" --templates "$T/a.tdb" --out "$T/x.csv" \
    --search-rounds=0
  expect 2 stderr "--scene 'one' is not an integer" -- "$b" --dataset "$T" --templates a.tdb --out x.csv --scene=one
  expect 2 stderr "--dataset is required" -- "$b" --templates a.tdb --out x.csv
fi
if [[ -n "${bin[mfc-eval]:-}" ]]; then
  b="${bin[mfc-eval]}"
  expect 0 stdout "Usage: mfc-eval detect" -- "$b" detect --help
  expect 0 stdout "Usage: mfc-eval refine" -- "$b" refine --help
  expect 0 stdout "Usage: mfc-eval" -- "$b" help
  expect 1 stderr "nope: no such dataset folder" -- "$b" detect --dataset="$T/nope" --templates="$T" --out="$T/o.json"
  expect 2 stderr "--timing-repeats must be in 1..10" -- "$b" detect --dataset "$T" --templates "$T" --out o.json \
    --timing-repeats=0
  expect 2 stderr "unknown option '--frobnicate'" -- "$b" refine --frobnicate
  expect 2 stderr "unknown command 'frob' (detect, refine, edges)" -- "$b" frob
fi
if [[ -n "${bin[mfc-sim]:-}" ]]; then
  b="${bin[mfc-sim]}"
  expect 1 stderr "$T/none.yaml" -- "$b" --camera="$T/none.yaml" --parts="$T" --out="$T/ds"
  expect 2 stderr "--scenes: 'two' is not a number" -- "$b" --camera "$cam" --parts "$T" --out "$T/ds" --scenes=two
fi
if [[ -n "${bin[mfc-match]:-}" ]]; then
  b="${bin[mfc-match]}"
  expect 1 stderr "none.png: no such file" -- "$b" --template="$T/none.png" --query="$T/q.png" --threshold=2.5
  expect 2 stderr "--threshold expects a number, got 'x'" -- "$b" --template a.png --query q.png --threshold=x
fi
if [[ -n "${bin[mfcd]:-}" ]]; then
  b="${bin[mfcd]}"
  expect 0 stdout "sim.yaml: valid" -- "$b" --config="$SRC/config/sim.yaml" --data-dir="$BUILD" --check-config
  expect 2 stderr "--benchmark 'x' is not an integer" -- "$b" --benchmark=x
fi
if [[ -n "${bin[mfcd-ctl]:-}" ]]; then
  b="${bin[mfcd-ctl]}"
  expect 2 stderr "cannot connect to $T/none.sock" -- "$b" --socket="$T/none.sock" status
  expect 2 stderr "--timeout 'x' is not an integer" -- "$b" --timeout=x status
  expect 2 stderr "unknown option '--frobnicate'" -- "$b" calibrate capture --frobnicate
  expect 2 stderr "a command is required" -- "$b" calibrate
  expect 2 stderr "unknown command 'sideways'" -- "$b" calibrate sideways
  expect 2 stderr "--pose '1,2,3': expected x,y,z,rx,ry,rz" -- "$b" calibrate check --pose=1,2,3
  expect 0 stdout "Usage: mfcd-ctl calibrate" -- "$b" calibrate --help
  expect 0 stdout "--mode" -- "$b" calibrate hand-eye start --help
  expect 0 stdout "RECIPE" -- "$b" trigger --help
fi
if [[ -n "${bin[mfc-plc-client]:-}" ]]; then
  b="${bin[mfc-plc-client]}"
  expect 2 stderr "cannot connect to 127.0.0.1:1:" -- "$b" --host=127.0.0.1 --port=1 --connect-timeout-ms=0 --cycles=1
  expect 2 stderr "--port 'p' is not an integer" -- "$b" --port=p
fi
[[ $fail -eq 0 ]] && echo "command lines: ok"
exit $fail
