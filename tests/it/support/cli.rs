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
