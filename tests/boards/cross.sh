# Cargo settings for the ARM targets, sourced by tests/boards/setup.sh, tests/boards/arm-tests.sh
# and .ci/run (`. tests/boards/cross.sh`): static binaries, the linkers, and QEMU user-mode
# emulation as the runner of test binaries. Environment variables instead of a .cargo/config.toml,
# so that a plain `cargo build` on the host is untouched. See docs/platforms.md.

# 32-bit ARM, hard float, NEON (Cortex-A7/A8/A9/A15 with NEON, Raspberry Pi 2 and later): Debian's
# cross gcc links against glibc, statically (packages gcc-arm-linux-gnueabihf and
# libc6-dev-armhf-cross). The thumbv7neon target rather than armv7, which assumes no NEON: with it
# the rasterizer's lanes are vectors, 21% fewer instructions a PocketPC frame (docs/platforms.md).
export CARGO_TARGET_THUMBV7NEON_UNKNOWN_LINUX_GNUEABIHF_LINKER=arm-linux-gnueabihf-gcc
export CARGO_TARGET_THUMBV7NEON_UNKNOWN_LINUX_GNUEABIHF_RUSTFLAGS="-C target-feature=+crt-static"
# Test binaries are static; doctests are linked by rustdoc without the flags above, so the
# emulator also gets the cross glibc for them.
export CARGO_TARGET_THUMBV7NEON_UNKNOWN_LINUX_GNUEABIHF_RUNNER="qemu-arm-static -L /usr/arm-linux-gnueabihf"

# 64-bit ARM on musl: static by default; Rust's own lld and musl's objects from rustup, no cross gcc.
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_MUSL_LINKER=rust-lld
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_MUSL_RUNNER=qemu-aarch64-static
