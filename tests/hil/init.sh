#!/bin/busybox sh
# /init of the mfcd HIL VM (runs from the initramfs, busybox-static only).
#
# Brings up the real kernel drivers the HAL is tested against, then chroots into the host's root
# filesystem (9p, read-only, with a tmpfs overlay so the guest may write) and runs one job script.
# Kernel command line:
#   mfc.job=<path>    script to run inside the chroot (sh <path>), default: none (drivers only)
#   mfc.share=<path>  host directory shared read-write (9p tag "share"), mounted at the same path
# The last console line is "MFC-HIL-EXIT=<status>"; tests/hil/run-vm.sh turns it into its exit code.
/bin/busybox --install -s /bin
export PATH=/bin:/sbin:/usr/bin:/usr/sbin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
mkdir -p /dev/pts /dev/shm
mount -t devpts devpts /dev/pts
mount -t tmpfs tmpfs /dev/shm

JOB=; SHARE=
for arg in $(cat /proc/cmdline); do
  case "$arg" in
    mfc.job=*) JOB=${arg#mfc.job=} ;;
    mfc.share=*) SHARE=${arg#mfc.share=} ;;
  esac
done

finish() { echo; echo "MFC-HIL-EXIT=$1"; sync; poweroff -f; sleep 5; }  # own line, whatever came before
setup_failed() { echo "MFC-HIL-SETUP-FAILED: $*"; finish 254; }

for m in configfs 9pnet_virtio 9p overlay virtio_pci vcan can-raw gpio-sim; do
  modprobe "$m" || setup_failed "modprobe $m"
done
# vivid: one device, capture node only (node_types bit 0), so it is /dev/video0.
modprobe vivid n_devs=1 node_types=0x1 || setup_failed "modprobe vivid"

# gpio-sim: one chip labelled "mfc-leds" with the eight LED lines.
mount -t configfs configfs /sys/kernel/config || setup_failed "mount configfs"
SIM=/sys/kernel/config/gpio-sim/mfc
mkdir -p $SIM/bank0 || setup_failed "gpio-sim configfs"
echo 8 > $SIM/bank0/num_lines
echo mfc-leds > $SIM/bank0/label
echo 1 > $SIM/live || setup_failed "gpio-sim live"

ip link add dev vcan0 type vcan && ip link set vcan0 up || setup_failed "vcan0"
[ -c /dev/video0 ] || setup_failed "vivid did not create /dev/video0"

[ -n "$JOB" ] || finish 0

ROOT=/newroot
mkdir -p /mnt/host /mnt/rw $ROOT
mount -t 9p -o trans=virtio,version=9p2000.L,ro,msize=512000,cache=loose hostroot /mnt/host \
  || setup_failed "9p mount of the host root"
mount -t tmpfs tmpfs /mnt/rw
mkdir -p /mnt/rw/upper /mnt/rw/work
mount -t overlay overlay -o lowerdir=/mnt/host,upperdir=/mnt/rw/upper,workdir=/mnt/rw/work $ROOT \
  || setup_failed "overlay over the host root"
for d in proc sys dev; do mount --rbind /$d $ROOT/$d; done
# No fresh tmpfs over /tmp: the checkout under test may live there (CI clones anywhere), and the
# overlay already makes every path writable (writes land in /mnt/rw, never on the host).
mount -t tmpfs tmpfs $ROOT/run
if [ -n "$SHARE" ]; then
  mkdir -p "$ROOT$SHARE"
  mount -t 9p -o trans=virtio,version=9p2000.L,msize=512000 share "$ROOT$SHARE" || setup_failed "9p mount of $SHARE"
fi
echo "MFC-HIL-START"
chroot $ROOT /bin/sh -c "cd '${SHARE:-/}' && exec /bin/sh '$JOB'"
finish $?
