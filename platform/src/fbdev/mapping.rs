//! Screen memory mapped into the process.

use std::fs::File;
use std::io;
use std::os::fd::AsRawFd;
use std::ptr::NonNull;

/// A shared, writable mapping of the first `len` bytes of a file; unmapped on drop.
#[derive(Debug)]
pub(crate) struct Mapping {
    ptr: NonNull<u8>,
    len: usize,
}

impl Mapping {
    /// Maps `len` (> 0) bytes of `file` from offset 0. The caller makes sure the file (or the
    /// device's memory) is at least that long: touching a page past a regular file's end raises
    /// SIGBUS.
    pub fn new(file: &File, len: usize) -> io::Result<Self> {
        if len == 0 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "nothing to map",
            ));
        }
        // SAFETY: a fresh mapping chosen by the kernel (address null) over an open descriptor;
        // no existing memory is touched. The result is checked against MAP_FAILED below.
        let ptr = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(io::Error::last_os_error());
        }
        let ptr =
            NonNull::new(ptr.cast::<u8>()).ok_or_else(|| io::Error::other("mmap gave null"))?;
        Ok(Self { ptr, len })
    }

    /// The mapped bytes.
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: `ptr` is the start of a live mapping of `len` readable and writable bytes
        // that only this value owns (it is unmapped only in `drop`), and `&mut self` makes this
        // the only slice over it for its lifetime.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr(), self.len) }
    }
}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: `ptr` and `len` are exactly what mmap returned and was asked for, the
        // mapping has not been unmapped before, and no slice into it outlives `self`.
        unsafe {
            libc::munmap(self.ptr.as_ptr().cast(), self.len);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_through_the_mapping_reach_the_file_and_an_empty_mapping_is_refused() {
        let path = std::env::temp_dir().join(format!("stripmask-map-{}", std::process::id()));
        std::fs::write(&path, [0u8; 10]).unwrap();
        let file = File::options().read(true).write(true).open(&path).unwrap();
        {
            let mut map = Mapping::new(&file, 8).unwrap();
            assert_eq!(map.bytes_mut().len(), 8);
            map.bytes_mut()[1..4].copy_from_slice(b"abc");
        }
        assert_eq!(std::fs::read(&path).unwrap(), b"\0abc\0\0\0\0\0\0");
        assert_eq!(
            Mapping::new(&file, 0).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
        let read_only = File::open(&path).unwrap();
        assert_eq!(
            Mapping::new(&read_only, 8).unwrap_err().raw_os_error(),
            Some(libc::EACCES)
        );
        std::fs::remove_file(&path).unwrap();
    }
}
