//! The triangle budget: how many triangles a frame may draw to hold the target frame rate, and
//! how the visible tiles share them.
//!
//! [`BudgetController`] predicts the budget from the last frames' times, as the paper does: it
//! fits `frame_time = overhead + cost × triangles` to recent `(frame_time, triangles)` samples
//! and sets the budget whose predicted frame time is `1 / target_fps`. It moves only part of the
//! way each frame, by a bounded factor, and ignores differences within a dead band, so the
//! budget settles instead of oscillating. A frame whose detail the pixel-error bound capped
//! ([`BudgetController::record_needing`]) does not let the budget grow.
//!
//! [`allocate`] shares a budget greedily in decreasing visual importance
//! ([`crate::engine::importance`]): each tile gets `pool × imp / (sum of the remaining imps)` triangles,
//! takes the finest strip mask that fits ([`MaskSet::finest_level_for`]), and what it does not
//! use goes back to the pool for the next tiles.

use crate::engine::importance::Importance;
use crate::engine::masks::MaskSet;

/// What the budget controller aims at and how fast it may move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BudgetSettings {
    /// Frames per second to hold.
    pub target_fps: f64,
    /// The budget never goes below this.
    pub min_budget: usize,
    /// The budget never goes above this (what a frame may draw when its cost is unknown or tiny).
    pub max_budget: usize,
    /// The budget of the first frame, before any timing is known.
    pub initial_budget: usize,
    /// Fraction of the way to the predicted budget taken each frame, in `(0, 1]`: below 1 it
    /// damps the reaction to a noisy frame.
    pub damping: f64,
    /// Largest factor between two consecutive budgets (`> 1`).
    pub max_step: f64,
    /// Relative difference between the predicted and the current budget below which the budget
    /// stays as it is, so that frame-time noise does not make tiles switch levels.
    pub deadband: f64,
    /// What a frame is expected to cost before any was timed (the device's cost model), or
    /// nothing known: see [`BudgetController`].
    pub expected: Option<FrameCost>,
}

/// A frame's expected cost: `overhead_s + triangle_s × triangles` seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameCost {
    /// Seconds a frame costs whatever it draws (clearing, filling pixels, set-up).
    pub overhead_s: f64,
    /// Seconds per triangle drawn.
    pub triangle_s: f64,
}

impl FrameCost {
    /// The triangles a frame of `frame_seconds` affords, or `None` when the cost is not a
    /// positive finite slope.
    fn triangles_in(&self, frame_seconds: f64) -> Option<f64> {
        (self.triangle_s.is_finite() && self.triangle_s > 0.0 && self.overhead_s.is_finite())
            .then(|| ((frame_seconds - self.overhead_s) / self.triangle_s).max(0.0))
    }
}

impl Default for BudgetSettings {
    fn default() -> Self {
        Self {
            target_fps: 25.0,
            min_budget: 1_000,
            max_budget: 4_000_000,
            initial_budget: 20_000,
            damping: 0.5,
            max_step: 2.0,
            deadband: 0.02,
            expected: None,
        }
    }
}

/// Weight of the newest frame in the running sample averages.
const SMOOTHING: f64 = 0.25;
/// The overhead is fitted only when the recent triangle counts spread by at least this fraction
/// of their mean; a settled budget gives no information about it.
const EXCITATION: f64 = 0.1;
/// A frame near the recent triangle counts whose time the model misses by more than this
/// fraction means the scene changed: the old samples are forgotten instead of being fitted
/// together with the new ones.
const SURPRISE: f64 = 0.2;
/// Fraction of the way the overhead estimate moves towards a new fit.
const OVERHEAD_GAIN: f64 = 0.5;

/// Predicts the triangle budget that holds the target frame rate from the last frames' times.
///
/// Call [`BudgetController::record`] after every frame with its time and the triangles it drew;
/// the returned budget is for the next frame.
///
/// The per-triangle cost is the slope from the estimated overhead to the average recent sample,
/// so the budget settles exactly where the measured frame time meets the target, whatever the
/// overhead estimate. That estimate (the intercept of a least-squares line through the recent
/// samples, when their triangle counts differ enough) only sets how fast it gets there; it is
/// kept at most `(1 - damping)` of the frame time, where an error cannot make the budget
/// overshoot.
///
/// A controller that knows what a frame is expected to cost ([`BudgetSettings::expected`])
/// starts at the budget that cost says holds the target, instead of at
/// [`BudgetSettings::initial_budget`], and until the recent triangle counts spread enough to fit
/// the overhead it takes the expected cost per triangle as the slope: the first frames draw
/// little (a view whose tiles are still coming in), and a slope through the origin would read
/// their fixed cost (clearing, filling pixels) as the cost of their few triangles and hold the
/// budget low for several frames. The expected slope stays admissible afterwards: the overhead
/// estimate may always be as large as that slope implies.
#[derive(Clone, Debug)]
pub struct BudgetController {
    settings: BudgetSettings,
    budget: usize,
    /// Exponentially weighted sums of 1, n, t, n², n·t over the recent samples
    /// (n = triangles, t = seconds).
    weight: f64,
    sum_n: f64,
    sum_t: f64,
    sum_nn: f64,
    sum_nt: f64,
    overhead: f64,
    cost: Option<f64>,
    /// Whether the overhead was ever fitted to samples that spread enough.
    fitted: bool,
}

impl BudgetController {
    /// A controller starting at `settings.initial_budget` (clamped to the limits).
    pub fn new(settings: BudgetSettings) -> Self {
        debug_assert!(settings.target_fps > 0.0 && settings.min_budget <= settings.max_budget);
        debug_assert!(settings.damping > 0.0 && settings.damping <= 1.0);
        debug_assert!(settings.max_step > 1.0 && settings.deadband >= 0.0);
        let initial = settings
            .expected
            .and_then(|e| e.triangles_in(1.0 / settings.target_fps))
            .map_or(settings.initial_budget, |n| n.round() as usize);
        Self {
            settings,
            budget: initial.clamp(settings.min_budget, settings.max_budget),
            weight: 0.0,
            sum_n: 0.0,
            sum_t: 0.0,
            sum_nn: 0.0,
            sum_nt: 0.0,
            overhead: 0.0,
            cost: None,
            fitted: false,
        }
    }

    /// The settings.
    pub fn settings(&self) -> &BudgetSettings {
        &self.settings
    }

    /// Triangles the next frame may draw.
    pub fn budget(&self) -> usize {
        self.budget
    }

    /// The estimated per-frame time that does not depend on triangles, in seconds.
    pub fn overhead(&self) -> f64 {
        self.overhead
    }

    /// The estimated seconds per triangle, once a frame has drawn some.
    pub fn cost_per_triangle(&self) -> Option<f64> {
        self.cost
    }

    /// Takes the time of the frame just drawn and the triangles it drew, and returns the budget
    /// of the next frame. Frames that drew nothing or have no valid time change nothing.
    pub fn record(&mut self, frame_seconds: f64, triangles: usize) -> usize {
        self.record_needing(frame_seconds, triangles, None)
    }

    /// [`BudgetController::record`] for a frame that needed only `need` triangles (every tile
    /// at the level the pixel-error bound asks, [`crate::engine::error_bound`]), when it did:
    /// such a frame says nothing about how many more triangles time would allow, so the budget
    /// does not grow, and it comes down to [`BudgetSettings::max_step`] times the need (a
    /// frame's need may grow that much before the budget binds again). The budget still shrinks
    /// when time is short. No wind-up: a fast machine does not pile up a budget of a million
    /// triangles for a view that needs a hundred thousand.
    pub fn record_needing(
        &mut self,
        frame_seconds: f64,
        triangles: usize,
        need: Option<usize>,
    ) -> usize {
        // A frame that drew nothing (its tiles still on their way) tells neither bound
        // anything: its need of nothing is not the view's.
        if !(frame_seconds.is_finite() && frame_seconds > 0.0) || triangles == 0 {
            return self.budget;
        }
        let before = self.budget;
        let next = self.predict(frame_seconds, triangles);
        if let Some(need) = need.filter(|&n| n <= before) {
            let ceiling = (need as f64 * self.settings.max_step).ceil() as usize;
            self.budget = next.min(before).min(ceiling.max(self.settings.min_budget));
        }
        self.budget
    }

    /// Fits the frame's sample and moves the budget towards the one that holds the target.
    fn predict(&mut self, frame_seconds: f64, triangles: usize) -> usize {
        if !(frame_seconds.is_finite() && frame_seconds > 0.0) || triangles == 0 {
            return self.budget;
        }
        let (n, t) = (triangles as f64, frame_seconds);
        if let Some(cost) = self.cost {
            // Only near the recent triangle counts: far from them a wrong overhead estimate
            // misses too, and its samples are what corrects it.
            let mean_n = self.sum_n / self.weight;
            let predicted = self.overhead + cost * n;
            if (n - mean_n).abs() <= EXCITATION * mean_n
                && (t - predicted).abs() > SURPRISE * predicted
            {
                self.forget();
            }
        }
        self.add(n, t);

        let mean_n = self.sum_n / self.weight;
        let mean_t = self.sum_t / self.weight;
        let var_n = self.sum_nn / self.weight - mean_n * mean_n;
        let cov = self.sum_nt / self.weight - mean_n * mean_t;
        // The overhead the expected cost per triangle implies for the recent samples.
        let implied = self
            .settings
            .expected
            .filter(|e| e.triangles_in(0.0).is_some())
            .map(|e| (mean_t - e.triangle_s * mean_n).max(0.0));
        if var_n > (EXCITATION * mean_n).powi(2) && cov > 0.0 {
            let fitted = mean_t - cov / var_n * mean_n;
            self.overhead += OVERHEAD_GAIN * (fitted - self.overhead);
            self.fitted = true;
        } else if let Some(implied) = implied.filter(|_| !self.fitted) {
            self.overhead = implied;
        }
        let target = 1.0 / self.settings.target_fps;
        let ceiling = ((1.0 - self.settings.damping) * target.min(mean_t))
            .max(implied.unwrap_or(0.0).min(mean_t));
        self.overhead = self.overhead.clamp(0.0, ceiling);
        let cost = (mean_t - self.overhead) / mean_n;
        self.cost = Some(cost);

        let current = self.budget as f64;
        let predicted = self.holding_target(cost);
        if (predicted - current).abs() > self.settings.deadband * current {
            let step = self.settings.max_step;
            let next = (current + self.settings.damping * (predicted - current))
                .clamp(current / step, current * step)
                .clamp(
                    self.settings.min_budget as f64,
                    self.settings.max_budget as f64,
                );
            self.budget = next.round() as usize;
        }
        self.budget
    }

    /// The triangles that hold the target frame rate at `cost` seconds each, by the overhead
    /// estimate: where [`BudgetController::predict`] moves the budget, and the heading.
    fn holding_target(&self, cost: f64) -> f64 {
        ((1.0 / self.settings.target_fps - self.overhead) / cost).max(0.0)
    }

    fn forget(&mut self) {
        self.weight = 0.0;
        self.sum_n = 0.0;
        self.sum_t = 0.0;
        self.sum_nn = 0.0;
        self.sum_nt = 0.0;
    }

    fn add(&mut self, n: f64, t: f64) {
        let keep = 1.0 - SMOOTHING;
        self.weight = keep * self.weight + SMOOTHING;
        self.sum_n = keep * self.sum_n + SMOOTHING * n;
        self.sum_t = keep * self.sum_t + SMOOTHING * t;
        self.sum_nn = keep * self.sum_nn + SMOOTHING * n * n;
        self.sum_nt = keep * self.sum_nt + SMOOTHING * n * t;
    }
}

/// One tile's share of the budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileAllocation {
    /// The strip-mask level to draw.
    pub level: usize,
    /// Its triangles.
    pub triangles: usize,
}

/// Shares `budget` triangles among the tiles of `importance` (all drawn with `masks`), greedily
/// in importance order; returns one allocation per tile, in the tiles' input order.
///
/// Every tile gets at least the coarsest mask, so the triangles of the coarsest masks are set
/// aside first and the pool shared is what remains. The sum never exceeds `budget` unless the
/// budget is below the coarsest masks of all tiles, and then every tile is at its coarsest.
///
/// Leftovers make the pool per unit of importance grow along the order, so a later tile could
/// outbid a more important one; no tile gets a finer level than a tile before it. What that
/// leaves in the pool is spent in a second pass, again in importance order and under the same
/// rule, so a budget covering every tile's finest mask gives every tile level 0.
pub fn allocate(budget: usize, importance: &Importance, masks: &MaskSet) -> Vec<TileAllocation> {
    allocate_capped(budget, importance, masks, &vec![0; importance.order.len()])
}

/// [`allocate`] for tiles that cannot all draw every level: tile `t` never gets a level finer
/// than `finest[t]` (a partial tile's [`crate::db::tile::PartialGrid::finest_mask_level`], a
/// level of `masks`' set). The triangles a capped tile cannot use stay in the pool for the next
/// tiles, like any leftover; the no-outbidding rule compares the levels the tiles could buy, so
/// a less important tile may draw finer than a more important one only because that one holds
/// too little.
pub fn allocate_capped(
    budget: usize,
    importance: &Importance,
    masks: &MaskSet,
    finest: &[usize],
) -> Vec<TileAllocation> {
    debug_assert_eq!(finest.len(), importance.values.len());
    let coarsest = masks.coarsest_level();
    let floor = masks.triangle_count(coarsest);
    let n = importance.order.len();
    let mut tiles = vec![
        TileAllocation {
            level: coarsest,
            triangles: floor,
        };
        n
    ];
    let mut pool = budget.saturating_sub(n * floor);
    let mut remaining: f64 = importance.values.iter().sum();

    // The level each tile could buy, before its cap: what the no-outbidding rule compares.
    let mut bought = vec![coarsest; n];
    let mut cap = 0;
    for (rank, &t) in importance.order.iter().enumerate() {
        let imp = importance.values[t];
        let share = if remaining > 0.0 {
            (pool as f64 * (imp / remaining).clamp(0.0, 1.0)) as usize
        } else {
            pool / (n - rank)
        };
        remaining -= imp;
        bought[t] = masks.finest_level_for(floor + share.min(pool)).max(cap);
        let level = bought[t].max(finest[t]);
        let triangles = masks.triangle_count(level);
        pool -= triangles - floor;
        tiles[t] = TileAllocation { level, triangles };
        cap = bought[t];
    }

    // Never coarser than the first pass bought: a capped tile cannot spend the pool, and must
    // not hold the next tiles back by more than it did.
    let mut cap = 0;
    for &t in &importance.order {
        let current = tiles[t];
        bought[t] = masks
            .finest_level_for(current.triangles + pool)
            .max(cap)
            .min(bought[t]);
        let level = bought[t].max(finest[t]);
        let triangles = masks.triangle_count(level);
        pool -= triangles - current.triangles;
        tiles[t] = TileAllocation { level, triangles };
        cap = bought[t];
    }
    tiles
}

/// The level a tile holding samples down to mask level `finest` draws when `level` is asked
/// for (a pinned level, see `crate::engine::Engine::force_levels`): never finer than it holds,
/// and with `powers_of_two` (partial tiles in the frame) the coarser level whose `l + 1` is a
/// power of two, so that every tile's border keeps samples every drawn neighbour holds.
pub fn drawable_level(level: usize, finest: usize, powers_of_two: bool) -> usize {
    let level = level.max(finest);
    if powers_of_two {
        (level + 1).next_power_of_two() - 1
    } else {
        level
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::engine::importance::{TileMeasure, Weights, visual_importance};
    use crate::engine::masks::LevelSet;

    /// What every allocation keeps: within `budget` (unless every tile is already at its
    /// coarsest), each tile at a level of `masks` no finer than its cap, counted right.
    pub(crate) fn check_allocation(
        a: &[TileAllocation],
        budget: usize,
        masks: &MaskSet,
        finest: &[usize],
    ) -> Result<(), TestCaseError> {
        let levels = masks.levels();
        let total: usize = a.iter().map(|t| t.triangles).sum();
        let floor = masks.triangle_count(masks.coarsest_level());
        prop_assert!(total <= budget || a.iter().all(|t| t.triangles == floor));
        for (t, alloc) in a.iter().enumerate() {
            prop_assert!(levels.contains(&alloc.level));
            prop_assert!(alloc.level >= finest[t]);
            prop_assert_eq!(alloc.triangles, masks.triangle_count(alloc.level));
        }
        Ok(())
    }

    /// A frame clock: `overhead + cost × triangles`, times `1 ± noise` from a seeded generator.
    struct SimulatedClock {
        overhead: f64,
        cost: f64,
        noise: f64,
        state: u64,
    }

    impl SimulatedClock {
        fn frame(&mut self, triangles: usize) -> f64 {
            // SplitMix64.
            self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            let unit = ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64;
            (self.overhead + self.cost * triangles as f64) * (1.0 + self.noise * (2.0 * unit - 1.0))
        }

        fn ideal(&self, fps: f64) -> f64 {
            (1.0 / fps - self.overhead) / self.cost
        }
    }

    /// Runs `frames` frames that draw exactly the budget; returns the budget's relative error
    /// against the ideal budget after every frame. `harder` multiplies the per-triangle cost
    /// from frame `at` on.
    fn run(
        overhead: f64,
        noise: f64,
        initial_budget: usize,
        frames: usize,
        harder: Option<(usize, f64)>,
        seed: u64,
    ) -> Vec<f64> {
        let settings = BudgetSettings {
            initial_budget,
            min_budget: 100,
            max_budget: 10_000_000,
            ..BudgetSettings::default()
        };
        let mut clock = SimulatedClock {
            overhead,
            cost: 1e-6,
            noise,
            state: seed,
        };
        let mut controller = BudgetController::new(settings);
        (0..frames)
            .map(|f| {
                if let Some((at, factor)) = harder
                    && f == at
                {
                    clock.cost *= factor;
                }
                let budget = controller.budget();
                let time = clock.frame(budget);
                let next = controller.record(time, budget);
                next as f64 / clock.ideal(settings.target_fps) - 1.0
            })
            .collect()
    }

    /// The first frame from which the error stays within ±`band` up to frame `end`.
    fn settled_from(errors: &[f64], end: usize, band: f64) -> Option<usize> {
        (0..end).find(|&f| errors[f..end].iter().all(|e| e.abs() <= band))
    }

    /// The largest error on the other side of zero than the first frame's: an overshoot.
    fn overshoot(errors: &[f64]) -> f64 {
        let side = errors[0].signum();
        errors.iter().map(|e| -side * e).fold(0.0, f64::max)
    }

    #[test]
    fn converges_without_oscillating_from_far_above_and_far_below() {
        // Ideal budgets: 40,000 without overhead, 30,000 with 10 ms, 20,000 with 20 ms.
        for overhead in [0.0, 0.010, 0.020] {
            for initial in [400_000, 300] {
                let errors = run(overhead, 0.0, initial, 120, None, 1);
                let settled = settled_from(&errors, errors.len(), 0.05);
                assert!(
                    settled.is_some_and(|f| f <= 25),
                    "overhead {overhead} from {initial}: {errors:.3?}"
                );
                assert!(overshoot(&errors) <= 0.02, "{errors:.3?}");
                // Monotone approach: the error shrinks until it is inside the dead band.
                for w in errors.windows(2) {
                    assert!(
                        w[1].abs() <= w[0].abs() || w[1].abs() <= 0.02,
                        "{errors:.3?}"
                    );
                }
                // Settled within the dead band (2 %), up to rounding.
                assert!(errors[errors.len() - 1].abs() <= 0.021, "{errors:.3?}");
            }
        }
    }

    #[test]
    fn converges_with_noisy_frame_times() {
        for seed in 0..20 {
            for overhead in [0.0, 0.010] {
                for initial in [400_000, 300] {
                    let errors = run(overhead, 0.03, initial, 150, None, seed);
                    let settled = settled_from(&errors, errors.len(), 0.05);
                    assert!(
                        settled.is_some_and(|f| f <= 25),
                        "seed {seed} overhead {overhead} from {initial}: {errors:.3?}"
                    );
                    assert!(overshoot(&errors) <= 0.05, "{errors:.3?}");
                    // Settled, noise moves the budget rarely and never swings it from one
                    // side of the dead band to the other.
                    let after = &errors[settled.unwrap()..];
                    let outside: Vec<f64> =
                        after.iter().copied().filter(|e| e.abs() > 0.02).collect();
                    let swings = outside
                        .windows(2)
                        .filter(|w| w[0].signum() != w[1].signum())
                        .count();
                    let moves = after.windows(2).filter(|w| w[0] != w[1]).count();
                    assert_eq!(swings, 0, "{errors:.3?}");
                    assert!(moves <= 15, "{moves} moves: {errors:.3?}");
                }
            }
        }
    }

    #[test]
    fn follows_a_scene_that_gets_harder_or_easier() {
        for factor in [2.0, 0.5, 4.0] {
            for noise in [0.0, 0.03] {
                let errors = run(0.010, noise, 20_000, 160, Some((60, factor)), 7);
                let before = settled_from(&errors, 60, 0.05);
                assert!(before.is_some_and(|f| f <= 25), "{errors:.3?}");
                let after = settled_from(&errors, errors.len(), 0.05);
                assert!(
                    after.is_some_and(|f| (60..=60 + 20).contains(&f)),
                    "factor {factor} noise {noise}: {:.3?}",
                    &errors[60..]
                );
                assert!(overshoot(&errors[60..]) <= 0.05, "{:.3?}", &errors[60..]);
            }
        }
    }

    #[test]
    fn estimates_overhead_and_cost_while_the_budget_moves() {
        let mut clock = SimulatedClock {
            overhead: 0.008,
            cost: 2e-6,
            noise: 0.0,
            state: 0,
        };
        let mut controller = BudgetController::new(BudgetSettings {
            initial_budget: 1_000,
            ..BudgetSettings::default()
        });
        for _ in 0..15 {
            let budget = controller.budget();
            controller.record(clock.frame(budget), budget);
        }
        assert!(
            (controller.overhead() - 0.008).abs() < 1e-4,
            "{}",
            controller.overhead()
        );
        let cost = controller.cost_per_triangle().unwrap();
        assert!((cost / 2e-6 - 1.0).abs() < 0.01, "{cost}");
    }

    #[test]
    fn a_known_frame_cost_starts_at_the_steady_budget_and_does_not_climb() {
        // A PocketPC-like frame: 60 ms whatever it draws, 27 µs per triangle, 7 fps: about
        // 3,070 triangles hold the target. The first frames draw only a few hundred (their
        // tiles are on their way), as a streaming view does.
        let (overhead, cost) = (0.060, 27e-6);
        let steady = (1.0 / 7.0 - overhead) / cost;
        let settings = BudgetSettings {
            target_fps: 7.0,
            ..BudgetSettings::default()
        };
        let expected = FrameCost {
            overhead_s: overhead,
            triangle_s: cost,
        };
        let mut seeded = BudgetController::new(BudgetSettings {
            expected: Some(expected),
            ..settings
        });
        let mut blind = BudgetController::new(BudgetSettings {
            initial_budget: 1_000,
            ..settings
        });
        let near = |b: usize| (b as f64 / steady - 1.0).abs() <= 0.05;
        assert!(
            near(seeded.budget()),
            "{} against {steady}",
            seeded.budget()
        );
        let mut blind_lowest = usize::MAX;
        for frame in 0..20 {
            for c in [&mut seeded, &mut blind] {
                let drawn = if frame < 5 { 400 } else { c.budget() };
                c.record(overhead + cost * drawn as f64, drawn);
            }
            assert!(near(seeded.budget()), "frame {frame}: {}", seeded.budget());
            if frame < 5 {
                blind_lowest = blind_lowest.min(blind.budget());
            }
        }
        // Without the expected cost, the first frames' fixed cost reads as the cost of their
        // few triangles, and the budget stays far below what holds the target.
        assert!((blind_lowest as f64) < 0.6 * steady, "{blind_lowest}");
        assert!(near(blind.budget()), "both settle: {}", blind.budget());
    }

    #[test]
    fn an_empty_frame_changes_nothing_even_while_the_error_bound_binds() {
        let mut c = BudgetController::new(BudgetSettings {
            initial_budget: 3_000,
            ..BudgetSettings::default()
        });
        // Nothing drawn (the tiles are on their way): its need of nothing is not the view's.
        assert_eq!(c.record_needing(0.05, 0, Some(0)), 3_000);
        assert_eq!(c.record_needing(0.0, 0, Some(0)), 3_000);
        // A frame that drew what τ asks still holds the budget at twice its need.
        assert_eq!(c.record_needing(0.001, 500, Some(500)), 1_000);
    }

    #[test]
    fn budget_stays_within_its_limits_and_ignores_empty_frames() {
        let settings = BudgetSettings {
            min_budget: 5_000,
            max_budget: 50_000,
            initial_budget: 20_000,
            ..BudgetSettings::default()
        };
        let mut c = BudgetController::new(settings);
        assert_eq!(c.record(0.02, 0), 20_000);
        assert_eq!(c.record(f64::NAN, 100), 20_000);
        for _ in 0..50 {
            let b = c.budget();
            c.record(1e-4, b); // far too fast: climbs to the maximum
            assert!(c.budget() <= 50_000 && c.budget() <= 2 * b);
        }
        assert_eq!(c.budget(), 50_000);
        for _ in 0..50 {
            let b = c.budget();
            c.record(10.0, b); // far too slow: falls to the minimum
            assert!(c.budget() >= 5_000 && 2 * c.budget() >= b);
        }
        assert_eq!(c.budget(), 5_000);
    }

    #[test]
    fn the_budget_does_not_grow_while_the_error_bound_holds_detail_back() {
        // A machine 100 times faster than the target needs: the budget alone climbs.
        let settings = BudgetSettings {
            initial_budget: 20_000,
            ..BudgetSettings::default()
        };
        let frame = |n: usize| 0.0004 * (1.0 + n as f64 / 20_000.0);
        let mut free = BudgetController::new(settings);
        let mut bound = BudgetController::new(settings);
        for _ in 0..40 {
            let (b, c) = (free.budget(), bound.budget());
            free.record(frame(b), b);
            // τ lets each frame draw only 8,000 triangles.
            let drawn = c.min(8_000);
            bound.record_needing(frame(drawn), drawn, Some(8_000));
            assert!(bound.budget() <= c, "grew from {c} to {}", bound.budget());
            assert!(bound.budget() <= 16_000, "{}", bound.budget());
        }
        assert!(free.budget() > 1_000_000, "{}", free.budget());
        // Once the need exceeds the budget, time decides again.
        let c = bound.budget();
        bound.record_needing(frame(c), c, Some(50_000));
        assert!(bound.budget() > c);
        // Time still shrinks a budget that τ binds.
        let mut slow = BudgetController::new(settings);
        slow.record_needing(1.0, 10_000, Some(10_000));
        assert!(slow.budget() < 20_000, "{}", slow.budget());
    }

    /// Importance of tiles at the given distances, all with the same relief.
    fn importance_by_distance(distances: &[f64]) -> Importance {
        let tiles: Vec<TileMeasure> = distances
            .iter()
            .map(|&distance| TileMeasure {
                distance,
                height: 1.0,
            })
            .collect();
        visual_importance(&tiles, Weights::new(1.0, 0.0).unwrap())
    }

    #[test]
    fn leftovers_of_an_important_tile_flow_to_the_next() {
        // 6 x 6 masks: 50, 18, 8, 8, 2 triangles. Importance 0.95 / 0.05.
        let masks = MaskSet::new(6, LevelSet::All);
        let imp = Importance {
            values: vec![0.95, 0.05],
            order: vec![0, 1],
        };
        // Pool 196 after the coarsest masks; the first tile's share (186) is more than level 0
        // takes, and its proportional share alone (9) would give the second tile level 2.
        let a = allocate(200, &imp, &masks);
        assert_eq!(
            a[0],
            TileAllocation {
                level: 0,
                triangles: 50
            }
        );
        assert_eq!(
            a[1],
            TileAllocation {
                level: 0,
                triangles: 50
            }
        );
        let a = allocate(70, &imp, &masks);
        assert_eq!(a[0].level, 0);
        assert_eq!(
            a[1],
            TileAllocation {
                level: 1,
                triangles: 18
            }
        );
    }

    #[test]
    fn equal_tiles_never_let_a_less_important_one_outbid_a_more_important_one() {
        let masks = MaskSet::new(6, LevelSet::All);
        // Pool 26. First pass: 2 + 13 buys level 2 (8, 7 left over); the second tile's 2 + 20
        // would buy level 1, finer than the first. The second pass gives level 1 to the first.
        let imp = Importance {
            values: vec![0.5, 0.5],
            order: vec![0, 1],
        };
        let a = allocate(30, &imp, &masks);
        assert_eq!(
            a[0],
            TileAllocation {
                level: 1,
                triangles: 18
            }
        );
        assert_eq!(
            a[1],
            TileAllocation {
                level: 2,
                triangles: 8
            }
        );
    }

    #[test]
    fn no_tiles_and_tiny_budgets() {
        let masks = MaskSet::new(17, LevelSet::All);
        assert!(allocate(1_000, &importance_by_distance(&[]), &masks).is_empty());
        let a = allocate(0, &importance_by_distance(&[1.0, 2.0, 3.0]), &masks);
        assert!(a.iter().all(|t| t.level == 15 && t.triangles == 2));
    }

    #[test]
    fn a_tile_capped_by_what_it_holds_leaves_its_triangles_to_the_next() {
        // 9 x 9 powers of two: levels 0, 1, 3, 7 with 128, 32, 8, 2 triangles.
        let masks = MaskSet::new(9, LevelSet::PowerOfTwo);
        let imp = Importance {
            values: vec![0.9, 0.1],
            order: vec![0, 1],
        };
        let whole = allocate(170, &imp, &masks);
        assert_eq!((whole[0].level, whole[1].level), (0, 1));
        let held = allocate_capped(170, &imp, &masks, &[3, 0]);
        assert_eq!(held[0].level, 3, "never finer than it holds");
        assert_eq!(held[1].level, 0, "its triangles go to the next tile");
        assert_eq!(allocate_capped(170, &imp, &masks, &[0, 0]), whole);
    }

    #[test]
    fn pinned_levels_snap_to_what_a_tile_can_draw() {
        assert_eq!(drawable_level(2, 0, false), 2);
        assert_eq!(drawable_level(2, 0, true), 3);
        assert_eq!(drawable_level(0, 3, false), 3);
        assert_eq!(drawable_level(4, 3, true), 7);
        assert_eq!(drawable_level(7, 1, true), 7);
    }

    fn frame() -> impl Strategy<Value = (usize, LevelSet, Vec<(f64, f64)>)> {
        (
            prop::sample::select(vec![2usize, 3, 6, 9, 17, 33, 65]),
            prop::sample::select(vec![LevelSet::All, LevelSet::PowerOfTwo]),
            prop::collection::vec((0.0..1e4f64, 0.0..500.0f64), 0..60),
        )
    }

    proptest! {
        #[test]
        fn allocations_respect_the_budget_and_the_importance_order(
            (s, set, measures) in frame(),
            fraction in 0.0..1.3f64,
        ) {
            let masks = MaskSet::new(s, set);
            let tiles: Vec<TileMeasure> = measures
                .iter()
                .map(|&(distance, height)| TileMeasure { distance, height })
                .collect();
            let imp = visual_importance(&tiles, Weights::default());
            let finest = tiles.len() * masks.triangle_count(0);
            let budget = (finest as f64 * fraction) as usize;
            let a = allocate(budget, &imp, &masks);
            prop_assert_eq!(a.len(), tiles.len());
            let total: usize = a.iter().map(|t| t.triangles).sum();
            let floor = masks.triangle_count(masks.coarsest_level());
            prop_assert!(total <= budget || a.iter().all(|t| t.triangles == floor));
            for t in &a {
                prop_assert!(masks.levels().contains(&t.level));
                prop_assert_eq!(t.triangles, masks.triangle_count(t.level));
            }
            for w in imp.order.windows(2) {
                prop_assert!(a[w[0]].level <= a[w[1]].level, "{:?}", a);
            }
            if budget >= finest {
                prop_assert!(a.iter().all(|t| t.level == 0));
            }
            // Nothing that could still be afforded is left: the least important tile that is
            // not at level 0 cannot buy its next finer level with what is left.
            let left = budget.saturating_sub(total);
            for &t in &imp.order {
                let finer = masks.levels().iter().rev().find(|&&l| l < a[t].level);
                if let Some(&finer) = finer {
                    let before = imp.order.iter().take_while(|&&u| u != t).last();
                    let allowed = before.is_none_or(|&u| a[u].level <= finer);
                    prop_assert!(
                        !allowed || masks.triangle_count(finer) - a[t].triangles > left,
                        "tile {} could move to level {} with {} left: {:?}", t, finer, left, a
                    );
                }
            }
        }

        #[test]
        fn held_allocations_respect_the_budget_and_the_caps(
            (s, _, measures) in frame(),
            fraction in 0.0..1.3f64,
            held in prop::collection::vec(0u32..8, 60),
        ) {
            let masks = MaskSet::new(s, LevelSet::PowerOfTwo);
            let tiles: Vec<TileMeasure> = measures
                .iter()
                .map(|&(distance, height)| TileMeasure { distance, height })
                .collect();
            let imp = visual_importance(&tiles, Weights::default());
            let levels = masks.levels();
            let finest: Vec<usize> = (0..tiles.len())
                .map(|t| levels[held[t] as usize % levels.len()])
                .collect();
            let all = tiles.len() * masks.triangle_count(0);
            let budget = (all as f64 * fraction) as usize;
            let a = allocate_capped(budget, &imp, &masks, &finest);
            check_allocation(&a, budget, &masks, &finest)?;
            if budget >= all {
                prop_assert!(a.iter().zip(&finest).all(|(t, &f)| t.level == f));
            }
        }
    }
}
