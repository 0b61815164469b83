//! Reading texels: one file per filter. Coordinates arrive as 16.16 texture repeats.

mod linear;
mod nearest;

pub(crate) use linear::Bilinear;
pub(crate) use nearest::Nearest;

use crate::fixed_point::TEXCOORD_LIMIT;
use crate::pixel::rgb565_to_rgb;
use crate::texture::{MipLevel, Texels, Texture, TextureFormat, Wrap};

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

/// One mip level as the inner loop sees it: `width x height` texels (powers of two), row-major.
#[derive(Clone, Copy)]
pub(crate) struct LevelView<'a, T> {
    texels: &'a [T],
    pub width: i64,
    pub height: i64,
    width_shift: u32,
    pub wrap: Wrap,
}

impl<'a, T> LevelView<'a, T> {
    /// A view of `texels`, which must hold `width x height` texels with power-of-two sides: the
    /// texel reads below rely on it.
    pub fn new(texels: &'a [T], width: u32, height: u32, wrap: Wrap) -> Self {
        assert!(width.is_power_of_two() && height.is_power_of_two());
        assert_eq!(texels.len(), width as usize * height as usize);
        Self {
            texels,
            width: width as i64,
            height: height as i64,
            width_shift: width.trailing_zeros(),
            wrap,
        }
    }
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

    /// The texel at column `x`, row `y`, wrapped into the level.
    #[inline]
    pub fn fetch(&self, x: i64, y: i64) -> T {
        let i = ((self.row(y) << self.width_shift) + self.column(x)) as usize;
        debug_assert!(i < self.texels.len());
        // SAFETY: `column` and `row` return `0..width` and `0..height`, and `new` checked that
        // the view holds `width * height` texels with `width == 1 << width_shift`.
        unsafe { *self.texels.get_unchecked(i) }
    }

    /// The 2x2 texels whose top-left is column `x`, row `y`, each wrapped into the level:
    /// `[top-left, top-right, bottom-left, bottom-right]`.
    #[inline]
    pub fn quad(&self, x: i64, y: i64) -> [T; 4] {
        let ((x0, x1), (y0, y1)) = (self.column_pair(x), self.row_pair(y));
        let (r0, r1) = (y0 << self.width_shift, y1 << self.width_shift);
        [r0 + x0, r0 + x1, r1 + x0, r1 + x1].map(|i| {
            debug_assert!((0..self.texels.len() as i64).contains(&i));
            // SAFETY: the pairs lie in `0..width` and `0..height` (`column_pair`, `row_pair`),
            // and `new` checked that the view holds `width * height` texels with
            // `width == 1 << width_shift`.
            unsafe { *self.texels.get_unchecked(i as usize) }
        })
    }
}

/// Borrows a level's texels in the storage type `T`; `None` when the level holds another type.
pub(crate) trait ViewOf: Texel {
    fn view(level: &MipLevel, wrap: Wrap) -> Option<LevelView<'_, Self>>;
    /// A draw's views when its texels are of this type (empty otherwise).
    fn select<'a, 't>(views: &'a TexViews<'t>) -> &'a [LevelView<'t, Self>];
}

/// A draw's texture levels as the inner loop reads them, built once per draw.
pub(crate) enum TexViews<'t> {
    /// No texture.
    None,
    /// RGB565 levels.
    Rgb565(Vec<LevelView<'t, u16>>),
    /// RGBA8888 levels.
    Rgba8888(Vec<LevelView<'t, [u8; 4]>>),
}

impl<'t> TexViews<'t> {
    /// The views of `texture`'s levels, wrapped as `wrap` says.
    pub fn new(texture: &'t Texture, wrap: Wrap) -> Self {
        match texture.format() {
            TextureFormat::Rgb565 => TexViews::Rgb565(
                texture
                    .levels()
                    .iter()
                    .map(|l| u16::view(l, wrap).expect("one texel type per texture"))
                    .collect(),
            ),
            TextureFormat::Rgba8888 => TexViews::Rgba8888(
                texture
                    .levels()
                    .iter()
                    .map(|l| <[u8; 4]>::view(l, wrap).expect("one texel type per texture"))
                    .collect(),
            ),
        }
    }
}

fn view_parts<'a, T>(level: &'a MipLevel, texels: &'a [T], wrap: Wrap) -> LevelView<'a, T> {
    LevelView::new(texels, level.width(), level.height(), wrap)
}

impl ViewOf for u16 {
    fn view(level: &MipLevel, wrap: Wrap) -> Option<LevelView<'_, u16>> {
        match level.texels() {
            Texels::Rgb565(t) => Some(view_parts(level, t, wrap)),
            Texels::Rgba8888(_) => None,
        }
    }
    fn select<'a, 't>(views: &'a TexViews<'t>) -> &'a [LevelView<'t, u16>] {
        match views {
            TexViews::Rgb565(v) => v,
            _ => &[],
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
    fn select<'a, 't>(views: &'a TexViews<'t>) -> &'a [LevelView<'t, [u8; 4]>] {
        match views {
            TexViews::Rgba8888(v) => v,
            _ => &[],
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
