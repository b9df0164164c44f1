#!/bin/sh
# `cmake --install BUILD --prefix /usr` into a DESTDIR, then what a Debian system would do with that
# tree, all confined to the DESTDIR: the files (package_common.sh), the installed programs run,
# the unit passes systemd-analyze verify, systemd-sysusers --root makes user mfcd (groups mfcd,
# gpio, video) and systemd-tmpfiles --root makes /var/lib/mfcd and its folders owned by mfcd with
# the camera file, never overwriting it afterwards; a second install keeps an edited
# /etc/mfcd/mfcd.yaml. The host's /etc/passwd and /etc/group are checked unchanged. A check whose
# tool is missing (or tmpfiles' chown when not root) is skipped: the others still run, then exit
# 77 names what was skipped.
# Usage: package_install_tree.sh BUILD SRC WORK PROGRAM...
set -eu
build="$1" src="$2" work="$3"; shift 3
. "$(dirname "$0")/package_common.sh"
skipped=""
skip() { echo "SKIP: $*"; skipped="$skipped; $*"; }

rm -rf "$work"; mkdir -p "$work"
root="$work/root"
host_ids="$(cat /etc/passwd /etc/group | cksum)"

DESTDIR="$root" cmake --install "$build" --prefix /usr > "$work/install.log" ||
  { cat "$work/install.log"; fail "cmake --install failed"; }
(cd "$root" && find . -type f -o -type l) | sed 's|^\./||' | sort > "$work/files.txt"
check_listing "$work/files.txt" "$src" "$@"
echo "install tree: $(wc -l < "$work/files.txt") files, every expected one present"

# The files are the sources, byte for byte (the unit is not rewritten on install).
unit="$root/$(grep -E '^(usr/)?lib/systemd/system/mfcd\.service$' "$work/files.txt")"
cmp -s "$unit" "$src/systemd/mfcd.service" || fail "installed unit differs from systemd/mfcd.service"
cmp -s "$root/etc/mfcd/mfcd.yaml" "$src/config/cell.yaml" || fail "/etc/mfcd/mfcd.yaml is not config/cell.yaml"
for f in "sysusers.d/mfcd.conf mfcd.sysusers" "tmpfiles.d/mfcd.conf mfcd.tmpfiles" \
         "udev/rules.d/60-mfcd-gpio.rules 60-mfcd-gpio.rules"; do
  rel="${f% *}" name="${f#* }"
  installed="$root/$(grep -E "^(usr/)?lib/$rel\$" "$work/files.txt")"
  cmp -s "$installed" "$src/systemd/$name" || fail "$rel is not systemd/$name"
done
grep -q '^SUBSYSTEM=="gpio", KERNEL=="gpiochip\*", GROUP="gpio", MODE="0660"$' "$src/systemd/60-mfcd-gpio.rules" ||
  fail "the udev rule does not give gpiochip* to group gpio, mode 0660"
# Installing again keeps the cell's edited configuration.
echo "# edited for this cell" >> "$root/etc/mfcd/mfcd.yaml"
DESTDIR="$root" cmake --install "$build" --prefix /usr > "$work/install2.log" || { cat "$work/install2.log"; fail "second cmake --install failed"; }
tail -n 1 "$root/etc/mfcd/mfcd.yaml" | grep -q '^# edited for this cell$' || fail "a second install replaced the edited /etc/mfcd/mfcd.yaml"
# The unit's paths are the tree's: --config in etc/mfcd, the program in usr/bin.
grep -q '^ExecStart=/usr/bin/mfcd --config /etc/mfcd/mfcd.yaml ' "$unit" || fail "ExecStart is not /usr/bin/mfcd --config /etc/mfcd/mfcd.yaml"

# Every installed program runs from the tree (its libraries resolve without the build tree).
for p in "$@"; do
  "$root/usr/bin/$p" --help > /dev/null 2>&1 || fail "installed $p --help failed"
  if command -v readelf > /dev/null 2>&1 && readelf -d "$root/usr/bin/$p" | grep -E 'R(UN)?PATH' | grep -q "$build"; then
    fail "installed $p keeps an RPATH into the build tree"
  fi
done
echo "programs: $# run --help from the tree"

# The installed mfcd does not search the build and source trees it was compiled in (the package
# ships these very binaries): a relative camera file is looked for in the config's folder,
# /var/lib/mfcd and /usr/share/mfcd only. The build tree's own mfcd finds it in config/.
case " $* " in *" mfcd "*)
  mkdir -p "$work/paths"
  printf 'camera:\n  model: camera-sim.yaml\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n' > "$work/paths/mfcd.yaml"
  out="$("$root/usr/bin/mfcd" --config "$work/paths/mfcd.yaml" --check-config 2>&1)" && fail "installed mfcd found camera-sim.yaml: $out"
  echo "$out" | grep -q "not found in the search path ($work/paths, /var/lib/mfcd, /usr/share/mfcd)" ||
    fail "installed mfcd's search path is not the config folder, /var/lib/mfcd, /usr/share/mfcd: $out"
  "$build/daemon/mfcd" --config "$work/paths/mfcd.yaml" --check-config > /dev/null 2>&1 ||
    fail "the build tree's mfcd does not find config/camera-sim.yaml"
  echo "search path: the installed mfcd leaves the build tree out" ;;
esac

# systemd-analyze verify. Its --root (systemd 252 has it) would need the whole OS in the root
# (sysinit.target, /bin/kill), so the installed unit is verified as a copy whose Exec lines name the
# installed mfcd.
if command -v systemd-analyze > /dev/null 2>&1; then
  sed -E "s|^(Exec[A-Za-z]*=)/usr/bin/mfcd|\1$root/usr/bin/mfcd|" "$unit" > "$work/mfcd.service"
  out="$(systemd-analyze verify "$work/mfcd.service" 2>&1)" || { echo "$out"; fail "systemd-analyze verify"; }
  if echo "$out" | grep -q "mfcd.service"; then echo "$out"; fail "systemd-analyze verify warned about the unit"; fi
  echo "systemd-analyze verify: installed unit ok"
else
  skip "systemd-analyze not installed (systemd: tools/deps/daemon.txt)"
fi

# sysusers.d: user mfcd with its own group and home /var/lib/mfcd, member of gpio and video.
if command -v systemd-sysusers > /dev/null 2>&1; then
  mkdir -p "$root/etc"
  systemd-sysusers --root="$root" mfcd.conf > "$work/sysusers.log" 2>&1 ||
    { cat "$work/sysusers.log"; fail "systemd-sysusers --root failed"; }
  grep -q '^mfcd:x:[0-9]*:[0-9]*:[^:]*:/var/lib/mfcd:' "$root/etc/passwd" || fail "no user mfcd (home /var/lib/mfcd) in DESTDIR/etc/passwd"
  grep -q '^mfcd:x:[0-9]*:' "$root/etc/group" || fail "no group mfcd"
  grep -q '^gpio:x:[0-9]*:\(.*,\)\?mfcd\(,.*\)\?$' "$root/etc/group" || fail "group gpio missing or mfcd not in it"
  grep -q '^video:x:[0-9]*:\(.*,\)\?mfcd\(,.*\)\?$' "$root/etc/group" || fail "mfcd not in group video"
  echo "systemd-sysusers --root: user mfcd, groups mfcd gpio video"
else
  skip "systemd-sysusers not installed"
fi

# tmpfiles.d: the folders, owned by mfcd, 0750, and the camera file, copied once.
if ! command -v systemd-tmpfiles > /dev/null 2>&1; then
  skip "systemd-tmpfiles not installed"
elif [ "$(id -u)" -ne 0 ] || ! grep -q '^mfcd:' "$root/etc/passwd" 2> /dev/null; then
  skip "systemd-tmpfiles --create: needs root (chown to mfcd) and the sysusers step"
else
  systemd-tmpfiles --root="$root" --create mfcd.conf > "$work/tmpfiles.log" 2>&1 ||
    { cat "$work/tmpfiles.log"; fail "systemd-tmpfiles --root --create failed"; }
  uid=$(sed -n 's/^mfcd:x:\([0-9]*\):.*/\1/p' "$root/etc/passwd")
  for d in var/lib/mfcd var/lib/mfcd/templates var/lib/mfcd/snapshots; do
    [ -d "$root/$d" ] || fail "/$d not created"
    [ "$(stat -c '%u %a' "$root/$d")" = "$uid 750" ] || fail "/$d is $(stat -c '%u %a' "$root/$d"), not mfcd ($uid) 750"
  done
  cam="$root/var/lib/mfcd/camera-sim.yaml"
  cmp -s "$cam" "$src/config/camera-sim.yaml" || fail "camera-sim.yaml not copied into /var/lib/mfcd"
  echo "# calibrated" >> "$cam"
  systemd-tmpfiles --root="$root" --create mfcd.conf > /dev/null 2>&1 || fail "second systemd-tmpfiles --create failed"
  grep -q '^# calibrated$' "$cam" || fail "systemd-tmpfiles overwrote the calibrated camera file"
  echo "systemd-tmpfiles --root: /var/lib/mfcd{,/templates,/snapshots} mfcd 0750, camera file kept"
fi

[ "$(cat /etc/passwd /etc/group | cksum)" = "$host_ids" ] || fail "the host's /etc/passwd or /etc/group changed"
if [ -n "$skipped" ]; then echo "skipped:${skipped#;}"; exit 77; fi
echo "install tree ok"
