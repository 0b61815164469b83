#!/usr/bin/env bash
# The same bytes on every CPU: builds the rasterizer's tests, golden images included, for 32-bit
# ARM with NEON (thumbv7neon-unknown-linux-gnueabihf, static glibc), 64-bit ARM
# (aarch64-unknown-linux-musl) and ARMv5TE with soft float (armv5te-unknown-linux-gnueabi, static
# glibc, run as QEMU's XScale PXA255): the integration tests, in the `suite` profile, and runs them
# under QEMU user-mode emulation. The golden PNGs (raster/tests/golden/) were made
# on x86-64 and the tests compare byte for byte, so passing here means byte-identical pictures on
# ARM in both precisions. Whole engine frames on ARM are the board tests' job (tests/it/boards.rs
# compares stripmask fb on the emulated vexpress-a9 with the host, byte for byte).
#
#   tests/boards/arm-tests.sh [TARGET...]     # default: all three
#   STRIPMASK_ARM_TESTS=all tests/boards/arm-tests.sh   # the unit tests too
#
# Installs with apt-get when missing: qemu-user-static, gcc-arm-linux-gnueabihf and
# libc6-dev-armhf-cross (armv7), gcc-arm-linux-gnueabi and libc6-dev-armel-cross (ARMv5TE; aarch64
# needs no C toolchain); adds the Rust targets with rustup, or where rustup serves no standard
# library for a target (ARMv5TE) builds it from source. Settings: tests/boards/cross.sh.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
# shellcheck source=tests/boards/apt.sh
. "$here/apt.sh"
profile=${STRIPMASK_BOARDS_PROFILE:-suite}
targets=("$@")
[ "${#targets[@]}" -gt 0 ] ||
    targets=(thumbv7neon-unknown-linux-gnueabihf aarch64-unknown-linux-musl armv5te-unknown-linux-gnueabi)

say() { echo "arm-tests: $*" >&2; }
die() {
    say "error: $*"
    exit 1
}
if [ "$(id -u)" -eq 0 ]; then sudo=(); else sudo=(sudo); fi

packages=(qemu-user-static)
for target in "${targets[@]}"; do
    case "$target" in
    thumbv7neon-unknown-linux-gnueabihf) packages+=(gcc-arm-linux-gnueabihf libc6-dev-armhf-cross) ;;
    aarch64-unknown-linux-musl) ;;
    armv5te-unknown-linux-gnueabi) packages+=(gcc-arm-linux-gnueabi libc6-dev-armel-cross) ;;
    *) die "unknown target '$target' (thumbv7neon-unknown-linux-gnueabihf, aarch64-unknown-linux-musl, armv5te-unknown-linux-gnueabi)" ;;
    esac
done
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
    command -v apt-get >/dev/null || die "apt-get not found; install ${missing[*]} by hand"
    say "apt-get install ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt_update "${sudo[@]}" apt-get
    "${sudo[@]}" apt-get install -y -qq --no-install-recommends --no-upgrade "${missing[@]}" >/dev/null
fi

# shellcheck source=tests/boards/cross.sh
. "$here/cross.sh"
cd "$root"
target_args=()
from_source=()
for target in "${targets[@]}"; do
    runner=CARGO_TARGET_$(tr 'a-z-' 'A-Z_' <<<"$target")_RUNNER
    if rustup_std "$target"; then
        say "$target: run by ${!runner}"
        target_args+=(--target "$target")
    else
        say "$target: run by ${!runner}; its standard library built from source"
        from_source+=("$target")
    fi
done
# The integration tests (golden images, watertightness, determinism, extremes) check every
# drawing path byte for byte, which is what can differ on ARM: 32-bit ARM composes its 64- and
# 128-bit arithmetic of 32-bit instructions, and the lanes run on NEON. The unit tests check the
# pieces, and run on the host; compiling them for each target would double the step.
case "${STRIPMASK_ARM_TESTS:-}" in
all) which=() ;;
*) which=(--test it) ;;
esac
# One cargo call for all targets: their builds share the two cores where one alone leaves a
# core idle. A standard library built from source is built for every target of its call, so
# those targets have their own.
say "the rasterizer's tests (${which[*]:-all})"
if [ "${#target_args[@]}" -gt 0 ]; then
    cargo test --profile "$profile" "${target_args[@]}" -p stripmask-raster "${which[@]}"
fi
for target in "${from_source[@]}"; do
    std_from_source test --profile "$profile" --target "$target" -p stripmask-raster "${which[@]}"
done
# The coverage masks in NEON assembly and the colour stage in passes run only on 32-bit ARM with
# NEON, the row step in words, the small loop's texture words and the span quotients in words on
# 32-bit cores: their unit tests, which hold them to the column loop, the lanes, the scalar
# reference and the wide products, run there too.
neon=thumbv7neon-unknown-linux-gnueabihf
if [ "${#which[@]}" -gt 0 ] && [[ " ${targets[*]} " == *" $neon "* ]]; then
    say "$neon: the unit tests of its coverage masks, colour stage and row step"
    cargo test --profile "$profile" --target "$neon" -p stripmask-raster --lib -- \
        edge:: fragments:: shade:: small:: pipeline::fixed::division::
fi
