//! Running the `stripmask` binary from tests: the command, a small archive built with it, and a
//! run that must end within a bound.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The `stripmask` binary of this build.
pub fn stripmask() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stripmask"))
}

/// `out` built from `tests/fixtures/plain.asc` in 17-sample tiles (6 tiles).
pub fn plain_archive(out: &Path) {
    let input = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/plain.asc");
    let ok = stripmask()
        .args(["build", "--quiet", "--tile-size", "17", "-o"])
        .arg(out)
        .arg(&input)
        .status()
        .unwrap();
    assert!(ok.success());
}

/// The exit code and stderr of `stripmask args`; a run past 30 s is killed and fails the test.
pub fn run_bounded(args: &[&str]) -> (Option<i32>, String) {
    let (code, err, _) = run_timed(args, Duration::from_secs(30));
    (code, err)
}

/// The exit code, stderr and wall time of `stripmask args`; a run past `limit` is killed and
/// fails the test.
pub fn run_timed(args: &[&str], limit: Duration) -> (Option<i32>, String, Duration) {
    let started = Instant::now();
    let mut child = stripmask()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("stripmask {args:?} did not end within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let took = started.elapsed();
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    (status.code(), err, took)
}

/// `stripmask fly SOURCE` quietly into `out`, with no frames or plots kept, and `extra`
/// arguments: its exit code, stderr and wall time (a run past a minute fails the test).
pub fn fly_quietly(source: &str, out: &Path, extra: &[&str]) -> (Option<i32>, String, Duration) {
    let mut args = vec![
        "fly",
        source,
        "--every",
        "0",
        "--no-plots",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    run_timed(&args, Duration::from_secs(60))
}
