//! The engine's controls for measurements: a simulated clock and link, pinned mask levels and
//! budgets, and whether a view is complete. The laboratory ([`crate::sim`], the `lab` feature)
//! compares runs with them; an application drawing frames has no use for them.

use std::sync::Arc;

use crate::db::grid::{TileId, TileMap};
use crate::db::tile::{levels_for_mask, progressive_levels};
use crate::engine::budget::{BudgetController, BudgetSettings};
use crate::engine::camera::Camera;
use crate::engine::client::Engine;
use crate::engine::cut::LastFrame;
use crate::engine::paging::TransferClock;
use crate::engine::plan::{FrameInputs, plan_view};

impl Engine {
    /// Sets the simulated time for a pager in [`PagerMode::Simulated`](crate::engine::paging::PagerMode::Simulated), seconds.
    pub fn set_time(&mut self, seconds: f64) {
        self.pager.set_time(seconds);
    }

    /// Times tile transfers for a pager in [`PagerMode::Simulated`](crate::engine::paging::PagerMode::Simulated).
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        self.pager.set_transfer_clock(clock);
    }

    /// Pins every drawn tile's mask level to `level_of(tile)` instead of the budget's choice
    /// (`None` gives the choice back to the budget): views with known level pairs, for
    /// measuring cracks. A partial tile draws no finer than it holds, and while any drawn tile
    /// is partial the pinned levels snap to powers of two ([`drawable_level`](crate::engine::budget::drawable_level)).
    pub fn force_levels(&mut self, level_of: Option<Box<dyn Fn(TileId) -> usize + Send>>) {
        self.forced_levels = level_of;
    }

    /// Whether the view of `camera` on the engine's viewport has everything it
    /// should draw with any of `budgets` triangles within `radius` level-0 tiles of the current
    /// one: its cut lacks no tile there (no tile it would refine misses a child), and every
    /// tile of the cut there holds at least the progressive levels of the coarsest mask level
    /// any of the budgets gives it if every tile in view held all its levels and that budget
    /// were shared among them (by the engine's allocation, no finer than τ needs, without the
    /// bonus of freshly fetched levels). It depends on the camera, the archive, what is
    /// resident and `budgets` only, not on the budgets the frames were drawn by, so paging
    /// strategies can be compared by it (`stream-compare`'s first complete view). Without
    /// budgets, the cut need only lack nothing.
    pub fn holds_view(&self, camera: &Camera, radius: u32, budgets: &[usize]) -> bool {
        let resident = self.pager.resident();
        let Some(center) = resident.current_tile() else {
            return false;
        };
        let near = |id: TileId| {
            let span = id.span();
            let gap = |c: u32, t: u32| {
                let (lo, hi) = (t * span, t * span + span - 1);
                lo.saturating_sub(c).max(c.saturating_sub(hi))
            };
            gap(center.x, id.x).max(gap(center.y, id.y)) <= radius
        };
        let no_kept = TileMap::default();
        let inputs = FrameInputs {
            holdings: self.pager.resident(),
            terrain: &self.terrain,
            pyramid: &self.pyramid,
            masks: &self.masks,
            weights: self.settings.weights,
            // The view's plan does not depend on the budget: each of `budgets` is shared below.
            budget: 0,
            forced_levels: None,
            max_error: self.settings.max_error,
            allocation: self.settings.allocation,
            cracks: self.settings.cracks,
            clearance: self.settings.clearance,
            kept: &no_kept,
            water_px: None,
            last: &LastFrame::default(),
        };
        let view = plan_view(&inputs, &self.view_of(camera));
        if view.cut.missing.iter().any(|&(id, _)| near(id)) {
            return false;
        }
        if budgets.is_empty() {
            return true;
        }
        let levels = progressive_levels(self.terrain.tile_size);
        // Per tile in reach, the fewest levels any of the budgets would have it draw: the
        // levels each budget offers the tiles in view had they held them all.
        let mut needed: TileMap<usize> = TileMap::default();
        for &budget in budgets {
            for (&(id, _, _), o) in view.cut.tiles.iter().zip(view.offer(&inputs, budget)) {
                if near(id) {
                    let l = levels_for_mask(o.level, levels);
                    needed
                        .entry(id)
                        .and_modify(|n| *n = (*n).min(l))
                        .or_insert(l);
                }
            }
        }
        needed
            .iter()
            .all(|(&id, &n)| resident.get(id).is_some_and(|t| t.levels >= n))
    }

    /// Sets the next frame's budget to `triangles`, where it stays until a recorded frame moves
    /// it: measurements at a fixed budget (the tradeoff report) bypass the frame-rate controller.
    pub fn hold_budget(&mut self, triangles: usize) {
        self.water_px = None;
        let settings = *self.budget.settings();
        self.budget = BudgetController::new(BudgetSettings {
            initial_budget: triangles,
            min_budget: settings.min_budget.min(triangles),
            max_budget: settings.max_budget.max(triangles),
            expected: None,
            ..settings
        });
    }
}
