//! The headless presenter: frames as PNG files in a folder.

use std::path::{Path, PathBuf};

use stripmask_raster::Framebuffer;

use crate::{Overlay, PlatformError, Presenter, compose_rgba};

/// Writes every `every`-th frame as `frame_NNNNNN.png` into a folder: the headless presenter.
#[derive(Debug)]
pub struct PngFrames {
    dir: PathBuf,
    every: u64,
    count: u64,
}

impl PngFrames {
    /// Creates the folder if needed; `every` of 0 is taken as 1.
    pub fn new(dir: impl AsRef<Path>, every: u64) -> Result<Self, PlatformError> {
        let dir = dir.as_ref().to_path_buf();
        std::fs::create_dir_all(&dir).map_err(|source| PlatformError::Folder {
            path: dir.clone(),
            source,
        })?;
        Ok(Self {
            dir,
            every: every.max(1),
            count: 0,
        })
    }
}

impl Presenter for PngFrames {
    fn present(&mut self, frame: &Framebuffer, hud: Option<&Overlay>) -> Result<(), PlatformError> {
        let n = self.count;
        self.count += 1;
        if !n.is_multiple_of(self.every) {
            return Ok(());
        }
        let path = self.dir.join(format!("frame_{n:06}.png"));
        compose_rgba(frame, hud)
            .save(&path)
            .map_err(|source| PlatformError::Write { path, source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stripmask_raster::{ColorFormat, DepthFormat};

    #[test]
    fn keeps_one_frame_in_every_and_writes_what_was_drawn() {
        let dir = std::env::temp_dir().join(format!("stripmask-png-{}", std::process::id()));
        let mut p = PngFrames::new(&dir, 2).unwrap();
        let mut fb = Framebuffer::new(4, 3, ColorFormat::Rgb565, DepthFormat::None).unwrap();
        for shade in [0u8, 80, 160] {
            fb.clear_color([shade, 255, 0]);
            p.present(&fb, None).unwrap();
        }
        let mut names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        assert_eq!(names, ["frame_000000.png", "frame_000002.png"]);
        let img = image::open(dir.join("frame_000002.png"))
            .unwrap()
            .to_rgba8();
        assert_eq!(img.get_pixel(3, 2).0, fb.to_rgba_image().get_pixel(3, 2).0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_unwritable_folder_is_reported_with_its_path() {
        let file = std::env::temp_dir().join(format!("stripmask-not-a-dir-{}", std::process::id()));
        std::fs::write(&file, b"x").unwrap();
        let err = PngFrames::new(file.join("sub"), 1).unwrap_err();
        assert!(err.to_string().contains("stripmask-not-a-dir"), "{err}");
        std::fs::remove_file(&file).unwrap();
    }
}
