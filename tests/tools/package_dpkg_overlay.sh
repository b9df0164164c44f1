#!/bin/sh
# The .deb through dpkg for real, on a throwaway copy of this system: run by package_deb.sh as
# `unshare -m --propagation private package_dpkg_overlay.sh DEB DIR` (root). In that private mount
# namespace / is overlaid with a tmpfs under DIR and dpkg runs chrooted in the overlay, as in an
# image build: no systemd or udevd running there, so the maintainer scripts' guards hold, and every
# write (users, /etc, /var/lib/dpkg) lands in the tmpfs, which goes when the namespace does.
# Checks: dpkg -i configures (user mfcd in video and gpio, /var/lib/mfcd and its folders owned by
# mfcd, the camera file, /etc/mfcd/mfcd.yaml a conffile), systemd-analyze verify passes on the
# installed unit as installed (/usr/bin/mfcd, a whole OS around it), the unit enables; dpkg -r
# disables it and keeps the configuration and data; dpkg -P removes /etc/mfcd and keeps the user.
# Exit 77 when overlayfs cannot be mounted here.
# shellcheck disable=SC2016 # in_root's commands are expanded by the shell in the chroot
set -eu
deb="$1" dir="$2"
fail() { echo "FAIL (dpkg in an overlay): $*"; exit 1; }
mkdir -p "$dir"
mount -t tmpfs mfcd-ovl "$dir" || { echo "SKIP: cannot mount a tmpfs here"; exit 77; }
mkdir -p "$dir/upper" "$dir/work" "$dir/root"
mount -t overlay mfcd-ovl -o "lowerdir=/,upperdir=$dir/upper,workdir=$dir/work" "$dir/root" 2> "$dir/mount.log" ||
  { cat "$dir/mount.log"; echo "SKIP: overlayfs over / not possible here"; exit 77; }
r="$dir/root"
mount -t proc proc "$r/proc"
mount --rbind /dev "$r/dev"
mount -t tmpfs tmpfs "$r/run"
mount -t tmpfs tmpfs "$r/tmp"
cp "$deb" "$r/tmp/mfcd.deb"
in_root() { chroot "$r" /bin/sh -c "$1"; }

in_root 'dpkg -i /tmp/mfcd.deb' > "$dir/dpkg-i.log" 2>&1 || { cat "$dir/dpkg-i.log"; fail "dpkg -i"; }
in_root 'dpkg-query -W -f="\${Status}" mfcd' | grep -q 'install ok installed' || fail "mfcd not installed"
groups=$(in_root 'id -nG mfcd') || fail "no user mfcd"
for g in mfcd video gpio; do
  case " $groups " in *" $g "*) ;; *) fail "mfcd is not in group $g (groups: $groups)" ;; esac
done
for d in /var/lib/mfcd /var/lib/mfcd/templates /var/lib/mfcd/snapshots; do
  [ "$(in_root "stat -c '%U:%G %a' $d")" = "mfcd:mfcd 750" ] || fail "$d is not mfcd:mfcd 0750"
done
in_root 'test -f /var/lib/mfcd/camera-sim.yaml' || fail "no /var/lib/mfcd/camera-sim.yaml"
in_root 'dpkg-query -W -f="\${Conffiles}" mfcd' | grep -q '^ /etc/mfcd/mfcd.yaml ' || fail "/etc/mfcd/mfcd.yaml is not a conffile"
out=$(in_root 'systemd-analyze verify mfcd.service' 2>&1) || { echo "$out"; fail "systemd-analyze verify"; }
if echo "$out" | grep -q "mfcd.service"; then echo "$out"; fail "systemd-analyze verify warned about the installed unit"; fi
in_root 'systemctl enable mfcd.service' > /dev/null 2>&1 || fail "systemctl enable mfcd.service"
in_root 'test -L /etc/systemd/system/multi-user.target.wants/mfcd.service' || fail "enable made no wants link"
echo "dpkg -i: configured; user mfcd ($groups), /var/lib/mfcd, conffile, unit verified and enabled"

in_root 'dpkg -r mfcd' > "$dir/dpkg-r.log" 2>&1 || { cat "$dir/dpkg-r.log"; fail "dpkg -r"; }
in_root 'test ! -e /etc/systemd/system/multi-user.target.wants/mfcd.service' || fail "dpkg -r left the wants link"
in_root 'test -f /etc/mfcd/mfcd.yaml && test -f /var/lib/mfcd/camera-sim.yaml' || fail "dpkg -r removed configuration or data"
in_root 'test ! -e /usr/bin/mfcd' || fail "dpkg -r left /usr/bin/mfcd"
in_root 'dpkg -P mfcd' > "$dir/dpkg-p.log" 2>&1 || { cat "$dir/dpkg-p.log"; fail "dpkg -P"; }
in_root 'test ! -e /etc/mfcd/mfcd.yaml' || fail "dpkg -P left /etc/mfcd/mfcd.yaml"
in_root 'getent passwd mfcd' > /dev/null || fail "dpkg -P removed the user"
echo "dpkg -r: disabled, configuration and data kept; dpkg -P: conffile gone, user kept"
