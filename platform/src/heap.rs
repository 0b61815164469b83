//! The C allocator under a long frame loop.

/// The size from which glibc gives a block pages of its own, returned to the system when the
/// block is freed: glibc's starting value.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const OWN_PAGES_FROM: libc::c_int = 128 << 10;

/// Keeps glibc's threshold for blocks with pages of their own at 128 KiB. By default glibc
/// raises it to the size of each such block freed, up to 32 MiB, and a frame loop frees blocks
/// of megabytes: from then on blocks below that size come from the heap, which the tiles that
/// come and go leave in pieces it cannot give back, and the process grows well past the
/// engine's memory limit (docs/scale.md). Call it first in `main`. Returns whether the
/// allocator took the setting; elsewhere than on glibc it does nothing and returns false.
pub fn keep_large_blocks_apart() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: `mallopt` sets one allocator parameter under the allocator's own lock; glibc
        // initialises its allocator before `main`, so no thread can be racing that set-up.
        unsafe { libc::mallopt(libc::M_MMAP_THRESHOLD, OWN_PAGES_FROM) == 1 }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glibc_takes_the_setting_and_other_libraries_are_left_alone() {
        let glibc = cfg!(all(target_os = "linux", target_env = "gnu"));
        assert_eq!(keep_large_blocks_apart(), glibc);
        // Large blocks come and go as before.
        let block = vec![7u8; 4 << 20];
        assert_eq!(
            block.iter().map(|&b| usize::from(b)).sum::<usize>(),
            7 << 22
        );
    }
}
