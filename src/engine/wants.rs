//! What streaming wants after a frame: the levels the frame's budget offers each tile drawn, the
//! tiles its cut lacks or went through, and the same for the view predicted ahead.

use glam::DVec3;

use crate::db::grid::{TileId, TileSet};
use crate::db::tile::{PartialGrid, levels_for_mask, progressive_levels};
use crate::engine::camera::{Camera, View};
use crate::engine::cut::Cut;
use crate::engine::frustum::{Aabb, Frustum};
use crate::engine::importance::{TileMeasure, visual_importance};
use crate::engine::paging::stream::{PredictedView, Want};
use crate::engine::plan::{FrameInputs, FramePlan, error_px};
use crate::engine::resident::ResidentTile;
use crate::engine::terrain::TerrainFrame;

/// The views ahead of the frame that streaming asks for.
#[derive(Clone, Copy)]
pub(super) struct Ahead<'a> {
    /// The camera when this frame's requests arrive: a tile out of its view by then would
    /// not draw what it asked for.
    pub(super) arrival: Option<&'a Camera>,
    /// The predicted view, with prediction.
    pub(super) predicted: Option<&'a PredictedView>,
}

/// What the pager should fetch for this frame: the levels the frame's budget offers each tile
/// drawn (no more than it holds for a tile that will have left the view when they arrive), the
/// tiles its cut lacks (the coarsest level; over a hole above everything) and the tiles it went
/// through (their coarsest level, which keeps the drawn tiles reachable); and the same for the
/// predicted view at half weight. The belt pager takes from them the tiles of the pyramid's
/// levels above 0; a progressive pager, all.
pub(super) fn frame_wants(
    inputs: &FrameInputs<'_>,
    plan: &FramePlan<'_>,
    ahead: Ahead<'_>,
    frame: &View,
) -> Vec<Want> {
    let levels = progressive_levels(inputs.terrain.tile_size);
    let arrival = ahead.arrival.map(|&camera| {
        (
            camera.position,
            Frustum::from_view_projection(&View { camera, ..*frame }.view_projection()),
        )
    });
    // A tile whose children the cut asks for is about to be replaced by them: its own finer
    // levels would arrive to be drawn no more.
    let refined: TileSet = plan
        .cut
        .missing
        .iter()
        .filter(|&&(id, _)| id.level < inputs.pyramid.root().level)
        .map(|&(id, _)| id.parent())
        .collect();
    let mut wants: Vec<Want> = plan
        .cut
        .tiles
        .iter()
        .zip(&plan.offered)
        .zip(&plan.pixels_per_metre)
        .map(|((&(id, tile, _), o), &ppm)| {
            let wished = levels_for_mask(o.level, levels);
            let stays = !refined.contains(&id)
                && arrival.as_ref().is_none_or(|(eye, frustum)| {
                    frustum.intersects(&held_box(inputs.terrain, id, tile, *eye))
                });
            Want {
                id,
                levels: if stays {
                    wished
                } else {
                    wished.min(tile.levels)
                },
                priority: shown_error_px(tile, ppm),
                predicted: false,
                drawn: true,
            }
        })
        .collect();
    wants.extend(cut_wants(&plan.cut, false));
    if let Some(view) = ahead.predicted {
        wants.extend(predicted_wants(inputs, view, frame));
    }
    wants
}

/// The wishes a cut makes beyond its drawn tiles: the coarsest level of each tile it lacks, of
/// each tile it went through and of each absent tile it met, with their priorities (halved for
/// the predicted view's).
pub(super) fn cut_wants(cut: &Cut<'_>, predicted: bool) -> Vec<Want> {
    let weight = if predicted { 0.5 } else { 1.0 };
    // The tiles gone through come last: they spare work, they add no detail.
    let through = cut.through.iter().map(|&id| (id, 0.0));
    let wants = cut
        .missing
        .iter()
        .chain(&cut.passed)
        .copied()
        .chain(through)
        .map(|(id, priority)| Want {
            id,
            levels: 1,
            priority: weight * priority,
            predicted,
            drawn: false,
        });
    // An absent tile in view is drawn as nothing, and kept as a drawn tile is: without it,
    // the tile above could not be replaced by its children and would draw over all of them.
    let absent = cut.absent.iter().map(|&id| Want {
        id,
        levels: 1,
        priority: 0.0,
        predicted,
        drawn: !predicted,
    });
    wants.chain(absent).collect()
}

/// The box of resident tile `id` between its lowest and highest held heights, relative to `eye`.
pub(super) fn held_box(
    terrain: &TerrainFrame,
    id: TileId,
    tile: &ResidentTile,
    eye: DVec3,
) -> Aabb {
    let (lo, hi) = terrain.tile_box(id, f64::from(tile.min), f64::from(tile.max));
    Aabb::new(lo - eye, hi - eye)
}

/// The predicted view's wishes: the tiles of its (pulled-back) cut, weighed from the predicted
/// eye, given the levels this frame's budget would buy them there, at half the error they would
/// show there (a guess counts less than what is on screen), and what that cut lacks.
pub(super) fn predicted_wants(
    inputs: &FrameInputs<'_>,
    view: &PredictedView,
    frame: &View,
) -> Vec<Want> {
    let terrain = inputs.terrain;
    let seen = inputs.cut(&View {
        camera: view.cull,
        ..*frame
    });
    let ahead = View {
        camera: view.camera,
        ..*frame
    };
    let measures: Vec<TileMeasure> = seen
        .tiles
        .iter()
        .map(|&(id, tile, _)| TileMeasure {
            distance: held_box(terrain, id, tile, view.camera.position).distance(DVec3::ZERO),
            height: f64::from(tile.max - tile.min),
        })
        .collect();
    let importance = visual_importance(&measures, inputs.weights);
    let needed = inputs.needed_levels(
        &ahead,
        seen.tiles
            .iter()
            .zip(&measures)
            .map(|(s, m)| (s.1, m.distance)),
    );
    // The predicted view shares the budget the way the frame does, so that what it asks for
    // ahead is what the frame will draw when the eye gets there.
    let errors = inputs.tile_errors(
        &ahead,
        seen.tiles
            .iter()
            .zip(&measures)
            .map(|(s, m)| (s.0, s.1, m.distance)),
    );
    let offered =
        inputs
            .allocation
            .share(inputs.budget, &importance, inputs.masks, &errors, &needed);
    let levels = progressive_levels(terrain.tile_size);
    let mut wants: Vec<Want> = seen
        .tiles
        .iter()
        .zip(&offered)
        .zip(&errors)
        .map(|((&(id, tile, _), o), e)| Want {
            id,
            levels: levels_for_mask(o.level, levels),
            priority: 0.5 * shown_error_px(tile, e.pixels_per_metre),
            predicted: true,
            drawn: false,
        })
        .collect();
    wants.extend(cut_wants(&seen, true));
    wants
}

/// The screen error `tile` shows at the finest mask its held levels draw, in pixels at
/// `pixels_per_metre` (as the allocation counts it, [`TileErrors::pixels`]): the priority of
/// its wish, so that the pager fetches the worst-looking tile first, the tile under a low eye
/// before the far ones. The visual importance, a share among the tiles in view that differs
/// little between them, would fetch them in almost arbitrary order.
pub(super) fn shown_error_px(tile: &ResidentTile, pixels_per_metre: f64) -> f64 {
    error_px(tile, tile.finest_mask_level(), pixels_per_metre)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    pub(super) fn an_absent_tile_in_view_is_wished_as_a_drawn_tile_and_a_predicted_one_is_not() {
        let sea = TileId::at(2, 1, 1);
        let cut = Cut {
            absent: vec![sea],
            ..Cut::default()
        };
        let now = cut_wants(&cut, false);
        assert_eq!(now.len(), 1);
        assert!(now[0].id == sea && now[0].drawn && !now[0].predicted && now[0].levels == 1);
        let ahead = cut_wants(&cut, true);
        assert!(ahead[0].id == sea && !ahead[0].drawn && ahead[0].predicted);
    }
}
