//! A local archive file, read with positioned reads (no shared cursor, so it is `Sync`).

use std::fs::File;
use std::path::Path;

use super::TileSource;
use crate::error::{Error, Result};

/// A local archive file.
pub struct FileSource {
    name: String,
    file: File,
    len: u64,
}

impl FileSource {
    /// Opens `path`.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let len = file.metadata().map_err(|e| Error::io(&name, e))?.len();
        Ok(FileSource { name, file, len })
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
        read_at(&self.file, &mut buf, offset).map_err(|e| Error::io(&self.name, e))?;
        Ok(buf)
    }
}
