//! The few ioctl requests this crate sends, each tied to the type the kernel reads or writes,
//! so that no caller can pair a request with a buffer of the wrong size.

use std::fs::File;
use std::io;
use std::os::fd::AsRawFd;

use libc::c_int;

use super::screen_info::{FbFixScreeninfo, FbVarScreeninfo};

/// A value the kernel fills in for one request.
pub(crate) trait IoctlGet: Default {
    /// The request number (linux/fb.h, linux/kd.h).
    const REQUEST: u32;
    /// The request's name, for errors.
    const NAME: &'static str;
}

impl IoctlGet for FbVarScreeninfo {
    const REQUEST: u32 = 0x4600;
    const NAME: &'static str = "FBIOGET_VSCREENINFO";
}

impl IoctlGet for FbFixScreeninfo {
    const REQUEST: u32 = 0x4602;
    const NAME: &'static str = "FBIOGET_FSCREENINFO";
}

/// The console mode as KDGETMODE writes it: an `int`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct KdMode(pub c_int);

impl IoctlGet for KdMode {
    const REQUEST: u32 = 0x4B3B;
    const NAME: &'static str = "KDGETMODE";
}

/// KDSETMODE: its argument is the mode itself, not a pointer.
const KDSETMODE: u32 = 0x4B3A;

/// Sends `T`'s request and returns what the kernel wrote.
pub(crate) fn get<T: IoctlGet>(file: &File) -> io::Result<T> {
    let mut out = T::default();
    // SAFETY: `T::REQUEST` is a read request whose argument is a pointer to exactly one `T`
    // (the `IoctlGet` impls pair each request with its repr(C) type from the kernel headers);
    // `out` is a live, writable `T` for the whole call, and the descriptor is open.
    let rc = unsafe { libc::ioctl(file.as_raw_fd(), T::REQUEST as _, &mut out as *mut T) };
    if rc == -1 {
        Err(io::Error::last_os_error())
    } else {
        Ok(out)
    }
}

/// Sets the console mode (KD_TEXT or KD_GRAPHICS) of the virtual terminal behind `tty`.
pub(crate) fn set_kd_mode(tty: &File, mode: KdMode) -> io::Result<()> {
    // SAFETY: KDSETMODE takes its argument by value (an integer mode); no memory is passed.
    let rc = unsafe { libc::ioctl(tty.as_raw_fd(), KDSETMODE as _, mode.0 as libc::c_ulong) };
    if rc == -1 {
        Err(io::Error::last_os_error())
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn regular_file() -> File {
        let path = std::env::temp_dir().join(format!("stripmask-ioctl-{}", std::process::id()));
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .unwrap();
        std::fs::remove_file(&path).unwrap();
        file
    }

    #[test]
    fn a_regular_file_refuses_every_request_with_enotty() {
        let file = regular_file();
        let errno = |e: io::Error| e.raw_os_error();
        assert_eq!(
            get::<FbVarScreeninfo>(&file).map_err(errno).unwrap_err(),
            Some(libc::ENOTTY)
        );
        assert_eq!(
            get::<FbFixScreeninfo>(&file).map_err(errno).unwrap_err(),
            Some(libc::ENOTTY)
        );
        assert_eq!(
            get::<KdMode>(&file).map_err(errno).unwrap_err(),
            Some(libc::ENOTTY)
        );
        assert_eq!(
            set_kd_mode(&file, KdMode(0)).map_err(errno).unwrap_err(),
            Some(libc::ENOTTY)
        );
    }
}
