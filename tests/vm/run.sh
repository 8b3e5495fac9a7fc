#!/usr/bin/env bash
# The live-camera test on a real V4L2 driver: boots Debian's stock kernel
# under QEMU (TCG, no KVM needed) with a busybox initramfs holding the vivid
# virtual camera and snd-dummy sound card modules and the release binary,
# runs `vibroscope devices`, `record` and the live-microphone pipeline
# inside (tests/vm/init.sh), reads the results back over the serial console
# and a second (virtio) disk, and checks them on the host
# (tests/vm_check.rs). Run by .ci/run; by hand: bash tests/vm/run.sh
#
# Needs qemu-system-x86, linux-image-amd64, busybox-static, kmod, and
# v4l-utils (v4l2-ctl unplugs the camera mid-stream in the VM) (installed
# here when missing, as root or with sudo). Everything it builds goes to
# target/vm/ (the kernel and initramfs are never committed). Any failure,
# including "cannot boot a VM on this machine", exits non-zero with the
# reason.
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
OUT=${VM_OUT:-$ROOT/target/vm}
TIMEOUT=${VM_TIMEOUT:-420}
START=$(date +%s)
fail() {
  echo "vm test: FAILED: $*" >&2
  exit 1
}

need=()
for p in qemu-system-x86 linux-image-amd64 busybox-static kmod v4l-utils; do
  dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
done
if [ "${#need[@]}" -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "vm test: installing ${need[*]}"
  { $SUDO apt-get update -qq &&
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"; } ||
    fail "cannot install ${need[*]} (needed to boot the test VM)"
fi
command -v qemu-system-x86_64 >/dev/null || fail "qemu-system-x86_64 not found after installing qemu-system-x86"

# The newest installed kernel that has its modules.
KVER=""
for k in $(ls /boot/vmlinuz-* 2>/dev/null | sed 's|/boot/vmlinuz-||' | sort -V); do
  [ -f "/lib/modules/$k/modules.dep" ] && KVER=$k
done
[ -n "$KVER" ] || fail "no /boot/vmlinuz-* with /lib/modules/<version>/modules.dep (is linux-image-amd64 installed?)"
KERNEL=/boot/vmlinuz-$KVER
[ -r "$KERNEL" ] || fail "$KERNEL is not readable"
BUSYBOX=$(command -v busybox || true)
[ -n "$BUSYBOX" ] && file -L "$BUSYBOX" 2>/dev/null | grep -q static || BUSYBOX=/bin/busybox
[ -x "$BUSYBOX" ] || fail "busybox (static) not found"

# The binary as the test suite builds it (cargo builds the package's binary
# for its integration tests): after `cargo test --release` in .ci/run this
# compiles nothing, where `cargo build --bin` would rebuild the dependencies
# without the dev-dependencies' features (4 min on two cores).
cargo test --release --test vm_check --no-run
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
BIN=$TARGET/release/vibroscope
# VM_NOKHWA=1 also builds the `nokhwa` kind (feature input-v4l) and runs it
# on vivid; off by default (nokhwa's dependencies add minutes of build).
NOKHWA_BIN=""
if [ "${VM_NOKHWA:-0}" = 1 ]; then
  CARGO_TARGET_DIR=$TARGET/nokhwa cargo build --release --features input-v4l --bin vibroscope
  NOKHWA_BIN=$TARGET/nokhwa/release/vibroscope
fi

echo "vm test: building the initramfs for kernel $KVER"
STAGE=$OUT/root
rm -rf "$STAGE" "$OUT/results" "$OUT/console.log"
mkdir -p "$STAGE"/{bin,sbin,dev,proc,sys,tmp,out,etc,lib/modules/$KVER} "$OUT/results"
cp "$BUSYBOX" "$STAGE/bin/busybox"
for a in sh ash mount umount modprobe insmod lsmod mkdir cat ls sleep poweroff echo grep sed tr \
  head tail tar sync dd kill uname wc cp rm test true false; do
  ln -sf busybox "$STAGE/bin/$a"
done
# Modules and their dependencies, resolved against the host's index.
for m in vivid snd-dummy virtio_pci virtio_blk; do
  modprobe -S "$KVER" -D "$m" | awk '$1 == "insmod" { print $2 }'
done | sort -u | while read -r ko; do
  mkdir -p "$STAGE$(dirname "$ko")"
  case "$ko" in
    *.xz) xz -dc "$ko" >"$STAGE${ko%.xz}" ;;
    *.zst) zstd -qdc "$ko" >"$STAGE${ko%.zst}" ;;
    *) cp "$ko" "$STAGE$ko" ;;
  esac
done
for f in modules.order modules.builtin modules.builtin.modinfo; do
  [ -f "/lib/modules/$KVER/$f" ] && cp "/lib/modules/$KVER/$f" "$STAGE/lib/modules/$KVER/"
done
depmod -b "$STAGE" "$KVER" || fail "depmod -b $STAGE $KVER failed"
# The binary (without debug info) and the shared libraries it links.
strip -o "$STAGE/bin/vibroscope" "$BIN" 2>/dev/null || cp "$BIN" "$STAGE/bin/vibroscope"
V4L2CTL=$(command -v v4l2-ctl) || fail "v4l2-ctl not found (package v4l-utils)"
cp "$V4L2CTL" "$STAGE/bin/v4l2-ctl"
if [ -n "$NOKHWA_BIN" ]; then
  strip -o "$STAGE/bin/vibroscope-nokhwa" "$NOKHWA_BIN" 2>/dev/null || cp "$NOKHWA_BIN" "$STAGE/bin/vibroscope-nokhwa"
fi
ldd "$BIN" "$V4L2CTL" $NOKHWA_BIN | grep -oE '/[^ :]+' | sort -u | while read -r lib; do
  mkdir -p "$STAGE$(dirname "$lib")"
  cp -L "$lib" "$STAGE$lib"
done
# ALSA's configuration (cpal opens "default" through it).
[ -d /usr/share/alsa ] && mkdir -p "$STAGE/usr/share" && cp -r /usr/share/alsa "$STAGE/usr/share/"
cp tests/vm/init.sh "$STAGE/init"
chmod +x "$STAGE/init"
(cd "$STAGE" && find . | "$BUSYBOX" cpio -o -H newc 2>/dev/null | gzip -1) >"$OUT/initramfs.cpio.gz"
truncate -s 0 "$OUT/results.img"
truncate -s 128M "$OUT/results.img"
echo "vm test: initramfs $(du -h "$OUT/initramfs.cpio.gz" | cut -f1); booting (timeout ${TIMEOUT}s)"

ACCEL=${VM_ACCEL:-tcg}
set +e
timeout "$TIMEOUT" qemu-system-x86_64 -accel "$ACCEL" -m 1G -smp 2 -nographic -no-reboot \
  -kernel "$KERNEL" -initrd "$OUT/initramfs.cpio.gz" \
  -append "console=ttyS0 panic=-1 quiet loglevel=3" \
  -drive "file=$OUT/results.img,format=raw,if=virtio" \
  </dev/null >"$OUT/console.log" 2>&1
rc=$?
set -e
tr -d '\r' <"$OUT/console.log" >"$OUT/console.txt"
if [ $rc -eq 124 ]; then
  tail -40 "$OUT/console.txt" >&2
  fail "the VM did not finish within ${TIMEOUT}s (console log: $OUT/console.txt)"
fi
grep -q '^@@VM done' "$OUT/console.txt" || {
  tail -60 "$OUT/console.txt" >&2
  fail "the VM did not boot or did not run the test (qemu exit $rc; console log: $OUT/console.txt)"
}
sed -n '/^@@VM /,$p' "$OUT/console.txt"
tar xf "$OUT/results.img" -C "$OUT/results" || fail "cannot read the results disk"
echo "vm test: VM finished after $(($(date +%s) - START)) s; checking the results on the host"
VIBROSCOPE_VM_OUT=$OUT cargo test --release --test vm_check -- --nocapture
echo "vm test: passed in $(($(date +%s) - START)) s"
