//! One frame's plan, from the view alone: the cut through the pyramid (Algorithm 2), the tiles'
//! visual importance, the levels τ needs, the budget shared among the tiles, and the levels
//! conformed where tiles of two pyramid levels meet. Pure: it reads what is resident and
//! changes nothing.

use std::cell::OnceCell;
use std::collections::BinaryHeap;

use crate::db::grid::{Pyramid, TileId, TileMap};
use crate::db::tile::PartialGrid;
use crate::engine::allocation::{Allocation, ErrorDescent, TileErrors};
use crate::engine::budget::{TileAllocation, drawable_level};
use crate::engine::camera::{PixelScale, View};
use crate::engine::cracks::CrackMode;
use crate::engine::cracks::neighbours::{
    Neighbourhood, conform, neighbour_levels, pyramid_borders,
};
use crate::engine::cut::{Cut, CutSettings, Holdings, LastFrame, cut};
use crate::engine::error_bound::{Bound, ErrorBound};
use crate::engine::importance::{Importance, TileMeasure, Weights, visual_importance};
use crate::engine::masks::{LevelSet, MaskSet};
use crate::engine::render::TileDraw;
use crate::engine::report::RenderedTile;
use crate::engine::resident::ResidentTile;
use crate::engine::terrain::TerrainFrame;

/// What a frame's plan is made from.
pub(super) struct FrameInputs<'e> {
    /// The resident tiles the cut goes through.
    pub(super) holdings: &'e dyn Holdings,
    pub(super) terrain: &'e TerrainFrame,
    pub(super) pyramid: &'e Pyramid,
    pub(super) masks: &'e MaskSet,
    pub(super) weights: Weights,
    /// This frame's triangle budget: the frame draws by it, and streaming wishes by it.
    pub(super) budget: usize,
    /// Levels pinned per tile instead of the budget's choice.
    pub(super) forced_levels: Option<&'e (dyn Fn(TileId) -> usize + Send)>,
    /// The pixel-error bound τ.
    pub(super) max_error: ErrorBound,
    /// How the tiles share the budget.
    pub(super) allocation: Allocation,
    /// How cracks are hidden: stitching asks tiles of two levels of the pyramid to meet.
    pub(super) cracks: CrackMode,
    /// No tile is seen from nearer than this (the eye's clearance), metres.
    pub(super) clearance: f64,
    /// The level each tile should keep if the budget allows (see [`Engine::kept_levels`]).
    pub(super) kept: &'e TileMap<usize>,
    /// The error the last frame's budget left on screen, if it capped the frame.
    pub(super) water_px: Option<f64>,
    /// What the last frame drew.
    pub(super) last: &'e LastFrame,
}

impl FrameInputs<'_> {
    /// Pixels per metre of height error at `distance` from the eye, no nearer than the
    /// clearance: a tile whose box holds the eye (distance 0) is not seen from closer than the
    /// eye keeps above the ground.
    pub(super) fn pixels_per_metre(&self, scale: &PixelScale, distance: f64) -> f64 {
        scale.at(distance.max(self.clearance))
    }

    /// The coarsest level of every tile whose error seen from `distance` is within τ.
    pub(super) fn needed_levels<'t>(
        &self,
        view: &View,
        tiles: impl Iterator<Item = (&'t ResidentTile, f64)>,
    ) -> Vec<usize> {
        let scale = view.pixel_scale();
        tiles
            .map(|(tile, distance)| {
                let ppm = self.pixels_per_metre(&scale, distance);
                self.max_error
                    .coarsest_level(&tile.level_errors, self.masks, ppm)
            })
            .collect()
    }

    /// Each tile's level errors, its pixels per metre at `distance` and its kept level: what
    /// sharing the budget by error weighs, for the frame and for the predicted view alike.
    pub(super) fn tile_errors<'t>(
        &self,
        view: &View,
        tiles: impl Iterator<Item = (TileId, &'t ResidentTile, f64)>,
    ) -> Vec<TileErrors<'t>> {
        let scale = view.pixel_scale();
        tiles
            .map(|(id, tile, distance)| TileErrors {
                metres: &tile.level_errors,
                pixels_per_metre: self.pixels_per_metre(&scale, distance),
                kept: self.kept.get(&id).copied(),
            })
            .collect()
    }

    /// What decides how deep the cut of a view goes: τ (none when it is off), the error the
    /// last frame's budget left when it capped the frame, and the screen.
    pub(super) fn cut_settings(&self) -> CutSettings {
        CutSettings {
            max_error_px: match self.max_error {
                ErrorBound::Off => None,
                ErrorBound::Pixels(_) => Some(self.max_error.pixels()),
            },
            water_px: self.water_px,
            clearance: self.clearance,
        }
    }

    /// The cut of `view` through the resident tiles.
    pub(super) fn cut<'p>(&self, view: &View) -> Cut<'p>
    where
        Self: 'p,
    {
        cut(
            self.holdings,
            self.terrain,
            self.pyramid,
            view,
            &self.cut_settings(),
            self.last,
        )
    }
}

/// One frame's plan: the tiles of the cut, their importance, and the mask level each draws and
/// would draw if it held every level.
pub(super) struct FramePlan<'p> {
    /// The cut: the tiles drawn (each with its resident copy and its box's distance from the
    /// eye), what the view lacks, the tiles gone through.
    pub(super) cut: Cut<'p>,
    pub(super) importance: Vec<f64>,
    /// The levels drawn.
    pub(super) allocation: Vec<TileAllocation>,
    /// The levels the budget offered: a tile drawn coarser is capped by what it holds, and
    /// streaming asks for what they lack.
    pub(super) offered: Vec<TileAllocation>,
    /// Per tile, pixels per metre of height error at its distance.
    pub(super) pixels_per_metre: Vec<f64>,
    pub(super) budget: usize,
    /// Triangles of every tile at the level τ asks (full resolution when τ is off).
    pub(super) need: usize,
    /// What capped the detail.
    pub(super) bound: Bound,
    /// Parts of the view with nothing to draw.
    pub(super) holes: usize,
    /// Per tile, whether stitching to another pyramid level made its level finer.
    pub(super) conformed: Vec<bool>,
    /// Which drawn tiles border which.
    pub(super) neighbourhood: Neighbourhood,
    /// When the budget capped the frame, the largest error on screen among the tiles it kept
    /// coarser than they could draw: the error the budget affords everywhere.
    pub(super) water_px: Option<f64>,
}

/// What a frame's plan takes from the view alone, whatever its budget: the cut, the tiles'
/// importance, the levels τ needs and each tile's errors.
pub(super) struct ViewPlan<'p> {
    /// The cut: the tiles in view to draw, what the view lacks, the tiles gone through.
    pub(super) cut: Cut<'p>,
    pub(super) importance: Importance,
    /// Per tile drawn, the coarsest level whose error is within τ.
    pub(super) needed: Vec<usize>,
    /// Triangles the needed levels take.
    pub(super) need: usize,
    /// Per tile drawn, the finest level it can draw: its held levels' finest, no finer than
    /// it needs.
    pub(super) finest: Vec<usize>,
    pub(super) errors: Vec<TileErrors<'p>>,
    /// Some tile in view holds only part of its levels.
    pub(super) partial: bool,
    /// Which drawn tiles border which.
    pub(super) neighbourhood: Neighbourhood,
    /// The error descents of the shares capped at `finest` and at `needed`, made at the
    /// first share that needs them: the frame shares several budgets.
    descents: [OnceCell<ErrorDescent>; 2],
}

/// Cuts through the pyramid and weighs the tiles in view (Algorithm 2), with the levels τ
/// needs: the part of the frame's plan its budget does not change (see [`ViewPlan`]).
pub(super) fn plan_view<'p>(inputs: &FrameInputs<'p>, view: &View) -> ViewPlan<'p> {
    let cut = inputs.cut(view);
    let measures: Vec<TileMeasure> = cut
        .tiles
        .iter()
        .map(|&(_, tile, distance)| TileMeasure {
            distance,
            height: f64::from(tile.max - tile.min),
        })
        .collect();
    let importance = visual_importance(&measures, inputs.weights);
    let partial = cut.tiles.iter().any(|(_, tile, _)| !tile.is_complete());
    // Partial tiles holding more than their corners draw powers-of-two levels only, which the
    // engine's masks are whenever such tiles are resident (see `Engine::new`): a level whose
    // `l + 1` is not a multiple of a drawn neighbour's stride needs border samples that
    // neighbour lacks.
    debug_assert!(
        inputs.masks.level_set() == LevelSet::PowerOfTwo
            || cut
                .tiles
                .iter()
                .all(|(_, t, _)| t.is_complete() || t.levels == 1)
    );
    let needed = inputs.needed_levels(view, cut.tiles.iter().map(|&(_, t, d)| (t, d)));
    let need = needed.iter().map(|&l| inputs.masks.triangle_count(l)).sum();
    let finest = cut
        .tiles
        .iter()
        .zip(&needed)
        .map(|((_, tile, _), &level)| tile.finest_mask_level().max(level))
        .collect();
    let errors = inputs.tile_errors(view, cut.tiles.iter().copied());
    let ids: Vec<TileId> = cut.tiles.iter().map(|t| t.0).collect();
    ViewPlan {
        neighbourhood: Neighbourhood::of(&ids),
        cut,
        importance,
        needed,
        need,
        finest,
        errors,
        partial,
        descents: Default::default(),
    }
}

impl ViewPlan<'_> {
    /// `budget` shared among the tiles in view, none finer than it can draw.
    pub(super) fn share(&self, inputs: &FrameInputs, budget: usize) -> Vec<TileAllocation> {
        self.share_capped(inputs, budget, false)
    }

    /// The levels `budget` offers the tiles in view had they held every level.
    pub(super) fn offer(&self, inputs: &FrameInputs, budget: usize) -> Vec<TileAllocation> {
        self.share_capped(inputs, budget, self.partial)
    }

    /// `budget` shared among the tiles in view, none finer than the levels τ needs
    /// (`needed`) or than the finest it can draw.
    fn share_capped(
        &self,
        inputs: &FrameInputs,
        budget: usize,
        needed: bool,
    ) -> Vec<TileAllocation> {
        let caps = if needed { &self.needed } else { &self.finest };
        let (importance, masks, errors) = (&self.importance, inputs.masks, &self.errors);
        match inputs.allocation {
            // The error share replays the view's descent; any other rule shares as it does.
            Allocation::Error => self.descents[usize::from(needed)]
                .get_or_init(|| ErrorDescent::new(importance, masks, errors, caps))
                .share(budget, importance, masks, errors, caps),
            rule => rule.share(budget, importance, masks, errors, caps),
        }
    }
}

/// The levels a share of the budget gives the tiles drawn, the levels it offers them, and which
/// tiles conforming made finer.
type Levels = (Vec<TileAllocation>, Vec<TileAllocation>, Vec<bool>);

/// The levels `budget` gives the tiles of `view` — forced when the engine pins them — and the
/// levels it offers them, conformed at the borders between pyramid levels when stitching; and
/// which tiles conforming made finer.
pub(super) fn levels(inputs: &FrameInputs, view: &ViewPlan, budget: usize) -> Levels {
    let mut allocation = view.share(inputs, budget);
    let mut offered = if view.partial {
        view.offer(inputs, budget)
    } else {
        allocation.clone()
    };
    if let Some(level_of) = inputs.forced_levels {
        for ((a, o), &(id, tile, _)) in allocation.iter_mut().zip(&mut offered).zip(&view.cut.tiles)
        {
            let pinned = level_of(id);
            o.level = drawable_level(pinned, 0, view.partial);
            a.level = drawable_level(pinned, tile.finest_mask_level(), view.partial);
            a.triangles = inputs.masks.triangle_count(a.level);
        }
    }
    let conformed = if inputs.cracks == CrackMode::Stitch {
        conform_levels(inputs, view, &mut allocation, &mut offered)
    } else {
        vec![false; allocation.len()]
    };
    (allocation, offered, conformed)
}

/// How much of the budget's error the cut keeps in view after a frame the budget did not bind.
pub(super) const WATER_DECAY: f64 = 0.8;

/// How many times a frame shares its budget again, less what conforming added, before it
/// searches from nothing for the share that fits.
pub(super) const CONFORM_PASSES: usize = 4;

/// Cuts, weighs (Algorithm 2) and shares the budget, no tile finer than τ needs, the levels of
/// tiles meeting a tile of another pyramid level conformed when stitching: the frame's plan.
/// What conforming adds is taken from the budget the others share.
pub(super) fn plan_frame<'p>(inputs: &FrameInputs<'p>, frame: &View) -> FramePlan<'p> {
    let view = plan_view(inputs, frame);
    let bound = match inputs.max_error {
        _ if view.need > inputs.budget || inputs.forced_levels.is_some() => Bound::Budget,
        ErrorBound::Off => Bound::Full,
        ErrorBound::Pixels(_) => Bound::Error,
    };
    let mut plan = levels(inputs, &view, inputs.budget);
    let drawn = |plan: &Levels| plan.0.iter().map(|a| a.triangles).sum::<usize>();
    if drawn(&plan) > inputs.budget && inputs.forced_levels.is_none() {
        // Conforming added what the share did not count: share that much less, a few times
        // (each pass lands close), then search between the last share over the budget and
        // the first within it for the largest that fits; then spend what is left where it
        // ties nothing.
        let (mut over, mut share) = (inputs.budget, inputs.budget);
        let mut fitting = None;
        for _ in 0..CONFORM_PASSES {
            let excess = drawn(&plan).saturating_sub(inputs.budget);
            if excess == 0 {
                fitting = Some(share);
                break;
            }
            over = share;
            share = share.saturating_sub(excess + inputs.budget / 256);
            plan = levels(inputs, &view, share);
        }
        let mut fits = match fitting {
            Some(share) => share,
            None if drawn(&plan) <= inputs.budget => share,
            None => {
                over = share;
                plan = levels(inputs, &view, 0);
                0
            }
        };
        while over - fits > (inputs.budget / 128).max(1) {
            let mid = fits + (over - fits) / 2;
            let tried = levels(inputs, &view, mid);
            if drawn(&tried) <= inputs.budget {
                (fits, plan) = (mid, tried);
            } else {
                over = mid;
            }
        }
        top_up(inputs, &view, &mut plan, inputs.budget);
    }
    let (allocation, offered, conformed) = plan;
    let water_px = (bound == Bound::Budget && inputs.forced_levels.is_none())
        .then(|| {
            allocation
                .iter()
                .zip(&view.finest)
                .zip(&view.errors)
                .filter(|((a, finest), _)| a.level > **finest)
                .map(|((a, _), e)| e.pixels(a.level))
                .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.max(e))))
        })
        .flatten();
    FramePlan {
        neighbourhood: view.neighbourhood,
        water_px,
        conformed,
        pixels_per_metre: view.errors.iter().map(|e| e.pixels_per_metre).collect(),
        holes: view.cut.holes.len(),
        cut: view.cut,
        importance: view.importance.values,
        allocation,
        offered,
        budget: inputs.budget,
        need: view.need,
        bound,
    }
}

/// Spends what conforming left of `budget` on the tiles away from the borders between pyramid
/// levels, whose levels stitching does not tie: a level finer at a time, the tile showing the
/// largest error first, none finer than its cap.
pub(super) fn top_up(inputs: &FrameInputs, view: &ViewPlan, plan: &mut Levels, budget: usize) {
    let (allocation, offered, _) = plan;
    let border = pyramid_borders(&view.neighbourhood);
    let mut left = budget.saturating_sub(allocation.iter().map(|a| a.triangles).sum());
    let finer = |level: usize| {
        inputs
            .masks
            .levels()
            .iter()
            .rev()
            .find(|&&l| l < level)
            .copied()
    };
    let mut heap: BinaryHeap<(OrderedError, usize)> = (0..allocation.len())
        .filter(|&k| !border[k] && allocation[k].level > view.finest[k])
        .map(|k| (OrderedError(view.errors[k].pixels(allocation[k].level)), k))
        .collect();
    while let Some((_, k)) = heap.pop() {
        let a = &mut allocation[k];
        let Some(next) = finer(a.level).filter(|&l| l >= view.finest[k]) else {
            continue;
        };
        let cost = inputs
            .masks
            .triangle_count(next)
            .saturating_sub(a.triangles);
        if cost > left {
            continue;
        }
        left -= cost;
        a.level = next;
        a.triangles += cost;
        offered[k].level = offered[k].level.min(next);
        if next > view.finest[k] {
            heap.push((OrderedError(view.errors[k].pixels(next)), k));
        }
    }
}

/// A screen error ordered as a number (never NaN: errors are finite or infinite).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct OrderedError(f64);

impl Eq for OrderedError {}

impl PartialOrd for OrderedError {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrderedError {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// Makes the levels of tiles that meet a tile of another pyramid level stitch ([`conform`]):
/// finer where needed, the offers with them (a tile holding too few levels for its conformed
/// mask is then asked for them). Returns which tiles changed.
pub(super) fn conform_levels(
    inputs: &FrameInputs,
    view: &ViewPlan,
    allocation: &mut [TileAllocation],
    offered: &mut [TileAllocation],
) -> Vec<bool> {
    let cut = &view.cut;
    let mut levels: Vec<usize> = allocation.iter().map(|a| a.level).collect();
    let finest: Vec<usize> = cut
        .tiles
        .iter()
        .map(|(_, t, _)| t.finest_mask_level())
        .collect();
    let error = |k: usize, level: usize| {
        let metres = cut.tiles[k].1.level_errors.get(level).copied();
        metres.map_or(f64::INFINITY, f64::from)
    };
    let mut changed = vec![false; levels.len()];
    let tile_size = inputs.terrain.tile_size;
    if !conform(
        &view.neighbourhood,
        &mut levels,
        tile_size,
        |k| finest[k],
        error,
    ) {
        return changed;
    }
    for (((a, o), level), c) in allocation
        .iter_mut()
        .zip(offered.iter_mut())
        .zip(levels)
        .zip(&mut changed)
    {
        if level != a.level {
            *c = true;
            a.level = level;
            a.triangles = inputs.masks.triangle_count(level);
        }
        o.level = o.level.min(level);
    }
    changed
}

impl<'p> FramePlan<'p> {
    /// Triangles the chosen masks hold.
    pub(super) fn triangles(&self) -> usize {
        self.allocation.iter().map(|a| a.triangles).sum()
    }

    /// The draw list: each tile with its level and its neighbours' levels (for crack hiding).
    pub(super) fn draws(&self, tile_size: usize) -> Vec<TileDraw<'p>> {
        let levels: Vec<usize> = self.allocation.iter().map(|a| a.level).collect();
        self.cut
            .tiles
            .iter()
            .zip(neighbour_levels(&self.neighbourhood, &levels, tile_size))
            .zip(&levels)
            .map(|((&(id, tile, distance), neighbours), &level)| TileDraw {
                id,
                tile,
                level,
                neighbours,
                distance,
            })
            .collect()
    }

    /// The report's drawn tiles, with each level's geometric error on screen
    /// ([`FrameInputs::pixels_per_metre`]).
    pub(super) fn rendered(&self) -> Vec<RenderedTile> {
        self.cut
            .tiles
            .iter()
            .zip(self.allocation.iter().zip(&self.offered))
            .zip(self.importance.iter().zip(&self.pixels_per_metre))
            .zip(&self.conformed)
            .map(
                |(((&(id, tile, _), (a, o)), (&importance, &ppm)), &conformed)| RenderedTile {
                    id,
                    importance,
                    level: a.level,
                    error_px: error_px(tile, a.level, ppm),
                    capped: a.level > o.level,
                    conformed,
                },
            )
            .collect()
    }
}

/// The screen error of `tile`'s mask level `level` at `pixels_per_metre`, as the allocation
/// counts it ([`TileErrors::pixels`]): what the report shows and what the pager ranks by agree
/// with what shared the budget, a level without a known error included.
pub(super) fn error_px(tile: &ResidentTile, level: usize, pixels_per_metre: f64) -> f64 {
    TileErrors {
        metres: &tile.level_errors,
        pixels_per_metre,
        kept: None,
    }
    .pixels(level)
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::engine::camera::Camera;
    use crate::engine::fake_holdings::{Fake, S, holding, terrain};
    use crate::engine::masks::LevelSet;
    use crate::engine::viewport::Viewport;

    /// The plan of 4 x 4 level-0 tiles (every tile of their pyramid held) seen whole from
    /// high above, under `budget` triangles and the bound `max_error`, with `forced` levels.
    fn plan_of(
        budget: usize,
        max_error: ErrorBound,
        forced: Option<&(dyn Fn(TileId) -> usize + Send)>,
        check: impl FnOnce(&FramePlan, &MaskSet),
    ) {
        let terrain = terrain(4, 4);
        let pyramid = terrain.pyramid();
        let fake: Fake = holding(&pyramid, pyramid.tiles().filter(|id| id.level == 0));
        let masks = MaskSet::new(S, LevelSet::All);
        let (kept, last) = (TileMap::default(), LastFrame::default());
        let inputs = FrameInputs {
            holdings: &fake,
            terrain: &terrain,
            pyramid: &pyramid,
            masks: &masks,
            weights: Weights::default(),
            budget,
            forced_levels: forced,
            max_error,
            allocation: Allocation::default(),
            cracks: CrackMode::None,
            clearance: 1.0,
            kept: &kept,
            water_px: None,
            last: &last,
        };
        let camera = Camera::looking_at(DVec3::new(80.0, 400.0, 81.0), DVec3::new(80.0, 0.0, 80.0));
        let view = View::new(camera, Viewport::new(120, 120), 1.0, 10_000.0);
        check(&plan_frame(&inputs, &view), &masks);
    }

    #[test]
    fn with_triangles_to_spare_and_no_bound_every_tile_draws_its_full_mask() {
        plan_of(usize::MAX, ErrorBound::Off, None, |plan, masks| {
            assert_eq!(plan.cut.tiles.len(), 16);
            assert_eq!(plan.bound, Bound::Full);
            assert!(plan.allocation.iter().all(|a| a.level == 0));
            assert_eq!(plan.triangles(), 16 * masks.triangle_count(0));
            let share: f64 = plan.importance.iter().sum();
            assert!(
                (share - 1.0).abs() < 1e-9,
                "importance shares sum to {share}"
            );
            assert_eq!(plan.holes, 0);
        });
    }

    #[test]
    fn a_short_budget_binds_and_the_masks_fit_it() {
        let full = 16 * MaskSet::new(S, LevelSet::All).triangle_count(0);
        let budget = full / 4;
        plan_of(budget, ErrorBound::Off, None, |plan, _| {
            assert_eq!(plan.bound, Bound::Budget);
            assert!(
                plan.triangles() <= budget,
                "{} > {budget}",
                plan.triangles()
            );
            assert!(plan.allocation.iter().any(|a| a.level > 0));
            assert!(
                plan.water_px.is_some(),
                "the error the budget left on screen"
            );
        });
    }

    #[test]
    fn pinned_levels_are_drawn_whatever_the_budget() {
        let pinned = |id: TileId| (id.x as usize + id.y as usize) % 2;
        plan_of(1, ErrorBound::Off, Some(&pinned), |plan, _| {
            for (&(id, _, _), a) in plan.cut.tiles.iter().zip(&plan.allocation) {
                assert_eq!(a.level, pinned(id), "{id}");
            }
        });
    }
}
