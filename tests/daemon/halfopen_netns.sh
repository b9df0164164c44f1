#!/usr/bin/env bash
# Half-open Modbus peers made by a firewall drop in a network namespace (ctest daemon_halfopen_netns).
#
#   halfopen_netns.sh MFCD_HALFOPEN MFCD_TEST_DAEMON
#
# Creates a network namespace and a veth pair with names unique to this run (mfcd-halfopen-<pid>,
# mfho<pid>h / mfho<pid>n), a /29 with the host end .1 (where the daemon binds) and two addresses
# in the namespace (.2: the peers that are cut off, .3: the PLC that reconnects), then runs
# `mfcd_halfopen run` (tests/daemon/halfopen_main.cpp), which starts the daemon, connects from the
# namespace with `ip netns exec`, drops the traffic with nft inside the namespace and checks.
# The namespace (with its nft table and the veth pair, whose peer end lives in it) is deleted on
# every exit path: normal end, failure, or SIGINT/SIGTERM/SIGHUP (trap; the test program is sent
# SIGTERM and ends its daemon and clients first). A run killed with SIGKILL
# cannot clean up; the next run deletes namespaces of this name pattern whose pid is gone.
# Exit 77 (ctest: skipped) with the reason when not root, when `ip`/`nft` are missing, or when
# namespaces, veth pairs or nft rules are not permitted here.
set -uo pipefail

halfopen="${1:?usage: halfopen_netns.sh MFCD_HALFOPEN MFCD_TEST_DAEMON}"
daemon="${2:?usage: halfopen_netns.sh MFCD_HALFOPEN MFCD_TEST_DAEMON}"

skip() { echo "SKIPPED: $*"; exit 77; }

[[ $(id -u) -eq 0 ]] || skip "needs root (network namespaces, veth, nft); CI runs as root"
command -v ip >/dev/null || skip "ip not found: apt-get install iproute2 (tools/deps/daemon.txt)"
command -v nft >/dev/null || skip "nft not found: apt-get install nftables (tools/deps/daemon.txt)"
command -v ss >/dev/null || skip "ss not found: apt-get install iproute2 (tools/deps/daemon.txt)"

# Leftovers of runs that were SIGKILLed (e.g. a ctest timeout): their pid no longer exists.
for ns in $(ip netns list 2>/dev/null | awk '{print $1}' | grep -E '^mfcd-halfopen-[0-9]+$'); do
  pid="${ns#mfcd-halfopen-}"
  kill -0 "$pid" 2>/dev/null || ip netns delete "$ns" 2>/dev/null || true
done

ns="mfcd-halfopen-$$"
veth_host="mfho$$h"
veth_ns="mfho$$n"
cleaned=""
child=""
cleanup() {
  set +e
  [[ -n $cleaned ]] && return
  cleaned=1
  # The test program ends its daemon when it is signalled (halfopen_main.cpp); its temporary
  # directory is left behind then.
  if [[ -n $child ]] && kill -0 "$child" 2>/dev/null; then
    kill -TERM "$child" 2>/dev/null
    wait "$child" 2>/dev/null
    rm -rf "${TMPDIR:-/tmp}/mfcd-test-halfopen-$child"
  fi
  # Processes still inside the namespace are this run's own clients (hold / plc): end them by pid.
  local pids
  pids="$(ip netns pids "$ns" 2>/dev/null || true)"
  [[ -n $pids ]] && kill -KILL $pids 2>/dev/null
  ip link delete "$veth_host" 2>/dev/null   # takes the peer end with it
  ip netns delete "$ns" 2>/dev/null
  if ip netns list 2>/dev/null | awk '{print $1}' | grep -qx "$ns" || ip link show "$veth_host" >/dev/null 2>&1; then
    echo "halfopen_netns.sh: could not remove namespace $ns / link $veth_host" >&2
  fi
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
trap 'exit 129' HUP

# A /29 nobody on this host uses: 10.234.X.Y with X, Y from the pid, moved on while taken.
subnet=""
for ((k = 0; k < 64; k++)); do
  n=$(( ($$ + k) % 8192 ))
  candidate="10.234.$(( n / 32 )).$(( (n % 32) * 8 ))"
  if [[ -z "$(ip -o -4 addr show to "$candidate/29" 2>/dev/null)$(ip -4 route show "$candidate/29" 2>/dev/null)" ]]; then
    subnet="$candidate"
    break
  fi
done
[[ -n $subnet ]] || { echo "halfopen_netns.sh: no free 10.234.x.y/29 subnet"; exit 1; }
base="${subnet%.*}"
last="${subnet##*.}"
host_addr="$base.$(( last + 1 ))"
holder_addr="$base.$(( last + 2 ))"
plc_addr="$base.$(( last + 3 ))"

err="$(ip netns add "$ns" 2>&1)" || skip "ip netns add not permitted here: $err"
err="$(ip link add "$veth_host" type veth peer name "$veth_ns" netns "$ns" 2>&1)" || skip "cannot create a veth pair: $err"
set -e
ip addr add "$host_addr/29" dev "$veth_host"
ip link set "$veth_host" up
ip -n "$ns" link set lo up
ip -n "$ns" addr add "$holder_addr/29" dev "$veth_ns"
ip -n "$ns" addr add "$plc_addr/29" dev "$veth_ns"
ip -n "$ns" link set "$veth_ns" up
set +e
err="$(ip netns exec "$ns" nft list ruleset 2>&1)" || skip "nft does not run in a network namespace here: $err"

# Wait for both ends to be usable (IPv4 needs no DAD, but the link must be up on both sides).
for ((i = 0; i < 50; i++)); do
  ip -n "$ns" -o link show "$veth_ns" | grep -q 'LOWER_UP' && ip -o link show "$veth_host" | grep -q 'LOWER_UP' && break
  sleep 0.1
done

echo "namespace $ns, veth $veth_host (host, $host_addr) <-> $veth_ns ($holder_addr, $plc_addr)"
# In the background and waited for, so that a signal runs the trap at once (bash defers traps while
# a foreground command runs).
"$halfopen" run --daemon "$daemon" --netns "$ns" --host-addr "$host_addr" --holder-addr "$holder_addr" --plc-addr "$plc_addr" &
child=$!
wait "$child"
rc=$?
child=""
exit "$rc"
