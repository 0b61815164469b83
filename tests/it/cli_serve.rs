//! `stripmask serve` prints its URL and `stripmask info URL` reads the archive through it.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};

fn stripmask() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stripmask"))
}

#[test]
fn serve_then_info_over_http() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plain.smdb");
    let input = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/plain.asc");
    let ok = stripmask()
        .args(["build", "--quiet", "--tile-size", "17", "-o"])
        .arg(&out)
        .arg(&input)
        .status()
        .unwrap();
    assert!(ok.success());

    let mut child = stripmask()
        .arg("serve")
        .arg(&out)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut url = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut url)
        .unwrap();
    let url = url.trim().to_string();
    let result = stripmask()
        .args(["info", "--json", "--check", &url])
        .output()
        .unwrap();
    child.kill().unwrap();
    child.wait().unwrap();

    assert!(
        url.starts_with("http://127.0.0.1:") && url.ends_with("/plain.smdb"),
        "{url}"
    );
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
    assert_eq!(v["name"], url.as_str());
    assert_eq!(v["tile_count"], 6);
    // 3 x 2 tiles, 2 x 1 above them, and the root.
    assert_eq!(v["check"]["tiles"], 9);
    assert_eq!(v["header"]["spacing"], 30.0);
}

#[test]
fn serve_refuses_a_missing_file_and_a_bad_drop_rate() {
    let o = stripmask()
        .args(["serve", "/nonexistent/x.smdb"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("/nonexistent/x.smdb"));
    let o = stripmask()
        .args(["serve", "Cargo.toml", "--drop-rate", "2"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "a bad flag is a usage error");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--drop-rate 2") && err.contains("0 and 1"),
        "{err}"
    );
    let o = stripmask().args(["serve", "Cargo.toml"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("Cargo.toml: bad magic"));
}

#[cfg(not(feature = "https"))]
#[test]
fn https_without_the_feature_says_how_to_get_it() {
    let o = stripmask()
        .args(["info", "https://example.invalid/x.smdb"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("https://example.invalid/x.smdb") && err.contains("--features https"),
        "{err}"
    );
}
