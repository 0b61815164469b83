//! Golden-image comparison shared by the golden tests of the rasterizer and of the engine (the
//! engine's `tests/it/support` includes this file): byte for byte, re-blessed with
//! `STRIPMASK_BLESS=1`, a mismatch written to `target/golden-failures/` of the crate under test.

use std::path::Path;

use stripmask_raster::Framebuffer;

/// Compares `fb` with `{dir}/{name}.png` (or writes it when blessing); `failures` is where a
/// mismatching picture goes.
pub fn check_in(dir: &Path, failures: &Path, name: &str, fb: &Framebuffer) {
    let actual = fb.to_rgba_image();
    let path = dir.join(format!("{name}.png"));
    if std::env::var_os("STRIPMASK_BLESS").is_some() {
        actual.save(&path).unwrap();
        return;
    }
    let expected = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (bless with STRIPMASK_BLESS=1)", path.display()))
        .to_rgba8();
    if expected != actual {
        std::fs::create_dir_all(failures).unwrap();
        actual.save(failures.join(format!("{name}.png"))).unwrap();
        let differing = if expected.dimensions() == actual.dimensions() {
            expected
                .pixels()
                .zip(actual.pixels())
                .filter(|(a, b)| a != b)
                .count()
        } else {
            usize::MAX
        };
        panic!(
            "{name}: {differing} pixels differ from {}; new image in {}",
            path.display(),
            failures.display()
        );
    }
}
