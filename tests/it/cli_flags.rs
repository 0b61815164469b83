//! Numeric flags out of range are usage errors (exit 2, naming the flag), never a panic or a
//! run that cannot end; negative values are accepted in the `--flag -0.1` form and refused by
//! range, like any other.

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn stripmask() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stripmask"))
}

/// The exit code and stderr of `stripmask args`, killed (and the test failed) after 30 s.
fn run(args: &[&str]) -> (Option<i32>, String) {
    let mut child = stripmask()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("stripmask {args:?} did not end");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    (status.code(), err)
}

#[test]
fn out_of_range_numbers_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("plain.smdb");
    let input = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/plain.asc");
    let (code, err) = run(&[
        "build",
        "--quiet",
        "--tile-size",
        "17",
        "-o",
        archive.to_str().unwrap(),
        input.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let out = dir.path().join("fly");
    let (archive, out) = (archive.to_str().unwrap(), out.to_str().unwrap());
    for (flag, value, extra) in [
        ("--latency-ms", "1e300", None),
        ("--jitter-ms", "1e300", None),
        ("--bandwidth-kbps", "1e-300", None),
        ("--latency-ms", "-0.1", None),
        ("--seconds", "nan", None),
        ("--seconds", "-1", None),
        ("--cpu-slowdown", "1e-30", Some(["--clock", "simulated"])),
        ("--target-fps", "inf", None),
    ] {
        let mut args = vec![
            "fly",
            archive,
            "--out",
            out,
            "--every",
            "0",
            "--quiet",
            "--no-plots",
            flag,
            value,
        ];
        if let Some(e) = extra {
            args.extend(e);
        }
        if flag != "--seconds" {
            args.extend(["--frames", "3"]);
        }
        let (code, err) = run(&args);
        assert_eq!(code, Some(2), "{flag} {value}: {err}");
        let said = flag.trim_start_matches("--").replace('-', "_");
        assert!(
            err.contains(flag) || err.contains(&said),
            "{flag} {value}: {err}"
        );
    }
}
