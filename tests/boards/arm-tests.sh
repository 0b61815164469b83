#!/usr/bin/env bash
# The same bytes on every CPU: builds the rasterizer's tests, golden images included, for 32-bit
# ARM with NEON (thumbv7neon-unknown-linux-gnueabihf, static glibc) and 64-bit ARM
# (aarch64-unknown-linux-musl): the integration tests, in the `suite` profile, and runs them under
# QEMU user-mode emulation. The golden PNGs (raster/tests/golden/) were made
# on x86-64 and the tests compare byte for byte, so passing here means byte-identical pictures on
# ARM in both precisions. Whole engine frames on ARM are the board tests' job (tests/it/boards.rs
# compares stripmask fb on the emulated vexpress-a9 with the host, byte for byte).
#
#   tests/boards/arm-tests.sh [TARGET...]     # default: both
#   STRIPMASK_ARM_TESTS=all tests/boards/arm-tests.sh   # the unit tests too
#
# Installs with apt-get when missing: qemu-user-static, gcc-arm-linux-gnueabihf and
# libc6-dev-armhf-cross (32-bit ARM; aarch64 needs no C toolchain); adds the Rust targets with rustup.
# Settings: tests/boards/cross.sh.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
profile=${STRIPMASK_BOARDS_PROFILE:-suite}
targets=("$@")
[ "${#targets[@]}" -gt 0 ] || targets=(thumbv7neon-unknown-linux-gnueabihf aarch64-unknown-linux-musl)

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
    *) die "unknown target '$target' (thumbv7neon-unknown-linux-gnueabihf, aarch64-unknown-linux-musl)" ;;
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
    "${sudo[@]}" apt-get update -qq
    "${sudo[@]}" apt-get install -y -qq --no-install-recommends --no-upgrade "${missing[@]}" >/dev/null
fi

# shellcheck source=tests/boards/cross.sh
. "$here/cross.sh"
installed=$(rustup target list --installed)
cd "$root"
target_args=()
for target in "${targets[@]}"; do
    grep -qx "$target" <<<"$installed" || rustup target add "$target"
    runner=CARGO_TARGET_$(tr 'a-z-' 'A-Z_' <<<"$target")_RUNNER
    say "$target: run by ${!runner}"
    target_args+=(--target "$target")
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
# core idle.
say "the rasterizer's tests (${which[*]:-all})"
cargo test --profile "$profile" "${target_args[@]}" -p stripmask-raster "${which[@]}"
