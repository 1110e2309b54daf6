#!/bin/bash
# Runs socketcan_probe inside a QEMU guest (TCG) on the host's Debian kernel, with the SocketCAN
# modules loaded and a vcan0 interface up: a real-kernel test of the socketcan: transport on a host
# whose own kernel has no AF_CAN (ARCHITECTURE §4). See README.md in this directory.
#
# Usage: run_socketcan_probe.sh PROBE [--workdir DIR] [--timeout SECONDS] [--kernel VMLINUZ] [--bzimage]
#                               [-- PROBE_ARGS...]
#   PROBE      the socketcan_probe executable (dynamically linked: it is copied into the initramfs
#              with the shared libraries ldd lists, and so is the host's iproute2 `ip`)
#   --workdir  where the initramfs and the console log go (kept); default: a temporary directory,
#              removed at exit
#   --timeout  wall-time guard on the guest (default 120 s, or $IMUCAL_QEMU_TIMEOUT_S)
#   --kernel   kernel image (default: $IMUCAL_QEMU_KERNEL, else the newest /boot/vmlinuz-VER whose
#              /lib/modules/VER has vcan)
#   --bzimage  boot the compressed kernel image as it is (default: its vmlinux through the PVH entry,
#              unpacked on the host, which saves the ~6 s the emulated decompressor needs)
# Prints the probe's JSON line and the measured times; exits with the probe's status, or 2 when the
# guest could not be built, booted or prepared (missing qemu, kernel, module; timeout). Never skips.
set -euo pipefail

die() {
  echo "run_socketcan_probe: FAIL: $*" >&2
  exit 2
}

[[ $# -ge 1 ]] || die "usage: $0 PROBE [--workdir DIR] [--timeout S] [--kernel VMLINUZ] [--bzimage] [-- PROBE_ARGS...]"
probe=$1
shift
workdir=""
timeout_s=${IMUCAL_QEMU_TIMEOUT_S:-120}
kernel=${IMUCAL_QEMU_KERNEL:-}
use_bzimage=0
probe_args=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --workdir) workdir=${2:?--workdir needs a directory}; shift 2 ;;
    --timeout) timeout_s=${2:?--timeout needs seconds}; shift 2 ;;
    --kernel) kernel=${2:?--kernel needs a path}; shift 2 ;;
    --bzimage) use_bzimage=1; shift ;;
    --) shift; probe_args=("$@"); break ;;
    *) die "unknown option '$1'" ;;
  esac
done
[[ $timeout_s =~ ^[0-9]+$ && $timeout_s -gt 0 ]] || die "--timeout must be a positive integer, got '$timeout_s'"
for a in "${probe_args[@]+"${probe_args[@]}"}"; do
  [[ $a =~ ^[A-Za-z0-9_./=-]+$ ]] || die "probe argument '$a' has characters the guest's init script cannot carry"
done

# ------------------------------------------------------------------------------------ host tools
[[ -x $probe ]] || die "probe '$probe' is not an executable file (build the socketcan_probe target)"
qemu=$(command -v qemu-system-x86_64) || die "qemu-system-x86_64 not found (Debian package qemu-system-x86)"
busybox=""
for b in /bin/busybox /usr/bin/busybox; do [[ -x $b ]] && { busybox=$b; break; }; done
[[ -n $busybox ]] || die "busybox not found (Debian package busybox-static)"
for t in cpio ldd timeout; do command -v "$t" >/dev/null || die "'$t' not found on the host"; done
# busybox's ip cannot create a vcan link ("type vcan"): the guest runs the host's iproute2 ip.
host_ip=$(command -v ip || true)
if [[ -z $host_ip ]] || ! "$host_ip" -V 2>/dev/null | grep -q iproute2; then
  die "iproute2 'ip' not found on the host (Debian package iproute2; busybox ip cannot add a vcan link)"
fi

# ------------------------------------------------------------------------------ kernel + modules
if [[ -z $kernel ]]; then
  for k in $(compgen -G '/boot/vmlinuz-*' | sort -rV); do
    v=${k#/boot/vmlinuz-}
    if compgen -G "/lib/modules/$v/kernel/drivers/net/can/vcan.ko*" >/dev/null; then
      kernel=$k
      break
    fi
  done
  [[ -n $kernel ]] || die "no /boot/vmlinuz-VER with SocketCAN modules in /lib/modules/VER (Debian package linux-image-amd64)"
fi
[[ -r $kernel ]] || die "kernel image '$kernel' is missing or unreadable"
kver=${kernel##*/vmlinuz-}
moddir=/lib/modules/$kver
[[ -r $moddir/modules.dep ]] || die "no $moddir/modules.dep for kernel '$kernel' (modules of version '$kver' not installed)"

# Load order: each wanted module after its dependencies (modules.dep lists them, nearest first).
wanted=(can can-raw can-dev vcan)
load_order=()
add_module() {  # $1 = path relative to $moddir
  local m
  for m in "${load_order[@]+"${load_order[@]}"}"; do [[ $m == "$1" ]] && return 0; done
  load_order+=("$1")
}
for name in "${wanted[@]}"; do
  line=$(grep -E "(^|/)${name}\.ko(\.xz|\.zst|\.gz)?:" "$moddir/modules.dep" | head -n1) ||
    die "module '$name' is not in $moddir/modules.dep (kernel '$kver' lacks SocketCAN/vcan modules)"
  path=${line%%:*}
  read -r -a deps <<<"${line#*:}"
  for ((i = ${#deps[@]} - 1; i >= 0; i--)); do add_module "${deps[i]}"; done
  add_module "$path"
done

if [[ -z $workdir ]]; then
  workdir=$(mktemp -d /tmp/imucal-qemu-socketcan.XXXXXX)
  trap 'rm -rf "$workdir"' EXIT
fi
mkdir -p "$workdir"
t_build0=$(date +%s.%N)

# Boot image. Under TCG the bzImage's own decompressor (xz in Debian) takes ~6 s of emulated CPU, so
# unless --bzimage is given the uncompressed vmlinux is unpacked on the host (~1 s, cached in the
# workdir) and booted through its PVH entry point (QEMU loads an ELF kernel with a PVH note directly).
# Same kernel, same modules; any problem with the unpacking falls back to booting the bzImage.
boot_image=$kernel
boot_mode=bzImage
extract_vmlinux() {  # $1 = bzImage, $2 = output; succeeds only for an ELF with a PVH entry note
  local magic tool off
  command -v readelf >/dev/null || return 1
  for magic in xz zstd gzip; do
    case $magic in
      xz) tool="xz -dc"; off=$(LC_ALL=C grep -abo $'\xfd7zXZ' "$1" | head -n1 | cut -d: -f1) ;;
      zstd) tool="zstd -qdc"; off=$(LC_ALL=C grep -abo $'\x28\xb5\x2f\xfd' "$1" | head -n1 | cut -d: -f1) ;;
      gzip) tool="gzip -dc"; off=$(LC_ALL=C grep -abo $'\x1f\x8b\x08' "$1" | head -n1 | cut -d: -f1) ;;
    esac
    if [[ -z $off ]] || ! command -v "${tool%% *}" >/dev/null; then continue; fi
    # The compressed payload is followed by the rest of the bzImage: the decompressor's complaint
    # about trailing data is expected; the ELF check below decides.
    tail -c +$((off + 1)) "$1" | $tool >"$2.tmp" 2>/dev/null || true
    if [[ $(head -c 4 "$2.tmp" 2>/dev/null | od -An -tx1 | tr -d ' ') == 7f454c46 ]] &&
      readelf -n "$2.tmp" 2>/dev/null | grep -q 'note type: (0x00000012)\|XEN_ELFNOTE_PHYS32_ENTRY'; then
      mv "$2.tmp" "$2"
      return 0
    fi
  done
  rm -f "$2.tmp"
  return 1
}
if [[ $use_bzimage -eq 0 ]]; then
  stamp="$kernel $(stat -c '%s %Y' "$kernel")"
  vmlinux=$workdir/vmlinux-$kver
  if [[ -s $vmlinux && -f $vmlinux.stamp && $(cat "$vmlinux.stamp") == "$stamp" ]] ||
    { rm -f "$vmlinux.stamp"; extract_vmlinux "$kernel" "$vmlinux" && echo "$stamp" >"$vmlinux.stamp"; }; then
    boot_image=$vmlinux
    boot_mode=PVH
  else
    echo "run_socketcan_probe: note: cannot unpack a PVH-bootable vmlinux from $kernel; booting the bzImage (slower)" >&2
  fi
fi

# ------------------------------------------------------------------------------------ initramfs
rm -rf "$workdir/root"
root=$workdir/root
mkdir -p "$root"/{bin,sbin,proc,sys,dev,tmp,lib/modules,usr/bin,usr/sbin}

cp "$busybox" "$root/bin/busybox"

copy_with_libs() {  # $1 = host executable, $2 = path in the guest
  local exe=$1 dest=$2 lib
  mkdir -p "$root/$(dirname "$dest")"
  cp -L "$exe" "$root/$dest"
  # ldd prints "name => /path (addr)" for libraries and "/path (addr)" for the interpreter.
  while read -r lib; do
    [[ -n $lib && -e $lib ]] || continue
    mkdir -p "$root/$(dirname "$lib")"
    [[ -e $root/$lib ]] || cp -L "$lib" "$root/$lib"
  done < <(ldd "$exe" 2>/dev/null | sed -nE 's/.*=> (\/[^ ]+) .*/\1/p; s/^[[:space:]]*(\/[^ ]+) \(.*/\1/p')
}
copy_with_libs "$probe" /probe
copy_with_libs "$host_ip" /usr/sbin/ip
guest_ip=/usr/sbin/ip

: >"$root/modules.order"
for m in "${load_order[@]}"; do
  src=$moddir/$m
  [[ -r $src ]] || die "module file $src is missing"
  base=$(basename "$m")
  case $base in
    *.ko.xz) command -v xz >/dev/null || die "xz needed to unpack $src"; xz -dc "$src" >"$root/lib/modules/${base%.xz}" ;;
    *.ko.zst) command -v zstd >/dev/null || die "zstd needed to unpack $src"; zstd -qdc "$src" >"$root/lib/modules/${base%.zst}" ;;
    *.ko.gz) gzip -dc "$src" >"$root/lib/modules/${base%.gz}" ;;
    *.ko) cp "$src" "$root/lib/modules/$base" ;;
    *) die "unexpected module file name $src" ;;
  esac
  echo "${base%.ko*}.ko" >>"$root/modules.order"
done

# The guest's PID 1. Every outcome ends in a marker line the host parses, then power-off.
cat >"$root/init" <<EOF
#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev 2>/dev/null
dmesg -n 1
echo "@@IMUCAL_UPTIME_INIT \$(cut -d' ' -f1 /proc/uptime)"
guest_fail() { echo "@@IMUCAL_GUEST_ERROR \$*"; poweroff -f; sleep 5; echo o >/proc/sysrq-trigger; }
for m in \$(cat /modules.order); do
  insmod /lib/modules/\$m || guest_fail "insmod \$m failed: \$(dmesg | tail -n 3)"
done
$guest_ip link add dev vcan0 type vcan || guest_fail "ip link add dev vcan0 type vcan failed"
$guest_ip link set vcan0 up || guest_fail "ip link set vcan0 up failed"
echo "@@IMUCAL_UPTIME_BEFORE_PROBE \$(cut -d' ' -f1 /proc/uptime)"
/probe --iface vcan0 ${probe_args[*]:-}
rc=\$?
echo "@@IMUCAL_UPTIME_AFTER_PROBE \$(cut -d' ' -f1 /proc/uptime)"
echo "@@IMUCAL_PROBE_EXIT \$rc"
poweroff -f
sleep 5
echo o >/proc/sysrq-trigger
EOF
chmod +x "$root/init"
(cd "$root" && find . -print0 | cpio --null -o -H newc --quiet) >"$workdir/initramfs.cpio"
t_build1=$(date +%s.%N)

# -------------------------------------------------------------------------------------- boot
# cryptomgr.notests: the crypto self-tests cost ~1.5 s of emulated CPU and concern nothing tested here.
console=$workdir/console.log
t_boot0=$(date +%s.%N)
set +e
timeout --kill-after=5 "$timeout_s" "$qemu" -accel tcg -nographic -no-reboot -nodefaults -serial stdio \
  -m 512 -smp 1 -kernel "$boot_image" -initrd "$workdir/initramfs.cpio" \
  -append "console=ttyS0 quiet loglevel=1 panic=-1 rdinit=/init cryptomgr.notests" </dev/null >"$console" 2>&1
qemu_rc=$?
set -e
t_boot1=$(date +%s.%N)
tr -d '\r' <"$console" >"$console.txt"

show_console() {
  echo "---- guest console (last 40 lines of $console) ----" >&2
  tail -n 40 "$console.txt" >&2
  echo "----" >&2
}
if [[ $qemu_rc -eq 124 || $qemu_rc -eq 137 ]]; then
  show_console
  die "the guest did not finish within $timeout_s s (qemu killed)"
fi
# Markers are matched anywhere in a line: terminal escapes from the firmware may precede the first.
marker() { sed -n "s/.*@@IMUCAL_$1 //p" "$console.txt" | head -n1; }
if [[ -n $(marker GUEST_ERROR) ]]; then
  show_console
  die "guest preparation failed: $(marker GUEST_ERROR)"
fi
probe_rc=$(marker PROBE_EXIT)
[[ $probe_rc =~ ^[0-9]+$ ]] || {
  show_console
  die "no probe exit status on the guest console (qemu exit status $qemu_rc)"
}
json=$(grep -m1 -o '{"[^{].*"probe":"socketcan".*}' "$console.txt") || {
  show_console
  die "the probe printed no JSON line (exit status $probe_rc)"
}
upi=$(marker UPTIME_INIT)
up0=$(marker UPTIME_BEFORE_PROBE)
up1=$(marker UPTIME_AFTER_PROBE)
echo "$json"
awk -v b0="$t_build0" -v b1="$t_build1" -v q0="$t_boot0" -v q1="$t_boot1" -v ui="$upi" -v u0="$up0" -v u1="$up1" -v k="$kernel ($boot_mode boot)" 'BEGIN {
  printf "run_socketcan_probe: kernel %s; vmlinux + initramfs built in %.1f s; qemu wall %.1f s (guest uptime: /init %.2f s, probe start %.2f s, probe %.2f s)\n",
         k, b1 - b0, q1 - q0, ui, u0, u1 - u0 }'
if [[ $probe_rc != 0 ]]; then
  echo "run_socketcan_probe: FAIL: socketcan_probe exited with status $probe_rc in the guest" >&2
  exit 1
fi
echo "run_socketcan_probe: PASS"
