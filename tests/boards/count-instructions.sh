#!/usr/bin/env bash
# Instructions per PocketPC frame (320x240 RGB565, 16-bit depth, 10,082 textured and shaded
# triangles, one thread: raster/examples/pocketpc_frames.rs) on each CPU, counted by a QEMU TCG
# plugin (tests/boards/insn-count.c) under user-mode emulation. A count, not a time: emulation
# says nothing about how fast a real core runs these instructions. docs/platforms.md has the
# figures and what they mean for a 400 MHz ARM.
#
#   tests/boards/count-instructions.sh [FRAMES]      # default 10
#
# Builds the example with the release profile for x86_64, 32-bit ARM with NEON and aarch64, runs
# it with 0 and FRAMES frames and prints (count(FRAMES) - count(0)) / FRAMES: the scene's set-up
# cancels out.
# Needs the packages of arm-tests.sh, a C compiler, and Debian's qemu-user package (which loads
# plugins; qemu-user-static cannot), downloaded and extracted under target/boards/qemu-user.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
frames=${1:-10}
out=${STRIPMASK_BOARDS_DIR:-$root/target/boards}
say() { echo "count-instructions: $*" >&2; }

qemu_user="$out/qemu-user"
if [ ! -x "$qemu_user/usr/bin/qemu-arm" ]; then
    mkdir -p "$qemu_user/debs"
    (cd "$qemu_user/debs" && apt-get -o APT::Sandbox::User=root download -qq qemu-user)
    dpkg-deb -x "$qemu_user"/debs/qemu-user_*.deb "$qemu_user"
fi
plugin="$out/libinsn-count.so"
cc -shared -fPIC -O2 -o "$plugin" "$here/insn-count.c"

# shellcheck source=tests/boards/cross.sh
. "$here/cross.sh"
cd "$root"
for target in x86_64-unknown-linux-gnu thumbv7neon-unknown-linux-gnueabihf aarch64-unknown-linux-musl; do
    case "$target" in
    x86_64-*) emulator=qemu-x86_64 ;;
    thumbv7neon-*) emulator=qemu-arm ;;
    aarch64-*) emulator=qemu-aarch64 ;;
    esac
    cargo build --quiet --release --target "$target" -p stripmask-raster --example pocketpc_frames
    binary="target/$target/release/examples/pocketpc_frames"
    count() {
        "$qemu_user/usr/bin/$emulator" -plugin "$plugin" -d plugin "$binary" "$1" 2>&1 >/dev/null |
            awk '/guest instructions:/ { print $3 }'
    }
    scene=$(count 0)
    total=$(count "$frames")
    picture=$("$qemu_user/usr/bin/$emulator" "$binary" 1 | sed 's/.*picture //')
    awk -v t="$target" -v s="$scene" -v a="$total" -v n="$frames" -v p="$picture" 'BEGIN {
        printf "%-32s %6.2fM instructions per frame (scene %.1fM), picture %s\n",
            t, (a - s) / n / 1e6, s / 1e6, p }'
done
