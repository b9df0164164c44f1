#!/usr/bin/env bash
# tests/hil/run-hil.sh — the HIL tier: boot the VM and run the HIL gtest binary (and optionally the
# vivid benchmark) inside it, chrooted into this machine's root so the host build runs unchanged.
#
# Usage: run-hil.sh --out DIR [--candump] HIL_TEST_BINARY [BENCH_BINARY] [-- GTEST_ARGS...]
#   DIR receives hil_tests.xml, bench_hal_vivid.json and the guest's output.
#   --candump: candump (can-utils) records vcan0 while the tests run, as an independent reader;
#   the tier fails unless it saw every frame of docs/mfcd.dbc (status 0x180, heartbeat 0x181, version 0x182,
#   pick 0x190-0x192). Its log is DIR/candump.log.
# Exit: 0 pass, 77 skipped (QEMU/kernel bits unavailable; MFC_HIL_REQUIRED=1 makes that a failure),
#       anything else a failure.
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
OUT=
[[ "${1:-}" == --out ]] && { OUT=$2; shift 2; }
CANDUMP=0
[[ "${1:-}" == --candump ]] && { CANDUMP=1; shift; }
TEST=${1:?usage: run-hil.sh --out DIR HIL_TEST_BINARY [BENCH_BINARY] [-- GTEST_ARGS...]}; shift
BENCH=
[[ $# -gt 0 && "$1" != -- ]] && { BENCH=$1; shift; }
[[ "${1:-}" == -- ]] && shift
OUT=${OUT:-$(dirname "$TEST")/hil-run}
mkdir -p "$OUT" && OUT=$(readlink -f "$OUT")
TEST=$(readlink -f "$TEST"); [[ -n "$BENCH" ]] && BENCH=$(readlink -f "$BENCH")
rm -f "$OUT"/hil_tests.xml "$OUT"/bench_hal_vivid.json

# The job runs inside the VM (busybox sh would also do; the chroot has the host's /bin/sh).
{
  echo 'export MFC_HIL=1'
  if [[ $CANDUMP == 1 ]]; then
    printf 'candump -L vcan0 > %q 2>&1 & cpid=$!\nsleep 0.5\n' "$OUT/candump.log"
  fi
  printf '%q --gtest_color=no --gtest_output=xml:%q' "$TEST" "$OUT/hil_tests.xml"
  for a in "$@"; do printf ' %q' "$a"; done
  echo '; rc=$?'
  if [[ -n "$BENCH" ]]; then
    printf '%q --benchmark_out=%q --benchmark_out_format=json --benchmark_color=false || rc=1\n' "$BENCH" "$OUT/bench_hal_vivid.json"
  fi
  if [[ $CANDUMP == 1 ]]; then
    printf 'sleep 0.5; kill $cpid; wait $cpid 2>/dev/null\n'
    printf 'for id in 180 181 182 190 191 192; do grep -q " vcan0 $id#" %q || { echo "candump saw no frame $id on vcan0"; rc=1; }; done\n' "$OUT/candump.log"
    printf 'echo "candump recorded $(wc -l < %q) frames on vcan0"\n' "$OUT/candump.log"
  fi
  echo 'exit $rc'
} > "$OUT/job.sh"

start=$(date +%s)
"$HERE/run-vm.sh" --share "$OUT" --job "$OUT/job.sh"
rc=$?
echo "run-hil: HIL tier finished with status $rc in $(( $(date +%s) - start )) s (results in $OUT)" >&2
if [[ $rc -eq 77 && "${MFC_HIL_REQUIRED:-0}" == 1 ]]; then
  echo "run-hil: MFC_HIL_REQUIRED=1: a skipped HIL tier is a failure" >&2
  exit 1
fi
exit "$rc"
