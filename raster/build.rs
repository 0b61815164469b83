//! Tells the crate what vectors its target has, as two `cfg`s: `wide_vectors` where `wide`'s
//! lanes are vectors (SSE2, NEON on aarch64, WebAssembly SIMD), and `arm_neon` where a 32-bit
//! ARM target has NEON, which stable Rust does not say through `cfg(target_feature)` on that
//! architecture: NEON is there on the `thumbv7neon` targets, and wherever the build's flags
//! enable it (`-C target-feature=+neon`). Code for cores with neither takes
//! `not(any(wide_vectors, arm_neon))`.

use std::env;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(arm_neon)");
    println!("cargo::rustc-check-cfg=cfg(wide_vectors)");
    let var = |name: &str| env::var(name).unwrap_or_default();
    let arch = var("CARGO_CFG_TARGET_ARCH");
    let features = var("CARGO_CFG_TARGET_FEATURE");
    let has = |f: &str| features.split(',').any(|x| x == f);
    if has("sse2") || (arch == "aarch64" && has("neon")) || has("simd128") {
        println!("cargo::rustc-cfg=wide_vectors");
    }
    if arch != "arm" {
        return;
    }
    let flags = var("CARGO_ENCODED_RUSTFLAGS");
    // The last word on `neon` in the flags' feature lists wins, as it does for the compiler.
    let from_flags = flags
        .split('\u{1f}')
        .filter_map(|f| f.split_once("target-feature=").map(|(_, list)| list))
        .flat_map(|list| list.split(','))
        .filter_map(|f| match f {
            "+neon" => Some(true),
            "-neon" => Some(false),
            _ => None,
        })
        .next_back();
    if from_flags.unwrap_or(var("TARGET").starts_with("thumbv7neon")) {
        println!("cargo::rustc-cfg=arm_neon");
    }
}
