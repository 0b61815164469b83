//! The 4x4 transform in the two precisions the pipeline runs in.
//!
//! The host builds each draw's matrix in f64 (eye-relative, see DESIGN.md) and hands it over once;
//! the fixed path then never touches a float. Its matrix is *block floating point*: 32-bit integer
//! mantissas below `2^29` sharing one exponent. With vertex positions in i32, every product is below
//! `2^60` and a clip coordinate (three products plus a translation) below `2^62`, so the transform is
//! exact in i64 and `z + w` cannot overflow. The shared exponent never needs applying: clipping
//! compares clip coordinates with each other, and the perspective divide takes their ratios.

use glam::{DMat4, Mat4, Vec4};

use crate::RasterError;

/// Bits of a fixed matrix mantissa: every entry has `|m| < 2^MANTISSA_BITS`.
pub const MANTISSA_BITS: u32 = 29;

/// The largest model origin a [`Transform`] takes, per axis: with it, a vertex position
/// (below 2^31) plus the origin stays below 2^31 + 2^24, and the transform stays exact in i64.
pub const MAX_ORIGIN: i32 = 1 << 24;

/// A matrix of i32 mantissas with one shared exponent: `value = mantissa * 2^-exponent`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FixedMat4 {
    /// Row-major mantissas: row `i` produces clip coordinate `i` (x, y, z, w).
    pub rows: [[i32; 4]; 4],
    /// Shared exponent.
    pub exponent: i32,
    /// The model origin's contribution, `rows[i][0..3] · origin`, exact; zero without an origin.
    pub origin_term: [i64; 4],
}

impl FixedMat4 {
    /// Quantises `m`; the largest entry keeps 28–29 significant bits.
    pub fn from_dmat4(m: &DMat4) -> Result<Self, RasterError> {
        let entries = m.to_cols_array();
        if entries.iter().any(|v| !v.is_finite()) {
            return Err(RasterError::NonFiniteTransform);
        }
        let max = entries.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if max == 0.0 {
            return Ok(Self {
                rows: [[0; 4]; 4],
                exponent: 0,
                origin_term: [0; 4],
            });
        }
        // Choose the exponent so that max * 2^exponent lies in [2^27, 2^28]; rounding can then
        // never reach 2^29.
        let exponent = 27 - max.log2().floor() as i32;
        let mut rows = [[0i32; 4]; 4];
        for (i, row) in rows.iter_mut().enumerate() {
            for (j, e) in row.iter_mut().enumerate() {
                let v = pow2_scale(m.col(j)[i], exponent).round();
                debug_assert!(v.abs() < (1u64 << MANTISSA_BITS) as f64);
                *e = v as i32;
            }
        }
        Ok(Self {
            rows,
            exponent,
            origin_term: [0; 4],
        })
    }

    /// Exact clip coordinates of an integer position (plus the model origin), in units of
    /// `2^-exponent`.
    #[inline]
    pub fn transform(&self, p: [i32; 3]) -> [i64; 4] {
        let [x, y, z] = p.map(i64::from);
        let mut c = [0i64; 4];
        for (c, (r, o)) in c.iter_mut().zip(self.rows.iter().zip(self.origin_term)) {
            *c = r[0] as i64 * x + r[1] as i64 * y + r[2] as i64 * z + (r[3] as i64 + o);
        }
        c
    }

    /// Converts a length in the matrix's output units (e.g. an eye distance compared with `w`) to
    /// the integer scale of its clip coordinates, saturating.
    pub fn scale_length(&self, v: f64) -> i64 {
        pow2_scale(v, self.exponent).clamp(i64::MIN as f64, i64::MAX as f64) as i64
    }
}

/// `v * 2^e` without overflowing the intermediate power when `|e| > 1023`.
fn pow2_scale(v: f64, e: i32) -> f64 {
    let half = e / 2;
    v * 2f64.powi(half) * 2f64.powi(e - half)
}

/// One draw's transform from model units to clip space, for both pipelines.
///
/// A draw may carry an integer model origin that is added to every vertex position before the
/// matrix applies, exactly in both pipelines. Meshes that share a matrix and differ only in their
/// origin (terrain tiles on one grid) then put shared border vertices at bit-identical screen
/// positions, so neighbouring draws meet without cracks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Block-floating-point twin used by the fixed path.
    pub fixed: FixedMat4,
    /// Single-precision twin used by the float path.
    pub float: Mat4,
    /// Model origin added to every position.
    pub origin: [i32; 3],
}

impl Transform {
    /// Builds both twins from the host's f64 matrix. Model positions are the vertices' integer
    /// `position`; clip space follows the Direct3D convention, depth 0..1 and y up
    /// (`glam::dcamera::rh::proj::directx`).
    pub fn new(m: DMat4) -> Result<Self, RasterError> {
        Ok(Self {
            fixed: FixedMat4::from_dmat4(&m)?,
            float: m.as_mat4(),
            origin: [0; 3],
        })
    }

    /// The same matrix applied to positions shifted by `origin` (each axis within
    /// ±[`MAX_ORIGIN`]).
    pub fn with_origin(mut self, origin: [i32; 3]) -> Result<Self, RasterError> {
        if origin.iter().any(|o| o.unsigned_abs() > MAX_ORIGIN as u32) {
            return Err(RasterError::OriginOutOfRange { origin });
        }
        let o = origin.map(i64::from);
        self.fixed.origin_term = self
            .fixed
            .rows
            .map(|r| r[0] as i64 * o[0] + r[1] as i64 * o[1] + r[2] as i64 * o[2]);
        self.origin = origin;
        Ok(self)
    }

    /// Clip coordinates of an integer position (plus the origin) in f32. The shifted position is
    /// summed in i64 and converted once, so equal shifted positions give equal results.
    #[inline]
    pub fn transform_float(&self, p: [i32; 3]) -> Vec4 {
        let at = |k: usize| (i64::from(p[k]) + i64::from(self.origin[k])) as f32;
        self.float * Vec4::new(at(0), at(1), at(2), 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn quantised_matrix_keeps_the_largest_entry_below_the_mantissa_bound() {
        for s in [1e-300, 1e-12, 1e-3, 1.0, 123.456, 1e9, 1e15] {
            let m = DMat4::from_scale(DVec3::splat(s))
                * DMat4::from_translation(DVec3::new(3.0, -2.0, 1.0));
            let f = FixedMat4::from_dmat4(&m).unwrap();
            let max = f
                .rows
                .iter()
                .flatten()
                .map(|v| v.unsigned_abs())
                .max()
                .unwrap();
            assert!(
                (1 << 27..1 << MANTISSA_BITS).contains(&max),
                "scale {s}: {max}"
            );
        }
    }

    #[test]
    fn transform_matches_the_f64_matrix_up_to_the_shared_exponent() {
        let m = glam::dcamera::rh::proj::directx::perspective(1.0, 4.0 / 3.0, 0.5, 1000.0)
            * glam::dcamera::rh::view::look_at_mat4(
                DVec3::new(10.0, 20.0, 30.0),
                DVec3::ZERO,
                DVec3::Y,
            );
        let f = FixedMat4::from_dmat4(&m).unwrap();
        let p = [7, -3, 12];
        let exact = m * glam::DVec4::new(7.0, -3.0, 12.0, 1.0);
        let got = f.transform(p).map(|c| c as f64 * 2f64.powi(-f.exponent));
        for i in 0..4 {
            assert!(
                (got[i] - exact[i]).abs() < 1e-6 * exact.abs().max_element(),
                "{got:?} {exact:?}"
            );
        }
    }

    #[test]
    fn an_origin_shifts_positions_exactly_in_both_twins() {
        let m = glam::dcamera::rh::proj::directx::perspective(1.0, 1.5, 0.5, 1e5)
            * glam::dcamera::rh::view::look_at_mat4(
                DVec3::new(3.0, 40.0, 9.0),
                DVec3::new(500.0, 0.0, 700.0),
                DVec3::Y,
            )
            * DMat4::from_scale(DVec3::new(30.0, 0.0625, 30.0));
        let base = Transform::new(m).unwrap();
        let shifted = base.with_origin([64, 0, -128]).unwrap();
        for p in [[0, 7, 0], [64, 9000, 3], [-5, 12, 130]] {
            let moved = [p[0] + 64, p[1], p[2] - 128];
            assert_eq!(shifted.fixed.transform(p), base.fixed.transform(moved));
            assert_eq!(shifted.transform_float(p), base.transform_float(moved));
        }
        assert!(matches!(
            base.with_origin([0, MAX_ORIGIN + 1, 0]),
            Err(RasterError::OriginOutOfRange { .. })
        ));
        let f = base.with_origin([-MAX_ORIGIN; 3]).unwrap().fixed;
        let c = f.transform([i32::MIN, i32::MIN, i32::MIN]);
        assert!(c.iter().all(|v| v.unsigned_abs() < 1 << 62));
    }

    #[test]
    fn non_finite_matrices_are_refused() {
        let mut m = DMat4::IDENTITY;
        m.x_axis.x = f64::NAN;
        assert!(matches!(
            FixedMat4::from_dmat4(&m),
            Err(RasterError::NonFiniteTransform)
        ));
    }

    #[test]
    fn extreme_positions_cannot_overflow_the_transform() {
        let m = DMat4::from_cols_array(&[1e9; 16]);
        let f = FixedMat4::from_dmat4(&m).unwrap();
        let c = f.transform([i32::MIN, i32::MAX, i32::MIN]);
        assert!(c.iter().all(|v| v.unsigned_abs() < 1 << 62));
    }
}
