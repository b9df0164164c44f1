#!/bin/sh
# systemd-analyze verify on systemd/mfcd.service, with ExecStart pointed at the built mfcd (verify
# checks that the binary exists). Exit 77 (skipped) where systemd-analyze is absent.
# Usage: verify_unit.sh UNIT MFCD_BINARY
set -eu
unit="$1"; mfcd="$(realpath "$2")"
command -v systemd-analyze >/dev/null 2>&1 || { echo "systemd-analyze not installed (tools/deps/daemon.txt lists systemd)"; exit 77; }
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
sed "s|^ExecStart=/usr/bin/mfcd|ExecStart=$mfcd|" "$unit" > "$tmp/mfcd.service"
out="$(systemd-analyze verify "$tmp/mfcd.service" 2>&1)" || { echo "$out"; exit 1; }
# verify exits 0 on some warnings; any line about our unit is a failure.
if echo "$out" | grep -q "mfcd.service"; then echo "$out"; exit 1; fi
for key in Type=notify WatchdogSec= Restart=on-failure RuntimeDirectory= StateDirectory= LimitRTPRIO= \
           DeviceAllow=char-video4linux DeviceAllow=char-gpiochip ProtectSystem=strict NoNewPrivileges=yes User=mfcd; do
  grep -q "^$key" "$unit" || { echo "mfcd.service lacks $key"; exit 1; }
done
echo "systemd-analyze verify: mfcd.service ok"
