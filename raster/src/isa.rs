//! The instruction set the hot loops run in.
//!
//! The crate is built for its target's baseline (SSE2 on x86-64), so that one binary runs on
//! every CPU of the target. Where the CPU running it also has AVX2, BMI1, BMI2, LZCNT, POPCNT
//! and FMA (x86-64-v3: x86 CPUs since 2013-2015), three loops run in a twin of themselves built
//! for those features (`#[target_feature]`): the vertex stage, a tile's triangles, and the
//! colour stage. `wide`, the lanes' crate, chooses its AVX2 forms at compile time, so inside a
//! twin its lanes keep their SSE2 forms; where that cost most, the bilinear RGB565 texel pairs,
//! the colour stage's twin reads them with one AVX2 gather (`sampler::gather_words_avx2`).
//! Apart from that read the twins are the same source, over integers (the float pipeline's
//! vertex stage too: Rust does not fuse a multiplication and an addition into FMA on its own),
//! and they give the same bytes as the baseline (`tests/it/determinism.rs`; the sampler's lane
//! test checks the gather); `pocketpc_frames --baseline` counts what they save. Each
//! rasterizer checks the CPU once; on other targets the twins are not built.

/// Which instructions a rasterizer's hot loops may use beyond its build target's baseline.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InstructionSet {
    /// The best the CPU running the program has, checked at run time: on x86-64, AVX2 with
    /// BMI1, BMI2, LZCNT, POPCNT and FMA where all are present. The default.
    #[default]
    Detected,
    /// Only the build target's baseline (SSE2 on x86-64): for comparing the two, or ruling the
    /// CPU-specific loops out. The picture does not depend on it.
    Baseline,
}

/// The choice of loops a flush runs, made once per rasterizer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Cpu {
    /// The x86-64-v3 twins (only ever true where the CPU has every feature they are built for).
    v3: bool,
}

impl Cpu {
    /// The loops `set` allows on this CPU.
    pub fn new(set: InstructionSet) -> Self {
        Self {
            v3: set == InstructionSet::Detected && has_v3(),
        }
    }

    /// Whether the x86-64-v3 twins run. The features are checked in `Cpu::new`: a `Cpu` that
    /// says yes is the safety argument for calling a twin.
    #[inline(always)]
    pub fn v3(self) -> bool {
        cfg!(target_arch = "x86_64") && self.v3
    }
}

/// Builds a function as an x86-64-v3 twin: for x86-64 only, with the features `has_v3` checks
/// (one list for both), so that a `Cpu` whose `v3()` holds is the safety argument for calling
/// it.
macro_rules! v3_twin {
    ($($item:tt)*) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt,fma")]
        $($item)*
    };
}
pub(crate) use v3_twin;

/// Every feature `v3_twin` builds for, present on this CPU (and enabled by its operating
/// system, which `avx2`'s check includes).
#[cfg(target_arch = "x86_64")]
fn has_v3() -> bool {
    use std::arch::is_x86_feature_detected as has;
    has!("avx2") && has!("bmi1") && has!("bmi2") && has!("lzcnt") && has!("popcnt") && has!("fma")
}

#[cfg(not(target_arch = "x86_64"))]
fn has_v3() -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn baseline_never_takes_the_twins() {
        assert!(!Cpu::new(InstructionSet::Baseline).v3());
        assert_eq!(Cpu::new(InstructionSet::Detected).v3(), has_v3());
    }
}
