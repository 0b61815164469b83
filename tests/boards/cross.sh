# shellcheck shell=bash
# Cargo settings for the ARM targets, sourced by tests/boards/setup.sh, tests/boards/arm-tests.sh,
# and tests/boards/count-instructions.sh (`. "$here/cross.sh"`): static binaries, the linkers, QEMU
# user-mode emulation as the runner of test binaries, and cargo for a target rustup does not serve. Environment variables instead of a .cargo/config.toml,
# so that a plain `cargo build` on the host is untouched. See docs/platforms.md.

# 32-bit ARM, hard float, NEON (Cortex-A7/A8/A9/A15 with NEON, Raspberry Pi 2 and later): Debian's
# cross gcc links against glibc, statically (packages gcc-arm-linux-gnueabihf and
# libc6-dev-armhf-cross). The thumbv7neon target rather than armv7, which assumes no NEON: with it
# the compiler vectorises where it can, 4% fewer instructions a PocketPC frame (docs/platforms.md).
export CARGO_TARGET_THUMBV7NEON_UNKNOWN_LINUX_GNUEABIHF_LINKER=arm-linux-gnueabihf-gcc
export CARGO_TARGET_THUMBV7NEON_UNKNOWN_LINUX_GNUEABIHF_RUSTFLAGS="-C target-feature=+crt-static"
# Test binaries are static; doctests are linked by rustdoc without the flags above, so the
# emulator also gets the cross glibc for them.
export CARGO_TARGET_THUMBV7NEON_UNKNOWN_LINUX_GNUEABIHF_RUNNER="qemu-arm-static -L /usr/arm-linux-gnueabihf"

# ARMv5TE, soft float (the paper's PocketPC's XScale, QEMU's `-cpu pxa255`): Debian's armel cross
# gcc and glibc, statically (packages gcc-arm-linux-gnueabi and libc6-dev-armel-cross). The
# runner emulates the PXA255, so an instruction newer than ARMv5TE fails the test.
export CARGO_TARGET_ARMV5TE_UNKNOWN_LINUX_GNUEABI_LINKER=arm-linux-gnueabi-gcc
export CARGO_TARGET_ARMV5TE_UNKNOWN_LINUX_GNUEABI_RUSTFLAGS="-C target-feature=+crt-static"
export CARGO_TARGET_ARMV5TE_UNKNOWN_LINUX_GNUEABI_RUNNER="qemu-arm-static -cpu pxa255 -L /usr/arm-linux-gnueabi"

# 64-bit ARM on musl: static by default; Rust's own lld and musl's objects from rustup, no cross gcc.
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_MUSL_LINKER=rust-lld
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_MUSL_RUNNER=qemu-aarch64-static

# Whether rustup serves TARGET's standard library, adding the target if it is not there yet.
rustup_std() {
    rustup target list --installed | grep -qx "$1" || rustup target add "$1" >/dev/null 2>&1
}

# `cargo SUBCOMMAND ARGS...` with the standard library of the ARGS' --target built from source
# (the rust-src component), for a target rustup serves none of for this toolchain
# (armv5te-unknown-linux-gnueabi: `rustup target add` fails): cargo's unstable -Zbuild-std,
# allowed on a stable toolchain by RUSTC_BOOTSTRAP=1. Scripts only; docs/platforms.md has what
# a user with a served target runs.
std_from_source() {
    local subcommand=$1
    shift
    rustup component list --installed | grep -qx rust-src || rustup component add rust-src
    RUSTC_BOOTSTRAP=1 cargo "$subcommand" -Zbuild-std=std,panic_abort "$@"
}

# `cargo SUBCOMMAND --target TARGET ARGS...`, TARGET's standard library from rustup or from source.
cross_cargo() {
    local subcommand=$1 target=$2
    shift 2
    if rustup_std "$target"; then
        cargo "$subcommand" --target "$target" "$@"
    else
        std_from_source "$subcommand" --target "$target" "$@"
    fi
}
