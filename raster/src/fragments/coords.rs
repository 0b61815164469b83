//! The range of the held fragments' texture coordinates, for the colour stage one fragment at
//! a time, which folds and wraps each coordinate in scalar words: where the level holds the
//! range inside (`LevelView::holds_inside`), it skips both. A row step that bounds its
//! fragments' coordinates names their range as it holds them (`Fragments::keep_within`); any
//! other makes the range unknown. Where the colour stage works in lanes or in NEON's passes,
//! whose wraps are vector work, the record is empty, and the ranges are not worked out.

use crate::sampler::{LevelView, Texel, UvRange};

/// What the buffer knows of its fragments' coordinates: all lie in `held`, unless `unknown`.
#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
#[derive(Clone, Debug)]
pub(super) struct Named {
    held: UvRange,
    unknown: bool,
}

#[cfg(any(test, not(any(wide_vectors, arm_neon))))]
impl Named {
    pub fn new() -> Self {
        Self {
            held: UvRange::EMPTY,
            unknown: false,
        }
    }

    /// Fragments whose coordinates lie in `range()` (anywhere for `None`) were held.
    #[inline(always)]
    pub fn held(&mut self, range: impl FnOnce() -> Option<UvRange>) {
        match range() {
            Some(r) => self.held = self.held.union(r),
            None => self.unknown = true,
        }
    }

    /// The buffer was emptied.
    #[inline(always)]
    pub fn emptied(&mut self) {
        (self.held, self.unknown) = (UvRange::EMPTY, false);
    }

    /// True when `view` holds every held fragment's coordinates inside.
    #[inline(always)]
    pub fn inside<T: Texel>(&self, view: Option<&LevelView<'_, T>>) -> bool {
        !self.unknown && view.is_some_and(|v| v.holds_inside(&self.held))
    }

    /// True when the held fragments' coordinates `u`, `v` lie in the range, or it is unknown:
    /// what the row steps promise (checked in builds with debug assertions).
    pub fn covers(&self, u: &[i32], v: &[i32]) -> bool {
        let within = |c: &[i32], k: usize| {
            c.iter()
                .all(|c| (self.held.lo[k]..=self.held.hi[k]).contains(c))
        };
        self.unknown || (within(u, 0) && within(v, 1))
    }
}

/// `Named` where the colour stage has no use for it.
#[cfg(any(wide_vectors, arm_neon))]
#[derive(Clone, Debug)]
pub(super) struct Unnamed;

#[cfg(any(wide_vectors, arm_neon))]
impl Unnamed {
    pub fn new() -> Self {
        Self
    }
    #[inline(always)]
    pub fn held(&mut self, _: impl FnOnce() -> Option<UvRange>) {}
    #[inline(always)]
    pub fn emptied(&mut self) {}
    #[inline(always)]
    pub fn inside<T: Texel>(&self, _: Option<&LevelView<'_, T>>) -> bool {
        false
    }
    pub fn covers(&self, _: &[i32], _: &[i32]) -> bool {
        true
    }
}

/// The record the build target's colour stage uses.
#[cfg(not(any(wide_vectors, arm_neon)))]
pub(super) type Coords = Named;
#[cfg(any(wide_vectors, arm_neon))]
pub(super) type Coords = Unnamed;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::Wrap;

    #[test]
    fn the_range_holds_every_fragment_held_since_the_buffer_was_emptied() {
        let texels = vec![0u16; 64];
        let view = LevelView::new(&texels, 8, 8, Wrap::Clamp);
        let range = |lo: i32, hi: i32| UvRange {
            lo: [lo; 2],
            hi: [hi; 2],
        };
        let (a, b, edge) = (range(9000, 20000), range(30000, 40000), range(10, 20000));
        let mut n = Named::new();
        assert!(!n.inside(Some(&view)), "nothing held");
        n.held(|| Some(a));
        assert!(n.inside(Some(&view)));
        assert!(!n.inside::<u16>(None));
        n.held(|| Some(b));
        assert_eq!(n.held, range(9000, 40000));
        // Fragments near the level's edge.
        n.held(|| Some(edge));
        assert!(!n.inside(Some(&view)));
        n.emptied();
        n.held(|| Some(a));
        assert!(n.inside(Some(&view)));
        // Fragments whose coordinates the row step did not bound.
        n.held(|| None);
        assert!(!n.inside(Some(&view)));
        n.emptied();
        assert!(!n.inside(Some(&view)), "nothing held");
        n.held(|| Some(b));
        assert!(n.inside(Some(&view)));
        assert!(n.covers(&[30000, 40000], &[35000, 30000]));
        assert!(!n.covers(&[30000, 40001], &[35000, 30000]));
        assert!(!n.covers(&[30000], &[29999]));
        n.held(|| None);
        assert!(n.covers(&[0], &[-5]), "unknown");
    }
}
