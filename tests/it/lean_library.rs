//! The library alone (`--no-default-features`) depends on none of the crates only the command,
//! the lab, the HTTP client and the server use: an embedder compiles none of them.

use std::process::Command;

/// The crates the library's optional features bring in.
const FEATURE_ONLY: [&str; 9] = [
    "clap",
    "plotters",
    "indicatif",
    "toml",
    "cpu-time",
    "ureq",
    "hyper",
    "hyper-util",
    "tokio",
];

#[test]
fn the_library_alone_depends_on_no_crate_of_the_command_or_the_lab() {
    let cargo = env!("CARGO");
    let out = match Command::new(cargo)
        .args(["tree", "--offline", "--no-default-features", "-e", "normal"])
        .args(["-p", "stripmask", "--prefix", "none", "--format", "{p}"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
    {
        Ok(out) => out,
        Err(e) => {
            eprintln!("skipped: cargo ({cargo}) cannot be run: {e}");
            return;
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "cargo tree failed: {stderr}");
    let tree = String::from_utf8_lossy(&out.stdout);
    let names: Vec<&str> = tree
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .collect();
    assert!(names.contains(&"stripmask-raster"), "{tree}");
    let found: Vec<&str> = FEATURE_ONLY
        .into_iter()
        .filter(|name| names.contains(name))
        .collect();
    assert!(
        found.is_empty(),
        "the library alone depends on {found:?}:\n{tree}"
    );
}
