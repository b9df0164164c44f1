#!/bin/sh
# systemd-analyze verify on systemd/mfcd.service, with its Exec lines pointed at the built mfcd
# (verify checks that the binary exists), and systemd-analyze security: overall exposure <= 2.0.
# Exit 77 (skipped) where systemd-analyze is absent.
# Usage: verify_unit.sh UNIT MFCD_BINARY
set -eu
unit="$1"; mfcd="$(realpath "$2")"
command -v systemd-analyze >/dev/null 2>&1 || { echo "systemd-analyze not installed (tools/deps/daemon.txt lists systemd)"; exit 77; }
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
sed -E "s|^(Exec[A-Za-z]*=)/usr/bin/mfcd|\1$mfcd|" "$unit" > "$tmp/mfcd.service"
out="$(systemd-analyze verify "$tmp/mfcd.service" 2>&1)" || { echo "$out"; exit 1; }
# verify exits 0 on some warnings; any line about our unit is a failure.
if echo "$out" | grep -q "mfcd.service"; then echo "$out"; exit 1; fi
for key in Type=notify WatchdogSec= Restart=on-failure RuntimeDirectory= StateDirectory= LimitRTPRIO= \
           DeviceAllow=char-video4linux DeviceAllow=char-gpiochip ProtectSystem=strict NoNewPrivileges=yes User=mfcd \
           "ExecStopPost=/usr/bin/mfcd .*--leds-off" RestartPreventExitStatus=2 SystemCallFilter=@system-service \
           ProtectProc=invisible IPAddressDeny=any; do
  grep -q "^$key" "$unit" || { echo "mfcd.service lacks $key"; exit 1; }
done
# The LED switch-off must work as the unit calls it: the built mfcd takes --leds-off.
"$mfcd" --help | grep -q -- "--leds-off" || { echo "mfcd has no --leds-off"; exit 1; }
# Exposure: systemd-analyze rates 0 (locked down) .. 10 (unprotected); --threshold is in tenths.
security="$(systemd-analyze security --offline=yes "$tmp/mfcd.service" 2>&1 | grep 'Overall exposure')" || true
echo "$security"
systemd-analyze security --offline=yes --threshold=20 "$tmp/mfcd.service" >/dev/null 2>&1 ||
  { echo "mfcd.service exposure above 2.0: $security"; exit 1; }
echo "systemd-analyze verify: mfcd.service ok"
