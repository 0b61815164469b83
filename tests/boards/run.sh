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
extra="$work/extra"
mkdir -p "$extra/data"
[ $# -eq 0 ] || cp "$@" "$extra/data/"
if [ -e "$dir/host-binary" ]; then
    # The board is the host's architecture and setup.sh built no stripmask for it: the host's
    # own binary goes in, with the shared libraries it loads, as tests/it/boards.rs does.
    binary=${STRIPMASK_BIN:-$root/target/suite/stripmask}
    [ -x "$binary" ] || {
        echo "run.sh: no $binary: build it (cargo build --profile suite) or name one in STRIPMASK_BIN" >&2
        exit 1
    }
    mkdir -p "$extra/usr/bin"
    cp "$binary" "$extra/usr/bin/stripmask"
    for lib in $(ldd "$binary" | grep -o '/[^ ]*'); do
        mkdir -p "$extra$(dirname "$lib")"
        cp -L "$lib" "$extra$lib"
    done
fi
# A second archive after the first, on a 4-byte boundary: the kernel unpacks both.
size=$(stat -c %s "$initrd")
head -c $(((4 - size % 4) % 4)) /dev/zero >>"$initrd"
(cd "$extra" && find . -mindepth 1 | sed "s|^\./||" | "$out/busybox-amd64/bin/busybox" cpio -o -H newc 2>/dev/null) >>"$initrd"
"${qemu[@]}" -initrd "$initrd" -serial mon:stdio -display none -vnc 127.0.0.1:0 -nic none -no-reboot
