//! Unit normals of a height grid from central differences, packed as `[i8; 3]` (127 is 1).
//!
//! A tile's vertices are lit whenever one of its levels becomes resident, thousands of samples
//! a frame while the eye moves, and on a core without an FPU each `f64` division or square root
//! is a library call of hundreds of instructions. So there the packed normal is decided in
//! integers: with `W = (2 spacing / quantum)²` and the neighbours' differences `Dx`, `Dz` in
//! quanta, each component's magnitude is `round(127 √(P / (W + Dx² + Dz²)))` for `P` = `Dx²`,
//! `W`, `Dz²`, estimated in fixed point and rounded by comparing squares. Where the estimate
//! lies too close to a rounding boundary to be sure of the side (a few samples in a hundred
//! thousand), or the numbers are out of the estimate's range, the sample is computed in `f64`:
//! the packed normals are those of the `f64` formula on every CPU.

use glam::DVec3;
use stripmask_raster::fixed_point::reciprocal;

/// Whether the build target does floating point in library calls (ARM with the soft-float
/// ABI, as the ARMv5TE of the paper's PocketPC): the per-sample float work of a tile's arrival
/// then takes integer paths, which give the same bytes and cost more instructions than an
/// FPU's elsewhere.
pub(crate) const FLOATS_IN_SOFTWARE: bool =
    cfg!(all(target_arch = "arm", not(target_abi = "eabihf")));

/// Log2 of the scale at which `W` is held in fixed point: enough bits that its rounding is
/// far below the estimate's own error.
const W_BITS: i32 = 40;

/// Neighbour heights (in quanta) beyond which the `f64` formula's own rounding could reach a
/// component's rounding boundary: such samples take the `f64` formula.
const HEIGHT_LIMIT: i64 = 1 << 26;

/// Packs the normals of one grid: a height quantum and a sample spacing.
#[derive(Clone, Copy, Debug)]
pub struct SlopeNormals {
    quantum: f64,
    two_spacing: f64,
    /// `W` scaled by `2^shift`, in `[2^40, 2^41)` or, for a large `W`, unscaled; `None` when
    /// `W` is out of the integer estimate's range.
    w: Option<u64>,
    shift: u32,
}

impl SlopeNormals {
    /// The normals of a grid of heights `quantum` metres a step with `spacing` metres between
    /// samples.
    pub fn new(quantum: f32, spacing: f64) -> SlopeNormals {
        let quantum = f64::from(quantum);
        let two_spacing = 2.0 * spacing;
        let w = (two_spacing / quantum).powi(2);
        let shift = if w.is_finite() && w > 0.0 {
            (W_BITS - w.log2().floor() as i32).clamp(0, 62) as u32
        } else {
            0
        };
        let scaled = w * 2f64.powi(shift as i32);
        let w = (scaled.is_finite() && scaled >= 2f64.powi(W_BITS - 1) && scaled < 2f64.powi(62))
            .then(|| scaled.round() as u64);
        SlopeNormals {
            quantum,
            two_spacing,
            w,
            shift,
        }
    }

    /// The packed unit normal at a sample whose neighbours west, east, north and south are
    /// `west`, `east`, `north` and `south` quanta high.
    pub fn packed(&self, west: i64, east: i64, north: i64, south: i64) -> [i8; 3] {
        let near = [west, east, north, south]
            .iter()
            .all(|h| h.unsigned_abs() < HEIGHT_LIMIT as u64);
        (FLOATS_IN_SOFTWARE && near)
            .then(|| self.in_integers(east - west, south - north))
            .flatten()
            .unwrap_or_else(|| self.in_floats(west, east, north, south))
    }

    /// The `f64` formula: slopes from the neighbours' heights in metres, the normal
    /// normalised, each component scaled by 127 and rounded half away from zero.
    fn in_floats(&self, west: i64, east: i64, north: i64, south: i64) -> [i8; 3] {
        let h = |q: i64| q as f64 * self.quantum;
        let dhdx = (h(east) - h(west)) / self.two_spacing;
        let dhdz = (h(south) - h(north)) / self.two_spacing;
        let n = DVec3::new(-dhdx, 1.0, -dhdz).normalize();
        n.to_array().map(|c| (c * 127.0).round() as i8)
    }

    /// The packed normal for height differences `dx` (east minus west) and `dz` (south minus
    /// north) in quanta, or `None` where the estimate cannot decide a component's rounding.
    fn in_integers(&self, dx: i64, dz: i64) -> Option<[i8; 3]> {
        let w = self.w?;
        let (a, b) = (dx.unsigned_abs().pow(2), dz.unsigned_abs().pow(2));
        let s = a + b;
        if s.leading_zeros() <= self.shift + 1 {
            return None;
        }
        // The denominator W + Dx² + Dz² is at least 2^40: 31 significant bits of it and of
        // each numerator give the ratio to 2^-29, with one reciprocal.
        let den = w + (s << self.shift);
        let cut = 33 - den.leading_zeros();
        let rec = reciprocal((den >> cut) as i64) as u64;
        let magnitude = |p: u64| -> Option<i8> {
            // 127² P / den at 32 fractional bits, within 2^18 of the exact value; the `f64`
            // formula's heights carry at most 2^-25 of v.
            let v = 16129 * (((p >> cut) * rec) >> 30);
            // twice the component, floored: the component rounds up past each odd value.
            let twice = square_root((v >> 30) as u32);
            let boundary = u64::from((twice | 1).pow(2)) << 30;
            (v.abs_diff(boundary) > (1 << 19) + (v >> 24)).then_some(twice.div_ceil(2) as i8)
        };
        let towards = |d: i64, m: i8| if d > 0 { -m } else { m };
        Some([
            towards(dx, magnitude(a << self.shift)?),
            magnitude(w)?,
            towards(dz, magnitude(b << self.shift)?),
        ])
    }
}

/// `floor(sqrt(x))`: from `ROOTS` for the `x < 2^16` of `SlopeNormals::in_integers`, else a bit
/// of the root at a time, where `u32::isqrt` divides, a library call on a core without a divider.
fn square_root(x: u32) -> u32 {
    if let Some(&root) = ROOTS.get(x as usize) {
        return u32::from(root);
    }
    let (mut root, mut bit) = (0, 1u32 << ((31 - x.leading_zeros()) / 2));
    while bit > 0 {
        let trial = root | bit;
        if trial * trial <= x {
            root = trial;
        }
        bit >>= 1;
    }
    root
}

/// `floor(sqrt(x))` for every `x < 2^16`, one load where the bit-by-bit root takes some 30
/// instructions, three times a sample (64 KiB).
static ROOTS: [u8; 1 << 16] = {
    let mut roots = [0u8; 1 << 16];
    let (mut x, mut r) = (0, 0u32);
    while x < 1 << 16 {
        while (r + 1) * (r + 1) <= x {
            r += 1;
        }
        roots[x as usize] = r as u8;
        x += 1;
    }
    roots
};

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every sample the integers decide agrees with the `f64` formula; returns how many they
    /// left to it.
    fn undecided(normals: &SlopeNormals, samples: impl Iterator<Item = [i64; 4]>) -> usize {
        let mut left = 0;
        for [west, east, north, south] in samples {
            let floats = normals.in_floats(west, east, north, south);
            match normals.in_integers(east - west, south - north) {
                Some(n) => assert_eq!(n, floats, "{normals:?} {west} {east} {north} {south}"),
                None => left += 1,
            }
            assert_eq!(normals.packed(west, east, north, south), floats);
        }
        left
    }

    #[test]
    fn every_slope_of_the_demo_grids_is_decided_in_integers_as_in_floats() {
        for level in 0..6 {
            let normals = SlopeNormals::new(0.0625, 30.0 * f64::from(1 << level));
            let samples = (-300..=300i64)
                .flat_map(|dx| (-300..=300i64).map(move |dz| [5000, 5000 + dx, 7000, 7000 + dz]));
            let left = undecided(&normals, samples);
            assert!(left < 40, "level {level}: {left} of 361,201 left to f64");
        }
    }

    #[test]
    fn square_roots_are_the_integer_square_roots() {
        for x in (0..1 << 20).chain([u32::MAX, u32::MAX - 1, (1 << 31) - 1, 1 << 31]) {
            assert_eq!(square_root(x), x.isqrt(), "{x}");
        }
        for r in [255u32, 256, 4095, 4096, 65535] {
            for x in [r * r - 1, r * r, r * r + 1] {
                assert_eq!(square_root(x), x.isqrt(), "{x}");
            }
        }
    }

    #[test]
    fn cliffs_and_flats_are_exact() {
        let normals = SlopeNormals::new(0.1, 1.0);
        assert_eq!(normals.packed(0, 0, 0, 0), [0, 127, 0]);
        assert_eq!(normals.in_integers(0, 0), Some([0, 127, 0]));
        // 2 m up over 2 m eastwards: a 45° slope facing west.
        assert_eq!(normals.in_integers(20, 0), Some([-90, 90, 0]));
        assert_eq!(normals.in_integers(-20, 0), Some([90, 90, 0]));
        assert_eq!(normals.packed(0, 0, 0, 1 << 23), [0, 0, -127]);
        assert_eq!(
            undecided(&normals, [[0, 20_000, -20_000, 0]].into_iter()),
            0
        );
    }

    #[test]
    fn grids_out_of_the_integer_range_take_the_floats() {
        for (quantum, spacing) in [(1.0, 1e-9), (1e-6, 1e12), (0.5, f64::INFINITY), (1.0, 0.0)] {
            let normals = SlopeNormals::new(quantum, spacing);
            assert_eq!(normals.in_integers(3, -4), None, "{quantum} {spacing}");
            assert_eq!(normals.packed(0, 3, 4, 0), normals.in_floats(0, 3, 4, 0));
        }
    }

    proptest! {
        #[test]
        fn any_grid_and_heights_pack_as_the_float_formula(
            quantum in prop_oneof![Just(0.0625f32), Just(0.1), Just(1.0), 1e-4f32..10.0],
            spacing in prop_oneof![Just(30.0), Just(1.0), 1e-2f64..1e5],
            base in -(1i64 << 27)..(1i64 << 27),
            d in prop::array::uniform4(-(1i64 << 20)..(1i64 << 20)),
        ) {
            let normals = SlopeNormals::new(quantum, spacing);
            undecided(&normals, std::iter::once(d.map(|d| base + d)));
        }

        #[test]
        fn gentle_slopes_are_nearly_all_decided_in_integers(
            quantum in prop_oneof![Just(0.0625f32), Just(0.01), 1e-2f32..1.0],
            spacing in 1f64..1e4,
            seed in any::<u64>(),
        ) {
            let normals = SlopeNormals::new(quantum, spacing);
            let mut x = seed | 1;
            let samples = (0..2000).map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                let d = |shift: u32| ((x >> shift) % 4001) as i64 - 2000;
                [0, d(0), 0, d(20)]
            });
            prop_assert!(undecided(&normals, samples) < 20);
        }
    }
}
