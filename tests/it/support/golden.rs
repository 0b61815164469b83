//! Golden-image comparison shared by the golden tests: byte for byte, re-blessed with
//! `STRIPMASK_BLESS=1`, a mismatch written to `target/golden-failures/`.

use std::path::PathBuf;

use stripmask_raster::Framebuffer;

/// Compares `fb` with `tests/golden/{name}.png` (or writes it when blessing).
pub fn check(name: &str, fb: &Framebuffer) {
    let actual = fb.to_rgba_image();
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let path = dir.join(format!("{name}.png"));
    if std::env::var_os("STRIPMASK_BLESS").is_some() {
        actual.save(&path).unwrap();
        return;
    }
    let expected = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (bless with STRIPMASK_BLESS=1)", path.display()))
        .to_rgba8();
    if expected != actual {
        let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/golden-failures");
        std::fs::create_dir_all(&out).unwrap();
        actual.save(out.join(format!("{name}.png"))).unwrap();
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
            out.display()
        );
    }
}
