//! A local archive file, read with positioned reads (no shared cursor, so it is `Sync`).
//!
//! The source pins the file it opened: its size, its modification time and (on unix) its
//! device and inode. When a read fails, or bytes it gave fail their checksum, it looks again;
//! a file that was rewritten, truncated or garbled in place, or a path that names another file
//! now, fails that read and every later one with [`Error::ArchiveChanged`].

use std::fs::{File, Metadata};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::SystemTime;

use super::TileSource;
use crate::error::{Error, Result};

/// A local archive file.
pub struct FileSource {
    name: String,
    path: PathBuf,
    file: File,
    len: u64,
    opened: Stamp,
    /// What showed that the archive changed, once something did.
    changed: OnceLock<String>,
}

/// What tells one version of a file from another.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Stamp {
    len: u64,
    modified: Option<SystemTime>,
    /// Device and inode (unix).
    identity: Option<(u64, u64)>,
}

impl Stamp {
    fn of(meta: &Metadata) -> Self {
        #[cfg(unix)]
        let identity = {
            use std::os::unix::fs::MetadataExt;
            Some((meta.dev(), meta.ino()))
        };
        #[cfg(not(unix))]
        let identity = None;
        Stamp {
            len: meta.len(),
            modified: meta.modified().ok(),
            identity,
        }
    }
}

impl FileSource {
    /// Opens `path`.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let meta = file.metadata().map_err(|e| Error::io(&name, e))?;
        Ok(FileSource {
            name,
            path: path.to_path_buf(),
            file,
            len: meta.len(),
            opened: Stamp::of(&meta),
            changed: OnceLock::new(),
        })
    }

    /// How the archive differs from the one opened, in words: the open file rewritten (its
    /// size or modification time), or the path naming another file; `None` when it looks the
    /// same.
    fn difference(&self) -> Option<String> {
        let now = match self.file.metadata() {
            Ok(meta) => Stamp::of(&meta),
            Err(e) => return Some(format!("it can no longer be examined: {e}")),
        };
        if now.len != self.opened.len {
            return Some(format!(
                "its size went from {} to {} bytes",
                self.opened.len, now.len
            ));
        }
        if now.modified != self.opened.modified {
            return Some("it was written to after it was opened".into());
        }
        match std::fs::metadata(&self.path) {
            Err(e) => Some(format!("its path no longer names it: {e}")),
            Ok(meta) if Stamp::of(&meta) != now => Some("its path names another file now".into()),
            Ok(_) => None,
        }
    }

    /// Whether the archive is still the one opened: [`Error::ArchiveChanged`] once it is not.
    fn unchanged(&self) -> Result<()> {
        let what = match self.changed.get() {
            Some(what) => what.clone(),
            None => match self.difference() {
                Some(what) => self.changed.get_or_init(|| what).clone(),
                None => return Ok(()),
            },
        };
        Err(Error::ArchiveChanged {
            name: self.name.clone(),
            what,
        })
    }
}

/// Fills `buf` from `file` at `offset`, without moving a cursor.
#[cfg(unix)]
pub(crate) fn read_at(file: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

/// Fills `buf` from `file` at `offset`.
#[cfg(windows)]
pub(crate) fn read_at(file: &File, mut buf: &mut [u8], mut offset: u64) -> std::io::Result<()> {
    while !buf.is_empty() {
        match std::os::windows::fs::FileExt::seek_read(file, buf, offset)? {
            0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            n => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
        }
    }
    Ok(())
}

impl TileSource for FileSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn size(&self) -> Result<u64> {
        Ok(self.len)
    }

    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        if self.changed.get().is_some() {
            self.unchanged()?;
        }
        let end = offset.checked_add(len).filter(|&e| e <= self.len);
        if end.is_none() {
            return Err(Error::invalid(
                &self.name,
                format!(
                    "truncated: bytes {offset}..{} requested, the file has {}",
                    offset.saturating_add(len),
                    self.len
                ),
            ));
        }
        let mut buf = vec![0; len as usize];
        if let Err(e) = read_at(&self.file, &mut buf, offset) {
            self.unchanged()?;
            return Err(Error::io(&self.name, e));
        }
        Ok(buf)
    }

    fn checksum_failed(&self) -> Result<()> {
        self.unchanged()
    }
}
