//! Tells the crate whether its 32-bit ARM target has NEON (`cfg(arm_neon)`): stable Rust does
//! not say so through `cfg(target_feature)` on that architecture. NEON is there on the
//! `thumbv7neon` targets, and wherever the build's flags enable it (`-C target-feature=+neon`).

use std::env;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(arm_neon)");
    let var = |name: &str| env::var(name).unwrap_or_default();
    if var("CARGO_CFG_TARGET_ARCH") != "arm" {
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
