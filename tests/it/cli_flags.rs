//! Numeric flags out of range are usage errors (exit 2, naming the flag), never a panic or a
//! run that cannot end; negative values are accepted in the `--flag -0.1` form and refused by
//! range, like any other.

use crate::support::cli::{plain_archive, run_bounded as run};

#[test]
fn out_of_range_numbers_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("plain.smdb");
    plain_archive(&archive);
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
