//! The test helper paints what it is asked to: the other tests rely on it.

use crate::common;

use stripmask_raster::ColorFormat;

#[test]
fn every_pixel_gets_its_own_colour() {
    let fb = common::painted(5, 4, ColorFormat::Rgba8888, common::pattern);
    for y in 0..4 {
        for x in 0..5 {
            assert_eq!(fb.pixel(x, y), common::pattern(x, y), "({x}, {y})");
        }
    }
}
