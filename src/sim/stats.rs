//! Per-frame statistics and the `stats.csv` they are written to.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// What one frame did: one row of `stats.csv`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameRecord {
    /// Frame number from 0.
    pub frame: u64,
    /// Flight time at the frame's start, seconds.
    pub time_s: f64,
    /// Time spent on the frame (bookkeeping and drawing), milliseconds.
    pub frame_ms: f64,
    /// Frames per second that `frame_ms` sustains.
    pub fps: f64,
    /// The frame rate the budget aims at.
    pub target_fps: f64,
    /// The triangle budget of the frame.
    pub budget: u64,
    /// Triangles drawn.
    pub triangles: u64,
    /// Pixels written.
    pub fragments: u64,
    /// Tiles drawn (in the view frustum and loaded).
    pub rendered_tiles: u64,
    /// Tiles in memory.
    pub loaded_tiles: u64,
    /// Accounted bytes of the loaded tiles.
    pub memory_bytes: u64,
    /// The memory limit.
    pub memory_limit_bytes: u64,
    /// Bytes downloaded since the start.
    pub downloaded_bytes: u64,
    /// Tiles downloaded since the start.
    pub downloads: u64,
    /// Belts of the complete square around the viewer.
    pub complete_belts: u64,
    /// Tiles being fetched.
    pub fetching: u64,
    /// Holes: parts of the terrain the view meets with nothing to draw (see
    /// [`crate::engine::FrameReport::holes`]).
    pub holes: u64,
    /// Bytes of the top of the pyramid, resident or reserved while on its way (part of
    /// `memory_bytes`).
    pub top_bytes: u64,
    /// The pixel-error bound τ, pixels (0: off).
    pub tau_px: f64,
    /// The largest geometric error of a drawn tile on screen, pixels.
    pub error_px: f64,
    /// 1 when the triangle budget capped the frame's detail, 0 when τ (or full resolution) did.
    pub budget_binds: u64,
    /// 1 when the budget was shared by projected error, 0 by visual importance.
    pub by_error: u64,
}

/// The CSV header, matching [`FrameRecord`]'s fields.
pub const CSV_HEADER: &str = "frame,time_s,frame_ms,fps,target_fps,budget,triangles,fragments,rendered_tiles,loaded_tiles,memory_bytes,memory_limit_bytes,downloaded_bytes,downloads,complete_belts,fetching,holes,top_bytes,tau_px,error_px,budget_binds,by_error";

impl FrameRecord {
    /// The record as one CSV line, without the newline.
    pub fn csv_line(&self) -> String {
        format!(
            "{},{:.4},{:.3},{:.2},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3},{},{}",
            self.frame,
            self.time_s,
            self.frame_ms,
            self.fps,
            self.target_fps,
            self.budget,
            self.triangles,
            self.fragments,
            self.rendered_tiles,
            self.loaded_tiles,
            self.memory_bytes,
            self.memory_limit_bytes,
            self.downloaded_bytes,
            self.downloads,
            self.complete_belts,
            self.fetching,
            self.holes,
            self.top_bytes,
            self.tau_px,
            self.error_px,
            self.budget_binds,
            self.by_error
        )
    }
}

/// Writes `stats.csv` row by row, flushed at the end (and on drop by the buffered writer).
pub struct StatsCsv {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl StatsCsv {
    /// Creates (truncates) `path` and writes the header.
    pub fn create(path: &Path) -> Result<StatsCsv> {
        let name = path.display().to_string();
        let file = std::fs::File::create(path).map_err(|e| Error::io(&name, e))?;
        let mut out = std::io::BufWriter::new(file);
        writeln!(out, "{CSV_HEADER}").map_err(|e| Error::io(&name, e))?;
        Ok(StatsCsv {
            path: path.to_path_buf(),
            out,
        })
    }

    /// Appends one frame.
    pub fn write(&mut self, r: &FrameRecord) -> Result<()> {
        writeln!(self.out, "{}", r.csv_line())
            .map_err(|e| Error::io(self.path.display().to_string(), e))
    }

    /// Flushes to disk.
    pub fn finish(mut self) -> Result<()> {
        self.out
            .flush()
            .map_err(|e| Error::io(self.path.display().to_string(), e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_and_lines_have_the_same_columns() {
        let r = FrameRecord {
            frame: 3,
            time_s: 0.5,
            budget: 3000,
            ..FrameRecord::default()
        };
        let line = r.csv_line();
        assert_eq!(line.split(',').count(), CSV_HEADER.split(',').count());
        assert!(line.starts_with("3,0.5000,"));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stats.csv");
        let mut csv = StatsCsv::create(&path).unwrap();
        csv.write(&r).unwrap();
        csv.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, format!("{CSV_HEADER}\n{line}\n"));
    }
}
