//! Visual importance of the tiles in the view frustum: the paper's Algorithm 2.
//!
//! Over the tiles that survive frustum culling,
//!
//! ```text
//! imp = a * (max_dist - dist) / sum_dist + b * height / sum_height
//! ```
//!
//! normalised so that the importances sum to 1. Near tiles and tall tiles matter more; `a` and
//! `b` (0.5 each by default) weigh the two and are normalised to sum 1. The triangle budget is
//! then shared in decreasing importance ([`crate::engine::budget`]).
//!
//! What "height" is, is up to the engine: it passes each tile's relief, the elevation range
//! `max - min` stored with the tile. Relief is what coarse masks lose — a flat tile looks the same
//! at any level, a rugged one does not — and unlike absolute elevation it does not depend on the
//! datum, so a high plateau does not outrank a mountain range rising from the sea.
//!
//! Degenerate frames give finite values: a sum of 0 (all tiles at distance 0, or no relief
//! anywhere) drops that term, and when both terms vanish (one tile, or all tiles alike) every
//! tile gets the same importance.

/// What importance needs to know about one tile in the frustum.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TileMeasure {
    /// Distance from the viewer to the tile's bounding box, `>= 0`
    /// ([`crate::engine::frustum::Aabb::distance`]).
    pub distance: f64,
    /// The tile's height term, `>= 0`: the engine passes its relief (max - min elevation).
    pub height: f64,
}

/// The weights `a` (distance) and `b` (height) of Algorithm 2, normalised to sum 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Weights {
    a: f64,
    b: f64,
}

impl Weights {
    /// Weights proportional to `distance` and `height`; `None` unless both are finite and
    /// non-negative and one is positive.
    pub fn new(distance: f64, height: f64) -> Option<Self> {
        let valid = |w: f64| w.is_finite() && w >= 0.0;
        let sum = distance + height;
        (valid(distance) && valid(height) && sum > 0.0 && sum.is_finite()).then(|| Self {
            a: distance / sum,
            b: height / sum,
        })
    }

    /// The normalised distance weight `a`.
    pub fn distance(&self) -> f64 {
        self.a
    }

    /// The normalised height weight `b`.
    pub fn height(&self) -> f64 {
        self.b
    }
}

impl Default for Weights {
    /// The paper's `a = b = 0.5`.
    fn default() -> Self {
        Self { a: 0.5, b: 0.5 }
    }
}

/// The importance of every tile of a frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Importance {
    /// Per tile, in input order: finite, `>= 0`, summing to 1 (empty for no tiles).
    pub values: Vec<f64>,
    /// Tile indices by decreasing importance; equal importances keep input order.
    pub order: Vec<usize>,
}

/// Algorithm 2 over the tiles in the frustum.
pub fn visual_importance(tiles: &[TileMeasure], weights: Weights) -> Importance {
    let clean = |v: f64| if v.is_finite() { v.max(0.0) } else { 0.0 };
    let mut sum_dist = 0.0;
    let mut sum_height = 0.0;
    let mut max_dist = 0.0f64;
    for t in tiles {
        debug_assert!(t.distance >= 0.0 && t.height >= 0.0, "{t:?}");
        let dist = clean(t.distance);
        sum_dist += dist;
        sum_height += clean(t.height);
        max_dist = max_dist.max(dist);
    }
    // A vanishing sum means the term does not tell tiles apart: drop it.
    let per_dist = if sum_dist > 0.0 {
        weights.a / sum_dist
    } else {
        0.0
    };
    let per_height = if sum_height > 0.0 {
        weights.b / sum_height
    } else {
        0.0
    };
    let mut values: Vec<f64> = tiles
        .iter()
        .map(|t| per_dist * (max_dist - clean(t.distance)) + per_height * clean(t.height))
        .collect();
    let total: f64 = values.iter().sum();
    if total > 0.0 && total.is_finite() {
        values.iter_mut().for_each(|v| *v /= total);
    } else {
        values.fill(1.0 / tiles.len() as f64);
    }
    let mut order: Vec<usize> = (0..tiles.len()).collect();
    // A stable sort: ties stay in input order.
    order.sort_by(|&i, &j| values[j].total_cmp(&values[i]));
    Importance { values, order }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn tile(distance: f64, height: f64) -> TileMeasure {
        TileMeasure { distance, height }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn values_follow_the_formula_and_sum_to_one() {
        let tiles = [tile(0.0, 10.0), tile(100.0, 30.0), tile(200.0, 0.0)];
        let imp = visual_importance(&tiles, Weights::default());
        // sum_dist 300, max_dist 200, sum_height 40:
        // raw = 0.5 * (200 - d) / 300 + 0.5 * h / 40, which already sums to 1.
        let raw = [
            0.5 * 200.0 / 300.0 + 0.5 * 10.0 / 40.0,
            0.5 * 100.0 / 300.0 + 0.5 * 30.0 / 40.0,
            0.0,
        ];
        let total: f64 = raw.iter().sum();
        for (v, r) in imp.values.iter().zip(raw) {
            assert!(close(*v, r / total), "{v} vs {}", r / total);
        }
        assert!(close(imp.values.iter().sum(), 1.0));
        assert_eq!(imp.order, [1, 0, 2]);
    }

    #[test]
    fn nearer_wins_at_equal_height_and_higher_wins_at_equal_distance() {
        let imp = visual_importance(
            &[tile(50.0, 5.0), tile(10.0, 5.0), tile(30.0, 5.0)],
            Weights::default(),
        );
        assert_eq!(imp.order, [1, 2, 0]);
        let imp = visual_importance(
            &[tile(20.0, 1.0), tile(20.0, 9.0), tile(20.0, 4.0)],
            Weights::default(),
        );
        assert_eq!(imp.order, [1, 2, 0]);
    }

    #[test]
    fn weights_are_normalised_and_select_the_criterion() {
        let w = Weights::new(3.0, 1.0).unwrap();
        assert!(close(w.distance(), 0.75) && close(w.height(), 0.25));
        assert_eq!(Weights::new(0.0, 0.0), None);
        assert_eq!(Weights::new(-1.0, 2.0), None);
        assert_eq!(Weights::new(f64::NAN, 2.0), None);
        assert_eq!(Weights::new(1.0, 1.0), Some(Weights::default()));

        // A near flat tile against a far rugged one: the weights decide.
        let tiles = [tile(10.0, 1.0), tile(90.0, 50.0)];
        let by_distance = visual_importance(&tiles, Weights::new(1.0, 0.0).unwrap());
        assert_eq!(by_distance.values, [1.0, 0.0]);
        let by_height = visual_importance(&tiles, Weights::new(0.0, 1.0).unwrap());
        assert_eq!(by_height.order, [1, 0]);
        assert!(close(by_height.values[1], 50.0 / 51.0));
        // Scaling both weights changes nothing.
        assert_eq!(
            visual_importance(&tiles, Weights::new(2.0, 6.0).unwrap()),
            visual_importance(&tiles, Weights::new(0.25, 0.75).unwrap())
        );
    }

    #[test]
    fn degenerate_frames_stay_finite() {
        let none = visual_importance(&[], Weights::default());
        assert!(none.values.is_empty() && none.order.is_empty());

        let one = visual_importance(&[tile(0.0, 0.0)], Weights::default());
        assert_eq!(one.values, [1.0]);
        let one = visual_importance(&[tile(35.0, 7.0)], Weights::default());
        assert_eq!(one.values, [1.0]);

        // All at the same distance: only height speaks.
        let same = visual_importance(&[tile(5.0, 1.0), tile(5.0, 3.0)], Weights::default());
        assert_eq!(same.values, [0.25, 0.75]);
        // No relief anywhere: only distance speaks.
        let flat = visual_importance(&[tile(0.0, 0.0), tile(10.0, 0.0)], Weights::default());
        assert_eq!(flat.values, [1.0, 0.0]);
        // Nothing tells them apart: equal shares, input order.
        let alike = visual_importance(&[tile(0.0, 0.0); 4], Weights::default());
        assert_eq!(alike.values, [0.25; 4]);
        assert_eq!(alike.order, [0, 1, 2, 3]);
    }

    #[test]
    fn ties_keep_input_order() {
        let tiles = [
            tile(10.0, 2.0),
            tile(0.0, 2.0),
            tile(10.0, 2.0),
            tile(0.0, 2.0),
        ];
        let imp = visual_importance(&tiles, Weights::default());
        assert_eq!(imp.order, [1, 3, 0, 2]);
    }

    proptest! {
        #[test]
        fn values_are_finite_non_negative_and_sum_to_one(
            tiles in prop::collection::vec((0.0..1e7f64, 0.0..1e4f64), 1..300),
            a in 0.0..1.0f64,
        ) {
            let tiles: Vec<TileMeasure> = tiles.into_iter().map(|(d, h)| tile(d, h)).collect();
            let weights = Weights::new(a, 1.0 - a).unwrap();
            let imp = visual_importance(&tiles, weights);
            prop_assert!(imp.values.iter().all(|v| v.is_finite() && *v >= 0.0));
            prop_assert!((imp.values.iter().sum::<f64>() - 1.0).abs() < 1e-9);
            let mut sorted = imp.order.clone();
            sorted.sort();
            prop_assert_eq!(sorted, (0..tiles.len()).collect::<Vec<_>>());
            prop_assert!(imp.order.windows(2).all(|w| imp.values[w[0]] >= imp.values[w[1]]));
        }
    }
}
