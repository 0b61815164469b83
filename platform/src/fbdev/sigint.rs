//! Ctrl-C while frames are on the console: a flag instead of death, so that the presenter is
//! dropped and the console restored. The previous handler comes back when the last guard goes.

use std::io;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// Set by the handler.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Live guards, and the handler that was there before the first one.
static INSTALLED: Mutex<Option<(usize, libc::sigaction)>> = Mutex::new(None);

extern "C" fn on_sigint(_: libc::c_int) {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// While alive, SIGINT sets a flag (see [`interrupted`]) instead of ending the process.
#[derive(Debug)]
pub(crate) struct SigintGuard(());

impl SigintGuard {
    /// Installs the handler (the first guard clears the flag and saves the old handler).
    pub fn install() -> io::Result<Self> {
        let mut installed = INSTALLED.lock().unwrap_or_else(|e| e.into_inner());
        match installed.as_mut() {
            Some((count, _)) => *count += 1,
            None => {
                INTERRUPTED.store(false, Ordering::SeqCst);
                // SAFETY: `sigaction` is a plain C struct for which all-zero is a valid value
                // (empty mask, no flags, SIG_DFL); the fields used are set below.
                let mut action: libc::sigaction = unsafe { std::mem::zeroed() };
                action.sa_sigaction = on_sigint as extern "C" fn(libc::c_int) as libc::sighandler_t;
                action.sa_flags = libc::SA_RESTART;
                // SAFETY: as above, all-zero is a valid `sigaction`; the kernel overwrites it.
                let mut old: libc::sigaction = unsafe { std::mem::zeroed() };
                // SAFETY: both pointers are to live `sigaction`s; the new handler only stores
                // to an atomic, which is async-signal-safe.
                let rc = unsafe { libc::sigaction(libc::SIGINT, &action, &mut old) };
                if rc == -1 {
                    return Err(io::Error::last_os_error());
                }
                *installed = Some((1, old));
            }
        }
        Ok(Self(()))
    }
}

impl Drop for SigintGuard {
    fn drop(&mut self) {
        let mut installed = INSTALLED.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((count, old)) = installed.as_mut() {
            *count -= 1;
            if *count == 0 {
                // SAFETY: `old` is the action the kernel returned when this handler went in.
                unsafe { libc::sigaction(libc::SIGINT, old, std::ptr::null_mut()) };
                *installed = None;
            }
        }
    }
}

/// Whether SIGINT arrived since the first live guard was installed.
pub(crate) fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn current_handler() -> libc::sighandler_t {
        // SAFETY: a null new action only reads the current one into the zeroed `cur`.
        unsafe {
            let mut cur: libc::sigaction = std::mem::zeroed();
            assert_eq!(libc::sigaction(libc::SIGINT, std::ptr::null(), &mut cur), 0);
            cur.sa_sigaction
        }
    }

    #[test]
    fn ctrl_c_sets_the_flag_and_the_old_handler_returns_with_the_last_guard() {
        let before = current_handler();
        let first = SigintGuard::install().unwrap();
        let second = SigintGuard::install().unwrap();
        assert!(!interrupted());
        // SAFETY: our handler is installed, so SIGINT only sets the flag.
        assert_eq!(unsafe { libc::raise(libc::SIGINT) }, 0);
        assert!(interrupted());
        drop(first);
        assert_ne!(current_handler(), before);
        drop(second);
        assert_eq!(current_handler(), before);
    }
}
