//! The light on the terrain, and the intensities of packed normals under it: a tile's vertex
//! colours.
//!
//! A tile's vertices are shaded whenever one of its levels becomes resident, and on a core
//! without an FPU every product of floats is a library call. So there the intensity
//! `round(255 clamp(ambient + (1 - ambient) max(0, n · l), 0, 1))`, with `n = c / 127` for each
//! packed component `c`, is computed in 32.32 fixed point; where it lies too close to a rounding
//! boundary for the fixed point to be sure of the side, or the light is out of its range, the `f64` formula decides: the bytes are that formula's on
//! every CPU.

use glam::DVec3;

use crate::engine::normals::FLOATS_IN_SOFTWARE;

/// Light shared by every tile: a direction towards the light and an ambient floor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Direction towards the light, world axes (x east, y up, z south); normalised on use.
    pub direction: DVec3,
    /// Intensity of a surface facing away from the light, 0 ..= 1.
    pub ambient: f64,
}

impl Default for Light {
    /// Late-afternoon sun from the north-west, as cartographers light relief.
    fn default() -> Self {
        Light {
            direction: DVec3::new(-1.0, 1.4, -1.0),
            ambient: 0.35,
        }
    }
}

/// One in 2^32: the fixed point's unit.
const ONE: i64 = 1 << 32;

/// How far (in 2^-32) a fixed-point sum may lie from the exact one: three rounded products
/// and a rounded ambient term, with room to spare.
const TOLERANCE: i64 = 1 << 12;

/// Shades packed normals under one light.
#[derive(Clone, Copy, Debug)]
pub struct Shading {
    towards: DVec3,
    ambient: f64,
    /// The light in 32.32 fixed point: 255 ambient, and each component of the unit direction
    /// times `255 (1 - ambient) / 127`; `None` for an ambient outside 0 ..= 1.
    fixed: Option<([i64; 3], i64)>,
    /// The intensity of a surface facing away from the light.
    shadow: u8,
}

impl Shading {
    /// The shading of `light`: its direction normalised (straight up if it has none).
    pub fn new(light: &Light) -> Shading {
        let towards = light.direction.normalize_or(DVec3::Y);
        let ambient = light.ambient;
        let scale = |x: f64| (x * ONE as f64).round() as i64;
        let fixed = (0.0..=1.0).contains(&ambient).then(|| {
            let per_unit = 255.0 * (1.0 - ambient) / 127.0;
            (
                towards.to_array().map(|t| scale(t * per_unit)),
                scale(255.0 * ambient),
            )
        });
        Shading {
            towards,
            ambient,
            fixed,
            shadow: (ambient.clamp(0.0, 1.0) * 255.0).round() as u8,
        }
    }

    /// The intensity, 0 ..= 255, of a surface with packed normal `normal`.
    pub fn of(&self, normal: [i8; 3]) -> u8 {
        FLOATS_IN_SOFTWARE
            .then(|| self.in_integers(normal))
            .flatten()
            .unwrap_or_else(|| self.in_floats(normal))
    }

    /// The `f64` formula.
    fn in_floats(&self, normal: [i8; 3]) -> u8 {
        let n = DVec3::from_array(normal.map(|c| f64::from(c) / 127.0));
        let lit = n.dot(self.towards).max(0.0);
        let intensity = (self.ambient + (1.0 - self.ambient) * lit).clamp(0.0, 1.0);
        (intensity * 255.0).round() as u8
    }

    /// The fixed-point intensity, or `None` where it cannot be sure of the rounding.
    fn in_integers(&self, normal: [i8; 3]) -> Option<u8> {
        let (towards, ambient) = self.fixed?;
        let lit: i64 = (0..3).map(|k| i64::from(normal[k]) * towards[k]).sum();
        if lit < -TOLERANCE {
            // Surely facing away: the `f64` formula's light is exactly 0.
            return Some(self.shadow);
        }
        // Taking the larger of the sum and 0 moves no error past the tolerance.
        let v = ambient + lit.max(0);
        if (v & (ONE - 1)).abs_diff(ONE / 2) <= TOLERANCE as u64 {
            return None;
        }
        Some(((v + ONE / 2) >> 32).clamp(0, 255) as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_packed_normal_gets_the_intensity_of_the_float_formula() {
        let lights = [
            Light::default(),
            Light {
                direction: DVec3::new(-0.3, 1.0, 0.7),
                ambient: 0.3,
            },
            Light {
                direction: DVec3::new(0.0, 0.0, 1.0),
                ambient: 0.0,
            },
            Light {
                direction: DVec3::new(2.0, -1.0, 0.5),
                ambient: 1.0,
            },
        ];
        for light in &lights {
            let shading = Shading::new(light);
            let mut left = 0;
            for k in 0..1u32 << 24 {
                let normal = [k as i8, (k >> 8) as i8, (k >> 16) as i8];
                let want = shading.in_floats(normal);
                assert_eq!(shading.of(normal), want, "{light:?} {normal:?}");
                match shading.in_integers(normal) {
                    Some(got) => assert_eq!(got, want, "{light:?} {normal:?}"),
                    None => left += 1,
                }
            }
            assert!(left < 1 << 14, "{light:?}: {left} normals left to f64");
        }
    }

    #[test]
    fn lights_out_of_range_take_the_floats() {
        for ambient in [-0.5, 1.5, f64::NAN] {
            let light = Light {
                direction: DVec3::Y,
                ambient,
            };
            let shading = Shading::new(&light);
            assert_eq!(shading.in_integers([0, 127, 0]), None);
            assert_eq!(shading.of([0, 127, 0]), shading.in_floats([0, 127, 0]));
        }
    }

    #[test]
    fn the_intensity_is_the_light_on_the_surface_over_the_ambient_floor() {
        let light = Light {
            direction: DVec3::new(0.0, 2.0, 0.0),
            ambient: 0.2,
        };
        let shading = Shading::new(&light);
        assert_eq!(shading.of([0, 127, 0]), 255);
        assert_eq!(shading.of([0, -127, 0]), 51);
        assert_eq!(shading.of([90, 90, 0]), 196);
    }
}
