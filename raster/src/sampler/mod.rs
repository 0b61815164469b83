//! Reading texels: one file per filter. Coordinates arrive as 16.16 texture repeats.

mod inside;
mod linear;
mod nearest;

pub(crate) use inside::UvRange;
pub(crate) use linear::Bilinear;
pub(crate) use nearest::Nearest;

use crate::fixed_point::TEXCOORD_LIMIT;
use crate::lanes::{LANES, Rgb8s, i32x8, narrow_u32, u16x8, u32x8};
use crate::pixel::rgb565_to_rgb;
use crate::texture::{MipLevel, Texels, Texture, TextureFormat, Wrap};
use wide::{CmpEq, CmpLt};

/// Keeps a 16.16 coordinate within `TEXCOORD_LIMIT`, so `u * width` cannot overflow whatever a
/// degenerate triangle interpolates.
#[inline]
pub(crate) fn clamp_coord(u: i64) -> i64 {
    u.clamp(-TEXCOORD_LIMIT, TEXCOORD_LIMIT)
}

/// A texel storage type.
pub(crate) trait Texel: Copy + Send + Sync + 'static {
    /// Eight texels in lanes.
    type Lanes: Copy;

    fn rgb(self) -> [u8; 3];

    /// Eight texels as lanes.
    fn lanes(t: [Self; LANES]) -> Self::Lanes;

    /// Eight pairs of neighbouring texels as the lanes of the first and of the second of each.
    fn pair_lanes(t: [[Self; 2]; LANES]) -> (Self::Lanes, Self::Lanes);

    /// `LevelView::gather_pairs`' reads as one AVX2 gather, for the x86-64-v3 twins
    /// (`crate::isa`), or `None` where this texel type has none.
    ///
    /// # Safety
    ///
    /// The CPU has the x86-64-v3 twins' features (`isa::Cpu::v3`), and each index and the one
    /// after it lie in `texels`.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn gather_pairs_avx2(
        _texels: &[Self],
        _index: i32x8,
    ) -> Option<(Self::Lanes, Self::Lanes)> {
        None
    }

    /// The colours of eight texels, as `rgb`.
    fn rgb_lanes(t: Self::Lanes) -> Rgb8s;

    /// The texel as a 32-bit word and back, for arrays of any texel type.
    #[cfg(any(test, arm_neon))]
    fn to_word(self) -> u32;
    #[cfg(any(test, arm_neon))]
    fn from_word(w: u32) -> Self;

    /// `blend` of eight 2x2 blocks, with the weights `fx`, `fy` (0..=255) in 16-bit lanes.
    fn blend_lanes(t: [Self::Lanes; 4], fx: u16x8, fy: u16x8) -> Rgb8s;

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

/// Eight 32-bit words as their low and high 16-bit halves (a pair of RGB565 texels read as one
/// word: the first texel in the low half on a little-endian CPU).
#[inline(always)]
fn halves(w: u32x8) -> (u16x8, u16x8) {
    (narrow_u32(w & u32x8::splat(0xFFFF)), narrow_u32(w >> 16))
}

crate::isa::v3_twin! {
    /// The 32-bit words at `texels + index` (in texels), read by one AVX2 gather.
    ///
    /// # Safety
    ///
    /// The CPU has the x86-64-v3 twins' features (`isa::Cpu::v3`), and each index and the one
    /// after it lie in `texels`.
    #[inline]
    unsafe fn gather_words_avx2(texels: &[u16], index: i32x8) -> u32x8 {
        use std::arch::x86_64::{
            _mm256_i32gather_epi32, _mm256_loadu_si256, _mm256_storeu_si256,
        };
        let index = index.to_array();
        debug_assert!(
            index
                .iter()
                .all(|&i| (0..texels.len() as i64 - 1).contains(&(i as i64)))
        );
        let mut words = [0u32; LANES];
        // SAFETY: the loads and the store touch the two 32-byte arrays; the gather reads 4
        // bytes at `texels + 2 * i` for each lane's index `i`, texels `i` and `i + 1`, which
        // the caller keeps inside `texels` (no alignment is needed).
        unsafe {
            let i = _mm256_loadu_si256(index.as_ptr().cast());
            let w = _mm256_i32gather_epi32::<2>(texels.as_ptr().cast(), i);
            _mm256_storeu_si256(words.as_mut_ptr().cast(), w);
        }
        u32x8::new(words)
    }
}

/// The 5- or 6-bit fields of RGB565 lanes widened to 8 bits by bit replication, as
/// `rgb565_to_rgb`.
#[inline(always)]
fn expand565(r: u16x8, g: u16x8, b: u16x8) -> Rgb8s {
    Rgb8s {
        r: (r << 3) | (r >> 2),
        g: (g << 2) | (g >> 4),
        b: (b << 3) | (b >> 2),
    }
}

impl Texel for u16 {
    type Lanes = u16x8;

    #[cfg(any(test, arm_neon))]
    #[inline(always)]
    fn to_word(self) -> u32 {
        self as u32
    }

    #[cfg(any(test, arm_neon))]
    #[inline(always)]
    fn from_word(w: u32) -> Self {
        w as u16
    }

    #[inline]
    fn rgb(self) -> [u8; 3] {
        rgb565_to_rgb(self)
    }

    #[inline(always)]
    fn lanes(t: [u16; LANES]) -> u16x8 {
        u16x8::new(t)
    }

    /// Each pair as one 32-bit lane (one load per pair), split into its halves in lanes.
    #[inline(always)]
    fn pair_lanes(t: [[u16; 2]; LANES]) -> (u16x8, u16x8) {
        halves(u32x8::new(t.map(|[a, b]| a as u32 | (b as u32) << 16)))
    }

    /// The eight pairs as one `vpgatherdd` of 32-bit words at `texels + 2 * index`: for scalar
    /// reads the compiler takes each index out of its lane, widens it, reads the pair and puts
    /// it back, some 24 instructions a row of a group.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn gather_pairs_avx2(texels: &[u16], index: i32x8) -> Option<(u16x8, u16x8)> {
        // SAFETY: the caller's contract: the twins' features are present and each pair lies in
        // `texels`.
        Some(halves(unsafe { gather_words_avx2(texels, index) }))
    }

    #[inline(always)]
    fn rgb_lanes(t: u16x8) -> Rgb8s {
        let (m5, m6) = (u16x8::splat(31), u16x8::splat(63));
        expand565(t >> 11, (t >> 5) & m6, t & m5)
    }

    /// `blend` field by field: the packed form's fields never carry into each other (see
    /// `SPREAD`), so each is `(a * (32 - fx) + b * fx) >> 5`, at most `63 * 32` in 16 bits.
    #[inline(always)]
    fn blend_lanes(t: [u16x8; 4], fx: u16x8, fy: u16x8) -> Rgb8s {
        let (four, s32) = (u16x8::splat(4), u16x8::splat(32));
        let (fx, fy) = ((fx + four) >> 3, (fy + four) >> 3);
        let (gx, gy) = (s32 - fx, s32 - fy);
        let field = |shift: i32, mask: u16| {
            let m = u16x8::splat(mask);
            let [a, b, c, d] = t.map(|p| (p >> shift) & m);
            let top = (a * gx + b * fx) >> 5;
            let bottom = (c * gx + d * fx) >> 5;
            (top * gy + bottom * fy) >> 5
        };
        expand565(field(11, 31), field(5, 63), field(0, 31))
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
    /// Each texel as the little-endian `u32` of its bytes: red in the low byte.
    type Lanes = u32x8;

    #[cfg(any(test, arm_neon))]
    #[inline(always)]
    fn to_word(self) -> u32 {
        u32::from_le_bytes(self)
    }

    #[cfg(any(test, arm_neon))]
    #[inline(always)]
    fn from_word(w: u32) -> Self {
        w.to_le_bytes()
    }

    #[inline]
    fn rgb(self) -> [u8; 3] {
        [self[0], self[1], self[2]]
    }

    #[inline(always)]
    fn lanes(t: [[u8; 4]; LANES]) -> u32x8 {
        u32x8::new(t.map(u32::from_le_bytes))
    }

    #[inline(always)]
    fn pair_lanes(t: [[[u8; 4]; 2]; LANES]) -> (u32x8, u32x8) {
        (
            Self::lanes(t.map(|[a, _]| a)),
            Self::lanes(t.map(|[_, b]| b)),
        )
    }

    #[inline(always)]
    fn rgb_lanes(t: u32x8) -> Rgb8s {
        let m = u32x8::splat(255);
        Rgb8s {
            r: narrow_u32(t & m),
            g: narrow_u32((t >> 8) & m),
            b: narrow_u32((t >> 16) & m),
        }
    }

    /// `blend` with the rows in 16-bit lanes (`a * (256 - fx) + b * fx <= 255 * 256`) and the
    /// final sum in 32-bit lanes.
    #[inline(always)]
    fn blend_lanes(t: [u32x8; 4], fx: u16x8, fy: u16x8) -> Rgb8s {
        let s256 = u16x8::splat(256);
        let (gx, gy) = (s256 - fx, s256 - fy);
        let [a, b, c, d] = t.map(Self::rgb_lanes);
        let channel = |a: u16x8, b: u16x8, c: u16x8, d: u16x8| {
            let top = a * gx + b * fx;
            let bottom = c * gx + d * fx;
            let sum = top.mul_widen(gy) + bottom.mul_widen(fy) + u32x8::splat(1 << 15);
            narrow_u32(sum >> 16)
        };
        Rgb8s {
            r: channel(a.r, b.r, c.r, d.r),
            g: channel(a.g, b.g, c.g, d.g),
            b: channel(a.b, b.b, c.b, d.b),
        }
    }
}

/// One mip level as the inner loop sees it: `width x height` texels (powers of two), row-major.
#[derive(Clone, Copy)]
pub(crate) struct LevelView<'a, T> {
    texels: &'a [T],
    pub width: i64,
    pub height: i64,
    width_shift: u32,
    height_shift: u32,
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
            height_shift: height.trailing_zeros(),
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

/// Eight 16.16 coordinates of one axis brought into `0..=0xFFFF` without changing a texel
/// address or a weight that the filters take from them: under `Repeat` the fraction (a side of
/// `2^k` texels repeats every `2^16`), under `Clamp` the nearest end of `0..=0xFFFF` (beyond it
/// both texels of a bilinear pair, and the nearest texel, are the edge's, whatever the weight).
/// Then `coordinate * side < 2^31` for sides up to `2^15` texels: 32-bit lanes suffice.
#[inline(always)]
fn fold(c: i32x8, wrap: Wrap) -> i32x8 {
    match wrap {
        Wrap::Repeat => c & i32x8::splat(0xFFFF),
        Wrap::Clamp => c.max(i32x8::ZERO).min(i32x8::splat(0xFFFF)),
    }
}

impl<'a, T: Texel> LevelView<'a, T> {
    /// Eight folded 16.16 coordinates (see `fold`) scaled to 16.16 texels: `(u * width,
    /// v * height)`, each in `0..2^31`.
    #[inline(always)]
    pub fn scale_lanes(&self, u: i32x8, v: i32x8) -> (i32x8, i32x8) {
        (
            fold(u, self.wrap) << self.width_shift,
            fold(v, self.wrap) << self.height_shift,
        )
    }

    /// Columns `x` and `x + 1` wrapped into the level, as `column_pair`, for `x` in
    /// `-1..width` (what bilinear addressing of a folded coordinate gives).
    #[inline(always)]
    pub fn column_pair_lanes(&self, x: i32x8) -> (i32x8, i32x8) {
        pair_lanes(x, self.width as i32, self.wrap)
    }

    /// For bilinear columns `x` and `x + 1` (`x` in `-1..width`) with weights `fx` (0..=255)
    /// towards the second: a column `s` whose texel and the next (one read each row,
    /// `gather_pairs`) blend with weights `fx'` to what the wrapped pair blends to with `fx`.
    /// Under `Clamp` a pair beyond an edge is the edge texel twice, which blends to itself
    /// whatever the weight: `s` is the pair inside the level that holds it, and `fx'` picks it
    /// (0 for the first, 256 for the second). Under `Repeat` the pair at the last column wraps
    /// to the first: `None` when a lane's does, as for a level one texel wide.
    #[inline(always)]
    pub fn neighbour_columns_lanes(&self, x: i32x8, fx: i32x8) -> Option<(i32x8, i32x8)> {
        let last = i32x8::splat(self.width as i32 - 1);
        match self.wrap {
            _ if self.width == 1 => None,
            Wrap::Repeat => {
                let s = x & last;
                (!s.cmp_eq(last).any()).then_some((s, fx))
            }
            Wrap::Clamp => {
                let (below, beyond) = (x.cmp_lt(i32x8::ZERO), x.cmp_eq(last));
                let s = x.max(i32x8::ZERO).min(last - i32x8::splat(1));
                let fx = beyond.blend(i32x8::splat(256), below.blend(i32x8::ZERO, fx));
                Some((s, fx))
            }
        }
    }

    /// Rows `y` and `y + 1` wrapped into the level, as `row_pair`, for `y` in `-1..height`.
    #[inline(always)]
    pub fn row_pair_lanes(&self, y: i32x8) -> (i32x8, i32x8) {
        pair_lanes(y, self.height as i32, self.wrap)
    }

    /// Texel index of column `x`, row `y` (both inside the level).
    #[inline(always)]
    pub fn index_lanes(&self, x: i32x8, y: i32x8) -> i32x8 {
        (y << self.width_shift) + x
    }

    /// The texels at eight indices, each in `0..width * height`.
    #[inline(always)]
    pub fn gather(&self, index: i32x8) -> T::Lanes {
        T::lanes(index.to_array().map(|i| {
            debug_assert!((0..self.texels.len() as i64).contains(&(i as i64)));
            // SAFETY: every index comes from `index_lanes` of columns and rows that
            // `pair_lanes` (or the nearest filter's folded coordinate) put in `0..width` and
            // `0..height`, and `new` checked that the view holds `width * height` texels with
            // `width == 1 << width_shift`.
            unsafe { *self.texels.get_unchecked(i as usize) }
        }))
    }

    /// The texels at eight indices and the texels after them: `(gather(index), gather(index +
    /// 1))`, each pair read at once. Each index and the one after it must lie in
    /// `0..width * height`.
    /// `V3`: called from an x86-64-v3 twin (`crate::isa`), where the texel type's AVX2 gather
    /// serves, if it has one.
    #[inline(always)]
    pub fn gather_pairs<const V3: bool>(&self, index: i32x8) -> (T::Lanes, T::Lanes) {
        #[cfg(target_arch = "x86_64")]
        if V3 {
            // SAFETY: only the x86-64-v3 twins pass `V3`, and they run where `isa::Cpu` found
            // their features; the indices are those of the reads below (see there).
            if let Some(pairs) = unsafe { T::gather_pairs_avx2(self.texels, index) } {
                return pairs;
            }
        }
        T::pair_lanes(index.to_array().map(|i| {
            debug_assert!((0..self.texels.len() as i64 - 1).contains(&(i as i64)));
            // SAFETY: every index comes from `index_lanes` of a row in `0..height` (`pair_lanes`)
            // and a column in `0..width - 1` (`neighbour_columns_lanes`), so it and the next
            // lie in one row of the `width * height` texels `new` checked; `[T; 2]` has `T`'s
            // alignment, so reading the two at once needs none beyond the slice's.
            unsafe { self.texels.as_ptr().add(i as usize).cast::<[T; 2]>().read() }
        }))
    }
}

/// Indices `i` and `i + 1` wrapped into `0..side` (a power of two) for `i` in `-1..side`: under
/// `Clamp`, `max(i, 0)` and `min(i + 1, side - 1)` are `column_pair`'s clamp for that range.
#[inline(always)]
fn pair_lanes(i: i32x8, side: i32, wrap: Wrap) -> (i32x8, i32x8) {
    let next = i + i32x8::splat(1);
    match wrap {
        Wrap::Repeat => {
            let m = i32x8::splat(side - 1);
            (i & m, next & m)
        }
        Wrap::Clamp => (i.max(i32x8::ZERO), next.min(i32x8::splat(side - 1))),
    }
}

/// `fold` of one coordinate.
#[inline(always)]
fn fold_one(c: i32, wrap: Wrap) -> i32 {
    match wrap {
        Wrap::Repeat => c & 0xFFFF,
        Wrap::Clamp => c.clamp(0, 0xFFFF),
    }
}

/// `pair_lanes` of one index.
#[inline(always)]
fn pair_one(i: i32, side: i32, wrap: Wrap) -> (i32, i32) {
    match wrap {
        Wrap::Repeat => (i & (side - 1), (i + 1) & (side - 1)),
        Wrap::Clamp => (i.max(0), (i + 1).min(side - 1)),
    }
}

/// The lanes' addressing for one fragment, in 32-bit integers: the colour stage's where lanes
/// are not vectors (`crate::lanes::VECTORS`), on 32-bit cores where `fetch` and `quad`'s 64-bit
/// arithmetic costs two instructions for one.
impl<'a, T: Texel> LevelView<'a, T> {
    /// `scale_lanes` of one fragment's coordinates.
    #[inline(always)]
    pub fn scale_one(&self, u: i32, v: i32) -> (i32, i32) {
        (
            fold_one(u, self.wrap) << self.width_shift,
            fold_one(v, self.wrap) << self.height_shift,
        )
    }

    /// The texel at column `x`, row `y`, both inside the level.
    #[inline(always)]
    pub fn texel(&self, x: i32, y: i32) -> T {
        let i = (y << self.width_shift) + x;
        debug_assert!((0..self.texels.len() as i64).contains(&(i as i64)));
        // SAFETY: the callers' columns and rows lie in `0..width` and `0..height` (the nearest
        // filter's come from folded coordinates), and `new` checked that the view holds
        // `width * height` texels with `width == 1 << width_shift`.
        unsafe { *self.texels.get_unchecked(i as usize) }
    }

    /// The 2x2 texels whose top-left is column `x`, row `y`, for `x` in `-1..width` and `y` in
    /// `-1..height` (what bilinear addressing of a folded coordinate gives), wrapped as
    /// `column_pair_lanes` and `row_pair_lanes` wrap them: where they lie, read by `quad_at`
    /// (apart, for a colour stage that works out every fragment's block before it reads any).
    #[inline(always)]
    pub fn quad_taps(&self, x: i32, y: i32) -> Quad {
        let (x0, x1) = pair_one(x, self.width as i32, self.wrap);
        let (y0, y1) = pair_one(y, self.height as i32, self.wrap);
        Quad([(x0, y0), (x1, y0), (x0, y1), (x1, y1)].map(|(x, y)| (y << self.width_shift) + x))
    }

    /// The texels of the block `q`.
    ///
    /// # Safety
    ///
    /// `q` comes from this view's `quad_taps`: its columns and rows come from `pair_one`, in
    /// `0..width` and `0..height`, so its indexes lie in the texels (as `texel`'s do), and the
    /// reads need no bounds check.
    #[inline(always)]
    pub unsafe fn quad_at(&self, q: Quad) -> [T; 4] {
        q.0.map(|i| {
            debug_assert!((0..self.texels.len() as i64).contains(&(i as i64)));
            // SAFETY: the caller's contract.
            unsafe { *self.texels.get_unchecked(i as usize) }
        })
    }
}

/// The indexes in its level of the 2x2 texels a bilinear sample blends (`LevelView::quad_taps`):
/// `[top-left, top-right, bottom-left, bottom-right]`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Quad([i32; 4]);

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
    /// `sample` at eight points, each coordinate 16.16 within `TEXCOORD_LIMIT`; `V3` when
    /// called from an x86-64-v3 twin (`crate::isa`).
    fn sample_lanes<const V3: bool>(view: &LevelView<'_, Self::Texel>, u: i32x8, v: i32x8)
    -> Rgb8s;
    /// One lane of `sample_lanes`, in 32-bit integers (`LevelView::scale_one`); `INSIDE` where
    /// the coordinate lies in a range the view holds inside (`LevelView::holds_inside`), which
    /// needs no fold or wrap.
    fn sample_one<const INSIDE: bool>(view: &LevelView<'_, Self::Texel>, u: i32, v: i32)
    -> [u8; 3];
    /// Whether `sample_one` blends a 2x2 block (`taps_one` gives it): for the colour stage in
    /// passes (`fragments/passes.rs`).
    #[cfg(any(test, arm_neon))]
    const TAPS: bool = false;
    /// `sample_one` up to its reads: the block at `(u, v)` and its weights `fx`, `fy`, whose
    /// `Texel::blend` is the sample; `None` where `TAPS` is false.
    #[cfg(any(test, arm_neon))]
    #[inline(always)]
    fn taps_one<const INSIDE: bool>(
        _view: &LevelView<'_, Self::Texel>,
        _u: i32,
        _v: i32,
    ) -> Option<(Quad, u32, u32)> {
        None
    }
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
    #[inline]
    fn sample_lanes<const V3: bool>(_: &LevelView<'_, u16>, _: i32x8, _: i32x8) -> Rgb8s {
        Rgb8s::splat([255; 3])
    }
    #[inline]
    fn sample_one<const INSIDE: bool>(_: &LevelView<'_, u16>, _: i32, _: i32) -> [u8; 3] {
        [255; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `blend` of each lane's block against `blend_lanes`, with the weights the lanes get
    /// (`fx` 256 from a clamped edge, `Bilinear::sample_lanes`).
    fn blends_agree<T: Texel>(
        t: [[T; 4]; LANES],
        fx: [u16; LANES],
        fy: [u16; LANES],
    ) -> Result<(), proptest::test_runner::TestCaseError> {
        let quad = [0, 1, 2, 3].map(|c| T::lanes(t.map(|q| q[c])));
        let lanes = T::blend_lanes(quad, u16x8::new(fx), u16x8::new(fy));
        for k in 0..LANES {
            let one = T::blend(t[k], fx[k] as u32, fy[k] as u32);
            proptest::prop_assert_eq!(lanes.lane(k), one, "lane {}", k);
        }
        Ok(())
    }

    proptest::proptest! {
        #[test]
        fn blending_one_block_equals_blending_lanes(
            rgb565 in proptest::array::uniform8(proptest::array::uniform4(proptest::num::u16::ANY)),
            rgba in proptest::array::uniform8(proptest::array::uniform4(proptest::array::uniform4(0u8..=255))),
            fx in proptest::array::uniform8(0u16..=256),
            fy in proptest::array::uniform8(0u16..=255),
        ) {
            blends_agree(rgb565, fx, fy)?;
            blends_agree(rgba, fx, fy)?;
        }
    }
}
