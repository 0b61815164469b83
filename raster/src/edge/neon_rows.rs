//! A small triangle's rows on 32-bit ARM with NEON: every row's mask of owned columns from the
//! edge functions in NEON lanes, computed when the rows are made.
//!
//! `wide`'s lanes are arrays there (its vectors are for SSE2, aarch64's NEON and wasm), and
//! Rust's NEON intrinsics for 32-bit ARM are not stable, so the lanes are inline assembly: a
//! row of up to 8 columns costs 21 instructions, where the scalar search of its run
//! (`SearchRows`) costs more than twice that on the PXA255. The masks are those of
//! `SearchRows` (tested against it).

use std::arch::asm;

/// Rows a small triangle spans at most (`SMALL`).
const MAX_ROWS: usize = super::SMALL as usize;

/// Column offsets of the first group of lanes, then each lane's bit in a row's mask for the
/// two groups of 4 columns.
static LANE_CONSTANTS: [i32; 12] = [0, 1, 2, 3, 1, 2, 4, 8, 16, 32, 64, 128];

/// A small triangle's rows, one mask of owned columns at a time (`next_mask`), with `x0` its
/// first column, `y` the current row and `end` the row past the last: the masks of every row,
/// computed at once in NEON lanes (see the module documentation).
pub(crate) struct NeonRows {
    /// Bit `k` of row `y - start`: column `x0 + k` is outside (some edge's sign bit is set).
    outside: [u16; MAX_ROWS],
    /// The first row.
    start: i64,
    /// The rectangle's columns as bits.
    columns: u32,
    /// First column of the rectangle: bit `k` of a mask is column `x0 + k`.
    pub x0: i64,
    /// The current row.
    pub y: i64,
    /// The row past the last.
    pub end: i64,
}

impl NeonRows {
    /// The rows `start..end` (at most `MAX_ROWS`) of a rectangle `width` columns wide (at most
    /// 16) from its first column `x0`, with `E + bias - 1` of the three edges at the first row's
    /// first column `row`, and what each changes by from a column to the next (`across`) and
    /// from a row to the next (`down`): within `SMALL` pixels every such value at a pixel of
    /// the rectangle lies in i32 (`Coverage::walk_small`), and lanes past the rectangle wrap,
    /// their bits dropped.
    #[inline(always)]
    pub fn new(
        edges: ([i32; 3], [i32; 3], [i32; 3]),
        width: u32,
        x0: i64,
        start: i64,
        end: i64,
    ) -> Self {
        debug_assert!((1..=16).contains(&width) && end - start <= MAX_ROWS as i64);
        let (row, across, down) = edges;
        // Filled before the rows are made: built in place, they would be copied whole when
        // returned.
        let mut outside = [0; MAX_ROWS];
        let n = (end - start).clamp(0, MAX_ROWS as i64) as usize;
        let params = |row: [i32; 3]| {
            [
                row[0], row[1], row[2], 0, across[0], across[1], across[2], 0, down[0], down[1],
                down[2], 0,
            ]
        };
        if n > 0 && width <= 4 {
            four_columns(&params(row), n, &mut outside);
        } else if n > 0 {
            eight_columns(&params(row), n, &mut outside);
            if width > 8 {
                // Columns 8..16, from the edges at column 8.
                let mut right = [0; MAX_ROWS];
                let row = [0, 1, 2].map(|i| row[i].wrapping_add(across[i].wrapping_mul(8)));
                eight_columns(&params(row), n, &mut right);
                for (o, r) in outside.iter_mut().zip(&right) {
                    *o |= r << 8;
                }
            }
        }
        NeonRows {
            outside,
            start,
            columns: (1u32 << width) - 1,
            x0,
            y: start,
            end,
        }
    }

    /// The owned columns of the current row as bits (bit `k` is column `x0 + k`), and a step to
    /// the next row.
    #[inline(always)]
    pub fn next_mask(&mut self) -> u32 {
        let outside = self.outside[(self.y - self.start) as usize & (MAX_ROWS - 1)];
        self.y += 1;
        !(outside as u32) & self.columns
    }
}

const _: () = assert!(MAX_ROWS.is_power_of_two());

/// The outside bits of columns `0..4` of `n` rows (`1..=MAX_ROWS`) into `out`, from `params`:
/// each edge's value at the first column of the first row, its step across, its step down
/// (each padded to 4 words).
#[inline(always)]
fn four_columns(params: &[i32; 12], n: usize, out: &mut [u16; MAX_ROWS]) {
    assert!((1..=MAX_ROWS).contains(&n));
    // SAFETY: the block reads the 48 bytes of `params` and the first 32 of `LANE_CONSTANTS`,
    // and writes `n` halfwords at `out`, which holds `MAX_ROWS >= n`; it touches no stack, and
    // every NEON register it writes is declared clobbered (the compiler saves the callee-saved
    // d8-d15).
    unsafe {
        asm!(
            "vld1.32 {{d26, d27}}, [{p}]!",
            "vld1.32 {{d28, d29}}, [{p}]!",
            "vld1.32 {{d30, d31}}, [{p}]",
            "vld1.32 {{d18, d19, d20, d21}}, [{k}]",
            // Each edge at columns 0..4 of the first row: row + lane * across.
            "vdup.32 q11, d28[0]",
            "vdup.32 q0, d26[0]",
            "vmla.i32 q0, q9, q11",
            "vdup.32 q11, d28[1]",
            "vdup.32 q2, d26[1]",
            "vmla.i32 q2, q9, q11",
            "vdup.32 q11, d29[0]",
            "vdup.32 q4, d27[0]",
            "vmla.i32 q4, q9, q11",
            "vdup.32 q6, d30[0]",
            "vdup.32 q7, d30[1]",
            "vdup.32 q8, d31[0]",
            "2:",
            // A lane is outside where the or of the three edges has its sign bit set: the
            // lanes' bits summed pairwise into the mask.
            "vorr q11, q0, q2",
            "vorr q11, q11, q4",
            "vshr.s32 q11, q11, #31",
            "vand q11, q11, q10",
            "vpadd.i32 d22, d22, d23",
            "vpadd.i32 d22, d22, d22",
            "vmov.32 {t}, d22[0]",
            "strh {t}, [{out}], #2",
            "vadd.i32 q0, q0, q6",
            "vadd.i32 q2, q2, q7",
            "vadd.i32 q4, q4, q8",
            "subs {n}, {n}, #1",
            "bne 2b",
            p = inout(reg) params.as_ptr() => _,
            k = in(reg) LANE_CONSTANTS.as_ptr(),
            out = inout(reg) out.as_mut_ptr() => _,
            n = inout(reg) n => _,
            t = out(reg) _,
            out("q0") _, out("q2") _, out("q4") _, out("q6") _, out("q7") _, out("q8") _,
            out("q9") _, out("q10") _, out("q11") _, out("q13") _, out("q14") _, out("q15") _,
            options(nostack),
        );
    }
}

/// `four_columns` for columns `0..8`: two groups of lanes, the second's bits above the first's.
#[inline(always)]
fn eight_columns(params: &[i32; 12], n: usize, out: &mut [u16; MAX_ROWS]) {
    assert!((1..=MAX_ROWS).contains(&n));
    // SAFETY: as `four_columns`, reading all 48 bytes of `LANE_CONSTANTS`.
    unsafe {
        asm!(
            "vld1.32 {{d26, d27}}, [{p}]!",
            "vld1.32 {{d28, d29}}, [{p}]!",
            "vld1.32 {{d30, d31}}, [{p}]",
            "vld1.32 {{d18, d19}}, [{k}]!",
            // Each edge at columns 0..4 (q0, q2, q4) and 4..8 (q1, q3, q5) of the first row.
            "vdup.32 q11, d28[0]",
            "vdup.32 q0, d26[0]",
            "vmla.i32 q0, q9, q11",
            "vshl.i32 q11, q11, #2",
            "vadd.i32 q1, q0, q11",
            "vdup.32 q11, d28[1]",
            "vdup.32 q2, d26[1]",
            "vmla.i32 q2, q9, q11",
            "vshl.i32 q11, q11, #2",
            "vadd.i32 q3, q2, q11",
            "vdup.32 q11, d29[0]",
            "vdup.32 q4, d27[0]",
            "vmla.i32 q4, q9, q11",
            "vshl.i32 q11, q11, #2",
            "vadd.i32 q5, q4, q11",
            "vdup.32 q6, d30[0]",
            "vdup.32 q7, d30[1]",
            "vdup.32 q8, d31[0]",
            "vld1.32 {{d18, d19, d20, d21}}, [{k}]",
            "2:",
            "vorr q11, q0, q2",
            "vorr q12, q1, q3",
            "vorr q11, q11, q4",
            "vorr q12, q12, q5",
            "vshr.s32 q11, q11, #31",
            "vshr.s32 q12, q12, #31",
            "vand q11, q11, q9",
            "vand q12, q12, q10",
            "vorr q11, q11, q12",
            "vpadd.i32 d22, d22, d23",
            "vpadd.i32 d22, d22, d22",
            "vmov.32 {t}, d22[0]",
            "strh {t}, [{out}], #2",
            "vadd.i32 q0, q0, q6",
            "vadd.i32 q1, q1, q6",
            "vadd.i32 q2, q2, q7",
            "vadd.i32 q3, q3, q7",
            "vadd.i32 q4, q4, q8",
            "vadd.i32 q5, q5, q8",
            "subs {n}, {n}, #1",
            "bne 2b",
            p = inout(reg) params.as_ptr() => _,
            k = inout(reg) LANE_CONSTANTS.as_ptr() => _,
            out = inout(reg) out.as_mut_ptr() => _,
            n = inout(reg) n => _,
            t = out(reg) _,
            out("q0") _, out("q1") _, out("q2") _, out("q3") _, out("q4") _, out("q5") _,
            out("q6") _, out("q7") _, out("q8") _, out("q9") _, out("q10") _, out("q11") _,
            out("q12") _, out("q13") _, out("q14") _, out("q15") _,
            options(nostack),
        );
    }
}
