//! What one frame did: the report [`crate::engine::Engine::render`] returns.

use stripmask_raster::{DrawStats, LineStats};

use crate::db::grid::TileId;
use crate::engine::allocation::Allocation;
use crate::engine::camera::View;
use crate::engine::error_bound::Bound;
use crate::engine::paging::PagerStats;

/// What one frame did.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameReport {
    /// What the frame was drawn from: the camera (as given, or lifted to the clearance with
    /// [`EngineSettings::lift_to_clearance`]), the viewport and the depth planes the engine
    /// fitted to the terrain.
    ///
    /// [`EngineSettings::lift_to_clearance`]: crate::engine::EngineSettings::lift_to_clearance
    pub view: View,
    /// The triangle budget of this frame.
    pub budget: usize,
    /// Triangles the chosen masks hold.
    pub triangles: usize,
    /// Tiles in the view frustum among the loaded ones: the tiles drawn.
    pub rendered_tiles: usize,
    /// What capped the frame's detail: the budget (time) or the error bound τ.
    pub bound: Bound,
    /// The rule that shared the budget among the tiles.
    pub allocation: Allocation,
    /// The largest geometric error of a drawn tile on screen, pixels (see
    /// [`RenderedTile::error_px`]).
    pub max_error_px: f64,
    /// The drawn tiles with their visual importance and mask level.
    pub rendered: Vec<RenderedTile>,
    /// Holes: parts of the terrain the view meets with nothing to draw — tiles of the pyramid
    /// in view with no resident copy and nothing resident over or under them (none once the
    /// top is resident).
    pub holes: usize,
    /// Tiles the view wants that are not resident yet, drawn meanwhile from a coarser tile
    /// over them: none once the view has settled.
    pub waiting: usize,
    /// What the rasterizer did.
    pub draw: DrawStats,
    /// What the wireframe's lines did (zero when it is off).
    pub wireframe: LineStats,
    /// Seconds the pager's update took at the frame's start: taking in arrived tiles and
    /// planning fetches — and, when the pager fetches on the frame's thread (stepped and
    /// simulated modes), the fetches themselves.
    pub paging_seconds: f64,
    /// Seconds spent on the cut, importance, budget, masks and the draw list.
    pub bookkeeping_seconds: f64,
    /// Seconds spent drawing.
    pub draw_seconds: f64,
    /// The pager's counters after this frame's update.
    pub pager: PagerStats,
}

impl FrameReport {
    /// Whether the frame drew terrain wherever the view meets some: no holes. Until the first
    /// such frame an engine draws sky where the tiles have not arrived.
    pub fn ready(&self) -> bool {
        self.holes == 0
    }

    /// Whether the frame drew the view as the engine wants it: ready, and no tile waiting.
    pub fn settled(&self) -> bool {
        self.ready() && self.waiting == 0
    }
}

/// One drawn tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderedTile {
    /// Which tile.
    pub id: TileId,
    /// Its visual importance this frame (the drawn tiles' values sum to 1).
    pub importance: f64,
    /// The strip-mask level it was drawn at.
    pub level: usize,
    /// Its level's geometric error on screen: the height error (metres, from the archive)
    /// times pixels per metre at its bounding box's distance from the eye; 0 for an exact
    /// level, infinite for a level without a known error, as the budget's allocation counts it.
    pub error_px: f64,
    /// Whether it drew coarser than the budget offered because it holds too few levels.
    pub capped: bool,
    /// Whether it drew finer than the budget and τ gave it, to stitch to a tile of another
    /// level of the pyramid ([`conform`](crate::engine::cracks::neighbours::conform)).
    pub conformed: bool,
}
