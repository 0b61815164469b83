//! The two pipelines behind one interface: `fixed` (integer, fast) and `float` (f32 reference).
//! Both snap to the same sub-pixel grid and share the coverage walker, so their pictures differ
//! only where arithmetic precision makes them differ.

pub(crate) mod fixed;
pub(crate) mod float;

pub(crate) use crate::attributes::{Attributes, TexMode};

use crate::clip::ClipVertex;
use crate::edge::Coverage;
use crate::fixed_point::{GUARD_BAND_PX, SUBPIXEL_HALF, SUBPIXEL_ONE};
use crate::matrix::Transform;
use crate::state::Fog;
use crate::vertex::Vertex;

/// The full-framebuffer viewport.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Viewport {
    pub width: u32,
    pub height: u32,
}

impl Viewport {
    /// Keeps a snapped position within the guard band around the viewport centre. Clipping puts
    /// every vertex there already; this only catches the rounding of a cut far along a long
    /// segment (or a NaN), so that the edge arithmetic's bounds hold for any input.
    #[inline]
    pub fn clamp_to_guard_band(&self, xy: [i64; 2]) -> [i64; 2] {
        let band = GUARD_BAND_PX * SUBPIXEL_ONE;
        let centre = [
            self.width as i64 * SUBPIXEL_HALF,
            self.height as i64 * SUBPIXEL_HALF,
        ];
        // Written out: the compiler makes `[0, 1].map(..)` an out-of-line call per vertex.
        let clamp = |k: usize| xy[k].clamp(centre[k] - band, centre[k] + band);
        [clamp(0), clamp(1)]
    }
}

/// A set-up triangle of either pipeline.
pub(crate) trait Setup: Send + Sync {
    fn coverage(&self) -> &Coverage;
    /// Mip level the triangle samples.
    fn level(&self) -> usize;
    /// The draw it belongs to (an index into the batch's draws).
    fn draw(&self) -> u32;
}

/// One precision's stages, so that both pipelines share the draw's control flow (batching,
/// set-up in chunks, binning, tiles).
pub(crate) trait Pipeline: 'static {
    /// A vertex in clip space.
    type Clip: ClipVertex + Send + Sync;
    /// A projected vertex.
    type Screen: Copy + Default + Send + Sync;
    /// A set-up triangle.
    type Triangle: Setup;
    /// An attribute plane kept beside the triangles (the fixed pipeline's compact record).
    type Plane: Copy + Send + Sync;
    /// What the vertex stage of one draw needs: matrix, viewport and guard band, fog.
    type Consts: Send + Sync;

    fn consts(transform: &Transform, vp: &Viewport, fog: Option<Fog>) -> Self::Consts;
    fn space(c: &Self::Consts) -> &<Self::Clip as ClipVertex>::Space;
    fn clip(c: &Self::Consts, v: &Vertex) -> Self::Clip;
    fn project(c: &Self::Consts, clip: &Self::Clip) -> Self::Screen;
    /// Snapped sub-pixel position.
    fn xy(s: &Self::Screen) -> [i64; 2];
    /// Sets up `v` (positive orientation, `area2 > 0`) for draw `draw`; planes kept beside the
    /// triangle go to `planes`.
    fn triangle(
        v: [&Self::Screen; 3],
        area2: i64,
        coverage: Coverage,
        attrs: &Attributes,
        draw: u32,
        planes: &mut Vec<Self::Plane>,
    ) -> Self::Triangle;
}
