#!/bin/sh
# The Debian package as `tools/mfc package` builds it: cpack (DEB) on the build tree, then
# dpkg-deb -f (name, version, architecture, maintainer, section, priority, Depends from
# dpkg-shlibdeps plus systemd and Mesa's drivers), dpkg-deb -c (the files of package_common.sh,
# owned by root, modes), the control archive (conffiles, maintainer scripts as in packaging/) and
# the maintainer scripts' guards, run with stand-ins for systemd-sysusers, systemd-tmpfiles,
# systemctl and udevadm on PATH that only record their arguments (nothing touches the host), and
# as root a real dpkg -i, -r and -P on a throwaway overlay of this system (package_dpkg_overlay.sh).
# The slower of the two package tests: cpack strips, runs dpkg-shlibdeps on and compresses the
# programs it finds built (it builds nothing: with Ninja it has no preinstall step), 5-11 s on 2
# cores. Exit 77 when dpkg-deb, dpkg-shlibdeps (dpkg-dev) or file is missing (tools/deps/package.txt).
# Usage: package_deb.sh CPACK BUILD SRC WORK VERSION PROGRAM...
set -eu
cpack="$1" build="$2" src="$3" work="$4" version="$5"; shift 5
. "$(dirname "$0")/package_common.sh"
for t in dpkg-deb dpkg-shlibdeps file; do
  command -v "$t" > /dev/null 2>&1 || { echo "SKIP: $t not installed (tools/deps/package.txt)"; exit 77; }
done
rm -rf "$work"; mkdir -p "$work"

start=$(date +%s)
"$cpack" -G DEB --config "$build/CPackConfig.cmake" -B "$work/out" > "$work/cpack.log" 2>&1 ||
  { cat "$work/cpack.log"; fail "cpack failed"; }
arch=$(dpkg --print-architecture)
deb="$work/out/mfcd_${version}_${arch}.deb"
[ -f "$deb" ] || { ls "$work/out"; fail "cpack made no $(basename "$deb")"; }
echo "cpack: $(basename "$deb"), $(($(stat -c %s "$deb") / 1024)) KiB in $(($(date +%s) - start)) s"

# Control fields.
field() { dpkg-deb -f "$deb" "$1"; }
[ "$(field Package)" = mfcd ] || fail "Package is '$(field Package)'"
[ "$(field Version)" = "$version" ] || fail "Version is '$(field Version)', not the project's $version"
[ "$(field Architecture)" = "$arch" ] || fail "Architecture is '$(field Architecture)'"
field Maintainer | grep -q '^[^<]\+ <[^@>]\+@[^>]\+>$' || fail "Maintainer '$(field Maintainer)' is not 'Name <address>'"
[ "$(field Section)" = misc ] || fail "Section is '$(field Section)'"
[ "$(field Priority)" = optional ] || fail "Priority is '$(field Priority)'"
field Description | head -n 1 | grep -q 'bin-picking vision daemon' || fail "no Description summary"
field Description | sed -n 2p | grep -q '^ *mfcd fires' || fail "the long Description does not follow the summary"
depends="$(field Depends)"
# From dpkg-shlibdeps (libc6, libsystemd0, libmodbus5, OpenCV, ...) and from packaging/.
for d in libc6 libsystemd0 libmodbus5 'libopencv-core[0-9.]*' systemd libgl1-mesa-dri; do
  echo "$depends" | tr ',' '\n' | grep -q "^ *$d\( (.*)\)\?$" || fail "Depends lacks $d: $depends"
done
echo "fields: Package mfcd, Version $version, Architecture $arch, Depends $(echo "$depends" | tr ',' '\n' | wc -l) entries"

# Files, owners and modes.
dpkg-deb -c "$deb" > "$work/contents.txt"
awk '$1 !~ /^d/ { print $6 }' "$work/contents.txt" | sed 's|^\./||' | sort > "$work/files.txt"
check_listing "$work/files.txt" "$src" "$@"
awk '$2 != "root/root" { print; bad = 1 } END { exit bad }' "$work/contents.txt" || fail "files not owned by root/root"
grep -q '^-rw-r--r-- .* \./etc/mfcd/mfcd\.yaml$' "$work/contents.txt" || fail "/etc/mfcd/mfcd.yaml is not 0644"
for p in "$@"; do
  grep -q "^-rwxr-xr-x .* \./usr/bin/$p\$" "$work/contents.txt" || fail "/usr/bin/$p is not 0755"
done
echo "contents: $(wc -l < "$work/files.txt") files, every expected one present"

# Control archive: the conffile and the maintainer scripts of packaging/, executable.
dpkg-deb -e "$deb" "$work/control"
[ "$(cat "$work/control/conffiles")" = /etc/mfcd/mfcd.yaml ] || fail "conffiles is not /etc/mfcd/mfcd.yaml"
for s in postinst prerm postrm; do
  cmp -s "$work/control/$s" "$src/packaging/$s" || fail "$s differs from packaging/$s"
  [ "$(stat -c %a "$work/control/$s")" = 755 ] || fail "$s is not 0755"
done

# The maintainer scripts' guards, with stand-ins recording each call as "NAME ARGS".
mkdir -p "$work/shim"
for t in systemd-sysusers systemd-tmpfiles systemctl udevadm; do
  # shellcheck disable=SC2016 # $* and ${SHIM_FAIL} are the stand-in's, expanded when it runs
  printf '#!/bin/sh\necho "%s $*" >> "%s/calls.log"\n[ "${SHIM_FAIL:-}" != %s ]\n' "$t" "$work" "$t" > "$work/shim/$t"
  chmod +x "$work/shim/$t"
done
# run [VAR=VALUE] SCRIPT ARGS...: the calls it made, in order, in $work/calls.log; it must exit 0.
run() {
  e=""; case "$1" in *=*) e="$1"; shift ;; esac
  s="$1"; shift; : > "$work/calls.log"
  env ${e:+"$e"} PATH="$work/shim:$PATH" sh "$work/control/$s" "$@" > /dev/null 2> "$work/stderr.log" ||
    { cat "$work/stderr.log"; fail "${e:+$e }$s $* exited non-zero"; }
}
called() { grep -q -x -F "$1" "$work/calls.log" || { cat "$work/calls.log"; fail "$2: no call '$1'"; }; }
not_called() { ! grep -q "^$1" "$work/calls.log" || { cat "$work/calls.log"; fail "$2: unexpected call '$1'"; }; }
systemd_up=no; [ -d /run/systemd/system ] && systemd_up=yes
udev_up=no; [ -d /run/udev ] && udev_up=yes

# An image build (DPKG_ROOT): files only, into the image; never the running system's managers.
img="$work/image"
run DPKG_ROOT="$img" postinst configure
called "systemd-sysusers --root=$img mfcd.conf" "postinst in DPKG_ROOT"
called "systemd-tmpfiles --root=$img --create mfcd.conf" "postinst in DPKG_ROOT"
not_called "systemctl" "postinst in DPKG_ROOT"; not_called "udevadm" "postinst in DPKG_ROOT"
run DPKG_ROOT="$img" prerm remove
called "systemctl --root=$img disable mfcd.service" "prerm remove in DPKG_ROOT"
not_called "systemctl stop" "prerm remove in DPKG_ROOT"

# A first install on this system: users, folders, udev and systemd when they are running, no start.
run postinst configure
called "systemd-sysusers mfcd.conf" "postinst configure"
called "systemd-tmpfiles --create mfcd.conf" "postinst configure"
if [ $udev_up = yes ]; then
  called "udevadm trigger --subsystem-match=gpio --sysname-match=gpiochip* --action=change" "postinst (udevd running)"
else
  not_called "udevadm" "postinst (no udevd: a chroot or container)"
fi
if [ $systemd_up = yes ]; then called "systemctl --system daemon-reload" "postinst (systemd running)"; fi
not_called "systemctl try-restart" "postinst on a first install"; not_called "systemctl start" "postinst"
not_called "systemctl enable" "postinst"
# An upgrade restarts a running service; a failing tmpfiles only warns.
run postinst configure 0.0.1
if [ $systemd_up = yes ]; then called "systemctl try-restart mfcd.service" "postinst on upgrade"; fi
run SHIM_FAIL=systemd-tmpfiles postinst configure
grep -q "systemd-tmpfiles --create mfcd.conf failed" "$work/stderr.log" || fail "no warning when systemd-tmpfiles fails"

# Removal stops (when systemd runs) and disables; an upgrade's prerm leaves the service alone.
run prerm remove
called "systemctl disable mfcd.service" "prerm remove"
if [ $systemd_up = yes ]; then called "systemctl stop mfcd.service" "prerm remove (systemd running)"; fi
run prerm upgrade 0.2.0
[ ! -s "$work/calls.log" ] || { cat "$work/calls.log"; fail "prerm upgrade called something"; }
run postrm purge
if [ $systemd_up = yes ]; then called "systemctl --system daemon-reload" "postrm purge"; fi
echo "maintainer scripts: guards ok (systemd running: $systemd_up, udevd running: $udev_up)"

# dpkg itself, on a throwaway overlay of this system in a private mount namespace
# (package_dpkg_overlay.sh); it needs root and a mount namespace.
if [ "$(id -u)" -ne 0 ] || ! unshare -m true > /dev/null 2>&1; then
  echo "SKIP: dpkg -i/-r/-P in an overlay of / needs root and unshare -m (the checks above passed)"
  exit 77
fi
unshare -m --propagation private sh "$(dirname "$0")/package_dpkg_overlay.sh" "$deb" "$work/overlay"
echo "package ok"
