//! Reading texels: one file per filter. Coordinates arrive as 16.16 texture repeats.

mod linear;
mod nearest;

pub(crate) use linear::Bilinear;
pub(crate) use nearest::Nearest;

use crate::fixed_point::TEXCOORD_LIMIT;
use crate::pixel::rgb565_to_rgb;
use crate::texture::{MipLevel, Texels, Wrap};

/// Keeps a 16.16 coordinate within `TEXCOORD_LIMIT`, so `u * width` cannot overflow whatever a
/// degenerate triangle interpolates.
#[inline]
fn clamp_coord(u: i64) -> i64 {
    u.clamp(-TEXCOORD_LIMIT, TEXCOORD_LIMIT)
}

/// A texel storage type.
pub(crate) trait Texel: Copy + Send + Sync + 'static {
    fn rgb(self) -> [u8; 3];

    /// Bilinear blend of a 2x2 block `[top-left, top-right, bottom-left, bottom-right]` with
    /// 8-bit weights `fx`, `fy` (0..=255) towards the right and the bottom.
    #[inline]
    fn blend(t: [Self; 4], fx: u32, fy: u32) -> [u8; 3] {
        let [a, b, c, d] = t.map(Self::rgb);
        [0, 1, 2].map(|k| {
            let top = a[k] as u32 * (256 - fx) + b[k] as u32 * fx;
            let bottom = c[k] as u32 * (256 - fx) + d[k] as u32 * fx;
            ((top * (256 - fy) + bottom * fy + (1 << 15)) >> 16) as u8
        })
    }
}

/// RGB565 with its fields spread apart (`-G-R-B` in 32 bits), so that one multiplication scales
/// all three channels by a 5-bit weight without carries between them.
const SPREAD: u32 = 0x07E0_F81F;

#[inline]
fn spread(p: u16) -> u32 {
    (p as u32 | (p as u32) << 16) & SPREAD
}

impl Texel for u16 {
    #[inline]
    fn rgb(self) -> [u8; 3] {
        rgb565_to_rgb(self)
    }

    /// Filters in the packed domain with 5-bit weights: as fine as the 5- and 6-bit channels, at
    /// a quarter of the multiplications.
    #[inline]
    fn blend(t: [u16; 4], fx: u32, fy: u32) -> [u8; 3] {
        let (fx, fy) = ((fx + 4) >> 3, (fy + 4) >> 3); // 0..=32
        let [a, b, c, d] = t.map(spread);
        let top = ((a * (32 - fx) + b * fx) >> 5) & SPREAD;
        let bottom = ((c * (32 - fx) + d * fx) >> 5) & SPREAD;
        let p = ((top * (32 - fy) + bottom * fy) >> 5) & SPREAD;
        rgb565_to_rgb((p | p >> 16) as u16)
    }
}

impl Texel for [u8; 4] {
    #[inline]
    fn rgb(self) -> [u8; 3] {
        [self[0], self[1], self[2]]
    }
}

/// One mip level as the inner loop sees it.
#[derive(Clone, Copy)]
pub(crate) struct LevelView<'a, T> {
    pub texels: &'a [T],
    pub width: i64,
    pub height: i64,
    pub width_shift: u32,
    pub wrap: Wrap,
}

impl<'a, T: Texel> LevelView<'a, T> {
    /// Column `x` wrapped into the level.
    #[inline]
    pub fn column(&self, x: i64) -> i64 {
        match self.wrap {
            Wrap::Repeat => x & (self.width - 1),
            Wrap::Clamp => x.clamp(0, self.width - 1),
        }
    }

    /// Row `y` wrapped into the level.
    #[inline]
    pub fn row(&self, y: i64) -> i64 {
        match self.wrap {
            Wrap::Repeat => y & (self.height - 1),
            Wrap::Clamp => y.clamp(0, self.height - 1),
        }
    }

    /// Columns `x` and `x + 1` wrapped into the level. Under clamping the second is the first
    /// plus one exactly when `x` lies in `0..width - 1`: one comparison instead of a second clamp.
    #[inline]
    pub fn column_pair(&self, x: i64) -> (i64, i64) {
        match self.wrap {
            Wrap::Repeat => (x & (self.width - 1), (x + 1) & (self.width - 1)),
            Wrap::Clamp => {
                // max/min rather than clamp: no check that the level is not empty per texel.
                let c = x.max(0).min(self.width - 1);
                (c, c + ((x as u64) < (self.width - 1) as u64) as i64)
            }
        }
    }

    /// Rows `y` and `y + 1` wrapped into the level, as `column_pair`.
    #[inline]
    pub fn row_pair(&self, y: i64) -> (i64, i64) {
        match self.wrap {
            Wrap::Repeat => (y & (self.height - 1), (y + 1) & (self.height - 1)),
            Wrap::Clamp => {
                let r = y.max(0).min(self.height - 1);
                (r, r + ((y as u64) < (self.height - 1) as u64) as i64)
            }
        }
    }

    /// The texel at an already wrapped column and row.
    #[inline]
    pub fn texel(&self, column: i64, row: i64) -> T {
        self.texels[((row << self.width_shift) + column) as usize]
    }

    /// The colour at `(x, y)`, wrapped.
    #[inline]
    pub fn fetch(&self, x: i64, y: i64) -> [u8; 3] {
        self.texel(self.column(x), self.row(y)).rgb()
    }
}

/// Borrows a level's texels in the storage type `T`; `None` when the level holds another type.
pub(crate) trait ViewOf: Texel {
    fn view(level: &MipLevel, wrap: Wrap) -> Option<LevelView<'_, Self>>;
}

fn view_parts<'a, T>(level: &'a MipLevel, texels: &'a [T], wrap: Wrap) -> LevelView<'a, T> {
    LevelView {
        texels,
        width: level.width() as i64,
        height: level.height() as i64,
        width_shift: level.width().trailing_zeros(),
        wrap,
    }
}

impl ViewOf for u16 {
    fn view(level: &MipLevel, wrap: Wrap) -> Option<LevelView<'_, u16>> {
        match level.texels() {
            Texels::Rgb565(t) => Some(view_parts(level, t, wrap)),
            Texels::Rgba8888(_) => None,
        }
    }
}

impl ViewOf for [u8; 4] {
    fn view(level: &MipLevel, wrap: Wrap) -> Option<LevelView<'_, [u8; 4]>> {
        match level.texels() {
            Texels::Rgba8888(t) => Some(view_parts(level, t, wrap)),
            Texels::Rgb565(_) => None,
        }
    }
}

/// A filter, or no texture at all: the inner loop is generic over this.
pub(crate) trait Filtering: Send + Sync + 'static {
    /// False for `NoTexture`: texture work compiles away.
    const ENABLED: bool;
    type Texel: ViewOf;
    fn sample(view: &LevelView<'_, Self::Texel>, u: i64, v: i64) -> [u8; 3];
}

/// Texturing off.
pub(crate) struct NoTexture;

impl Filtering for NoTexture {
    const ENABLED: bool = false;
    type Texel = u16;
    #[inline]
    fn sample(_: &LevelView<'_, u16>, _: i64, _: i64) -> [u8; 3] {
        [255; 3]
    }
}
