//! The engine's golden images, in `tests/golden/` (see the rasterizer's `golden_check.rs`).

use std::path::Path;

use stripmask_raster::Framebuffer;

#[path = "../../../raster/tests/it/golden_check.rs"]
mod golden_check;

/// Compares `fb` with `tests/golden/{name}.png` (or writes it when blessing).
pub fn check(name: &str, fb: &Framebuffer) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    golden_check::check_in(
        &root.join("tests/golden"),
        &root.join("target/golden-failures"),
        name,
        fb,
    );
}
