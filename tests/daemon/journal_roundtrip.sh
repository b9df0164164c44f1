#!/bin/sh
# journal_roundtrip.sh PROBE CYCLE JOB: runs mfcd_journal_probe under a real systemd-journald and
# prints what journald stored, as journalctl -o json lines under section markers:
#   == mode <systemd-run|private-journald>
#   == entries        entries with MFCD_JOB_ID=JOB (the probe's three cycle lines)
#   == error-code-2   entries with MFCD_ERROR_CODE=2 MFCD_JOB_ID=JOB (the error line only)
#   == stdout         the probe's stdout/stderr stream (its "journal sink open" line, nothing else)
# Which journald:
# * systemd is PID 1 with its journal: the probe runs as a transient service (systemd-run), so
#   systemd itself connects its stderr to the journal and sets $JOURNAL_STREAM, as for mfcd.service.
# * otherwise, as root where unshare(1) may make a mount namespace (a container without systemd):
#   a private systemd-journald in that namespace, with tmpfs over /run and /var/log so nothing of the
#   host changes, and in a new PID namespace (with its own /proc), so that journald ends with the
#   script however the script ends; systemd-cat connects the probe's stdout/stderr to it and $JOURNAL_STREAM is set to
#   that stream's device:inode, as systemd would.
# Neither: prints "SKIP: <reason>" and exits 77.
set -u
probe=$1 cycle=$2 job=$3

skip() { echo "SKIP: $*"; exit 77; }
have() { command -v "$1" >/dev/null 2>&1; }

have journalctl || skip "journalctl not found"

if [ -d /run/systemd/system ] && [ -S /run/systemd/journal/socket ] && have systemd-run; then
  unit="mfcd-journal-test-$$-$job"
  if systemd-run --quiet --wait --collect --unit="$unit" -p StandardOutput=journal -p StandardError=journal \
       "$probe" "$cycle" "$job" >/dev/null 2>&1; then
    journalctl --sync >/dev/null 2>&1 || true
    i=0  # journald stores asynchronously: wait for the three entries (5 s at most)
    while [ "$(journalctl --no-pager -o json _SYSTEMD_UNIT="$unit.service" MFCD_JOB_ID="$job" 2>/dev/null | wc -l)" -lt 3 ] &&
          [ $i -lt 50 ]; do i=$((i + 1)); sleep 0.1; done
    echo "== mode systemd-run"
    echo "== entries"
    journalctl --no-pager -o json _SYSTEMD_UNIT="$unit.service" MFCD_JOB_ID="$job"
    echo "== error-code-2"
    journalctl --no-pager -o json _SYSTEMD_UNIT="$unit.service" MFCD_ERROR_CODE=2 MFCD_JOB_ID="$job"
    echo "== stdout"
    journalctl --no-pager -o json _SYSTEMD_UNIT="$unit.service" _TRANSPORT=stdout
    exit 0
  fi
  # Not permitted (not root, no polkit rule): try a private journald below.
fi

[ "$(id -u)" = 0 ] || skip "no system journald to run under (systemd is not PID 1 or systemd-run was refused) and not root for a private one"
for tool in unshare systemd-cat stat; do have $tool || skip "$tool not found"; done
journald=
for j in /lib/systemd/systemd-journald /usr/lib/systemd/systemd-journald; do [ -x "$j" ] && journald=$j && break; done
[ -n "$journald" ] || skip "systemd-journald not found"
unshare -m -p -f --mount-proc --propagation private true 2>/dev/null ||
  skip "unshare of a mount and PID namespace is not permitted here (no CAP_SYS_ADMIN)"

inner='
set -eu
probe=$1 cycle=$2 job=$3 journald=$4
for dir in /run /var/log; do
  mount -n -t tmpfs -o mode=0755 tmpfs $dir 2>/dev/null || { echo "SKIP: cannot mount a tmpfs over $dir here"; exit 77; }
done
mkdir -p /run/systemd/journal /run/log
"$journald" </dev/null >/dev/null 2>&1 &
jpid=$!
trap "kill $jpid 2>/dev/null; wait $jpid 2>/dev/null || true" EXIT
i=0
until [ -S /run/systemd/journal/socket ] && [ -S /run/systemd/journal/stdout ]; do
  i=$((i + 1))
  [ $i -le 200 ] || { echo "SKIP: the private systemd-journald did not start"; exit 77; }
  sleep 0.05
done
systemd-cat -t mfcd-journal-probe /bin/sh -c "export JOURNAL_STREAM=\$(stat -L -c %d:%i /proc/self/fd/2); exec \"\$@\"" \
  sh "$probe" "$cycle" "$job" </dev/null
journalctl --sync
echo "== mode private-journald"
echo "== entries"
journalctl --no-pager -o json MFCD_JOB_ID="$job"
echo "== error-code-2"
journalctl --no-pager -o json MFCD_ERROR_CODE=2 MFCD_JOB_ID="$job"
echo "== stdout"
journalctl --no-pager -o json _TRANSPORT=stdout
'
exec unshare -m -p -f --mount-proc --propagation private /bin/sh -c "$inner" sh "$probe" "$cycle" "$job" "$journald"
