//! The frame's cut through the pyramid: for every part of the terrain in view, exactly one
//! resident tile to draw — the coarsest whose geometric error on screen meets τ and whose
//! texels are no wider than [`TEXEL_PIXELS`], finer near the eye, coarser to the horizon, as
//! deep as the resident tiles reach — and what the view would need beyond them.
//!
//! The walk starts at the root and goes down only where the view is: a tile out of the view
//! frustum is left with everything under it, a tile fine enough is drawn, and a tile that is
//! not is replaced by its children in view when what is resident covers them; otherwise it is
//! drawn and its missing children in view are asked for. A tile that is not resident itself is
//! gone through when some tile under it is, and is a hole otherwise. So the tiles drawn cover
//! the view once, without overlap, and the walk costs what the view holds, not what the archive
//! does.
//!
//! When the last frame's budget could not meet τ, more tiles would cost bookkeeping and buy no
//! detail the budget can pay for: a tile is then refined only where the last frame showed at
//! least half the error the budget left (drawn there, or, for a tile refined last frame, under
//! it a quarter: the gap keeps a view from switching between a tile and its children).

use glam::DVec3;

use crate::db::grid::{Pyramid, TileId, TileMap};
use crate::engine::camera::{PixelScale, View};
use crate::engine::frustum::{Aabb, Frustum};
use crate::engine::paging::Residency;
use crate::engine::resident::ResidentTile;
use crate::engine::terrain::TerrainFrame;

/// The widest a texel of a drawn tile may be on screen, pixels: a tile whose texels would be
/// wider is replaced by its children, which hold twice the texels over the same ground.
pub const TEXEL_PIXELS: f64 = 1.5;

/// Of the error the last frame's budget left, the share a tile drawn there must have shown to
/// be refined.
pub const SPLIT_SHARE: f64 = 0.5;

/// Of the error the last frame's budget left, the share the tiles drawn under a tile refined
/// there must have shown for it to stay refined.
pub const MERGE_SHARE: f64 = 0.25;

/// How much more the children a tile lacks matter once some of its children are held.
const BEGUN_SET_WEIGHT: f64 = 4.0;

/// What decides how deep the cut goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutSettings {
    /// The pixel-error bound τ: a tile whose finest level's error on screen exceeds it is
    /// refined; `None` refines every tile whose children are there (full resolution).
    pub max_error_px: Option<f64>,
    /// When the last frame's budget capped its detail, the largest error on screen it left
    /// (see the module's documentation); `None` when it did not.
    pub water_px: Option<f64>,
    /// No tile is seen from nearer than this (the eye's clearance), metres.
    pub clearance: f64,
}

/// What the cut reads of the resident tiles: the pager's [`Residency`], or any other holding.
pub trait Holdings {
    /// The resident copy of tile `id`, if any.
    fn tile(&self, id: TileId) -> Option<&ResidentTile>;
    /// Tiles below `id` (of any level) that are resident.
    fn covered(&self, id: TileId) -> u32;
}

impl Holdings for Residency<ResidentTile> {
    fn tile(&self, id: TileId) -> Option<&ResidentTile> {
        self.get(id)
    }

    fn covered(&self, id: TileId) -> u32 {
        Residency::covered(self, id)
    }
}

/// What the last frame drew, for the next frame's cut: each drawn tile's error on screen, and
/// for each tile above them the largest error drawn under it.
#[derive(Clone, Debug, Default)]
pub struct LastFrame {
    drawn: TileMap<f64>,
    under: TileMap<f64>,
}

impl LastFrame {
    /// The record of a frame that drew `drawn` (tile, error on screen in pixels) from the
    /// pyramid `pyramid`.
    pub fn new(drawn: impl Iterator<Item = (TileId, f64)>, pyramid: &Pyramid) -> LastFrame {
        let mut last = LastFrame::default();
        for (id, error) in drawn {
            last.drawn.insert(id, error);
            for level in id.level + 1..pyramid.levels() as u8 {
                let above = last
                    .under
                    .entry(id.ancestor(level))
                    .or_insert(f64::NEG_INFINITY);
                if *above >= error {
                    // Every tile further up holds at least as much already.
                    break;
                }
                *above = error;
            }
        }
        last
    }
}

/// A frame's cut and what it lacks.
#[derive(Debug, Default)]
pub struct Cut<'p> {
    /// The tiles to draw, each with its resident copy and its box's distance from the eye.
    pub tiles: Vec<(TileId, &'p ResidentTile, f64)>,
    /// Tiles the view needs that no one holds, with how much they matter: the children of a
    /// tile it would refine (the screen error of that tile, pixels), and the tiles in view over
    /// which nothing is resident (infinite: a hole).
    pub missing: Vec<(TileId, f64)>,
    /// The resident tiles the walk went down through, each with the largest error of the
    /// tiles drawn under it: what keeps the drawn tiles reachable.
    pub passed: Vec<(TileId, f64)>,
    /// Parts of the view with nothing to draw: tiles in view with no resident copy and nothing
    /// resident under them (nothing is a hole where the top is resident).
    pub holes: Vec<TileId>,
    /// Absent tiles in view that the walk reached: every sample nodata, nothing drawn, no hole.
    pub absent: Vec<TileId>,
    /// Tiles without a copy that the walk went through to resident tiles under them: with a
    /// copy, the cut could stop there and draw one tile instead of many.
    pub through: Vec<TileId>,
}

/// The cut of `view` through the tiles `resident` holds.
/// `last` is what the last frame drew, which matters when `settings.water_px` says its budget
/// capped it.
pub fn cut<'p>(
    resident: &'p (impl Holdings + ?Sized),
    terrain: &TerrainFrame,
    pyramid: &Pyramid,
    view: &View,
    settings: &CutSettings,
    last: &LastFrame,
) -> Cut<'p> {
    let mut walk = Walk {
        resident,
        terrain,
        pyramid,
        view,
        settings,
        last,
        frustum: Frustum::from_view_projection(&view.view_projection()),
        scale: view.pixel_scale(),
        out: Cut::default(),
        above: Vec::new(),
    };
    walk.visit(pyramid.root(), None);
    walk.out
}

/// The walk's state: what it reads and what it has found so far.
struct Walk<'p, 'w, H: Holdings + ?Sized> {
    resident: &'p H,
    terrain: &'w TerrainFrame,
    pyramid: &'w Pyramid,
    view: &'w View,
    settings: &'w CutSettings,
    last: &'w LastFrame,
    frustum: Frustum,
    /// The view's pixels per metre by distance (`shown_px`).
    scale: PixelScale,
    out: Cut<'p>,
    /// For each entry of `out.passed`, the index of the one above it.
    above: Vec<Option<usize>>,
}

impl<'p, H: Holdings + ?Sized> Walk<'p, '_, H> {
    /// Visits tile `id` under the passed tile `parent` (an index in `out.passed`); returns
    /// false when part of it in view has nothing to draw (its holes are in `out.holes`).
    fn visit(&mut self, id: TileId, parent: Option<usize>) -> bool {
        let eye = self.view.camera.position;
        let tile = self.resident.tile(id);
        // An absent tile has no heights: it is boxed like a tile not yet loaded.
        let (lo, hi) = match tile {
            Some(t) if !t.absent => self
                .terrain
                .tile_box(id, f64::from(t.min), f64::from(t.max)),
            _ => self
                .terrain
                .tile_box(id, self.terrain.heights.0, self.terrain.heights.1),
        };
        let aabb = Aabb::new(lo - eye, hi - eye);
        if !self.frustum.intersects(&aabb) {
            return true;
        }
        let Some(tile) = tile else {
            // Gone through when tiles under it are resident: they may cover its part in view.
            if id.level > 0 && self.resident.covered(id) > 0 {
                self.out.through.push(id);
                let children: Vec<TileId> = self.pyramid.children(id).collect();
                return self.visit_all(&children, parent);
            }
            self.out.holes.push(id);
            self.out.missing.push((id, f64::INFINITY));
            return false;
        };
        if tile.absent {
            self.out.absent.push(id);
            return true;
        }
        let distance = aabb.distance(DVec3::ZERO);
        let shown = shown_px(tile, id, distance, &self.scale, self.terrain, self.settings);
        let refine = id.level > 0
            && self
                .settings
                .max_error_px
                .is_none_or(|tau| shown.error > tau || shown.texel > TEXEL_PIXELS)
            && self.worth_refining(id, shown.error);
        if refine && self.refine(id, tile, parent, shown.error.max(shown.texel)) {
            return true;
        }
        let mut up = parent;
        while let Some(k) = up {
            let p = &mut self.out.passed[k];
            p.1 = p.1.max(shown.error);
            up = self.above[k];
        }
        self.out.tiles.push((id, tile, distance));
        true
    }

    /// Whether refining tile `id`, whose finest level shows `finest_error` pixels, buys detail
    /// the budget can pay for (always, unless the last frame's budget capped its detail): when
    /// it was drawn, if it showed at least [`SPLIT_SHARE`] of the error the budget left; when
    /// its children were, unless it shows less than that at its finest and they showed less
    /// than [`MERGE_SHARE`] of it; else if its finest level shows more than [`SPLIT_SHARE`].
    fn worth_refining(&self, id: TileId, finest_error: f64) -> bool {
        let Some(water) = self.settings.water_px else {
            return true;
        };
        let coarse_enough = finest_error <= SPLIT_SHARE * water;
        match (self.last.drawn.get(&id), self.last.under.get(&id)) {
            (Some(&drawn), _) => drawn > SPLIT_SHARE * water,
            (None, Some(&under)) => !coarse_enough || under > MERGE_SHARE * water,
            (None, None) => !coarse_enough,
        }
    }

    /// Visits every tile of `ids` (all of them, so that every hole is found); returns whether
    /// none had a hole.
    fn visit_all(&mut self, ids: &[TileId], parent: Option<usize>) -> bool {
        let mut covered = true;
        for &id in ids {
            covered &= self.visit(id, parent);
        }
        covered
    }

    /// Replaces resident tile `id` by its children in view, when what is resident covers them
    /// without a hole; otherwise leaves the walk as it was, asks for what the children lack
    /// (with `priority`, the tile's error on screen) and returns false.
    fn refine(
        &mut self,
        id: TileId,
        tile: &ResidentTile,
        parent: Option<usize>,
        priority: f64,
    ) -> bool {
        let eye = self.view.camera.position;
        // The children in view: their heights lie within the tile's finest error of its own
        // range, its samples being some of theirs.
        let margin = f64::from(tile.level_errors.first().copied().unwrap_or(0.0));
        let (lo_h, hi_h) = (f64::from(tile.min) - margin, f64::from(tile.max) + margin);
        let children: Vec<TileId> = self
            .pyramid
            .children(id)
            .filter(|&c| {
                let (lo, hi) = self.terrain.tile_box(c, lo_h, hi_h);
                self.frustum.intersects(&Aabb::new(lo - eye, hi - eye))
            })
            .collect();
        let marks = (
            self.out.tiles.len(),
            self.out.passed.len(),
            self.out.holes.len(),
            self.out.absent.len(),
            self.out.missing.len(),
            self.out.through.len(),
        );
        let here = self.out.passed.len();
        self.out.passed.push((id, 0.0));
        self.above.push(parent);
        let covered = self.visit_all(&children, Some(here));
        if covered {
            return true;
        }
        // Not a hole after all: this tile stands in, and its children it lacks are wanted as
        // much as its error — its children first, what lies under them once they are here.
        self.out.tiles.truncate(marks.0);
        self.out.passed.truncate(marks.1);
        self.above.truncate(marks.1);
        self.out.holes.truncate(marks.2);
        self.out.absent.truncate(marks.3);
        self.out.missing.truncate(marks.4);
        self.out.through.truncate(marks.5);
        let count = children.len();
        let lacking = children
            .into_iter()
            .filter(|&c| self.resident.tile(c).is_none())
            .collect::<Vec<_>>();
        // A set begun goes before one not begun: a tile is replaced by all its children or by
        // none, so a child that arrived draws nothing until its last sibling does.
        let begun = lacking.len() < count;
        let priority = if begun {
            BEGUN_SET_WEIGHT * priority
        } else {
            priority
        };
        self.out
            .missing
            .extend(lacking.into_iter().map(|c| (c, priority)));
        false
    }
}

/// What a tile would show on screen at `distance`: the error of its finest level (its own
/// samples against the full resolution they stand for) and the width of a texel, pixels.
struct Shown {
    error: f64,
    texel: f64,
}

fn shown_px(
    tile: &ResidentTile,
    id: TileId,
    distance: f64,
    scale: &PixelScale,
    terrain: &TerrainFrame,
    settings: &CutSettings,
) -> Shown {
    let ppm = scale.at(distance.max(settings.clearance));
    let texels = ((tile.texture.levels()[0].width() as usize) << tile.texture_base).max(2);
    let texel = terrain.level_metres(id.level) / (texels - 1) as f64;
    Shown {
        error: f64::from(tile.level_errors.first().copied().unwrap_or(0.0)) * ppm,
        texel: texel * ppm,
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::db::grid::TileSet;
    use crate::engine::camera::Camera;
    use crate::engine::fake_holdings::{Fake, S, SPACING, holding, terrain, tile};
    use crate::engine::viewport::Viewport;

    /// The cut of 4 x 4 tiles seen whole from high above, at full resolution.
    fn from_above(fake: &Fake) -> Cut<'_> {
        from_above_after(fake, None, &LastFrame::default())
    }

    /// The same after a frame that drew `last`, whose budget left `water_px` on screen.
    fn from_above_after<'p>(fake: &'p Fake, water_px: Option<f64>, last: &LastFrame) -> Cut<'p> {
        let terrain = terrain(4, 4);
        let camera = Camera::looking_at(DVec3::new(80.0, 400.0, 81.0), DVec3::new(80.0, 0.0, 80.0));
        let view = View::new(camera, Viewport::new(120, 120), 1.0, 10_000.0);
        let settings = CutSettings {
            max_error_px: None,
            water_px,
            clearance: 1.0,
        };
        cut(fake, &terrain, &terrain.pyramid(), &view, &settings, last)
    }

    #[test]
    fn the_last_frame_records_the_largest_error_drawn_under_each_tile() {
        let pyramid = terrain(4, 4).pyramid();
        let drawn = [
            (TileId::new(0, 0), 3.0),
            (TileId::new(1, 1), 5.0),
            (TileId::new(3, 3), 1.0),
            (TileId::at(1, 0, 1), 2.0),
        ];
        let last = LastFrame::new(drawn.into_iter(), &pyramid);
        assert_eq!(last.drawn[&TileId::new(1, 1)], 5.0);
        assert_eq!(last.under[&TileId::at(1, 0, 0)], 5.0);
        assert_eq!(last.under[&TileId::at(1, 1, 1)], 1.0);
        assert_eq!(last.under[&pyramid.root()], 5.0);
        assert!(!last.under.contains_key(&TileId::at(1, 1, 0)));
    }

    #[test]
    fn under_a_capped_budget_the_cut_refines_where_the_last_frame_erred_most() {
        let pyramid = terrain(4, 4).pyramid();
        let fake = holding(&pyramid, pyramid.tiles());
        // The root drawn at 10 px of the 10 the budget left: refined. At 4 px: kept whole.
        let at = |error: f64| LastFrame::new([(pyramid.root(), error)].into_iter(), &pyramid);
        assert_eq!(from_above_after(&fake, Some(10.0), &at(4.0)).tiles.len(), 1);
        assert_eq!(
            from_above_after(&fake, Some(10.0), &at(10.0)).tiles.len(),
            4
        );
        // The level-1 tiles drawn last frame, under the root: they showed 3 px of 10, more
        // than a quarter, so the root stays refined; at 2 px they make way for the root,
        // which shows no more than half the water at its finest level.
        let children = |error: f64| {
            let drawn = pyramid.children(pyramid.root()).map(|c| (c, error));
            LastFrame::new(drawn, &pyramid)
        };
        assert_eq!(
            from_above_after(&fake, Some(10.0), &children(3.0))
                .tiles
                .len(),
            4
        );
        assert_eq!(
            from_above_after(&fake, Some(10.0), &children(2.0))
                .tiles
                .len(),
            1
        );
        // Without a capped budget, the cut follows τ alone: every tile to level 0.
        assert_eq!(from_above_after(&fake, None, &at(4.0)).tiles.len(), 16);
    }

    #[test]
    fn the_walk_goes_through_tiles_not_held_to_the_tiles_under_them() {
        let pyramid = terrain(4, 4).pyramid();
        let fake = holding(&pyramid, pyramid.tiles().filter(|id| id.level != 1));
        let cut = from_above(&fake);
        assert_eq!(cut.tiles.len(), 16);
        assert!(cut.tiles.iter().all(|t| t.0.level == 0));
        assert!(cut.holes.is_empty() && cut.missing.is_empty());
        assert_eq!(
            cut.through.len(),
            4,
            "a copy of each would spare drawing four"
        );
    }

    #[test]
    fn the_children_of_a_set_begun_are_asked_for_before_those_of_a_set_not_begun() {
        let pyramid = terrain(4, 4).pyramid();
        let root = pyramid.root();
        // The root and one of its children: the other three are asked for, more than the
        // children of a root held alone.
        let begun = holding(&pyramid, [root, TileId::new(0, 0).ancestor(1)].into_iter());
        let alone = holding(&pyramid, [root].into_iter());
        let (begun, alone) = (from_above(&begun), from_above(&alone));
        assert_eq!((begun.missing.len(), alone.missing.len()), (3, 4));
        for (b, a) in begun.missing.iter().zip(&alone.missing) {
            assert!(a.1 > 0.0 && a.1.is_finite(), "{a:?}");
            assert_eq!(b.1, BEGUN_SET_WEIGHT * a.1, "{b:?} {a:?}");
        }
    }

    #[test]
    fn a_hole_under_a_tile_not_held_draws_the_tile_above_and_asks_for_its_children() {
        let pyramid = terrain(4, 4).pyramid();
        let fake = holding(
            &pyramid,
            pyramid
                .tiles()
                .filter(|id| id.level != 1 && *id != TileId::new(0, 0)),
        );
        let cut = from_above(&fake);
        let drawn: Vec<TileId> = cut.tiles.iter().map(|t| t.0).collect();
        assert_eq!(drawn, vec![pyramid.root()]);
        assert!(cut.holes.is_empty() && cut.through.is_empty());
        let mut asked: Vec<TileId> = cut.missing.iter().map(|m| m.0).collect();
        asked.sort();
        let mut children: Vec<TileId> = pyramid.children(pyramid.root()).collect();
        children.sort();
        assert_eq!(
            asked, children,
            "its children first, not what lies under them"
        );
        assert!(cut.missing.iter().all(|m| m.1.is_finite()));
    }

    proptest! {
        /// Whatever is resident and wherever the eye is, every level-0 tile in view is covered
        /// by exactly one tile the cut drew, found absent or counted as a hole; no tile drawn
        /// lies over another; and the cut draws only resident tiles.
        #[test]
        fn the_cut_covers_the_view_once(
            (tiles_x, tiles_y) in (1u32..13, 1u32..13),
            held in proptest::collection::vec(0u8..4, 400),
            eye in (-100.0..700.0f64, 5.0..800.0f64, -100.0..700.0f64),
            target in (0.0..500.0f64, 0.0..500.0f64),
            tau in prop_oneof![Just(None), (0.1..20.0f64).prop_map(Some)],
        ) {
            let terrain = terrain(tiles_x, tiles_y);
            let pyramid = terrain.pyramid();
            let mut fake = Fake::default();
            // 0: not resident, 1: absent, 2 and 3: resident (half the tiles).
            for (k, id) in pyramid.tiles().enumerate() {
                let copy = match held[k % held.len()] {
                    0 => continue,
                    1 => ResidentTile::absent(S, id.level, SPACING, None),
                    _ => tile(id),
                };
                fake.tiles.insert(id, copy);
                for level in id.level + 1..pyramid.levels() as u8 {
                    *fake.covered.entry(id.ancestor(level)).or_default() += 1;
                }
            }
            let camera = Camera::looking_at(
                DVec3::new(eye.0, eye.1, eye.2),
                DVec3::new(target.0, 0.0, target.1),
            );
            let view = View::new(camera, Viewport::new(160, 120), 1.0, 10_000.0);
            let settings = CutSettings {
                max_error_px: tau,
                water_px: None,
                clearance: 1.0,
            };
            let cut = cut(&fake, &terrain, &pyramid, &view, &settings, &LastFrame::default());
            let drawn: TileSet = cut.tiles.iter().map(|t| t.0).collect();
            prop_assert_eq!(drawn.len(), cut.tiles.len(), "a tile drawn twice");
            for &(id, copy, _) in &cut.tiles {
                prop_assert!(!copy.absent && fake.tiles.contains_key(&id));
            }
            let stops: Vec<TileId> = cut
                .tiles
                .iter()
                .map(|t| t.0)
                .chain(cut.holes.iter().copied())
                .chain(cut.absent.iter().copied())
                .collect();
            let frustum = Frustum::from_view_projection(&view.view_projection());
            for l in pyramid.tiles().filter(|id| id.level == 0) {
                let (lo, hi) = terrain.tile_box(l, 0.0, 100.0);
                let seen = frustum
                    .intersects(&Aabb::new(lo - camera.position, hi - camera.position));
                let over: Vec<&TileId> = stops
                    .iter()
                    .filter(|s| l.ancestor(s.level) == **s)
                    .collect();
                if seen {
                    prop_assert_eq!(over.len(), 1, "{} is covered by {:?}", l, over);
                } else {
                    prop_assert!(over.len() <= 1, "{} is covered by {:?}", l, over);
                }
            }
        }
    }
}
