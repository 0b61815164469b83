//! The temporary files builds write beside their output (`.NAME.PID-N.partial`), and the
//! clean-up of those a killed build left behind.
//!
//! A build that fails or panics removes its own temporary file; one killed (SIGKILL, power
//! loss) cannot. The next build to the same output removes the temporary files of that output
//! whose process no longer runs. Whether a process runs is known on Linux (`/proc/PID`); on
//! other systems stale files are left where they are, hidden beside the output.

use std::path::{Path, PathBuf};

/// The temporary file of writer number `n` of process `pid` for the archive at `path`.
pub fn partial_path(path: &Path, pid: u32, n: u64) -> Option<PathBuf> {
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name()?);
    name.push(format!(".{pid}-{n}.partial"));
    Some(path.with_file_name(name))
}

/// The process that wrote `candidate`, if it is a temporary file of the archive at `path`.
fn writer_pid(path: &Path, candidate: &str) -> Option<u32> {
    let file_name = path.file_name()?.to_str()?;
    let rest = candidate
        .strip_prefix('.')?
        .strip_prefix(file_name)?
        .strip_prefix('.')?
        .strip_suffix(".partial")?;
    let (pid, n) = rest.split_once('-')?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(pid) || !digits(n) {
        return None;
    }
    pid.parse().ok()
}

/// Whether process `pid` is known to have ended: `None` where that cannot be told.
fn has_ended(pid: u32) -> Option<bool> {
    let proc = Path::new("/proc");
    if !cfg!(target_os = "linux") || !proc.join("self").exists() {
        return None;
    }
    Some(!proc.join(pid.to_string()).exists())
}

/// Removes the temporary files of earlier builds of `path` whose process has ended (never one
/// of a process that runs, this one included); returns those removed. Removes nothing where
/// processes cannot be told apart (outside Linux).
pub fn remove_stale(path: &Path) -> Vec<PathBuf> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut removed = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| writer_pid(path, n)) else {
            continue;
        };
        if pid != std::process::id()
            && has_ended(pid) == Some(true)
            && std::fs::remove_file(entry.path()).is_ok()
        {
            removed.push(entry.path());
        }
    }
    removed.sort();
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_this_archives_temporary_names_are_read_as_a_writer() {
        let out = Path::new("/data/model.smdb");
        let own = partial_path(out, 42, 7).unwrap();
        assert_eq!(own, Path::new("/data/.model.smdb.42-7.partial"));
        let name = own.file_name().unwrap().to_str().unwrap();
        assert_eq!(writer_pid(out, name), Some(42));
        for other in [
            ".model.smdb.partial",
            ".model.smdb.x-1.partial",
            ".model.smdb.42-.partial",
            ".other.smdb.42-7.partial",
            ".model.smdb.42-7.partial.bak",
            "model.smdb.42-7.partial",
            ".model.smdb.old.42-7.partial",
        ] {
            assert_eq!(writer_pid(out, other), None, "{other}");
        }
    }
}
