//! The `build` and `info` commands on the real Puget Sound height map.

use std::path::PathBuf;
use std::process::Command;

fn stripmask() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stripmask"))
}

fn puget() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png")
}

#[test]
fn build_puget_sound_then_info_json_describes_the_grid() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("puget.smdb");
    let status = stripmask()
        .args([
            "build",
            "--quiet",
            "--spacing",
            "160",
            "--vertical-scale",
            "0.1",
            "-o",
        ])
        .arg(&out)
        .arg(puget())
        .status()
        .unwrap();
    assert!(status.success());
    let output = stripmask()
        .args(["info", "--json", "--check"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(v["header"]["tiles_x"], 8);
    assert_eq!(v["header"]["tiles_y"], 8);
    assert_eq!(v["header"]["tile_size"], 129);
    assert_eq!(v["header"]["texture_size"], 128);
    assert_eq!(v["tile_count"], 64);
    assert_eq!(
        v["pyramid"],
        serde_json::json!([[8, 8], [4, 4], [2, 2], [1, 1]])
    );
    let levels = v["stored_level_bytes_mean"].as_array().unwrap();
    assert_eq!(levels.len(), 8);
    assert_eq!(v["measured"], "every tile");
    assert_eq!(v["header"]["min_height"], 0.0);
    // The highest sample is 43798 raw units (Mount Rainier, 4379.8 m at 0.1 m per unit).
    let max = v["header"]["max_height"].as_f64().unwrap();
    assert!((max - 4379.8).abs() < 0.01, "{max}");
    assert_eq!(v["check"]["tiles"], 64 + 16 + 4 + 1);
    assert_eq!(v["check"]["absent"], 0);
    // An open reads the header and the directory: a few hundred bytes for this model.
    let opening = v["opening_bytes"].as_u64().unwrap();
    assert!((160..4096).contains(&opening), "{opening}");

    let text = stripmask().arg("info").arg(&out).output().unwrap();
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(text.contains("8 x 8 tiles of 129 x 129 samples"), "{text}");
    assert!(
        text.contains("163840 x 163840 m of model (1025 x 1025 samples)")
            && text.contains("padded with 0 column(s) east and 0 row(s) south"),
        "{text}"
    );
}

#[test]
fn errors_name_the_file_and_exit_1_bad_flags_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let bogus = dir.path().join("bogus.png");
    std::fs::write(&bogus, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let out = dir.path().join("x.smdb");
    let o = stripmask()
        .args(["build", "--quiet", "-o"])
        .arg(&out)
        .arg(&bogus)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bogus.png") && err.contains("PNG"), "{err}");
    assert!(!out.exists());

    // `info` reads a DEM as `build` would, and anything else as an archive.
    let o = stripmask().arg("info").arg(&bogus).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bogus.png") && err.contains("PNG"), "{err}");
    let not_archive = dir.path().join("bogus.smdb");
    std::fs::write(&not_archive, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let o = stripmask().arg("info").arg(&not_archive).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bogus.smdb") && err.contains("magic"), "{err}");

    // Bad flags: the library's check (tile size), clap's (raw layout flags go together), and
    // clap's with the library's names as the possible values (codec).
    let refused = |flag: &[&str]| {
        let o = stripmask()
            .args(["build", "--quiet", "-o"])
            .arg(&out)
            .arg(puget())
            .args(flag)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{flag:?} is a usage error");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let err = refused(&["--tile-size", "100"]);
    assert!(
        err.contains("tile size 100") && err.contains("2^n + 1"),
        "{err}"
    );
    let err = refused(&["--width", "4"]);
    assert!(
        err.contains("--height") && err.contains("--sample-type"),
        "{err}"
    );
    let err = refused(&["--codec", "zstd"]);
    assert!(
        err.contains("zstd") && err.contains("none, lz4, deflate"),
        "{err}"
    );
    assert!(!out.exists());
}
