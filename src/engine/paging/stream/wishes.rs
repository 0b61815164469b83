//! Wished levels with hysteresis. The budget moves a tile across a level boundary from frame to
//! frame (the controller's budget and the importance shares shift a little every frame), and a
//! tile at the frustum's edge leaves and re-enters the view. Acting on every frame's lower wish
//! would cancel requests only to make them again, and cancel bytes on their way that the next
//! frames draw. So a tile's wish rises at once and falls only after the frames asked for less
//! during [`HOLD_SECONDS`]: until then what was asked for stays wished (not cancelled, its levels
//! not dropped to make room), and a request the current frame does not ask for waits unsent.

use super::Want;
use crate::db::grid::TileMap;

/// Seconds a tile's wish must stay lower (or absent) before the pager acts on the lower wish:
/// the render window of a delivery, so that levels asked for just before a dip are still
/// drawn if the wish comes back within it.
pub const HOLD_SECONDS: f64 = 1.0;

/// One tile's held wish.
#[derive(Clone, Copy, Debug)]
struct Held {
    want: Want,
    /// Since when the frames' wishes have been lower than `want.levels`.
    lower_since: Option<f64>,
}

/// The wishes the pager acts on, per tile: the most levels asked for, held against a lower wish
/// for [`HOLD_SECONDS`].
#[derive(Clone, Debug, Default)]
pub struct Wishes {
    held: TileMap<Held>,
}

impl Wishes {
    /// Takes in a frame's wishes at `now` (seconds); returns each tile's held wish (those
    /// asking for at least one level). A tile's priority is this frame's when it asks; its wish
    /// is the prediction's when the frame that set its levels had them from the predicted view
    /// alone (a held wish the prediction raised stays the prediction's while the view asks
    /// for less).
    pub fn update(&mut self, wants: &[Want], now: f64) -> TileMap<Want> {
        let frame = merge(wants);
        for (id, w) in &frame {
            self.held.entry(*id).or_insert(Held {
                want: *w,
                lower_since: None,
            });
        }
        self.held.retain(|id, held| {
            let asked = frame.get(id);
            let levels = asked.map_or(0, |w| w.levels);
            let lower = levels < held.want.levels;
            if !lower || now - *held.lower_since.get_or_insert(now) >= HOLD_SECONDS {
                held.want.levels = levels;
                held.lower_since = None;
                if let Some(w) = asked {
                    held.want.predicted = w.predicted;
                }
            }
            if let Some(w) = asked {
                held.want.priority = w.priority;
            }
            held.want.levels > 0
        });
        self.held.iter().map(|(id, h)| (*id, h.want)).collect()
    }
}

/// Each tile's strongest wish of a frame: the most levels and the highest priority asked, drawn
/// when any wish says so; the
/// prediction's when only the predicted view asks for that many levels (levels the view does
/// not ask for are the prediction's, even where the view asks for fewer).
pub fn merge(wants: &[Want]) -> TileMap<Want> {
    let mut frame: TileMap<Want> = TileMap::default();
    for w in wants {
        frame
            .entry(w.id)
            .and_modify(|m| {
                if w.levels > m.levels || (w.levels == m.levels && !w.predicted) {
                    m.predicted = w.predicted;
                }
                m.levels = m.levels.max(w.levels);
                m.priority = m.priority.max(w.priority);
                m.drawn |= w.drawn;
            })
            .or_insert(*w);
    }
    frame
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::grid::TileId;

    fn want(levels: usize) -> Want {
        Want {
            id: TileId::new(1, 2),
            levels,
            priority: 0.5,
            predicted: false,
            drawn: true,
        }
    }

    fn held(wishes: &mut Wishes, levels: Option<usize>, now: f64) -> usize {
        let wants: Vec<Want> = levels.map(want).into_iter().collect();
        wishes
            .update(&wants, now)
            .get(&TileId::new(1, 2))
            .map_or(0, |w| w.levels)
    }

    #[test]
    fn a_wish_rises_at_once_and_falls_after_the_hold() {
        let mut w = Wishes::default();
        assert_eq!(held(&mut w, Some(3), 0.0), 3);
        assert_eq!(held(&mut w, Some(4), 0.25), 4);
        // A boundary flicker: 3, 4, 3, 4, 3 keeps 4.
        for (k, levels) in [3, 4, 3, 4, 3].into_iter().enumerate() {
            assert_eq!(held(&mut w, Some(levels), 0.25 * (k + 2) as f64), 4);
        }
        // Lower since 1.5 s, and then the tile leaves the view.
        assert_eq!(held(&mut w, Some(2), 2.0), 4);
        assert_eq!(held(&mut w, Some(2), 2.5), 2, "lower for a second");
        assert_eq!(held(&mut w, None, 3.0), 2);
        assert_eq!(held(&mut w, None, 4.0), 0);
        assert!(w.held.is_empty(), "a tile nobody asks for is forgotten");
    }

    fn asked(levels: usize, predicted: bool) -> Want {
        Want {
            predicted,
            ..want(levels)
        }
    }

    #[test]
    fn levels_only_the_prediction_asks_for_are_the_predictions() {
        let id = TileId::new(1, 2);
        let merged = |wants: &[Want]| merge(wants)[&id];
        let m = merged(&[asked(3, false), asked(5, true)]);
        assert_eq!((m.levels, m.predicted), (5, true));
        let m = merged(&[asked(5, true), asked(3, false)]);
        assert_eq!((m.levels, m.predicted), (5, true));
        let m = merged(&[asked(5, true), asked(5, false)]);
        assert_eq!((m.levels, m.predicted), (5, false));
        let m = merged(&[asked(4, false), asked(2, true)]);
        assert_eq!((m.levels, m.predicted), (4, false));

        // A wish the prediction raised stays its own while held against the view's fewer
        // levels, and becomes the view's once the view asks for as many.
        let mut w = Wishes::default();
        let held = |w: &mut Wishes, wants: &[Want], now: f64| {
            let h = w.update(wants, now)[&id];
            (h.levels, h.predicted)
        };
        assert_eq!(
            held(&mut w, &[asked(3, false), asked(5, true)], 0.0),
            (5, true)
        );
        assert_eq!(held(&mut w, &[asked(3, false)], 0.25), (5, true));
        assert_eq!(held(&mut w, &[asked(3, false)], 1.5), (3, false));
        assert_eq!(
            held(&mut w, &[asked(3, false), asked(4, true)], 1.75),
            (4, true)
        );
        assert_eq!(held(&mut w, &[asked(4, false)], 2.0), (4, false));
    }
}
