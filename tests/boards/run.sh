#!/usr/bin/env bash
# Boots a board that tests/boards/setup.sh set up, with a shell on its serial console, to try
# stripmask by hand:
#
#   tests/boards/run.sh BOARD [FILE...]       # each FILE is copied to /data on the board
#
# e.g. tests/boards/run.sh vexpress-a9 terrain.smdb, then on the board
#   stripmask fb /data/terrain.smdb --size 640x480 --input /dev/input/event0
# Ctrl-A C switches between the board's console and the QEMU monitor (`screendump shot.ppm`,
# `sendkey l`, `quit`); Ctrl-A X ends QEMU. The screen itself is on a VNC server at
# 127.0.0.1:5900 (display :0) while QEMU runs.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out=${STRIPMASK_BOARDS_DIR:-$root/target/boards}
[ $# -ge 1 ] || {
    echo "usage: $0 BOARD [FILE...]   (boards: vexpress-a9 x86-vesa)" >&2
    exit 2
}
board=$1
shift
dir="$out/$board"
[ -f "$dir/qemu-args" ] || {
    echo "run.sh: board '$board' is not set up: run tests/boards/setup.sh $board" >&2
    exit 1
}
for f in "$@"; do
    [ -f "$f" ] || {
        echo "run.sh: $f is not a file" >&2
        exit 1
    }
done
mapfile -t qemu <"$dir/qemu-args"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
initrd="$work/initramfs"
cp "$dir/initramfs.cpio.gz" "$initrd"
if [ $# -gt 0 ]; then
    # A second archive after the first, on a 4-byte boundary: the kernel unpacks both.
    size=$(stat -c %s "$initrd")
    head -c $(((4 - size % 4) % 4)) /dev/zero >>"$initrd"
    mkdir -p "$work/extra/data"
    cp "$@" "$work/extra/data/"
    (cd "$work/extra" && find data | "$out/busybox-amd64/bin/busybox" cpio -o -H newc 2>/dev/null) >>"$initrd"
fi
"${qemu[@]}" -initrd "$initrd" -serial mon:stdio -display none -vnc 127.0.0.1:0 -nic none -no-reboot
