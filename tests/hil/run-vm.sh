#!/usr/bin/env bash
# tests/hil/run-vm.sh — boot the HIL VM (QEMU, TCG) and run one job script chrooted into this machine's
# root filesystem; exit with the job's status.
#
# Usage: run-vm.sh [--share DIR] [--job SCRIPT]
#   --share DIR   shared read-write with the guest at the same path (job output goes here)
#   --job SCRIPT  run `sh SCRIPT` inside the guest (cwd = DIR); without it the VM only checks the drivers
# Environment: MFC_HIL_TIMEOUT (seconds, default 300), MFC_HIL_CACHE (see setup.sh).
# Exit: the job's status; 77 = skipped (QEMU or kernel bits unavailable, message on stderr);
#       125 = the VM produced no result (timeout, panic) — a failure, with the console log kept.
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
SHARE=; JOB=
while [[ $# -gt 0 ]]; do
  case "$1" in
    --share) SHARE=$(readlink -f "$2"); shift ;;
    --job) JOB=$(readlink -f "$2"); shift ;;
    *) echo "run-vm: unknown argument '$1'" >&2; exit 2 ;;
  esac
  shift
done

command -v qemu-system-x86_64 >/dev/null \
  || { echo "run-vm: SKIP: qemu-system-x86_64 not found (apt-get install qemu-system-x86, or tools/mfc setup)" >&2; exit 77; }
# Can QEMU start at all here (sandboxes without /dev/shm, seccomp, ...)? TCG needs no KVM. KVM is
# deliberately not used: on these machines /dev/kvm is a paravirtual kvm_pvm that cannot run a stock kernel.
if ! echo quit | timeout 30 qemu-system-x86_64 -accel tcg -nodefaults -display none -monitor stdio -S >/dev/null 2>&1; then
  echo "run-vm: SKIP: qemu-system-x86_64 cannot start a TCG machine here" >&2; exit 77
fi

out=$("$HERE/setup.sh")
rc=$?
[[ $rc -eq 0 ]] || exit "$rc"   # 77 = skip, with setup.sh's message
KDIR=$(sed -n 1p <<<"$out"); INITRD=$(sed -n 2p <<<"$out")

APPEND="console=ttyS0 quiet loglevel=3 panic=-1"
EXTRA=(-virtfs local,path=/,mount_tag=hostroot,security_model=passthrough,readonly=on,multidevs=remap)
if [[ -n "$SHARE" ]]; then
  APPEND+=" mfc.share=$SHARE"
  EXTRA+=(-virtfs "local,path=$SHARE,mount_tag=share,security_model=passthrough,multidevs=remap")
fi
[[ -n "$JOB" ]] && APPEND+=" mfc.job=$JOB"

# -cpu max: the project builds for x86-64-v2 (SSE4.2, POPCNT), which the default qemu64 model lacks.
LOG=$(mktemp "${TMPDIR:-/tmp}/mfc-hil-console.XXXXXX")
start=$(date +%s.%N)
timeout -k 5 "${MFC_HIL_TIMEOUT:-300}" qemu-system-x86_64 -accel tcg -cpu max -m 1024 -smp 2 -display none \
  -no-reboot -nodefaults -serial stdio -kernel "$KDIR/vmlinux" -initrd "$INITRD" -append "$APPEND" \
  "${EXTRA[@]}" </dev/null 2>&1 | tee "$LOG"
end=$(date +%s.%N)
rc=$(tr -d '\r' <"$LOG" | sed -n 's/^MFC-HIL-EXIT=\([0-9]*\)$/\1/p' | tail -1)
awk -v s="$start" -v e="$end" 'BEGIN{printf "run-vm: VM wall time %.1f s\n", e - s}' >&2
if [[ -z "$rc" ]]; then
  echo "run-vm: FAILED: no MFC-HIL-EXIT line from the VM (timeout after ${MFC_HIL_TIMEOUT:-300} s or kernel panic); console log kept in $LOG" >&2
  exit 125
fi
rm -f "$LOG"
exit "$rc"
