//! The apron: for every progressive level, the samples one step of that level's grid outside the
//! tile's four borders, taken from the neighbouring tiles when the archive is built.
//!
//! A client computes vertex normals by central differences over the grid it holds. Without the
//! apron, a border sample's difference across the border is one-sided and the two tiles sharing
//! that border light it differently: a line along every tile border. With it, both tiles see the
//! same samples on both sides of the border at every level, so they compute the same normal for
//! every border vertex they share.
//!
//! Level `g`'s apron is four runs of `2^g + 1` values, west, east, north, south: run `k` of the
//! west side is the sample at level-`g` grid position `(-1, k)`, of the east side `(side, k)`, of
//! the north side `(k, -1)`, of the south side `(k, side)`. Each is stored as its difference in
//! archive quanta from the border sample next to it (`(0, k)`, `(side - 1, k)`, `(k, 0)`,
//! `(k, side - 1)`), saturated to `i16`; beyond the archive's grid the builder stores the linear
//! extrapolation of the border, which makes the central difference the one-sided one.

/// Which of the four runs of an apron level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Border {
    /// Outside the western column: position `(-1, k)`.
    West,
    /// Outside the eastern column: position `(side, k)`.
    East,
    /// Outside the northern row: position `(k, -1)`.
    North,
    /// Outside the southern row: position `(k, side)`.
    South,
}

impl Border {
    /// The four runs in stored order.
    pub const ALL: [Border; 4] = [Border::West, Border::East, Border::North, Border::South];

    /// The grid position outside the border at run index `k` of a level `side` samples wide,
    /// and the border sample inside next to it.
    pub fn positions(self, k: usize, side: usize) -> ((isize, isize), (usize, usize)) {
        let (k, last) = (k as isize, side as isize - 1);
        let (outside, inside) = match self {
            Border::West => ((-1, k), (0, k)),
            Border::East => ((last + 1, k), (last, k)),
            Border::North => ((k, -1), (k, 0)),
            Border::South => ((k, last + 1), (k, last)),
        };
        (outside, (inside.0 as usize, inside.1 as usize))
    }
}

/// The samples just outside a tile's borders, one level per progressive level held.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Apron {
    /// Per level `g`: `4 (2^g + 1)` differences in quanta, runs in [`Border::ALL`] order.
    levels: Vec<Vec<i16>>,
}

impl Apron {
    /// Values one level of `side` samples per side holds: four runs of `side`.
    pub fn level_len(side: usize) -> usize {
        4 * side
    }

    /// The apron whose level `g` (a grid `sides[g]` wide) has run value `k` of border `b` from
    /// `value(g, b, k)`.
    pub fn from_fn(sides: &[usize], mut value: impl FnMut(usize, Border, usize) -> i16) -> Apron {
        let levels = sides
            .iter()
            .enumerate()
            .map(|(g, &side)| {
                Border::ALL
                    .iter()
                    .flat_map(|&b| (0..side).map(move |k| (b, k)))
                    .map(|(b, k)| value(g, b, k))
                    .collect()
            })
            .collect();
        Apron { levels }
    }

    /// The difference in quanta from the border sample to the one outside it, at run index `k`
    /// of border `b` of level `level` (a grid `side` samples wide).
    pub fn delta(&self, level: usize, border: Border, k: usize) -> i16 {
        let side = self.levels[level].len() / 4;
        let run = Border::ALL
            .iter()
            .position(|&b| b == border)
            .expect("one of the four");
        self.levels[level][run * side + k]
    }

    /// Levels held.
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Whether no level is held.
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// The raw values of level `level`, runs in [`Border::ALL`] order.
    pub fn level(&self, level: usize) -> &[i16] {
        &self.levels[level]
    }

    /// Adds the next level's raw values (`4 (2^g + 1)` of them).
    pub fn push(&mut self, values: Vec<i16>) {
        self.levels.push(values);
    }

    /// The first `levels` levels.
    pub fn truncated(&self, levels: usize) -> Apron {
        Apron {
            levels: self.levels[..levels.min(self.levels.len())].to_vec(),
        }
    }

    /// Bytes the values take in memory.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(Vec::len).sum::<usize>() * std::mem::size_of::<i16>()
    }
}

/// `outside - inside` quanta, saturated to `i16`: the stored form of an apron sample.
pub fn saturating_delta(outside: i64, inside: i64) -> i16 {
    (outside - inside).clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_are_stored_west_east_north_south_and_truncate_by_level() {
        let apron = Apron::from_fn(&[2, 3], |g, b, k| (100 * g + 10 * b as usize + k) as i16);
        assert_eq!(apron.len(), 2);
        assert_eq!(apron.level(0), [0, 1, 10, 11, 20, 21, 30, 31]);
        assert_eq!(apron.delta(1, Border::North, 2), 122);
        assert_eq!(apron.delta(1, Border::West, 0), 100);
        assert_eq!(apron.truncated(1).len(), 1);
        assert_eq!(apron.bytes(), 2 * (8 + 12));
        assert_eq!(Apron::level_len(3), 12);
    }

    #[test]
    fn positions_lie_one_step_outside_the_border_sample() {
        assert_eq!(Border::West.positions(2, 5), ((-1, 2), (0, 2)));
        assert_eq!(Border::East.positions(2, 5), ((5, 2), (4, 2)));
        assert_eq!(Border::North.positions(3, 5), ((3, -1), (3, 0)));
        assert_eq!(Border::South.positions(3, 5), ((3, 5), (3, 4)));
    }

    #[test]
    fn differences_saturate() {
        assert_eq!(saturating_delta(5, 2), 3);
        assert_eq!(saturating_delta(100_000, 0), i16::MAX);
        assert_eq!(saturating_delta(-100_000, 0), i16::MIN);
    }
}
