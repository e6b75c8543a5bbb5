#!/usr/bin/env bash
# Runs a test binary on a real vcan0. Where the kernel has CAN and we are root, directly on the
# host; otherwise inside a small qemu VM booted from Debian's own kernel (docs/vcan-in-qemu.md).
#
#   run-on-vcan.sh [--cache DIR] [--file PATH]... [--binary PATH]... [--timeout S] [--mode auto|host|vm] -- BINARY [ARGS...]
#
# --cache   where the Debian kernel and CAN modules are kept between runs (under the build dir;
#           never committed). Default: $HIL_VCAN_CACHE or ./vcan-cache.
# --file    an extra file or folder packed into the VM at the same absolute path (configs, scripts).
# --binary  an extra program the test starts (e.g. hilbench), packed with every library ldd lists.
# --timeout seconds before the VM is killed (default 600).
# The binary's exit code decides on the host; in the VM the marker line "HIL-VCAN-RESULT rc=N"
# printed by /init decides, and the inner output is printed as it comes.
set -euo pipefail

cache="${HIL_VCAN_CACHE:-$PWD/vcan-cache}"
mode="${HIL_VCAN_MODE:-auto}"
timeout_s=600
extra=()
binaries=()
while (($#)); do
  case "$1" in
    --cache) cache="$2"; shift 2 ;;
    --file) extra+=("$2"); shift 2 ;;
    --binary) binaries+=("$(readlink -f "$2")"); shift 2 ;;
    --timeout) timeout_s="$2"; shift 2 ;;
    --mode) mode="$2"; shift 2 ;;
    --) shift; break ;;
    -*) echo "run-on-vcan: unknown option $1" >&2; exit 2 ;;
    *) break ;;
  esac
done
(($#)) || { echo "usage: run-on-vcan.sh [options] -- BINARY [ARGS...]" >&2; exit 2; }
binary="$(readlink -f "$1")"; shift
[[ -x "$binary" ]] || { echo "run-on-vcan: $binary is not an executable" >&2; exit 2; }

host_has_can() {
  [[ $EUID -eq 0 ]] || return 1
  [[ -d /proc/net/can ]] || modprobe vcan 2>/dev/null || return 1
  ip link show vcan0 >/dev/null 2>&1 || ip link add dev vcan0 type vcan 2>/dev/null || return 1
  ip link set up vcan0 2>/dev/null
}

if [[ "$mode" == host || ( "$mode" == auto && -d /proc/net/can ) ]] && host_has_can; then
  echo "run-on-vcan: host vcan0"
  exec "$binary" "$@"
fi
[[ "$mode" != host ]] || { echo "run-on-vcan: host has no CAN support" >&2; exit 1; }

# ---- the kernel: Debian's linux-image package, fetched as a file, cached -------------------
mkdir -p "$cache"
exec 9>"$cache/.lock"
flock 9  # parallel ctest jobs share one download
kver=$(apt-cache depends linux-image-amd64 2>/dev/null | sed -n 's/.*Depends: linux-image-\(.*-amd64\)$/\1/p' | head -1 || true)
if [[ -z "$kver" ]]; then  # no apt lists yet: refresh once, else take what the cache has
  apt-get update -qq >/dev/null 2>&1 || true
  kver=$(apt-cache depends linux-image-amd64 2>/dev/null | sed -n 's/.*Depends: linux-image-\(.*-amd64\)$/\1/p' | head -1 || true)
fi
if [[ -z "$kver" ]]; then
  kver=$(ls "$cache" | sed -n 's/^kernel-//p' | head -1)
fi
[[ -n "$kver" ]] || { echo "run-on-vcan: cannot tell which Debian kernel to fetch" >&2; exit 1; }
kdir="$cache/kernel-$kver"
mods=(kernel/net/can/can.ko kernel/net/can/can-raw.ko kernel/drivers/net/can/dev/can-dev.ko kernel/drivers/net/can/vcan.ko)
if [[ ! -f "$kdir/vmlinuz" ]]; then
  echo "run-on-vcan: fetching linux-image-$kver into $cache"
  tmp=$(mktemp -d "$cache/fetch.XXXXXX")
  if ! (cd "$tmp" && apt-get download "linux-image-$kver" >/dev/null 2>&1); then
    apt-get update -qq >/dev/null 2>&1 || true
    (cd "$tmp" && apt-get download "linux-image-$kver") >/dev/null 2>&1 || { echo "run-on-vcan: apt-get download linux-image-$kver failed" >&2; rm -rf "$tmp"; exit 1; }
  fi
  dpkg -x "$tmp"/linux-image-*.deb "$tmp/x"
  mkdir -p "$kdir.new"
  cp "$tmp/x/boot/vmlinuz-$kver" "$kdir.new/vmlinuz"
  for m in "${mods[@]}"; do cp "$tmp/x/lib/modules/$kver/$m" "$kdir.new/"; done
  rm -rf "$tmp" "$kdir"
  mv "$kdir.new" "$kdir"
fi
flock -u 9

# ---- the initramfs: busybox, ip, can-utils, the binary and every library ldd lists ---------
work=$(mktemp -d "${TMPDIR:-/tmp}/hil-vcan.XXXXXX")
trap 'rm -rf "$work"' EXIT
root="$work/root"
mkdir -p "$root"/{bin,sbin,proc,sys,dev,tmp,lib/modules}
add_file() {  # copies a file (resolving symlinks) to the same path inside the image
  local dst="$root$1"
  [[ -e "$dst" ]] && return 0
  mkdir -p "$(dirname "$dst")"
  cp -L "$1" "$dst"
}
add_binary() {
  add_file "$1"
  local lib
  while read -r lib; do add_file "$lib"; done < <(ldd "$1" 2>/dev/null | grep -o '/[^ ]*' || true)
}
cp /bin/busybox "$root/bin/busybox"
for b in "$binary" "${binaries[@]}" "$(command -v ip)" "$(command -v candump)" "$(command -v cansend)" "$(command -v cangen)"; do
  add_binary "$b"
done
for f in "${extra[@]}"; do
  if [[ -d "$f" ]]; then
    while IFS= read -r g; do add_file "$g"; done < <(find "$(readlink -f "$f")" -type f)
  else
    add_file "$(readlink -f "$f")"
  fi
done
for m in "${mods[@]}"; do cp "$kdir/$(basename "$m")" "$root/lib/modules/"; done
args=""
for a in "$@"; do args+=" $(printf '%q' "$a")"; done
cat > "$root/init" <<INIT
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin:/sbin:/usr/bin:/usr/sbin HOME=/tmp TMPDIR=/tmp
mount -t proc proc /proc; mount -t sysfs sys /sys; mount -t devtmpfs dev /dev; mkdir -p /tmp; chmod 1777 /tmp
mkdir -p /dev/pts; mount -t devpts devpts /dev/pts
for m in can can-raw can-dev vcan; do insmod /lib/modules/\$m.ko || echo "insmod \$m failed"; done
ip link add dev vcan0 type vcan && ip link set up vcan0
ip link set lo up
cd /tmp
echo "run-on-vcan: guest \$(uname -r), vcan0 up"
$(printf '%q' "$binary")$args
echo "HIL-VCAN-RESULT rc=\$?"
poweroff -f
INIT
chmod +x "$root/init"
(cd "$root" && find . | cpio -o -H newc --quiet | gzip -1) > "$work/initrd.gz"

# ---- boot: TCG (kvm hangs on this kind of machine); the marker decides ---------------------
log="$work/console.log"
set +e
timeout "$timeout_s" qemu-system-x86_64 -accel tcg -m 512 -smp "${HIL_VCAN_SMP:-2}" -nographic -no-reboot \
  -kernel "$kdir/vmlinuz" -initrd "$work/initrd.gz" \
  -append "console=ttyS0 panic=-1 loglevel=3 quiet" </dev/null 2>&1 | tee "$log"
qrc=${PIPESTATUS[0]}
set -e
rc=$(sed -n 's/.*HIL-VCAN-RESULT rc=\([0-9]*\).*/\1/p' "$log" | tail -1)
if [[ -z "$rc" ]]; then
  echo "run-on-vcan: no result marker from the VM (qemu exit $qrc; 124 means timeout after ${timeout_s}s)" >&2
  exit 1
fi
echo "run-on-vcan: test exit code $rc"
exit "$rc"
