#!/usr/bin/env bash
# tests/hil/setup.sh — prepare the kernel bits of the HIL VM and print the cache directory.
#
# The VM boots Debian's own kernel (the one linux-image-amd64 points at) with vivid, vcan and an
# out-of-tree gpio-sim. Debian 12 ships CONFIG_GPIO_SIM off, so gpio-sim.c (and the irq_sim it needs)
# is built from linux-source of the *same* version against linux-headers of the same ABI.
#
# Result, cached per kernel version in $MFC_HIL_CACHE (default ~/.cache/mfcd-hil/<kver>/):
#   vmlinux            uncompressed kernel, booted directly (PVH): avoids slow in-guest xz under TCG
#   modules/<kver>/    just the modules the VM loads, plus depmod output
#   gpio-sim.ko
#   initramfs-<hash>.cpio.gz   busybox + init.sh + modules (rebuilt when init.sh changes)
#
# Exit codes: 0 ready (cache dir on stdout), 77 prerequisites missing (message on stderr: the caller
# skips), anything else a real failure.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
CACHE_ROOT="${MFC_HIL_CACHE:-${XDG_CACHE_HOME:-${HOME:-/tmp}/.cache}/mfcd-hil}"
# Modules the VM's /init loads (their dependencies are resolved with modprobe --show-depends).
VM_MODULES="configfs vivid vcan can-raw virtio_pci 9pnet_virtio 9p overlay"

log() { echo "hil-setup: $*" >&2; }
skip() { echo "hil-setup: SKIP: $*" >&2; exit 77; }

as_root() { if [[ $(id -u) -eq 0 ]]; then "$@"; elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo "$@"; else return 1; fi; }

# Host tools. tools/mfc setup installs them from tools/deps/hal.txt; install here too so the HIL tier
# also works on a machine that only ran this script.
need_pkgs=()
for tool_pkg in qemu-system-x86_64:qemu-system-x86 busybox:busybox-static modprobe:kmod cpio:cpio xz:xz-utils make:make gcc:gcc; do
  command -v "${tool_pkg%%:*}" >/dev/null || need_pkgs+=("${tool_pkg#*:}")
done
# The VM has no libc before the chroot: /bin/busybox must be the static build.
dpkg-query -W -f='${Status}' busybox-static 2>/dev/null | grep -q 'install ok installed' || need_pkgs+=(busybox-static)
if [[ ${#need_pkgs[@]} -gt 0 ]]; then
  log "installing ${need_pkgs[*]}"
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${need_pkgs[@]}" >&2 \
    || { as_root apt-get update -q >&2 && as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${need_pkgs[@]}" >&2; } \
    || skip "cannot install ${need_pkgs[*]} (needs root and Debian's apt archive); run tools/mfc setup"
fi

# Which kernel? The ABI number (6.1.0-NN) moves with security updates: ask the metapackage.
resolve_kernel() {
  local pkg
  pkg=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}')
  [[ -n "$pkg" ]] || return 1
  KPKG=$pkg
  KVER=${pkg#linux-image-}
  KDEBVER=$(apt-cache policy "$pkg" | awk '/Candidate:/{print $2}')
  [[ -n "$KDEBVER" && "$KDEBVER" != "(none)" ]]
}
if ! resolve_kernel; then
  # No apt lists (or offline): use the newest kernel already in the cache.
  KVER=$(ls -1 "$CACHE_ROOT" 2>/dev/null | sort -V | tail -1 || true)
  [[ -n "$KVER" && -f "$CACHE_ROOT/$KVER/.complete" ]] || skip "apt-cache cannot resolve linux-image-amd64 (run apt-get update) and no cached kernel in $CACHE_ROOT"
  log "apt lists unavailable; using cached kernel $KVER"
fi
DIR="$CACHE_ROOT/$KVER"

build_kernel_bits() {
  log "building kernel bits for $KVER ($KPKG $KDEBVER) in $DIR"
  local src="linux-source-${KVER%%.0-*}"   # linux-source-6.1
  local hdr="/usr/src/linux-headers-$KVER"
  if [[ ! -f "$hdr/Makefile" ]]; then
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "linux-headers-$KVER=$KDEBVER" >&2 \
      || skip "linux-headers-$KVER=$KDEBVER is not installed and cannot be installed (needs root); run tools/mfc setup"
  fi
  local tmp; tmp=$(mktemp -d "$CACHE_ROOT/.build.XXXXXX"); chmod 755 "$tmp"  # apt-get download runs as _apt
  trap 'rm -rf "$tmp"' RETURN
  (cd "$tmp" && apt-get download "$KPKG=$KDEBVER" "$src=$KDEBVER" >&2) \
    || skip "apt-get download $KPKG $src failed (Debian archive unreachable or apt lists stale: apt-get update)"
  mkdir "$tmp/kernel"
  dpkg -x "$tmp/${KPKG}_"*.deb "$tmp/kernel"
  depmod -b "$tmp/kernel" "$KVER"

  # The bzImage's payload is xz: pull it out so QEMU can boot the ELF directly (PVH entry point).
  local vmlinuz="$tmp/kernel/boot/vmlinuz-$KVER" off
  off=$(LC_ALL=C grep -obUaP '\xfd7zXZ\x00' "$vmlinuz" | head -1 | cut -d: -f1)
  [[ -n "$off" ]] || { log "no xz payload in $vmlinuz"; return 1; }
  tail -c +$((off + 1)) "$vmlinuz" | xz -dcq > "$tmp/vmlinux" 2>/dev/null || true   # trailing garbage is expected
  [[ "$(head -c4 "$tmp/vmlinux" | tail -c3)" == ELF ]] || { log "extracted vmlinux is not an ELF image"; return 1; }

  # gpio-sim from the same source version; irq_to_desc() is not exported to modules in 6.1, so the
  # bundled irq_sim copy calls generic_handle_irq() (same effect for a simple irq chip).
  mkdir "$tmp/gpiosim"
  dpkg-deb --fsys-tarfile "$tmp/${src}_"*.deb | tar -xO "./usr/src/$src.tar.xz" | xz -dc -T0 \
    | tar -x -C "$tmp/gpiosim" --transform='s|.*/||' --wildcards \
        '*/drivers/gpio/gpio-sim.c' '*/drivers/gpio/gpiolib.h' '*/kernel/irq/irq_sim.c'
  mv "$tmp/gpiosim/gpio-sim.c" "$tmp/gpiosim/gpio_sim_main.c"
  sed -i 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/' "$tmp/gpiosim/irq_sim.c"
  grep -q 'generic_handle_irq(irqnum)' "$tmp/gpiosim/irq_sim.c" || { log "irq_sim.c patch did not apply"; return 1; }
  printf 'obj-m := gpio-sim.o\ngpio-sim-y := gpio_sim_main.o irq_sim.o\n' > "$tmp/gpiosim/Kbuild"
  make -s -C "$hdr" M="$tmp/gpiosim" -j"$(nproc)" modules >&2

  # Keep only the modules the VM loads (and their dependencies).
  local out="$tmp/out"; mkdir -p "$out/modules/lib/modules/$KVER/extra"
  local m ko
  for m in $VM_MODULES; do
    modprobe -d "$tmp/kernel" -S "$KVER" --show-depends "$m" | awk '$1=="insmod"{print $2}'
  done | sort -u | while read -r ko; do
    local rel=${ko#"$tmp/kernel/"}
    mkdir -p "$out/modules/$(dirname "$rel")"; cp "$ko" "$out/modules/$rel"
  done
  strip --strip-debug -o "$out/modules/lib/modules/$KVER/extra/gpio-sim.ko" "$tmp/gpiosim/gpio-sim.ko"
  cp "$tmp/kernel/lib/modules/$KVER/"modules.{order,builtin,builtin.modinfo} "$out/modules/lib/modules/$KVER/"
  depmod -b "$out/modules" "$KVER"
  mv "$tmp/vmlinux" "$out/vmlinux"
  echo "$KPKG=$KDEBVER" > "$out/.complete"
  rm -rf "$DIR"; mv "$out" "$DIR"
}

mkdir -p "$CACHE_ROOT"
if [[ ! -f "$DIR/.complete" ]]; then
  build_kernel_bits || { echo "hil-setup: FAILED building kernel bits for $KVER" >&2; exit 1; }
else
  log "cached kernel bits: $DIR ($(cat "$DIR/.complete"))"
fi

# initramfs: cheap, rebuilt whenever init.sh changes.
hash=$(cat "$HERE/init.sh" /bin/busybox | sha256sum | cut -c1-12)
initrd="$DIR/initramfs-$hash.cpio.gz"
if [[ ! -s "$initrd" ]]; then
  root=$(mktemp -d); trap 'rm -rf "$root"' EXIT
  mkdir -p "$root"/{bin,sbin,dev,proc,sys,tmp,run,etc,mnt,lib}
  cp /bin/busybox "$root/bin/busybox"
  cp "$HERE/init.sh" "$root/init"; chmod 755 "$root/init"
  cp -a "$DIR/modules/lib/modules" "$root/lib/"
  rm -f "$DIR"/initramfs-*.cpio.gz
  (cd "$root" && find . | cpio -o -H newc --quiet | gzip -1) > "$initrd.tmp" && mv "$initrd.tmp" "$initrd"
  log "built $initrd"
fi
echo "$DIR"
echo "$initrd"
