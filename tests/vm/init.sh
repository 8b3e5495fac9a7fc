#!/bin/sh
# /init of the test VM (busybox). Loads vivid and snd-dummy, runs vibroscope
# against /dev/video0 and reports over the serial console: every line the
# host checks starts with "@@VM ". Outputs go to the second disk as a tar.
export PATH=/bin:/sbin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
mount -t tmpfs tmp /tmp
mkdir -p /out
mount -t tmpfs out /out
say() { echo "@@VM $*"; }
say "kernel $(uname -r) cpus $(grep -c ^processor /proc/cpuinfo)"
for m in vivid snd-dummy virtio_pci virtio_blk; do
  modprobe "$m" || say "modprobe $m failed"
done
n=0
while [ ! -e /dev/video0 ] && [ $n -lt 100 ]; do sleep 0.1; n=$((n + 1)); done
say "nodes $(ls /dev | grep -E '^(video|snd)' | tr '\n' ' ') $(ls /dev/snd 2>/dev/null | tr '\n' ' ')"
cd /out
export RUST_BACKTRACE=1
# The emulated CPU cannot keep the sound card fed; one warning per ALSA
# underrun would flood the log (the speaker sums them up at the end).
export RUST_LOG=warn,vibroscope_devices::speaker::cpal_device=error

# 1. Devices.
vibroscope devices > devices.txt 2>&1
say "devices rc=$?"
sed 's/^/  /' devices.txt

# 2. Record two seconds, asking for a size vivid does not have.
vibroscope record --device /dev/video0 -o /out/rec.y4m --seconds 2 \
  --width 400 --height 300 --fps 30 --format yuyv --stats > record.txt 2>&1
say "record rc=$?"
sed 's/^/  /' record.txt
vibroscope probe /out/rec.y4m > probe.txt 2>&1
say "probe rc=$?"
sed 's/^/  /' probe.txt

# 2b. The nokhwa kind on the same camera (only with VM_NOKHWA=1). Runs while
# the device is still in YUYV: nokhwa 0.10 cannot open a V4L2 camera whose
# current format is GREY (it looks for the FourCC "GRAY").
if [ -x /bin/vibroscope-nokhwa ]; then
  printf '[[stage]]\nid = "cam"\nkind = "nokhwa"\nwidth = 320\nheight = 180\nfps = 30\nmax_frames = 30\n\n[[stage]]\nid = "rec"\nkind = "y4m"\ninput = "cam"\npath = "/out/nokhwa.y4m"\n' > /tmp/nokhwa.toml
  vibroscope-nokhwa run /tmp/nokhwa.toml --stats --quiet > nokhwa.txt 2>&1
  say "nokhwa rc=$?"
  sed 's/^/  /' nokhwa.txt
  # The same without a size: nokhwa picks the highest frame rate itself.
  sed -i '/^width\|^height\|^fps/d' /tmp/nokhwa.toml
  sed -i 's|/out/nokhwa.y4m|/out/nokhwa-auto.y4m|' /tmp/nokhwa.toml
  vibroscope-nokhwa run /tmp/nokhwa.toml --stats --quiet > nokhwa-auto.txt 2>&1
  say "nokhwa-auto rc=$?"
  sed 's/^/  /' nokhwa-auto.txt
fi

# 3. The live microphone pipeline for a few seconds.
vibroscope run live-microphone --set cam.duration_s=4 --set out.path=/out/live.wav \
  --stats --quiet > live.txt 2>&1
say "live rc=$?"
sed 's/^/  /' live.txt

# 3b. Live motion magnification, side by side, to standard output (where a
# player such as ffplay would read it).
vibroscope run live-magnify --set cam.duration_s=4 --stats --quiet \
  > /out/magnify.y4m 2> magnify.txt
say "magnify rc=$?"
sed 's/^/  /' magnify.txt

# 4. Faults on a real driver: a missing node, a format it does not offer.
vibroscope record --device /dev/video99 -o /out/missing.y4m --seconds 1 > missing.txt 2>&1
say "missing rc=$?"
sed 's/^/  /' missing.txt

vibroscope record --device /dev/video0 -o /out/mjpeg.y4m --seconds 1 --format mjpeg > unsupported.txt 2>&1
say "unsupported rc=$?"
sed 's/^/  /' unsupported.txt

# 5. Ctrl-C while recording: exit 130 and a valid file. Meanwhile a second
# recorder finds the camera busy.
vibroscope record --device /dev/video0 -o /out/interrupted.y4m --width 320 --height 180 \
  > interrupted.txt 2>&1 &
pid=$!
sleep 2
vibroscope record --device /dev/video0 -o /out/busy.y4m --seconds 1 > busy.txt 2>&1
say "busy rc=$?"
sed 's/^/  /' busy.txt
sleep 1
kill -INT $pid
wait $pid
say "interrupted rc=$?"
sed 's/^/  /' interrupted.txt

# 6. Unplugged mid-stream: vivid's "Disconnect" control emulates a USB
# unplug (every ioctl then fails with ENODEV). Last: the node goes away.
vibroscope run live-microphone --set cam.duration_s=60 --set out.path=/out/unplug.wav \
  --quiet > unplug.txt 2>&1 &
pid=$!
sleep 4
v4l2-ctl -d /dev/video0 --set-ctrl disconnect=1 > unplug-ctl.txt 2>&1
say "disconnect rc=$?"
wait $pid
say "unplug rc=$?"
sed 's/^/  /' unplug.txt unplug-ctl.txt

tar cf /dev/vda -C /out . && say "results written"
sync
say "done"
poweroff -f
