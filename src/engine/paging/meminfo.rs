//! A memory limit given as a percentage of the available memory, as in the paper.

use crate::error::{Error, Result};

const MEMINFO: &str = "/proc/meminfo";

/// `percent` (in `(0, 100]`) of the memory the system reports available now (`MemAvailable` of
/// `/proc/meminfo`), in bytes. Linux only: elsewhere an error asks for a limit in bytes.
pub fn memory_limit_from_available(percent: f64) -> Result<usize> {
    if !(percent > 0.0 && percent <= 100.0) {
        return Err(Error::setting(
            "memory limit as a percentage of available memory",
            percent,
            "a percentage in (0, 100]",
        ));
    }
    let available = available_bytes()?;
    Ok((available as f64 * percent / 100.0) as usize)
}

#[cfg(target_os = "linux")]
fn available_bytes() -> Result<u64> {
    let text = std::fs::read_to_string(MEMINFO).map_err(|e| Error::io(MEMINFO, e))?;
    parse_mem_available(&text)
        .ok_or_else(|| Error::invalid(MEMINFO, "no readable `MemAvailable: N kB` line"))
}

#[cfg(not(target_os = "linux"))]
fn available_bytes() -> Result<u64> {
    Err(Error::io(
        MEMINFO,
        std::io::Error::new(
            std::io::ErrorKind::Unsupported,
            "only Linux has it: give the memory limit in megabytes",
        ),
    ))
}

/// The `MemAvailable` line of a `/proc/meminfo` text, in bytes.
pub fn parse_mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?;
    let mut words = line.split_whitespace();
    let kib: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => kib.checked_mul(1024),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_available_is_read_in_kibibytes() {
        let text =
            "MemTotal:       16318332 kB\nMemFree:         1234 kB\nMemAvailable:    8000000 kB\n";
        assert_eq!(parse_mem_available(text), Some(8_000_000 * 1024));
        assert_eq!(parse_mem_available("MemTotal: 5 kB\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: lots kB\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: 12 MB\n"), None);
    }

    #[test]
    fn percentages_outside_0_to_100_are_refused() {
        for p in [0.0, -5.0, 100.5, f64::NAN] {
            let e = memory_limit_from_available(p).unwrap_err().to_string();
            assert!(e.contains("percentage"), "{e}");
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_percentage_of_available_memory_is_a_positive_fraction_of_it() {
        let all = memory_limit_from_available(100.0).unwrap();
        let tenth = memory_limit_from_available(10.0).unwrap();
        assert!(tenth > 0 && tenth < all, "{tenth} of {all}");
    }
}
